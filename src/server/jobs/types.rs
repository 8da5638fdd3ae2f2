//! What the admin plane's job endpoints read and write: a job's request (`POST
//! /admin/v1/jobs`), its state, progress and record (what `GET /admin/v1/jobs/{id}` answers
//! and the jobs folder keeps).

use super::Activate;
use super::run::JobResult;
use reflectance_core::classify::ClassifierOptions;
use reflectance_core::estimate::EstimatorOptions;
use reflectance_core::features::FeatureOptions;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Where the labelled data of a `train` or `cross_validate` job come from: exactly one of
/// `dataset` (a manifest; features are extracted first) or `table` (a feature table written
/// by `reflectance features --out`), relative to the data directory.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LearnParams {
    /// Manifest CSV relative to the data directory (`manifest`, the CLI's name, is accepted
    /// too).
    #[serde(default, alias = "manifest", skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Feature table CSV relative to the data directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<String>,
    // The training options, as the command line's flags of the same names; the document
    // lists them among this object's own properties (`openapi::own_properties`).
    #[serde(flatten)]
    #[schema(inline)]
    pub options: ClassifierOptions,
    /// With `dataset`: the extraction's options (extensions beyond those `features` names,
    /// preprocessing), as the command line's flags of the same names.
    #[serde(flatten)]
    pub extraction: FeatureOptions,
    /// With `estimator_table` (train) or `ward_classes` (cross_validate): the Ward-parameter
    /// regression, as the command line's `--regressor` and `--ridge-*` options.
    #[serde(flatten)]
    pub estimator: EstimatorOptions,
}

impl LearnParams {
    fn paths(&self) -> [Option<&str>; 2] {
        [self.dataset.as_deref(), self.table.as_deref()]
    }
}

fn default_seed() -> u64 {
    1
}
fn default_size() -> usize {
    256
}
fn default_true() -> bool {
    true
}

/// A job to run, as posted to `POST /admin/v1/jobs`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum JobRequest {
    /// Train a model and publish it as a new version.
    Train {
        /// Model name (a-z, 0-9, '_', '-').
        name: String,
        #[serde(flatten)]
        data: LearnParams,
        #[serde(default)]
        activate: Activate,
        /// Class file with the classes' Ward parameters, relative to the data directory.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        classes: Option<String>,
        /// Store a leave-one-illumination-out CV summary with the model (required by
        /// `activate: if_better`).
        #[serde(default = "default_true")]
        #[schema(default = true)]
        cross_validate: bool,
        /// Also fit a Ward-parameter estimator on this feature table (relative to the data
        /// directory; extracted with the model's feature flags), reading the model's
        /// `features` (gradient-boosted trees, as `train --estimator-table` by default).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimator_table: Option<String>,
        /// The class file of the estimator table's materials (their Ward parameters),
        /// relative to the data directory; required with `estimator_table`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimator_classes: Option<String>,
        /// With `estimator_table`: the estimator's features (a named set or a list of names;
        /// default: `features`); the extraction computes the families both sets name, as
        /// `train --estimator-features` does.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        estimator_features: Option<String>,
        /// Fit the classifier without white on the classes' reference materials only,
        /// leaving out the images of their members (`CLASS+MEMBER` in a rendered file's
        /// name), as `train --no-white-references-only` does.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        no_white_references_only: bool,
    },
    /// Leave-one-illumination-out cross-validation.
    CrossValidate {
        #[serde(flatten)]
        data: LearnParams,
        /// Estimate the Ward parameters instead of classifying: the class file (relative to
        /// the data directory) whose materials are the data's classes. The regression reads
        /// `features` (gradient-boosted trees, as `cv --estimate` by default).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ward_classes: Option<String>,
    },
    /// Render Ward spheres under light probes into a dataset with a manifest.
    Render {
        /// A folder of `.hdr` probes or a probe list file, relative to the data directory.
        probes: String,
        /// Class file (`{"classes": [{"name", "rho_d", "rho_s", "alpha"}]}`), relative to
        /// the data directory.
        classes: String,
        /// Output folder relative to the data directory (created).
        out: String,
        /// Image size in pixels (71…4096: the sphere's radius, size / 2.2, must be ≥ 32 px).
        #[serde(default = "default_size")]
        #[schema(default = 256, minimum = 71, maximum = 4096)]
        size: usize,
        #[serde(default = "default_seed")]
        #[schema(default = 1)]
        seed: u64,
        /// Photograph-like captures of every image (`@cap<k>` training views; see
        /// `reflectance render --captures`).
        #[serde(default)]
        #[schema(default = 0, maximum = 64)]
        captures: usize,
    },
}

impl JobRequest {
    pub fn kind(&self) -> &'static str {
        match self {
            JobRequest::Train { .. } => "train",
            JobRequest::CrossValidate { .. } => "cross_validate",
            JobRequest::Render { .. } => "render",
        }
    }

    /// Every path of the data directory the job reads or writes.
    pub(super) fn paths(&self) -> Vec<&str> {
        let found: Vec<Option<&str>> = match self {
            JobRequest::Train {
                data,
                classes,
                estimator_table,
                estimator_classes,
                ..
            } => [
                data.paths().as_slice(),
                &[
                    classes.as_deref(),
                    estimator_table.as_deref(),
                    estimator_classes.as_deref(),
                ],
            ]
            .concat(),
            JobRequest::CrossValidate { data, ward_classes } => {
                [data.paths().as_slice(), &[ward_classes.as_deref()]].concat()
            }
            JobRequest::Render {
                probes,
                classes,
                out,
                ..
            } => vec![Some(probes), Some(classes), Some(out)],
        };
        found.into_iter().flatten().collect()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 5] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
    ];

    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
}

/// How far a job is: `done` of `total` units (images or folds) of its current stage
/// (`queued`, `starting`, `features`, `fit` (the classifier's calibration folds, then its
/// calibration), `prediction_sets`, `fit_without_white`, `cross_validate`, `estimate`,
/// `publish`, `activate`, `render`, `done`). A stage is 0 of 0 only as it begins.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobProgress {
    pub stage: String,
    pub done: usize,
    pub total: usize,
}

/// A job and what became of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobRecord {
    pub id: String,
    pub state: JobState,
    /// The job as submitted (with defaults filled in).
    pub request: JobRequest,
    /// RFC 3339 times.
    pub created: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub finished: Option<String>,
    pub progress: JobProgress,
    /// Whether a cancellation was requested (a running job stops at its next check).
    #[serde(default)]
    pub cancel_requested: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<JobResult>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}
