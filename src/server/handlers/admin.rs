//! Admin plane: jobs and the model registry (bearer token required).

use crate::server::error::{ApiError, Kind, Problem, Unauthorized};
use crate::server::jobs::{JobManager, JobRecord, JobRequest, JobState};
use crate::server::state::SharedState;
use axum::Json;
use axum::extract::rejection::{JsonRejection, PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use reflectance_core::classify::ClassifierOptions;
use reflectance_core::estimate::EstimatorOptions;
use reflectance_core::features::FeatureOptions;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::sync::Arc;
use utoipa::{IntoParams, ToSchema};

pub(super) fn jobs(state: &SharedState) -> Result<Arc<JobManager>, ApiError> {
    state
        .jobs
        .clone()
        .ok_or_else(|| ApiError::internal("the job system is not running"))
}

pub(super) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(ApiError::internal)?
}

const COMMON: &[&str] = &["type"];
/// A learning job's data, before the training, extraction and estimator options' keys.
const LEARN: &[&str] = &["dataset", "manifest", "table"];

/// Refuse unknown keys (a typo must not silently fall back to a default).
fn check_keys(body: &Value) -> Result<(), ApiError> {
    let Value::Object(map) = body else {
        return Err(ApiError::new(
            Kind::InvalidJob,
            "the job must be a JSON object",
        ));
    };
    let kind = map.get("type").and_then(Value::as_str).unwrap_or_default();
    let extra: &[&str] = match kind {
        "train" => &[
            "name",
            "activate",
            "classes",
            "cross_validate",
            "estimator_table",
            "estimator_classes",
            "estimator_features",
            "no_white_references_only",
        ],
        "cross_validate" => &["ward_classes"],
        "render" => &["probes", "classes", "out", "size", "seed", "captures"],
        _ => {
            let detail = match map.get("type") {
                None => {
                    "the job has no type: give \"type\": train, cross_validate or render".into()
                }
                Some(other) => {
                    format!("type must be train, cross_validate or render, not {other}")
                }
            };
            return Err(ApiError::new(Kind::InvalidJob, detail));
        }
    };
    let learn = match kind {
        "render" => Vec::new(),
        _ => (LEARN.iter().chain(&ClassifierOptions::KEYS))
            .map(|k| k.to_string())
            .chain(FeatureOptions::keys())
            .chain(EstimatorOptions::keys())
            .collect(),
    };
    let accepted: Vec<&str> = (COMMON.iter().chain(extra).copied())
        .chain(learn.iter().map(String::as_str))
        .collect();
    if let Some(key) = map.keys().find(|k| !accepted.contains(&k.as_str())) {
        return Err(ApiError::new(
            Kind::InvalidJob,
            format!(
                "unknown parameter {key:?} for a {kind} job; accepted: {}",
                accepted.join(", ")
            ),
        ));
    }
    Ok(())
}

