//! What to train: the options a user gives ([`ClassifierOptions`]: the command line's flags,
//! a learning job's JSON keys) and the specification they make over a table's columns
//! ([`TrainSpec`]: what [`super::fit`] and [`super::cross_validate`] read).

use crate::learn::error::LearnError;
use crate::learn::feature_set::FeatureSet;
use serde::{Deserialize, Deserializer, Serialize};
use std::fmt;
use std::str::FromStr;

/// Folds of the internal cross-validation that produces the calibration decision values,
/// unless the specification names another number.
pub const CALIBRATION_FOLDS: usize = 5;

/// The SVM's default C (docs/design.md §3 "Classifiers").
pub const DEFAULT_C: f64 = 100.0;

/// The feature set a learning job reads when it names none.
pub const DEFAULT_FEATURES: &str = "hand6";

/// The seed of training when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// How an SVM's probabilities are made from its decision values (docs/design.md §3
/// "Classifiers").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationKind {
    /// One temperature for a softmax of the decision values, fitted on the decision values
    /// of illuminations held out in turn (the most probable class is the largest decision
    /// value).
    #[default]
    Softmax,
    /// libsvm's per-class Platt sigmoids on a stratified internal cross-validation (as
    /// scikit-learn's `SVC(probability=True)`; kept for comparisons with it).
    Platt,
}

/// Which classifier to train (docs/design.md §3 "Classifiers"); spelled `svm`, `nn`, `knn5`,
/// `chance` ([`FromStr`] and [`fmt::Display`]; serde reads and writes the same words, so a
/// model file, a job and the command line accept and refuse the same).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ClassifierKind {
    /// An RBF-kernel support vector machine (the paper's classifier).
    #[default]
    Svm,
    /// Nearest neighbour (1-NN) in standardized input space.
    Nn,
    /// 5 nearest neighbours, by vote.
    Knn5,
    /// The training class frequencies, whatever the input: the baseline every classifier must beat.
    Chance,
}

impl FromStr for ClassifierKind {
    type Err = LearnError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "svm" => Ok(ClassifierKind::Svm),
            "nn" => Ok(ClassifierKind::Nn),
            "knn5" => Ok(ClassifierKind::Knn5),
            "chance" => Ok(ClassifierKind::Chance),
            other => Err(LearnError::InvalidParameter(format!(
                "unknown classifier {other:?} (expected svm, nn, knn5 or chance)"
            ))),
        }
    }
}

impl<'de> Deserialize<'de> for ClassifierKind {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = std::borrow::Cow::<str>::deserialize(deserializer)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

impl fmt::Display for ClassifierKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ClassifierKind::Svm => "svm",
            ClassifierKind::Nn => "nn",
            ClassifierKind::Knn5 => "knn5",
            ClassifierKind::Chance => "chance",
        })
    }
}

/// Hyper-parameter grid of the SVM: C values × γ multipliers (γ = multiplier / number of
/// classifier inputs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    /// SVM C values (> 0).
    pub c: Vec<f64>,
    /// γ multipliers (> 0): γ = multiplier / number of classifier inputs.
    pub gamma_multipliers: Vec<f64>,
}

impl Default for Grid {
    fn default() -> Self {
        Grid {
            c: vec![1.0, 10.0, 100.0, 1000.0],
            gamma_multipliers: vec![0.25, 0.5, 1.0, 2.0, 4.0],
        }
    }
}

/// What to train: the features, the classifier, its hyper-parameters and its calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainSpec {
    /// The classifier's inputs.
    pub features: FeatureSet,
    /// The classifier.
    pub classifier: ClassifierKind,
    /// SVM C (default [`DEFAULT_C`]).
    pub c: f64,
    /// SVM γ; `None` = 1 / number of classifier inputs.
    pub gamma: Option<f64>,
    /// Choose (C, γ) by inner leave-one-illumination-out CV on the training data.
    pub grid: Option<Grid>,
    /// How decision values become probabilities.
    pub calibration: CalibrationKind,
    /// Folds of the calibration (illuminations dealt to this many; 0: one fold per
    /// illumination, each held out in turn).
    pub calibration_folds: usize,
}

