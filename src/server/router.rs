//! Routers of the two planes and the middleware every request passes through:
//! request id, trace context (and its span), metrics, request log, problem+json normalization (outermost), then panic
//! catching, the per-request timeout and the body limit.

use super::error::{self, ApiError, BODY_LIMIT, Kind, OPEN_INFERENCE, REQUEST_ID};
use super::handlers::{
    admin, classify, datasets, health, locate, material, models, preview, v2, web,
};
use super::metrics;
use super::state::SharedState;
use super::trace;
use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::timeout::TimeoutLayer;

pub const REQUEST_ID_HEADER: &str = "x-request-id";

/// A client's id is kept when it is 1–128 visible ASCII characters; otherwise one is made.
fn client_request_id(request: &Request) -> Option<String> {
    let value = request.headers().get(REQUEST_ID_HEADER)?.to_str().ok()?;
    let ok = (1..=128).contains(&value.len()) && value.bytes().all(|b| b.is_ascii_graphic());
    ok.then(|| value.to_string())
}

/// 32 hex digits: a per-process random prefix and a counter (unique, cheap, not secret).
fn new_request_id() -> String {
    static PREFIX: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let prefix = *PREFIX.get_or_init(|| {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        reflectance_core::util::rng::Rng::new(nanos ^ u64::from(std::process::id()).rotate_left(32))
            .next_u64()
    });
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("{prefix:016x}{n:016x}")
}

/// Decrements the in-flight gauge even when the client goes away mid-request.
struct InFlight;

impl InFlight {
    fn enter() -> InFlight {
        metrics::in_flight(1.0);
        InFlight
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        metrics::in_flight(-1.0);
    }
}

async fn observe(State(state): State<SharedState>, mut request: Request, next: Next) -> Response {
    let started = Instant::now();
    let wall_start = std::time::SystemTime::now();
    let context = trace::Context::of_request(request.headers());
    let request_id = client_request_id(&request).unwrap_or_else(new_request_id);
    if let Ok(v) = HeaderValue::from_str(&request_id) {
        request.headers_mut().insert(REQUEST_ID_HEADER, v);
    }
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = request.method().clone();
    let path = request.uri().path().to_string();
    let _in_flight = InFlight::enter();
    let id = request_id.clone();
    let open_inference = path == "/v2" || path.starts_with("/v2/");
    // Dataset uploads count their bytes against limits of their own.
    let body_limit = (path != "/admin/v1/datasets").then_some(state.config.body_limit);
    let mut response = trace::CURRENT
        .scope(
            context.clone(),
            REQUEST_ID.scope(
                request_id.clone(),
                OPEN_INFERENCE.scope(
                    open_inference,
                    BODY_LIMIT.scope(body_limit, async move {
                        let response = next.run(request).await;
                        error::normalize(response, &id).await
                    }),
                ),
            ),
        )
        .await;
    if let Ok(v) = HeaderValue::from_str(&request_id) {
        response.headers_mut().insert(REQUEST_ID_HEADER, v);
    }
    if let Ok(v) = HeaderValue::from_str(&context.traceparent()) {
        response.headers_mut().insert("traceresponse", v);
    }
    let status = response.status().as_u16();
    let seconds = started.elapsed().as_secs_f64();
    metrics::request(&route, method.as_str(), status, seconds);
    // One access-log line per request; probes and scrapes only at debug level.
    let ms = seconds * 1e3;
    let quiet =
        route.starts_with("/health/") || route.starts_with("/v2/health/") || route == "/metrics";
    let trace_id = context.trace_id_hex();
    match (status >= 500, quiet) {
        (true, _) => tracing::warn!(%request_id, %trace_id, %method, %path, status, ms, "request"),
        (false, false) => {
            tracing::info!(%request_id, %trace_id, %method, %path, status, ms, "request")
        }
        (false, true) => {
            tracing::debug!(%request_id, %trace_id, %method, %path, status, ms, "request")
        }
    }
    if !quiet {
        let attributes = vec![
            (
                "http.request.method",
                trace::Value::Text(method.to_string()),
            ),
            ("http.route", trace::Value::Text(route.clone())),
            ("url.path", trace::Value::Text(path)),
            (
                "http.response.status_code",
                trace::Value::Int(i64::from(status)),
            ),
            ("request_id", trace::Value::Text(request_id)),
        ];
        let name = format!("{method} {route}");
        trace::request_span(&context, name, wall_start, attributes, status >= 500);
    }
    response
}

