//! The one error type of the learning layer.

/// A learned part whose pieces disagree (a model file edited, cut short or of another
/// version): what disagrees.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[error("{0}")]
pub struct Inconsistent(pub String);

#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum LearnError {
    #[error("the feature table has no rows")]
    NoRows,
    #[error("row {row} ({path}): empty {what}")]
    EmptyLabel {
        row: usize,
        path: String,
        what: &'static str,
    },
    #[error("row {row} ({path}): {got} values for {expected} feature columns")]
    RaggedRow {
        row: usize,
        path: String,
        expected: usize,
        got: usize,
    },
    #[error("row {row} ({path}): feature {name} is not finite ({value})")]
    NonFinite {
        row: usize,
        path: String,
        name: String,
        value: f64,
    },
    #[error("need at least 2 classes, found {0}")]
    TooFewClasses(usize),
    #[error("invalid feature set {spec:?}: {detail}")]
    BadFeatureSet { spec: String, detail: String },
    #[error("unknown feature names: {}", .0.join(", "))]
    UnknownFeatures(Vec<String>),
    #[error("{0}")]
    InvalidParameter(String),
    #[error("coverage must be a number from 0.5 to 0.999, not {0}")]
    BadCoverage(f64),
    #[error("the training data has {0} class(es) with rows; at least 2 are needed")]
    TooFewTrainingClasses(usize),
    #[error("cross-validation needs at least 2 illuminations, found {0}")]
    TooFewGroups(usize),
    #[error("input row has {got} values, the model expects {expected}")]
    RowLength { expected: usize, got: usize },
    #[error("input feature {name} is not finite ({value})")]
    NonFiniteInput { name: String, value: f64 },
    #[error("inconsistent model: {0}")]
    InvalidModel(String),
    #[error("numerical failure: {0}")]
    Numerical(String),
    #[error("cancelled")]
    Cancelled,
}
