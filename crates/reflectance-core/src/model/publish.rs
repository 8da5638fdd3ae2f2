//! From a trained model to a served version: publication beside its report, and the policy
//! that decides whether the new version replaces the active one. The command line and the
//! service's training jobs both go through here.

use crate::model::registry::Registry;
use crate::model::train::{TrainError, Trained};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What to do with a trained version.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Activate {
    /// Publish only (the active version stays).
    #[default]
    Never,
    /// Activate the new version.
    Always,
    /// Activate when its cross-validated accuracy is higher than the active version's
    /// stored one (or when the model has no active version).
    IfBetter,
}

/// The version a new one would replace: its number and its stored CV accuracy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Current {
    pub version: u32,
    pub accuracy: Option<f64>,
}

/// What [`Activate::decide`] found: whether to activate, and why (its `Display`, the
/// reason a job reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decision {
    Always,
    NoActiveVersion,
    Better { new: f64, old: f64, version: u32 },
    Never,
    NotBetter { new: f64, old: f64, version: u32 },
    NoStoredAccuracy { version: u32 },
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

impl Trained {
    /// Publish the model as the next version of its name in `registry`, with its
    /// cross-validation report beside it (`report.json`): its version and folder.
    pub fn publish(&mut self, registry: &Registry) -> Result<(u32, PathBuf), TrainError> {
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