fn panic_response(panic: Box<dyn std::any::Any + Send + 'static>) -> Response {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_default();
    ApiError::internal(format!("panic: {what}")).into_response()
}

async fn not_found() -> ApiError {
    ApiError::new(Kind::NotFound, "no such route")
}

/// What every request passes through inside the observer: panic catching, a time limit
/// and a body limit.
fn guarded(
    router: Router<SharedState>,
    timeout: Duration,
    body_limit: Option<usize>,
) -> Router<SharedState> {
    let router = router
        .layer(CatchPanicLayer::custom(panic_response))
        .layer(TimeoutLayer::with_status_code(
            StatusCode::REQUEST_TIMEOUT,
            timeout,
        ))
        .layer(DefaultBodyLimit::disable());
    match body_limit {
        Some(limit) => router.layer(RequestBodyLimitLayer::new(limit)),
        None => router,
    }
}

/// The middleware stack shared by both planes; `long` holds routes with limits of their
/// own (dataset uploads: the handler counts the bytes against its limit).
fn finish(
    router: Router<SharedState>,
    long: Option<(Router<SharedState>, Duration)>,
    state: &SharedState,
) -> Router {
    let config = &state.config;
    let mut router = guarded(router, config.request_timeout, Some(config.body_limit));
    if let Some((long, timeout)) = long {
        router = router.merge(guarded(long, timeout, None));
    }
    router
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(state.clone(), observe))
        .with_state(state.clone())
}

/// The data plane: classification, models, health, metrics, OpenAPI, KServe V2.
pub fn data_router(state: SharedState) -> Router {
    let router = Router::new()
        .route("/v1/classify", post(classify::classify_default))
        .route("/", get(web::index))
        .route("/docs", get(web::docs))
        .route("/assets/{file}", get(web::asset))
        .route("/v1/locate", post(locate::locate))
        .route("/v1/preview", get(preview::preview))
        .route("/v1/material.gltf", get(material::gltf))
        .route("/v1/models", get(models::list))
        .route("/v1/models/{name}", get(models::get))
        .route("/v1/models/{name}/classify", post(classify::classify_named))
        .route("/health/live", get(health::live))
        .route("/health/ready", get(health::ready))
        .route("/metrics", get(health::metrics))
        .route("/openapi.yaml", get(super::openapi::serve))
        .route("/v2", get(v2::server_metadata))
        .route("/v2/health/live", get(v2::health_live))
        .route("/v2/health/ready", get(v2::health_ready))
        .route("/v2/models/{name}", get(v2::model_metadata))
        .route("/v2/models/{name}/ready", get(v2::model_ready))
        .route("/v2/models/{name}/infer", post(v2::infer))
        .route(
            "/v2/models/{name}/versions/{version}",
            get(v2::model_version_metadata),
        )
        .route(
            "/v2/models/{name}/versions/{version}/ready",
            get(v2::model_version_ready),
        )
        .route(
            "/v2/models/{name}/versions/{version}/infer",
            post(v2::infer_version),
        );
    finish(router, None, &state)
}

async fn admin_auth(State(state): State<SharedState>, request: Request, next: Next) -> Response {
    super::auth::require_token(State(state), request, next).await
}

/// The admin plane: jobs and registry, behind the bearer token.
pub fn admin_router(state: SharedState) -> Router {
    let router = Router::new()
        .route("/admin/v1/jobs", post(admin::submit).get(admin::list))
        .route("/admin/v1/jobs/{id}", get(admin::get))
        .route("/admin/v1/jobs/{id}/events", get(admin::events))
        .route("/admin/v1/jobs/{id}/cancel", post(admin::cancel))
        .route("/admin/v1/models/{name}/versions", get(admin::versions))
        .route(
            "/admin/v1/models/{name}/versions/{version}/activate",
            post(admin::activate),
        )
        .route(
            "/admin/v1/models/{name}/versions/{version}",
            axum::routing::delete(admin::delete_version),
        )
        .route("/admin/v1/datasets", get(datasets::list))
        .route(
            "/admin/v1/datasets/{name}",
            get(datasets::get).delete(datasets::delete),
        )
        .route_layer(middleware::from_fn_with_state(state.clone(), admin_auth));
    let uploads = Router::new()
        .route("/admin/v1/datasets", post(datasets::upload))
        .route_layer(middleware::from_fn_with_state(state.clone(), admin_auth));
    let upload_timeout = state.config.datasets.timeout;
    finish(router, Some((uploads, upload_timeout)), &state)
}
