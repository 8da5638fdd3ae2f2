//! What the classes are made of, and what captures a model was trained for: the Ward
//! material of a class, class files, designs of continuous materials, and the capture
//! envelope.

pub mod design;
mod envelope;
mod finish;
pub mod gltf;
mod ward;

pub use envelope::{CaptureEnvelope, CaptureRanges, InvalidRanges, VIEW_TAG};
pub use finish::{DISC_MAX_TILT_DEG, Disc, Finish, Fresnel, Specular};
use serde::{Deserialize, Serialize};
use std::path::Path;
pub use ward::{InvalidWard, Ward};

/// One reflectance class, or one member of it: its name, its Ward parameters and what a
/// real-like member adds to them (on the wire flat, as class files hold it: `{"name",
/// "rho_d", "rho_s", "alpha"}`, and optionally `"member"`, `"ior"`, `"metal"`, `"disc"`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Flat", into = "Flat")]
pub struct Material {
    /// The class's name (not empty).
    pub name: String,
    /// Which of the class's materials this is (`None`: the class's reference material, the
    /// one a model records and answers name).
    pub member: Option<String>,
    /// Its Ward parameters.
    pub ward: Ward,
    /// A Fresnel term and a printed disc, when it has them.
    pub finish: Finish,
}

/// A class as class files spell it. Not `#[serde(flatten)]`: that buffers the object, and
/// a class file's errors would then point past the class rather than at the bad value.
#[derive(Serialize, Deserialize)]
#[serde(rename = "Material", expecting = "struct Material")]
struct Flat {
    name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    member: Option<String>,
    rho_d: f64,
    rho_s: f64,
    alpha: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ior: Option<f64>,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    metal: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    disc: Option<Disc>,
}

impl TryFrom<Flat> for Material {
    type Error = String;

    fn try_from(f: Flat) -> Result<Material, String> {
        let ward = Ward {
            rho_d: f.rho_d,
            rho_s: f.rho_s,
            alpha: f.alpha,
        };
        let fresnel = match (f.ior, f.metal) {
            (Some(ior), false) => Fresnel::Dielectric { ior },
            (None, true) => Fresnel::Metal,
            (None, false) => Fresnel::Constant,
            (Some(_), true) => {
                return Err(format!(
                    "class {:?}: a material is a dielectric (\"ior\") or a metal (\"metal\": \
                     true), not both",
                    f.name
                ));
            }
        };
        let finish = Finish {
            fresnel,
            disc: f.disc,
        };
        Ok(Material {
            name: f.name,
            member: f.member,
            ward,
            finish,
        })
    }
}

