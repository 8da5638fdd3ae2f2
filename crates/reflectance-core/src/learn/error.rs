//! The one error type of the learning layer.

/// A learned part whose pieces disagree (a model file edited, cut short or of another
/// version): what disagrees.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[error("{0}")]
pub struct Inconsistent(pub String);

/// Why training, cross-validation or a prediction cannot go on.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum LearnError {
    /// The feature table has no rows.
    #[error("the feature table has no rows")]
    NoRows,
    /// A row has an empty label.
    #[error("row {row} ({path}): empty {what}")]
    EmptyLabel {
        /// The row's 0-based index in the table.
        row: usize,
        /// The row's image path.
        path: String,
        /// Which label: `class`, `illumination`, or the illumination before an `@`.
        what: &'static str,
    },
    /// A row has another number of values than the table has feature columns.
    #[error("row {row} ({path}): {got} values for {expected} feature columns")]
    RaggedRow {
        /// The row's 0-based index in the table.
        row: usize,
        /// The row's image path.
        path: String,
        /// Feature columns in the table.
        expected: usize,
        /// Values in the row.
        got: usize,
    },
    /// A training value is NaN or infinite.
    #[error("row {row} ({path}): feature {name} is not finite ({value})")]
    NonFinite {
        /// The row's 0-based index in the table.
        row: usize,
        /// The row's image path.
        path: String,
        /// The feature's name.
        name: String,
        /// The offending value (NaN or ±∞).
        value: f64,
    },
    /// Fewer than 2 classes in the label set.
    #[error("need at least 2 classes, found {0}")]
    TooFewClasses(usize),
    /// A feature set specification cannot be resolved.
    #[error("invalid feature set {spec:?}: {detail}")]
    BadFeatureSet {
        /// The specification as given (`hand6`, `pca6`, a list…).
        spec: String,
        /// Why it cannot be resolved.
        detail: String,
    },
    /// Feature names the table or model does not have.
    #[error("unknown feature names: {}", .0.join(", "))]
    UnknownFeatures(Vec<String>),
    /// A training or model parameter out of range, with the rule it breaks.
    #[error("{0}")]
    InvalidParameter(String),
    /// A prediction-set coverage outside [0.5, 0.999].
    #[error("coverage must be a number from 0.5 to 0.999, not {0}")]
    BadCoverage(f64),
    /// Fewer than 2 classes have rows to train on.
    #[error("the training data has {0} class(es) with rows; at least 2 are needed")]
    TooFewTrainingClasses(usize),
    /// Fewer than 2 illuminations to hold out one at a time.
    #[error("cross-validation needs at least 2 illuminations, found {0}")]
    TooFewGroups(usize),
    /// An input row's length differs from the model's features.
    #[error("input row has {got} values, the model expects {expected}")]
    RowLength {
        /// Features the model expects.
        expected: usize,
        /// Values in the row.
        got: usize,
    },
    /// An input value is NaN or infinite.
    #[error("input feature {name} is not finite ({value})")]
    NonFiniteInput {
        /// The feature's name.
        name: String,
        /// The offending value (NaN or ±∞).
        value: f64,
    },
    /// A learned part's pieces disagree (see [`Inconsistent`]).
    #[error("inconsistent model: {0}")]
    InvalidModel(String),
    /// A numerical method failed (a singular matrix, no convergence).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// The caller cancelled the work.
    #[error("cancelled")]
    Cancelled,
}
