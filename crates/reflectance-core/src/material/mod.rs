//! What the classes are made of, and what captures a model was trained for: the Ward
//! material of a class, class files, designs of continuous materials, and the capture
//! envelope.

pub mod design;
mod envelope;
pub mod gltf;

pub use envelope::{CaptureEnvelope, CaptureRanges, InvalidRanges, VIEW_TAG};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One reflectance class: isotropic Ward parameters (diffuse ρd, specular ρs, roughness
/// α; α = 0 is the ideal mirror).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// The class's name (not empty).
    pub name: String,
    /// Diffuse reflectance ρd ≥ 0.
    pub rho_d: f64,
    /// Specular reflectance ρs ≥ 0, with ρd + ρs ≤ 1.
    pub rho_s: f64,
    /// Roughness α, in [0, 1] (0: the ideal mirror).
    pub alpha: f64,
}

/// A class whose parameters break the rules of [`Material::validate`].
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("class {name:?}: need 0 ≤ rho_d, 0 ≤ rho_s, rho_d + rho_s ≤ 1 and 0 ≤ alpha ≤ 1")]
pub struct MaterialError {
    /// The class's name.
    pub name: String,
}

impl Material {
    /// Check the rules: a name, 0 ≤ ρd, 0 ≤ ρs, ρd + ρs ≤ 1 and 0 ≤ α ≤ 1.
    pub fn validate(&self) -> Result<(), MaterialError> {
        // The sum may exceed 1 by rounding (0.7 + 0.3 in a class file); each part may not.
        let ok = (0.0..=1.0).contains(&self.rho_d)
            && (0.0..=1.0).contains(&self.rho_s)
            && self.rho_d + self.rho_s <= 1.0 + 1e-12
            && (0.0..=1.0).contains(&self.alpha)
            && !self.name.is_empty();
        if ok {
            Ok(())
        } else {
            Err(MaterialError {
                name: self.name.clone(),
            })
        }
    }
}

/// Why a class file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ClassFileError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// Its path.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file is not JSON of a class list, or lists no class.
    #[error("{path}: not a class file ({detail})")]
    Invalid {
        /// Its path.
        path: String,
        /// What is wrong.
        detail: String,
    },
    /// A class breaks the parameter rules.
    #[error(transparent)]
    Material(#[from] MaterialError),
    /// Two classes of the same name.
    #[error("duplicate class name {0:?}")]
    DuplicateClass(String),
}

#[derive(Deserialize)]
struct ClassFile {
    classes: Vec<Material>,
}

/// Read a class file (`{"classes": [{"name", "rho_d", "rho_s", "alpha"}, …]}`): at least
/// one class, every one valid, no name twice.
pub fn load_classes(path: &Path) -> Result<Vec<Material>, ClassFileError> {
    let invalid = |detail: String| ClassFileError::Invalid {
        path: path.display().to_string(),
        detail,
    };
    let text = std::fs::read_to_string(path).map_err(|source| ClassFileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let file: ClassFile = serde_json::from_str(&text).map_err(|e| invalid(e.to_string()))?;
    let mut seen = std::collections::HashSet::new();
    for class in &file.classes {
        class.validate()?;
        if !seen.insert(class.name.as_str()) {
            return Err(ClassFileError::DuplicateClass(class.name.clone()));
        }
    }
    if file.classes.is_empty() {
        return Err(invalid("no classes".into()));
    }
    Ok(file.classes)
}

#[cfg(test)]
mod tests {
    use super::Material;

    fn material(rho_d: f64, rho_s: f64) -> Material {
        Material {
            name: "m".into(),
            rho_d,
            rho_s,
            alpha: 0.05,
        }
    }

    #[test]
    fn each_reflectance_is_at_most_one_and_their_sum_rounds() {
        assert!(material(1.0, 0.0).validate().is_ok());
        // A sum above 1 by rounding only, as class files hold.
        assert!(material(0.700_000_000_000_000_1, 0.3).validate().is_ok());
        assert!(material(1.000_000_000_000_000_2, 0.0).validate().is_err());
        assert!(material(0.0, 1.000_000_000_000_000_2).validate().is_err());
        assert!(material(0.6, 0.5).validate().is_err());
        assert!(material(-0.0001, 0.5).validate().is_err());
    }
}