impl From<Material> for Flat {
    fn from(m: Material) -> Flat {
        let Ward {
            rho_d,
            rho_s,
            alpha,
        } = m.ward;
        let (ior, metal) = match m.finish.fresnel {
            Fresnel::Constant => (None, false),
            Fresnel::Dielectric { ior } => (Some(ior), false),
            Fresnel::Metal => (None, true),
        };
        Flat {
            name: m.name,
            member: m.member,
            rho_d,
            rho_s,
            alpha,
            ior,
            metal,
            disc: m.finish.disc,
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
    /// A member name that cannot be part of a file name.
    #[error("class {name:?}: a member is named by letters, digits, '_' and '-', not {member:?}")]
    Member {
        /// The class's name.
        name: String,
        /// The member's name.
        member: String,
    },
    /// A Fresnel term or a disc outside its rules.
    #[error("class {label:?}: {rule}")]
    Finish {
        /// The class's name, with its member's.
        label: String,
        /// The rule broken, with the values.
        rule: String,
    },
}

/// The separator of a class's name and its member's in file names (`black_shiny+billiard`).
pub const MEMBER_SEPARATOR: char = '+';

/// Whether a rendered image's path names a class's member (`…__black_shiny+billiard.pfm`,
/// as `render` names it: the material's [`Material::label`] after the last `__`) rather
/// than its reference material.
pub fn names_a_member(path: &str) -> bool {
    let name = path.rsplit(['/', '\\']).next().unwrap_or(path);
    name.rsplit_once("__")
        .is_some_and(|(_, material)| material.contains(MEMBER_SEPARATOR))
}

impl Material {
    /// A class's reference material: plain Ward, no member.
    pub fn new(name: impl Into<String>, ward: Ward) -> Material {
        Material {
            name: name.into(),
            member: None,
            ward,
            finish: Finish::default(),
        }
    }

    /// How rendered files name it: the class's name, and its member's after
    /// [`MEMBER_SEPARATOR`] (the reference material: the name alone, as ever).
    pub fn label(&self) -> String {
        match &self.member {
            None => self.name.clone(),
            Some(member) => format!("{}{MEMBER_SEPARATOR}{member}", self.name),
        }
    }

    /// Check the rules: a name, parameters that keep [`Ward::validate`]'s, a member named
    /// by letters, digits, `_` and `-`; a Fresnel term only on a specular part (ρs > 0), an
    /// index of refraction in (1, 4]; a disc's albedo in [0, 1] with albedo + ρs ≤ 1 and
    /// its radius in (0°, 90°].
    pub fn validate(&self) -> Result<(), MaterialError> {
        if self.name.is_empty() {
            return Err(MaterialError::Unnamed);
        }
        self.ward.validate().map_err(|ward| MaterialError::Ward {
            name: self.name.clone(),
            ward,
        })?;
        if let Some(member) = &self.member {
            let allowed = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
            if member.is_empty() || !member.chars().all(allowed) {
                return Err(MaterialError::Member {
                    name: self.name.clone(),
                    member: member.clone(),
                });
            }
        }
        let refuse = |rule: String| {
            Err(MaterialError::Finish {
                label: self.label(),
                rule,
            })
        };
        match self.finish.fresnel {
            Fresnel::Constant => {}
            _ if self.ward.rho_s <= 0.0 => {
                return refuse("a Fresnel term (\"ior\" or \"metal\") needs rho_s > 0".into());
            }
            Fresnel::Dielectric { ior } if !(ior > 1.0 && ior <= 4.0) => {
                return refuse(format!("need 1 < ior ≤ 4, not ior {ior}"));
            }
            _ => {}
        }
        if let Some(Disc { albedo, radius }) = self.finish.disc {
            let ok = (0.0..=1.0).contains(&albedo)
                && albedo + self.ward.rho_s <= 1.0 + 1e-12
                && radius > 0.0
                && radius <= 90.0;
            if !ok {
                return refuse(format!(
                    "a disc needs 0 ≤ albedo, albedo + rho_s ≤ 1 and 0 < radius ≤ 90 (degrees), \
                     not albedo {albedo}, radius {radius}"
                ));
            }
        }
        Ok(())
    }
}

/// The reference material of class `name` in `materials`: its entry without a member
/// (what a model records as the class's Ward parameters).
pub fn reference<'a>(materials: &'a [Material], name: &str) -> Option<&'a Material> {
    materials
        .iter()
        .find(|m| m.name == name && m.member.is_none())
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
    /// Two classes of the same name, neither a member (or two members of one name).
    #[error("duplicate class name {0:?}")]
    DuplicateClass(String),
    /// A class with members but no reference entry (one without `member`).
    #[error(
        "class {0:?} has members but no reference material (an entry of its name without \
         \"member\")"
    )]
    NoReference(String),
}

#[derive(Deserialize)]
struct ClassFile {
    classes: Vec<Material>,
}

