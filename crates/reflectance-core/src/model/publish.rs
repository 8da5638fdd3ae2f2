//! From a trained model to a served version: publication beside its report, and the policy
//! that decides whether the new version replaces the active one. The command line and the
//! service's training jobs both go through here.

use crate::model::registry::{Registry, RegistryError};
use crate::model::train::{TrainError, Trained};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What to do with a trained version.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Activate {
    /// Publish only (the active version stays).
    #[default]
    Never,
    /// Activate the new version.
    Always,
    /// Activate when its cross-validated accuracy is higher than the active version's
    /// stored one (or when the model has no active version).
    #[cfg_attr(feature = "cli", value(alias = "if_better"))]
    IfBetter,
}

/// The version a new one would replace: its number and its stored CV accuracy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Current {
    /// The active version's number.
    pub version: u32,
    /// Its stored cross-validated accuracy, in [0, 1] (absent in models trained without CV).
    pub accuracy: Option<f64>,
}

impl Current {
    /// The active version of `name` in `registry` and its stored accuracy (read from its
    /// file), when it has one that loads.
    pub fn in_registry(registry: &Registry, name: &str) -> Option<Current> {
        let version = registry.active(name).ok()?;
        let model = registry.load(name, version).ok()?;
        Some(Current {
            version,
            accuracy: model.training.cv.as_ref().map(|cv| cv.accuracy),
        })
    }
}

/// What [`Activate::decide`] found: whether to activate, and why (its `Display`, the
/// reason a job reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decision {
    /// Activate: always.
    Always,
    /// Activate: the model had no active version (`if_better`).
    NoActiveVersion,
    /// Activate: better than the active version (`if_better`).
    Better {
        /// The new version's CV accuracy.
        new: f64,
        /// The active version's.
        old: f64,
        /// The active version.
        version: u32,
    },
    /// Do not activate: never.
    Never,
    /// Do not activate: not better than the active version (`if_better`).
    NotBetter {
        /// The new version's CV accuracy.
        new: f64,
        /// The active version's.
        old: f64,
        /// The active version.
        version: u32,
    },
    /// Do not activate: the active version has no stored accuracy to compare with.
    NoStoredAccuracy {
        /// The active version.
        version: u32,
    },
    /// Do not activate: the new version has no CV accuracy (`if_better`).
    NoAccuracy,
}

impl Decision {
    /// Whether the new version is to be activated.
    pub fn activates(self) -> bool {
        matches!(
            self,
            Decision::Always | Decision::NoActiveVersion | Decision::Better { .. }
        )
    }
}

impl std::fmt::Display for Decision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Decision::Always => f.write_str("activate: always"),
            Decision::Never => f.write_str("activate: never"),
            Decision::NoActiveVersion => f.write_str("no active version"),
            Decision::Better { new, old, version } => {
                write!(f, "CV accuracy {new:.4} > {old:.4} of version {version}")
            }
            Decision::NotBetter { new, old, version } => {
                write!(f, "CV accuracy {new:.4} ≤ {old:.4} of version {version}")
            }
            Decision::NoStoredAccuracy { version } => write!(
                f,
                "active version {version} has no stored CV accuracy to compare with"
            ),
            Decision::NoAccuracy => f.write_str("no CV accuracy"),
        }
    }
}

impl Activate {
    /// Whether a new version of cross-validated accuracy `new` is to be activated in place
    /// of `current`, and why.
    pub fn decide(self, new: Option<f64>, current: Option<Current>) -> Decision {
        match self {
            Activate::Never => Decision::Never,
            Activate::Always => Decision::Always,
            Activate::IfBetter => match (current, new) {
                (None, _) => Decision::NoActiveVersion,
                (Some(c), Some(new)) => match c.accuracy {
                    Some(old) if new > old => Decision::Better {
                        new,
                        old,
                        version: c.version,
                    },
                    Some(old) => Decision::NotBetter {
                        new,
                        old,
                        version: c.version,
                    },
                    None => Decision::NoStoredAccuracy { version: c.version },
                },
                (Some(_), None) => Decision::NoAccuracy,
            },
        }
    }
}

/// A version published by [`Trained::publish_by`], and what its policy decided.
#[derive(Debug)]
pub struct Published {
    /// The new version.
    pub version: u32,
    /// Its folder.
    pub dir: PathBuf,
    /// Whether it is to be activated, and why. The caller activates it (the command line
    /// in the registry, the service in memory and in the registry).
    pub decision: Decision,
    /// Why the version active before could not be pinned, when it could not (the new
    /// version may then be active by the registry's rule, the latest).
    pub pin_failed: Option<RegistryError>,
}

impl Trained {
    /// The one way from a trained model to a version, for the command line and the jobs
    /// alike: pin the version active before (`current`: the one served, else the
    /// registry's), so that publication never activates the new one implicitly; publish;
    /// decide by `policy` against `current`.
    pub fn publish_by(
        &mut self,
        registry: &Registry,
        current: Option<Current>,
        policy: Activate,
    ) -> Result<Published, TrainError> {
        let name = self.model.name.clone();
        let pin_failed = current.and_then(|c| registry.set_active(&name, c.version).err());
        let (version, dir) = self.publish(registry)?;
        let accuracy = self.model.training.cv.as_ref().map(|cv| cv.accuracy);
        Ok(Published {
            version,
            dir,
            decision: policy.decide(accuracy, current),
            pin_failed,
        })
    }

    /// Publish the model as the next version of its name in `registry`, with its
    /// cross-validation report beside it (`report.json`): its version and folder.
    fn publish(&mut self, registry: &Registry) -> Result<(u32, PathBuf), TrainError> {
        let report = self
            .report
            .as_ref()
            .map(serde_json::to_vec_pretty)
            .transpose()?;
        let extra: Vec<(&str, &[u8])> = report
            .iter()
            .map(|r| ("report.json", r.as_slice()))
            .collect();
        Ok(registry.publish(&mut self.model, &extra)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policy_activates_what_it_says() {
        let current = |accuracy| {
            Some(Current {
                version: 3,
                accuracy,
            })
        };
        let never = Activate::Never.decide(Some(1.0), None);
        assert!(!never.activates());
        assert_eq!(never.to_string(), "activate: never");
        assert!(
            Activate::Always
                .decide(None, current(Some(0.9)))
                .activates()
        );
        let if_better = |new, cur| Activate::IfBetter.decide(new, cur);
        assert_eq!(if_better(None, None), Decision::NoActiveVersion);
        assert!(if_better(None, None).activates());
        let better = if_better(Some(0.95), current(Some(0.9)));
        assert!(better.activates());
        assert_eq!(
            better.to_string(),
            "CV accuracy 0.9500 > 0.9000 of version 3"
        );
        let equal = if_better(Some(0.9), current(Some(0.9)));
        assert!(!equal.activates());
        assert_eq!(
            equal.to_string(),
            "CV accuracy 0.9000 ≤ 0.9000 of version 3"
        );
        assert!(!if_better(Some(0.9), current(None)).activates());
        let unknown = if_better(None, current(Some(0.5)));
        assert!(!unknown.activates());
        assert_eq!(unknown.to_string(), "no CV accuracy");
    }
}