impl TrainSpec {
    /// A specification with the defaults: C = [`DEFAULT_C`], γ = 1 / inputs, no grid, the
    /// default calibration and its folds.
    pub fn new(features: FeatureSet, classifier: ClassifierKind) -> Self {
        TrainSpec {
            features,
            classifier,
            c: DEFAULT_C,
            gamma: None,
            grid: None,
            calibration: CalibrationKind::default(),
            calibration_folds: CALIBRATION_FOLDS,
        }
    }
}

/// How a classifier is trained, as a user chooses it: one definition for the command line
/// (flattened into `cv`'s and `train`'s arguments, feature `cli`), the service's learning
/// jobs (JSON keys, feature `openapi` for the schema) and a model's classifier for objects;
/// [`ClassifierOptions::spec`] makes the [`TrainSpec`] of a table, so that all accept and
/// refuse the same. The extraction's options are [`crate::features::FeatureOptions`], the
/// estimator's [`crate::estimate::EstimatorOptions`], beside these.
///
/// The doc comments are the JSON keys' descriptions (openapi.yaml); where the command
/// line's help says more, its `help` says it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClassifierOptions {
    /// A named set (hand6, hand2, mean1, hand6+log, hand6+log+radial, hand6+log+radial+dep,
    /// hand6+cap, hand6+log+cap, hand6+log+ctr, hand6+log+cap+ctr, estimator, scale_free), all,
    /// auto<N>, pca<N>, or a comma-separated list of names.
    #[serde(default = "default_features")]
    #[cfg_attr(feature = "openapi", schema(default = "hand6"))]
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            help = "A named set (hand6, hand2, mean1, hand6+log, hand6+log+radial, \
                    hand6+log+radial+dep, hand6+cap, hand6+log+cap, hand6+log+ctr, \
                    hand6+log+cap+ctr, estimator, scale_free), all, auto<N>, pca<N>, or a \
                    comma-separated list of names. `all`, `auto<N>` and `pca<N>` range over the table's columns"
        )
    )]
    pub features: String,
    /// svm, nn, knn5 or chance.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(value_type = String, default = "svm"))]
    #[cfg_attr(
        feature = "cli",
        arg(long, default_value_t = ClassifierKind::Svm, help = "svm, nn (1-NN), knn5 or chance")
    )]
    pub classifier: ClassifierKind,
    /// SVM C.
    #[serde(default = "default_c")]
    #[cfg_attr(feature = "openapi", schema(default = default_c))]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_C))]
    pub c: f64,
    /// SVM γ (default 1 / number of classifier inputs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub gamma: Option<f64>,
    /// Choose C and γ by inner leave-one-illumination-out CV.
    #[serde(default)]
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            help = "Choose C and γ by inner leave-one-illumination-out CV over a default grid"
        )
    )]
    pub grid: bool,
    /// Folds of illuminations that calibrate the probabilities, the prediction sets and the
    /// domain check (0: every illumination held out in turn).
    #[serde(default = "default_calibration_folds")]
    #[cfg_attr(feature = "openapi", schema(default = 5))]
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            default_value_t = CALIBRATION_FOLDS,
            help = "Folds of illuminations whose held-out decision values calibrate the \
                    probabilities, the prediction sets and the domain check (0: every \
                    illumination held out in turn)"
        )
    )]
    pub calibration_folds: usize,
    #[serde(default = "default_seed")]
    #[cfg_attr(feature = "openapi", schema(default = 1))]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_SEED))]
    #[allow(
        missing_docs,
        reason = "undocumented on the command line and in openapi.yaml"
    )]
    pub seed: u64,
}

fn default_features() -> String {
    DEFAULT_FEATURES.into()
}

fn default_c() -> f64 {
    DEFAULT_C
}

fn default_calibration_folds() -> usize {
    CALIBRATION_FOLDS
}

fn default_seed() -> u64 {
    DEFAULT_SEED
}

impl Default for ClassifierOptions {
    /// What a learning job gets for the keys it leaves out.
    fn default() -> Self {
        ClassifierOptions {
            features: default_features(),
            classifier: ClassifierKind::default(),
            c: DEFAULT_C,
            gamma: None,
            grid: false,
            calibration_folds: CALIBRATION_FOLDS,
            seed: DEFAULT_SEED,
        }
    }
}