/// Read a class file (`{"classes": [{"name", "rho_d", "rho_s", "alpha"}, …]}`, entries
/// optionally with `member`, `ior`, `metal`, `disc`): at least one class, every entry
/// valid, no name (or name and member) twice, and every class with its reference entry.
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
        if !seen.insert(class.label()) {
            return Err(ClassFileError::DuplicateClass(class.label()));
        }
    }
    for class in &file.classes {
        if reference(&file.classes, &class.name).is_none() {
            return Err(ClassFileError::NoReference(class.name.clone()));
        }
    }
    if file.classes.is_empty() {
        return Err(invalid("no classes".into()));
    }
    Ok(file.classes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rendered_path_names_a_member_after_its_probe() {
        for member in [
            "p0__black_shiny+billiard.pfm",
            "cc0/some_probe@rot90@cap2__gray_shiny+plastic_rough.jpg",
            r"dir\probe__chrome+steel.png",
        ] {
            assert!(names_a_member(member), "{member}");
        }
        for reference in [
            "p0__black_shiny.pfm",
            "a+b/some_probe@cap1__chrome.png",
            "photo+1.jpg",
            "black_shiny+billiard",
        ] {
            assert!(!names_a_member(reference), "{reference}");
        }
    }

    #[test]
    fn a_class_needs_a_name_and_valid_parameters() {
        let ward = Ward {
            rho_d: 0.7,
            rho_s: 0.25,
            alpha: 0.01,
        };
        let class = |name: &str, ward| Material::new(name, ward);
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

    /// The optional fields read and write back as written; an entry without them writes
    /// exactly the paper's four fields (above).
    #[test]
    fn members_fresnel_terms_and_discs_read_and_write_flat() {
        let text = r#"{"name":"black_shiny","member":"billiard","rho_d":0.02,"rho_s":0.04,"alpha":0.003,"ior":1.5,"disc":{"albedo":0.85,"radius":25.0}}"#;
        let m: Material = serde_json::from_str(text).unwrap();
        assert_eq!(m.member.as_deref(), Some("billiard"));
        assert_eq!(m.finish.fresnel, Fresnel::Dielectric { ior: 1.5 });
        assert_eq!(
            m.finish.disc,
            Some(Disc {
                albedo: 0.85,
                radius: 25.0
            })
        );
        assert_eq!(m.label(), "black_shiny+billiard");
        assert!(m.validate().is_ok());
        assert_eq!(serde_json::to_string(&m).unwrap(), text);
        let metal = r#"{"name":"chrome","member":"steel","rho_d":0.0,"rho_s":0.55,"alpha":0.0,"metal":true}"#;
        let m: Material = serde_json::from_str(metal).unwrap();
        assert_eq!(m.finish.fresnel, Fresnel::Metal);
        assert_eq!(serde_json::to_string(&m).unwrap(), metal);
        let both = r#"{"name":"x","rho_d":0.0,"rho_s":0.5,"alpha":0.0,"metal":true,"ior":1.5}"#;
        let e = serde_json::from_str::<Material>(both).unwrap_err();
        assert!(e.to_string().contains("not both"), "{e}");
        let typo =
            r#"{"name":"x","rho_d":0.0,"rho_s":0.5,"alpha":0.0,"disc":{"albedo":0.5,"radus":3}}"#;
        assert!(serde_json::from_str::<Material>(typo).is_err());
    }

    #[test]
    fn fresnel_terms_members_and_discs_keep_their_rules() {
        let base: Material = serde_json::from_str(
            r#"{"name":"a","member":"m","rho_d":0.1,"rho_s":0.04,"alpha":0.0,"ior":1.5}"#,
        )
        .unwrap();
        let with = |f: &dyn Fn(&mut Material)| {
            let mut m = base.clone();
            f(&mut m);
            m.validate()
        };
        assert!(with(&|_| ()).is_ok());
        let refused = [
            with(&|m| m.member = Some("a/b".into())),
            with(&|m| m.member = Some(String::new())),
            with(&|m| m.ward.rho_s = 0.0),
            with(&|m| m.finish.fresnel = Fresnel::Dielectric { ior: 1.0 }),
            with(&|m| m.finish.fresnel = Fresnel::Dielectric { ior: f64::NAN }),
            with(&|m| {
                m.finish.disc = Some(Disc {
                    albedo: 0.97,
                    radius: 20.0,
                })
            }),
            with(&|m| {
                m.finish.disc = Some(Disc {
                    albedo: 0.5,
                    radius: 0.0,
                })
            }),
        ];
        for r in refused {
            assert!(r.is_err());
        }
        let e = with(&|m| m.finish.fresnel = Fresnel::Dielectric { ior: 0.5 }).unwrap_err();
        assert_eq!(
            e.to_string(),
            "class \"a+m\": need 1 < ior ≤ 4, not ior 0.5"
        );
    }

    /// Members share their class's name; the reference entry (no member) is required once;
    /// true duplicates are refused.
    #[test]
    fn a_class_file_has_one_reference_per_class_and_no_duplicates() {
        let dir = std::env::temp_dir().join(format!("classes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let load = |entries: &str| {
            let path = dir.join("c.json");
            std::fs::write(&path, format!(r#"{{"classes": [{entries}]}}"#)).unwrap();
            load_classes(&path)
        };
        let reference_entry = r#"{"name":"a","rho_d":0.1,"rho_s":0.1,"alpha":0.01}"#;
        let member = |m: &str| {
            format!(
                r#"{{"name":"a","member":"{m}","rho_d":0.02,"rho_s":0.04,"alpha":0,"ior":1.5}}"#
            )
        };
        let ok = load(&format!(
            "{},{},{}",
            member("x"),
            reference_entry,
            member("y")
        ))
        .unwrap();
        assert_eq!(ok.len(), 3);
        let r = reference(&ok, "a").unwrap();
        assert_eq!((r.member.as_ref(), r.ward.rho_d), (None, 0.1));
        let e = load(&format!("{reference_entry},{reference_entry}")).unwrap_err();
        assert_eq!(e.to_string(), "duplicate class name \"a\"");
        let e = load(&format!(
            "{reference_entry},{},{}",
            member("x"),
            member("x")
        ))
        .unwrap_err();
        assert_eq!(e.to_string(), "duplicate class name \"a+x\"");
        let e = load(&member("x")).unwrap_err();
        assert!(
            matches!(e, ClassFileError::NoReference(ref n) if n == "a"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
