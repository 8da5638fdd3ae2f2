//! Health, metrics and the OpenAPI document.

use crate::server::error::{ApiError, Kind, Problem};
use crate::server::state::{Phase, SharedState};
use axum::Json;
use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Health {
    /// `live` or `ready`.
    pub status: String,
}

/// The process is up (it answers).
#[utoipa::path(
    get,
    operation_id = "live", path = "/health/live",
    tag = "health",
    responses((status = 200, description = "Alive", body = Health))
)]
pub async fn live() -> Json<Health> {
    Json(Health {
        status: "live".into(),
    })
}

/// Ready for traffic: the models are loaded and the server is not draining.
pub fn readiness(state: &SharedState) -> Result<(), ApiError> {
    match state.readiness.get() {
        Phase::Ready => Ok(()),
        Phase::Loading => Err(ApiError::new(Kind::NotReady, "loading models").retry_after(1)),
        Phase::Draining => Err(ApiError::new(Kind::NotReady, "draining: shutting down")),
    }
}

/// Classification is possible once the models are loaded (while draining, requests that
/// still arrive are served).
pub fn serving(state: &SharedState) -> Result<(), ApiError> {
    match state.readiness.get() {
        Phase::Loading => Err(ApiError::new(Kind::NotReady, "loading models").retry_after(1)),
        Phase::Ready | Phase::Draining => Ok(()),
    }
}

/// Ready for traffic.
#[utoipa::path(
    get,
    operation_id = "ready", path = "/health/ready",
    tag = "health",
    responses(
        (status = 200, description = "Ready", body = Health),
        (status = 503, description = "Loading models or draining (`not-ready`); the detail says which", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn ready(State(state): State<SharedState>) -> Result<Json<Health>, ApiError> {
    readiness(&state)?;
    Ok(Json(Health {
        status: "ready".into(),
    }))
}

/// Prometheus metrics (text exposition format 0.0.4).
#[utoipa::path(
    get,
    operation_id = "metrics", path = "/metrics",
    tag = "health",
    responses((status = 200, description = "Metrics", body = String, content_type = "text/plain; version=0.0.4"))
)]
pub async fn metrics(State(state): State<SharedState>) -> Response {
    let _ = &state;
    let text = crate::server::metrics::render();
    let mut response = text.into_response();
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; version=0.0.4; charset=utf-8"),
    );
    response
}
