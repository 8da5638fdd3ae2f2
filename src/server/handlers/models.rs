//! `GET /v1/models` and `GET /v1/models/{name}`.

use crate::server::error::{ApiError, Problem};
use crate::server::state::{LoadedModel, SharedState};
use crate::server::store::Served;
use axum::Json;
use axum::extract::{Path, State};
use reflectance_core::inference::ClassOut;
use reflectance_core::model::Request;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelSummary {
    pub name: String,
    /// The version that answers requests without `?version=`.
    pub active_version: u32,
    /// When this replica loaded the active version (RFC 3339, UTC).
    pub loaded: String,
    /// Whether `POST /v1/classify` uses this model.
    pub default: bool,
    pub classes: Vec<String>,
    pub feature_set: String,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelList {
    pub default_model: String,
    pub models: Vec<ModelSummary>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct FeatureSetOut {
    /// As specified at training (`hand6`, `auto6`, `pca6`, a list…).
    pub set: String,
    /// The classifier's inputs.
    pub selected: Vec<String>,
    /// Number of features extracted per image (117 with the default configuration).
    pub extracted: usize,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ClassifierOut {
    /// `svm`, `nn`, `knn5` or `chance`.
    pub kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    pub calibrated: bool,
}

/// The prediction sets' calibration.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct SetsOut {
    /// Held-out images that calibrated them.
    pub images: usize,
    /// Folds of whole illuminations (else stratified rows).
    pub folds: usize,
    pub by_illumination: bool,
    pub measured: Vec<reflectance_core::classify::conformal::Measured>,
}

/// The domain check's calibration.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct DomainCalibrationOut {
    /// Held-out images that calibrated it.
    pub images: usize,
    /// The checks it makes: `typicality`, `outline`, `brightness`.
    pub checks: Vec<String>,
    /// The rate it was set to flag held-out valid images at, and the rate it did.
    pub false_alarm: f64,
    pub held_out_flagged: f64,
}

/// What a classifier knows of its own reliability.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ReliabilityOut {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction_sets: Option<SetsOut>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub domain: Option<DomainCalibrationOut>,
}

/// The calibrations of the classifier used with a white reference, of the one used
/// without and of the one used for objects located by their normals (each absent when the
/// model has none: it then answers with the first).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct CalibrationOut {
    pub with_white: ReliabilityOut,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub without_white: Option<ReliabilityOut>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objects: Option<ReliabilityOut>,
}

