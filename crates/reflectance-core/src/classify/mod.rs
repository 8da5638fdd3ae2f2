//! The classifier: automatic selection, PCA, the SVM (own SMO solver), k-NN and chance
//! baselines, calibrated probabilities, prediction sets, the domain check, the fitted
//! pipeline ([`Classifier`]) and leave-one-illumination-out cross-validation.

pub mod calibration;
pub mod conformal;
pub mod cv;
pub mod domain;
pub(crate) mod knn;
pub(crate) mod pca;
pub mod pipeline;
pub mod select;
pub mod svm;

pub use cv::{CvReport, CvSummary, cross_validate, cross_validate_with};
pub use pipeline::{Classifier, ClassifierKind, DEFAULT_C, Grid, SpecText, TrainSpec, fit};