/// Submit a job.
#[utoipa::path(
    post,
    operation_id = "submit_job",
    path = "/admin/v1/jobs",
    tag = "admin",
    security(("bearer" = [])),
    request_body(content = JobRequest, content_type = "application/json"),
    responses(
        (status = 202, description = "Queued", body = JobRecord,
         headers(("location" = String, description = "/admin/v1/jobs/{id}"))),
        (status = 400, description = "Malformed JSON (`malformed-request`)", body = Problem, content_type = "application/problem+json"),
        Unauthorized,
        (status = 415, description = "Not application/json (`unsupported-media-type`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Invalid parameters (`invalid-job`, `invalid-field`) or a path that is missing or outside the data directory (`invalid-path`)", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "Queue full (`job-queue-full`); see Retry-After", body = Problem, content_type = "application/problem+json",
         headers(("retry-after" = u32, description = "Seconds"))),
        (status = 503, description = "Shutting down (`not-ready`), or the job record cannot be written to a read-only or forbidden jobs folder (`storage-unavailable`)", body = Problem, content_type = "application/problem+json"),
        (status = 507, description = "The disk is full: the job record cannot be written (`insufficient-storage`); nothing was queued", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn submit(
    State(state): State<SharedState>,
    body: Result<Json<Value>, JsonRejection>,
) -> Result<Response, ApiError> {
    let Json(body) = body?;
    check_keys(&body)?;
    let request: JobRequest =
        serde_json::from_value(body).map_err(|e| ApiError::new(Kind::InvalidJob, e.to_string()))?;
    let manager = jobs(&state)?;
    let record = blocking(move || Ok(manager.submit(request)?)).await?;
    let location = format!("/admin/v1/jobs/{}", record.id);
    let mut response = (StatusCode::ACCEPTED, Json(record)).into_response();
    if let Ok(v) = HeaderValue::from_str(&location) {
        response.headers_mut().insert(header::LOCATION, v);
    }
    Ok(response)
}

#[derive(Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct StateQuery {
    /// Only jobs in this state.
    pub state: Option<JobState>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct JobList {
    /// Newest first.
    pub jobs: Vec<JobRecord>,
}

/// List jobs.
#[utoipa::path(
    get,
    operation_id = "list_jobs",
    path = "/admin/v1/jobs",
    tag = "admin",
    security(("bearer" = [])),
    params(StateQuery),
    responses(
        (status = 200, description = "Jobs, newest first", body = JobList),
        Unauthorized,
        (status = 422, description = "Unknown state (`invalid-field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn list(
    State(state): State<SharedState>,
    query: Result<Query<StateQuery>, QueryRejection>,
) -> Result<Json<JobList>, ApiError> {
    let Query(query) = query?;
    let manager = jobs(&state)?;
    let jobs = blocking(move || Ok(manager.list(query.state))).await?;
    Ok(Json(JobList { jobs }))
}

/// One job.
#[utoipa::path(
    get,
    operation_id = "get_job", path = "/admin/v1/jobs/{id}",
    tag = "admin",
    security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = JobRecord),
        Unauthorized,
        (status = 404, description = "Unknown job (`job-not-found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get(
    State(state): State<SharedState>,
    Path(id): Path<String>,
) -> Result<Json<JobRecord>, ApiError> {
    let manager = jobs(&state)?;
    Ok(Json(blocking(move || Ok(manager.get(&id)?)).await?))
}

/// A job as it goes, as server-sent events (`text/event-stream`): `progress` with the job's
/// record at once and at every change of its state, stage or progress, then `end` with its
/// final record, and the stream closes.
#[utoipa::path(
    get,
    operation_id = "job_events", path = "/admin/v1/jobs/{id}/events",
    tag = "admin",
    security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "Server-sent events: `event: progress` (then `event: end`), each `data:` a job record (JobRecord) as JSON", body = String, content_type = "text/event-stream"),
        Unauthorized,
        (status = 404, description = "Unknown job (`job-not-found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn events(
    State(state): State<SharedState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    use axum::response::sse::{Event, KeepAlive, Sse};
    use tokio::sync::broadcast::error::RecvError;
    let manager = jobs(&state)?;
    // Listening before the first look: no change falls between the two.
    let changes = manager.subscribe();
    let first = manager.get(&id)?;
    let start = (changes, manager, Some(first), false);
    let stream =
        futures_util::stream::unfold(start, move |(mut changes, manager, mut next, ended)| {
            let id = id.clone();
            async move {
                loop {
                    if ended {
                        return None;
                    }
                    if let Some(record) = next.take() {
                        let end = record.state.is_terminal();
                        let name = if end { "end" } else { "progress" };
                        let event = Event::default().event(name).json_data(&record);
                        return Some((event, (changes, manager, None, end)));
                    }
                    next = match changes.recv().await {
                        Ok(record) => Some(record).filter(|r| r.id == id),
                        // Fallen behind: the record as it is now.
                        Err(RecvError::Lagged(_)) => Some(manager.get(&id).ok()?),
                        Err(RecvError::Closed) => return None,
                    };
                }
            }
        });
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response())
}