fn reliability(head: reflectance_core::model::Head) -> ReliabilityOut {
    ReliabilityOut {
        prediction_sets: head.prediction_sets.map(|s| SetsOut {
            images: s.n,
            folds: s.folds,
            by_illumination: s.by_illumination,
            measured: s.measured.clone(),
        }),
        domain: head.domain.map(|d| DomainCalibrationOut {
            images: d.n,
            checks: d
                .checks
                .iter()
                .map(|c| reflectance_core::inference::wire_name(&c.kind))
                .collect(),
            false_alarm: d.false_alarm,
            held_out_flagged: d.held_out_flagged,
        }),
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct TrainingOut {
    pub dataset: String,
    pub images: usize,
    pub illuminations: usize,
    pub seed: u64,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelDetail {
    pub name: String,
    /// The version this replica serves.
    pub active_version: u32,
    /// When this replica loaded it (RFC 3339, UTC): at start, at an activation, or when a
    /// look at the registry (`--poll-interval`) found it.
    pub loaded: String,
    /// The replica that answered (its host name: the pod's name on Kubernetes).
    pub replica: String,
    /// Versions in the registry, ascending.
    pub versions: Vec<u32>,
    /// Creation time of the active version (RFC 3339).
    pub created: String,
    /// In class order (the order of KServe `probabilities`).
    pub classes: Vec<ClassOut>,
    pub features: FeatureSetOut,
    pub classifier: ClassifierOut,
    pub training: TrainingOut,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cv: Option<reflectance_core::model::StoredCv>,
    /// Prediction sets and the domain check, calibrated on held-out illuminations.
    pub calibration: CalibrationOut,
    /// SHA-256 of the active version's model file content.
    pub sha256: String,
}

/// When a served version was loaded, as RFC 3339.
pub fn loaded(served: &Served) -> String {
    let secs = served
        .loaded
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    reflectance_core::model::rfc3339(secs)
}

/// This process's host name (the pod's name on Kubernetes), else `HOSTNAME`, else empty.
pub fn replica() -> String {
    static NAME: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    NAME.get_or_init(|| {
        let mut buffer = [0u8; 256];
        // SAFETY: the buffer and its length are ours; gethostname writes at most that many.
        let rc = unsafe { libc::gethostname(buffer.as_mut_ptr().cast(), buffer.len()) };
        let end = buffer.iter().position(|&b| b == 0).unwrap_or(buffer.len());
        match rc {
            0 if end > 0 => String::from_utf8_lossy(&buffer[..end]).into_owned(),
            _ => std::env::var("HOSTNAME").unwrap_or_default(),
        }
    })
    .clone()
}

pub fn detail(served: &Served, versions: Vec<u32>) -> ModelDetail {
    let model: &LoadedModel = &served.model;
    let f = model.file();
    let (c, gamma) = match f.classifier.model() {
        reflectance_core::classify::pipeline::Model::Svm(m) => (Some(m.c), Some(m.gamma)),
        _ => (None, None),
    };
    ModelDetail {
        name: f.name.clone(),
        active_version: f.version,
        loaded: loaded(served),
        replica: replica(),
        versions,
        created: f.created.clone(),
        classes: f.classes.iter().map(ClassOut::from).collect(),
        features: FeatureSetOut {
            set: f.features.set.clone(),
            selected: f.features.selected.clone(),
            extracted: model.feature_names().len(),
        },
        classifier: ClassifierOut {
            kind: f.classifier.kind().to_string(),
            c,
            gamma,
            calibrated: f.classifier.is_calibrated(),
        },
        training: TrainingOut {
            dataset: f.training.dataset.clone(),
            images: f.training.images,
            illuminations: f.training.illuminations,
            seed: f.training.seed,
        },
        cv: f.training.cv.clone(),
        calibration: CalibrationOut {
            with_white: reliability(f.head(Request {
                white_given: true,
                object: false,
            })),
            without_white: f.no_white.as_ref().map(|_| {
                reliability(f.head(Request {
                    white_given: false,
                    object: false,
                }))
            }),
            objects: f.objects.as_ref().map(|_| {
                reliability(f.head(Request {
                    white_given: true,
                    object: true,
                }))
            }),
        },
        sha256: f.sha256.clone(),
    }
}

/// The served models.
#[utoipa::path(
    get,
    operation_id = "list_models", path = "/v1/models",
    tag = "models",
    responses((status = 200, description = "Served models", body = ModelList))
)]
pub async fn list(State(state): State<SharedState>) -> Json<ModelList> {
    let models = state
        .models
        .all_served()
        .iter()
        .map(|served| (served, &served.model))
        .map(|(served, m)| ModelSummary {
            name: m.name().to_string(),
            active_version: m.version(),
            loaded: loaded(served),
            default: m.name() == state.config.default_model,
            classes: m.file().classifier.classes().to_vec(),
            feature_set: m.file().features.set.clone(),
        })
        .collect();
    Json(ModelList {
        default_model: state.config.default_model.clone(),
        models,
    })
}

/// One model: classes with Ward parameters, feature set, versions, CV summary.
#[utoipa::path(
    get,
    operation_id = "get_model", path = "/v1/models/{name}",
    tag = "models",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "The model's active version", body = ModelDetail),
        (status = 404, description = "Unknown model (`model-not-found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<ModelDetail>, ApiError> {
    let served = state.models.served_with_time(&name)?;
    let registry = state.models.registry().clone();
    let version = served.model.version();
    let versions = tokio::task::spawn_blocking(move || registry.versions(&name))
        .await
        .map_err(ApiError::internal)?
        .unwrap_or_else(|_| vec![version]);
    Ok(Json(detail(&served, versions)))
}
