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

impl Activate {
    /// Whether a new version of cross-validated accuracy `new` is to be activated in place
    /// of `current`: `Ok(why)` to activate, `Err(why not)`.
    pub fn decide(self, new: Option<f64>, current: Option<Current>) -> Result<String, String> {
        match self {
            Activate::Never => Err("activate: never".to_string()),
            Activate::Always => Ok("activate: always".to_string()),
            Activate::IfBetter => match (current, new) {
                (None, _) => Ok("no active version".to_string()),
                (Some(c), Some(new)) => match c.accuracy {
                    Some(old) if new > old => Ok(format!(
                        "CV accuracy {new:.4} > {old:.4} of version {}",
                        c.version
                    )),
                    Some(old) => Err(format!(
                        "CV accuracy {new:.4} ≤ {old:.4} of version {}",
                        c.version
                    )),
                    None => Err(format!(
                        "active version {} has no stored CV accuracy to compare with",
                        c.version
                    )),
                },
                (Some(_), None) => Err("no CV accuracy".to_string()),
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
        assert_eq!(
            Activate::Never.decide(Some(1.0), None),
            Err("activate: never".into())
        );
        assert!(Activate::Always.decide(None, current(Some(0.9))).is_ok());
        let if_better = |new, cur| Activate::IfBetter.decide(new, cur);
        assert_eq!(if_better(None, None), Ok("no active version".into()));
        assert_eq!(
            if_better(Some(0.95), current(Some(0.9))),
            Ok("CV accuracy 0.9500 > 0.9000 of version 3".into())
        );
        assert_eq!(
            if_better(Some(0.9), current(Some(0.9))),
            Err("CV accuracy 0.9000 ≤ 0.9000 of version 3".into())
        );
        assert!(if_better(Some(0.9), current(None)).is_err());
        assert_eq!(
            if_better(None, current(Some(0.5))),
            Err("no CV accuracy".into())
        );
    }
}
