//! `POST /v1/classify` and `POST /v1/models/{name}/classify`: a multipart form (or JSON with
//! the files base64) in, classification out. The CPU work (decode, locate, features, predict) runs on the CPU pool behind the
//! admission semaphore (429 when saturated); the async side only moves bytes.

use super::input::{Body, JsonInput, RawInput};
use crate::server::error::{ApiError, ClassificationProblems, Kind, Problem};
use crate::server::metrics;
use crate::server::state::SharedState;
use crate::server::trace;
use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use reflectance_core::inference::{self, Classified, ClassifyResponse, Input};
use serde::Deserialize;
use std::time::Instant;
use utoipa::IntoParams;

#[derive(Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct VersionQuery {
    /// A specific version (default: the active one).
    #[param(minimum = 1)]
    pub version: Option<u32>,
}

/// Run a validated request against a model of the state: admission, CPU pool.
pub async fn run(
    state: &SharedState,
    name: &str,
    version: Option<u32>,
    input: Input,
) -> Result<Classified, ApiError> {
    state.models.served(name)?;
    let permit = state.cpu.admit()?;
    state
        .cpu
        .run(permit, work(state, name, version, input))
        .await
}

/// Classify a batch, its images queued on the CPU pool at once and admitted together (a
/// batch counts as as many requests as it holds images). The first image that fails fails
/// the batch, named by its index.
pub async fn run_batch(
    state: &SharedState,
    name: &str,
    version: Option<u32>,
    inputs: Vec<Input>,
) -> Result<Vec<Classified>, ApiError> {
    state.models.served(name)?;
    let n = inputs.len();
    let mut all = state.cpu.admit_many(n)?;
    let mut permits: Vec<_> = (1..n).filter_map(|_| all.split(1)).collect();
    permits.push(all);
    let queued: Vec<_> = inputs
        .into_iter()
        .zip(permits)
        .map(|(input, permit)| state.cpu.spawn(permit, work(state, name, version, input)))
        .collect();
    let mut classified = Vec::with_capacity(n);
    for (i, answer) in queued.into_iter().enumerate() {
        classified.push(answer.await.map_err(|e| e.in_batch(i, n))?);
    }
    Ok(classified)
}

/// The CPU work of one request: the model, then decode, locate, features and predict.
fn work(
    state: &SharedState,
    name: &str,
    version: Option<u32>,
    input: Input,
) -> impl FnOnce() -> Result<Classified, ApiError> + Send + 'static {
    let limits = state.config.limits;
    let state = state.clone();
    let name = name.to_string();
    let context = trace::current().filter(|_| trace::enabled());
    move || {
        let started = std::time::SystemTime::now();
        let model = state.models.get(&name, version)?;
        let classified = inference::classify(model, input, limits)?;
        metrics::stage("decode", classified.decode_ms / 1e3);
        metrics::stage("features", classified.features_ms / 1e3);
        metrics::stage("predict", classified.predict_ms / 1e3);
        if let Some(context) = context {
            let c = &classified;
            let locate = c.analysis.locate_ms;
            trace::stage_spans(
                &context,
                started,
                &[
                    ("decode", c.decode_ms),
                    ("locate", locate),
                    ("features", c.features_ms - locate),
                    ("classify", c.predict_ms - c.estimate_ms),
                    ("estimate", c.estimate_ms),
                ],
            );
        }
        Ok(classified)
    }
}

fn response(c: Classified, started: Instant) -> Response {
    let request_id = crate::server::error::current_request_id();
    let version = c.model.version();
    let body = c.response(request_id, started.elapsed().as_secs_f64() * 1e3);
    let mut headers = HeaderMap::new();
    headers.insert("x-model-version", HeaderValue::from(version));
    let timing = &body.timing_ms;
    let server_timing = format!(
        "decode;dur={:.3}, features;dur={:.3}, predict;dur={:.3}, total;dur={:.3}",
        timing.decode, timing.features, timing.predict, timing.total
    );
    if let Ok(v) = HeaderValue::from_str(&server_timing) {
        headers.insert("server-timing", v);
    }
    (headers, Json(body)).into_response()
}