/// Cancel a job: a queued job at once, a running one between images or folds.
#[utoipa::path(
    post,
    operation_id = "cancel_job", path = "/admin/v1/jobs/{id}/cancel",
    tag = "admin",
    security(("bearer" = [])),
    params(("id" = String, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job: `cancelled` if it was queued, else `running` with `cancel_requested` until it stops", body = JobRecord),
        Unauthorized,
        (status = 404, description = "Unknown job (`job-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "Already finished (`job-finished`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn cancel(
    State(state): State<SharedState>,
    Path(id): Path<String>,
) -> Result<Json<JobRecord>, ApiError> {
    let manager = jobs(&state)?;
    Ok(Json(blocking(move || Ok(manager.cancel(&id)?)).await?))
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct VersionInfo {
    pub version: u32,
    /// Served by `POST /v1/models/{name}/classify` without `?version=`.
    pub active: bool,
    /// Whether the version loads: schema, checksum and self-test pass.
    pub valid: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub created: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feature_set: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cv_accuracy: Option<f64>,
    /// Why the version does not load.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct VersionList {
    pub name: String,
    /// The served version (absent when the model is not served).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active: Option<u32>,
    pub versions: Vec<VersionInfo>,
}

/// A model's versions in the registry.
#[utoipa::path(
    get,
    operation_id = "list_versions", path = "/admin/v1/models/{name}/versions",
    tag = "admin",
    security(("bearer" = [])),
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "Versions, ascending", body = VersionList),
        Unauthorized,
        (status = 404, description = "Unknown model (`model-not-found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn versions(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<VersionList>, ApiError> {
    let worker = state.clone();
    blocking(move || {
        let registry = worker.models.registry();
        let versions = registry.versions(&name)?;
        let active = worker.models.active(&name).map(|m| m.version());
        let versions = versions
            .into_iter()
            .map(|v| match registry.load(&name, v) {
                Ok(m) => VersionInfo {
                    version: v,
                    active: active == Some(v),
                    valid: true,
                    created: Some(m.created),
                    feature_set: Some(m.features.set),
                    cv_accuracy: m.training.cv.map(|c| c.accuracy),
                    error: None,
                },
                Err(e) => VersionInfo {
                    version: v,
                    active: active == Some(v),
                    valid: false,
                    created: None,
                    feature_set: None,
                    cv_accuracy: None,
                    error: Some(e.to_string()),
                },
            })
            .collect();
        crate::heap::release_free();
        Ok(Json(VersionList {
            name,
            active,
            versions,
        }))
    })
    .await
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Activation {
    pub name: String,
    pub version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub previous: Option<u32>,
    /// Whether the registry recorded the choice (false: a read-only models folder; the
    /// activation holds until the process restarts, or with `--poll-interval` until its
    /// next look at the registry).
    pub persisted: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
}

/// Promote or roll back: load, verify, self-test, then swap atomically.
#[utoipa::path(
    post,
    operation_id = "activate_version", path = "/admin/v1/models/{name}/versions/{version}/activate",
    tag = "admin",
    security(("bearer" = [])),
    params(("name" = String, Path, description = "Model name", example = "ward6"), ("version" = u32, Path, description = "Version", minimum = 1)),
    responses(
        (status = 200, description = "Activated; requests already running finish on the previous version", body = Activation),
        Unauthorized,
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "The version's file is refused (`invalid-model`): the previous version keeps serving", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn activate(
    State(state): State<SharedState>,
    path: Result<Path<(String, u32)>, PathRejection>,
) -> Result<Json<Activation>, ApiError> {
    let Path((name, version)) = path?;
    let worker = state.clone();
    blocking(move || {
        let done = worker.models.activate(&name, version)?;
        Ok(Json(Activation {
            name,
            version,
            previous: done.previous,
            persisted: done.warning.is_none(),
            warning: done.warning,
        }))
    })
    .await
}

/// Delete an inactive version.
#[utoipa::path(
    delete,
    operation_id = "delete_version",
    path = "/admin/v1/models/{name}/versions/{version}",
    tag = "admin",
    security(("bearer" = [])),
    params(("name" = String, Path, description = "Model name", example = "ward6"), ("version" = u32, Path, description = "Version", minimum = 1)),
    responses(
        (status = 204, description = "Deleted"),
        Unauthorized,
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The version is active (`version-active`)", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "The registry is read-only or forbidden (`storage-unavailable`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn delete_version(
    State(state): State<SharedState>,
    path: Result<Path<(String, u32)>, PathRejection>,
) -> Result<StatusCode, ApiError> {
    let Path((name, version)) = path?;
    let worker = state.clone();
    blocking(move || Ok(worker.models.delete(&name, version)?)).await?;
    Ok(StatusCode::NO_CONTENT)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::server::jobs::{Activate, LearnParams};
    use reflectance_core::features::Preprocessing;

    #[test]
    fn every_field_of_every_job_type_is_accepted() {
        let data = LearnParams {
            dataset: Some("m.csv".into()),
            table: Some("t.csv".into()),
            options: ClassifierOptions {
                gamma: Some(0.1),
                ..ClassifierOptions::default()
            },
            extraction: FeatureOptions {
                preprocessing: Preprocessing {
                    working_radius: Some(64.0),
                    saturation: Some(1.25),
                    blur_at_working_radius: true,
                },
                ..FeatureOptions::default()
            },
            ..LearnParams::default()
        };
        let jobs = [
            JobRequest::Train {
                name: "ward6".into(),
                data: data.clone(),
                activate: Activate::IfBetter,
                classes: Some("classes.json".into()),
                cross_validate: true,
                estimator_table: Some("materials.csv".into()),
                estimator_classes: Some("materials.json".into()),
                estimator_features: Some("hand6+log+cap+ctr".into()),
                no_white_references_only: true,
            },
            JobRequest::CrossValidate {
                data,
                ward_classes: Some("classes.json".into()),
            },
            JobRequest::Render {
                probes: "probes".into(),
                classes: "classes.json".into(),
                out: "out".into(),
                size: 96,
                seed: 1,
                captures: 2,
            },
        ];
        for job in jobs {
            let body = serde_json::to_value(&job).unwrap();
            assert!(check_keys(&body).is_ok(), "{body}");
        }
        let untyped = check_keys(&serde_json::json!({"name": "ward6"})).unwrap_err();
        assert!(untyped.detail.contains("no type"), "{}", untyped.detail);
        let cli_name = serde_json::json!({"type": "train", "manifest": "m.csv"});
        assert!(check_keys(&cli_name).is_ok());
        let typo = serde_json::json!({"type": "train", "manifests": "m.csv"});
        let refused = check_keys(&typo).unwrap_err().detail;
        assert!(
            refused.contains("\"manifests\"") && refused.contains("dataset, manifest, table"),
            "{refused}"
        );
        let listed = "dataset, manifest, table, features, classifier, c, gamma, grid, seed, \
                      calibration_folds, blur_at_working_radius, capture_features";
        assert!(refused.contains(listed), "{refused}");
    }

    #[test]
    fn an_unknown_classifier_is_refused_in_the_classifier_s_words() {
        let job = serde_json::json!({"type": "train", "name": "x", "dataset": "m.csv", "classifier": "tree"});
        let refused = serde_json::from_value::<JobRequest>(job).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "unknown classifier \"tree\" (expected svm, nn, knn5 or chance)"
        );
    }
}
