//! Learning: feature sets, automatic selection, PCA, standardization, the SVM (own SMO
//! solver), k-NN and chance baselines, Platt calibration, the fitted pipeline
//! ([`Classifier`]) and leave-one-illumination-out cross-validation.
//!
//! Everything is deterministic for a fixed seed and independent of the number of threads:
//! randomness comes only from [`crate::rng::Rng`] streams forked per task, and parallel
//! loops collect their results in a fixed order.

pub mod calibration;
pub mod cv;
pub mod dataset;
pub mod error;
pub mod feature_set;
pub mod knn;
pub mod model;
pub mod normal;
pub mod pca;
pub mod scaler;
pub mod select;
pub mod svm;

pub use cv::{CvReport, cross_validate};
pub use dataset::Dataset;
pub use error::LearnError;
pub use feature_set::FeatureSet;
pub use model::{Classifier, ClassifierKind, Grid, TrainSpec, fit};