impl ClassifierOptions {
    /// The JSON keys, in the order a job's refusal of an unknown key lists them.
    pub const KEYS: [&str; 7] = [
        "features",
        "classifier",
        "c",
        "gamma",
        "grid",
        "seed",
        "calibration_folds",
    ];

    /// The specification over a table whose columns are `names`: the feature set resolved
    /// against them, and the numbers checked.
    pub fn spec(&self, names: &[String]) -> Result<TrainSpec, LearnError> {
        let features = FeatureSet::parse_with(&self.features, names)?;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.c) || self.gamma.is_some_and(|g| !positive(g)) {
            return Err(LearnError::InvalidParameter(
                "C (c) and γ (gamma) must be finite and positive".into(),
            ));
        }
        if self.calibration_folds == 1 {
            return Err(LearnError::InvalidParameter(
                "calibration folds must be at least 2 (0: one per illumination)".into(),
            ));
        }
        Ok(TrainSpec {
            features,
            classifier: self.classifier,
            c: self.c,
            gamma: self.gamma,
            grid: self.grid.then(Grid::default),
            calibration: CalibrationKind::default(),
            calibration_folds: self.calibration_folds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names() -> Vec<String> {
        (0..5).map(|j| format!("f{j}")).collect()
    }

    #[test]
    fn the_keys_are_those_serde_reads_and_writes() {
        let every = ClassifierOptions {
            gamma: Some(0.5),
            ..ClassifierOptions::default()
        };
        let serde_json::Value::Object(map) = serde_json::to_value(every).unwrap() else {
            panic!("not an object")
        };
        let mut written: Vec<&str> = map.keys().map(String::as_str).collect();
        let mut keys = ClassifierOptions::KEYS.to_vec();
        written.sort_unstable();
        keys.sort_unstable();
        assert_eq!(written, keys);
    }

    #[test]
    fn a_job_without_keys_gets_the_defaults() {
        let read: ClassifierOptions = serde_json::from_str("{}").unwrap();
        assert_eq!(read, ClassifierOptions::default());
        let spec = ClassifierOptions {
            features: "f0,f2".into(),
            ..read
        }
        .spec(&names())
        .unwrap();
        let expected = TrainSpec::new(
            FeatureSet::List(vec!["f0".into(), "f2".into()]),
            ClassifierKind::Svm,
        );
        assert_eq!(spec, expected);
    }

    #[test]
    fn the_classifier_is_read_as_it_is_spelled_and_refused_in_its_own_words() {
        for kind in [
            ClassifierKind::Svm,
            ClassifierKind::Nn,
            ClassifierKind::Knn5,
            ClassifierKind::Chance,
        ] {
            let json = serde_json::to_string(&kind).unwrap();
            assert_eq!(json, format!("\"{kind}\""));
            assert_eq!(serde_json::from_str::<ClassifierKind>(&json).unwrap(), kind);
        }
        let refused = serde_json::from_value::<ClassifierOptions>(serde_json::json!({
            "classifier": "tree"
        }))
        .unwrap_err();
        assert_eq!(
            refused.to_string(),
            "unknown classifier \"tree\" (expected svm, nn, knn5 or chance)"
        );
    }

    #[test]
    fn numbers_out_of_range_are_refused() {
        let refused = |options: ClassifierOptions| options.spec(&names()).unwrap_err().to_string();
        let base = ClassifierOptions {
            features: "all".into(),
            ..ClassifierOptions::default()
        };
        let c = ClassifierOptions {
            c: -1.0,
            ..base.clone()
        };
        assert!(refused(c).contains("C (c) and γ (gamma)"));
        let gamma = ClassifierOptions {
            gamma: Some(f64::NAN),
            ..base.clone()
        };
        assert!(refused(gamma).contains("C (c) and γ (gamma)"));
        let folds = ClassifierOptions {
            calibration_folds: 1,
            ..base
        };
        assert!(refused(folds).contains("calibration folds"));
    }
}