async fn handle(
    state: SharedState,
    name: &str,
    version: Option<u32>,
    body: Result<Body, ApiError>,
) -> Result<Response, ApiError> {
    let started = Instant::now();
    super::health::serving(&state)?;
    state.models.served(name)?;
    let input = body?.read().await?.validate()?;
    let classified = run(&state, name, version, input).await?;
    Ok(response(classified, started))
}

/// What both multipart classification operations answer beside their own problems, for the
/// OpenAPI document.
#[derive(utoipa::IntoResponses)]
#[allow(
    dead_code,
    clippy::large_enum_variant,
    reason = "a type for the OpenAPI document, never built"
)]
pub enum MultipartClassification {
    #[response(status = 200, description = "Classification",
        headers(
            ("x-request-id" = String, description = "The request's id (the client's, if it sent a valid one)"),
            ("x-model-version" = u32, description = "The model version that answered"),
            ("server-timing" = String, description = "decode, features, predict and total durations in ms")))]
    Classified(ClassifyResponse),
}

/// What every operation that reads a form may answer about its body, for the OpenAPI
/// document.
#[derive(utoipa::IntoResponses)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
pub enum MultipartProblems {
    #[response(
        status = 400,
        description = "Malformed multipart or JSON body (`malformed-request`)",
        content_type = "application/problem+json"
    )]
    Malformed(Problem),
    #[response(
        status = 415,
        description = "A body the route does not read (`unsupported-media-type`: the detail says what was sent and what to send) or an image format not read (`unsupported-image-format`: the detail names the format found and the formats read)",
        content_type = "application/problem+json"
    )]
    Unsupported(Problem),
}

/// Classify with the default model's active version.
#[utoipa::path(
    post,
    operation_id = "classify", path = "/v1/classify",
    tag = "classification",
    request_body(content((RawInput = "multipart/form-data"), (JsonInput = "application/json"))),
    responses(
        MultipartClassification,
        MultipartProblems,
        (status = 404, description = "Default model not served (`model-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Missing image (`missing-field`), unknown or invalid field (`unknown-field`, `invalid-field`), corrupt or unusable image (`corrupt-image`, `invalid-image`), bad circle, mask or normals (`bad-geometry`), bad white reference (`bad-white`)", body = Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    )
)]
pub async fn classify_default(
    State(state): State<SharedState>,
    body: Result<Body, ApiError>,
) -> Result<Response, ApiError> {
    let name = state.config.default_model.clone();
    handle(state, &name, None, body).await
}

/// Classify with a named model (its active version, or `?version=`).
#[utoipa::path(
    post,
    operation_id = "classify_with_model", path = "/v1/models/{name}/classify",
    tag = "classification",
    params(("name" = String, Path, description = "Model name", example = "ward6"), VersionQuery),
    request_body(content((RawInput = "multipart/form-data"), (JsonInput = "application/json"))),
    responses(
        MultipartClassification,
        MultipartProblems,
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Missing image (`missing-field`), unknown or invalid field or query parameter (`unknown-field`, `invalid-field`), corrupt or unusable image (`corrupt-image`, `invalid-image`), bad circle, mask or normals (`bad-geometry`), bad white reference (`bad-white`), refused model file (`invalid-model`)", body = Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    )
)]
pub async fn classify_named(
    State(state): State<SharedState>,
    Path(name): Path<String>,
    query: Result<Query<VersionQuery>, QueryRejection>,
    body: Result<Body, ApiError>,
) -> Result<Response, ApiError> {
    let Query(query) = query?;
    if query.version == Some(0) {
        return Err(ApiError::new(
            Kind::InvalidField,
            "version must be a positive integer",
        ));
    }
    handle(state, &name, query.version, body).await
}
