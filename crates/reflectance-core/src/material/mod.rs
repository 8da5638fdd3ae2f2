//! What the classes are made of, and what captures a model was trained for: the Ward
//! material of a class, class files, designs of continuous materials, and the capture
//! envelope.

pub mod design;
mod envelope;
pub mod gltf;
mod ward;

pub use envelope::{CaptureEnvelope, CaptureRanges, InvalidRanges, VIEW_TAG};
use serde::{Deserialize, Serialize};
use std::path::Path;
pub use ward::{InvalidWard, Ward};

/// One reflectance class: its name and its Ward parameters (on the wire flat, as class
/// files hold it: `{"name", "rho_d", "rho_s", "alpha"}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "Flat", into = "Flat")]
pub struct Material {
    /// The class's name (not empty).
    pub name: String,
    /// Its Ward parameters.
    pub ward: Ward,
}

/// A class as class files spell it. Not `#[serde(flatten)]`: that buffers the object, and
/// a class file's errors would then point past the class rather than at the bad value.
#[derive(Serialize, Deserialize)]
#[serde(rename = "Material", expecting = "struct Material")]
struct Flat {
    name: String,
    rho_d: f64,
    rho_s: f64,
    alpha: f64,
}

impl From<Flat> for Material {
    fn from(f: Flat) -> Material {
        let ward = Ward {
            rho_d: f.rho_d,
            rho_s: f.rho_s,
            alpha: f.alpha,
        };
        Material { name: f.name, ward }
    }
}

impl From<Material> for Flat {
    fn from(m: Material) -> Flat {
        let Ward {
            rho_d,
            rho_s,
            alpha,
        } = m.ward;
        Flat {
            name: m.name,
            rho_d,
            rho_s,
            alpha,
        }
    }
}

/// A class that breaks the rules of [`Material::validate`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MaterialError {
    /// A class without a name.
    #[error("a class needs a name")]
    Unnamed,
    /// A class whose parameters break the rules of [`Ward::validate`].
    #[error("class {name:?}: {ward}")]
    Ward {
        /// The class's name.
        name: String,
        /// Its parameters, and the rules.
        ward: InvalidWard,
    },
}

impl Material {
    /// Check the rules: a name, and parameters that keep [`Ward::validate`]'s.
    pub fn validate(&self) -> Result<(), MaterialError> {
        if self.name.is_empty() {
            return Err(MaterialError::Unnamed);
        }
        self.ward.validate().map_err(|ward| MaterialError::Ward {
            name: self.name.clone(),
            ward,
        })
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
    use super::{Material, MaterialError, Ward};

    #[test]
    fn a_class_needs_a_name_and_valid_parameters() {
        let ward = Ward {
            rho_d: 0.7,
            rho_s: 0.25,
            alpha: 0.01,
        };
        let class = |name: &str, ward| Material {
            name: name.into(),
            ward,
        };
        assert!(class("a", ward).validate().is_ok());
        assert_eq!(class("", ward).validate(), Err(MaterialError::Unnamed));
        let bright = Ward { rho_s: 0.5, ..ward };
        let e = class("a", bright).validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("class \"a\": {}", bright.validate().unwrap_err())
        );
    }

    /// On the wire a class is flat, as class files hold it; an error points at the bad
    /// value.
    #[test]
    fn a_class_reads_and_writes_flat() {
        let text = r#"{"name":"chrome","rho_d":0.0,"rho_s":0.75,"alpha":0.0}"#;
        let class: Material = serde_json::from_str(text).unwrap();
        assert_eq!(class.ward.rho_s, 0.75);
        assert_eq!(serde_json::to_string(&class).unwrap(), text);
        let bad = r#"{"name":"x","rho_d":"0.3","rho_s":0.1,"alpha":0.0}"#;
        let e = serde_json::from_str::<Material>(bad).unwrap_err();
        assert_eq!((e.line(), e.column()), (1, 25), "{e}");
        let e = serde_json::from_str::<Material>("3").unwrap_err();
        assert!(e.to_string().contains("expected struct Material"), "{e}");
    }
}
