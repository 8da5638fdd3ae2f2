//! The classifier: automatic selection, PCA, the SVM (own SMO solver), k-NN and chance
//! baselines, calibrated probabilities, prediction sets, the domain check, the fitted
//! pipeline ([`Classifier`]) and leave-one-illumination-out cross-validation; what to train
//! ([`ClassifierOptions`] as a user gives it, [`TrainSpec`] over a table).

pub mod calibration;
pub mod conformal;
pub mod cv;
pub mod domain;
pub mod grid;
pub(crate) mod knn;
pub mod options;
pub(crate) mod pca;
pub mod pipeline;
mod prepare;
pub mod select;
pub mod svm;

pub use cv::{CvReport, CvSummary, cross_validate, cross_validate_with};
pub use options::{
    CALIBRATION_FOLDS, CalibrationKind, ClassifierKind, ClassifierOptions, DEFAULT_C, Grid,
    TrainSpec,
};
pub use pipeline::{Classifier, fit};
