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
    pub name: String,
    pub rho_d: f64,
    pub rho_s: f64,
    pub alpha: f64,
}

#[derive(Debug, thiserror::Error, PartialEq)]
#[error("class {name:?}: need 0 ≤ rho_d, 0 ≤ rho_s, rho_d + rho_s ≤ 1 and 0 ≤ alpha ≤ 1")]
pub struct MaterialError {
    pub name: String,
}

impl Material {
    pub fn validate(&self) -> Result<(), MaterialError> {
        let ok = self.rho_d >= 0.0
            && self.rho_s >= 0.0
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

#[derive(Debug, thiserror::Error)]
pub enum ClassFileError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a class file ({detail})")]
    Invalid { path: String, detail: String },
    #[error(transparent)]
    Material(#[from] MaterialError),
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
