//! The one place where failures become HTTP: every error of the service is an
//! `application/problem+json` document (RFC 9457) with `type`, `title`, `status`, `detail`
//! and `request_id`. Handlers return [`ApiError`]; [`normalize`] (run by the middleware for
//! every response) turns whatever else produced an error status — axum's extractor
//! rejections, unknown routes (404), wrong methods (405), the body limit (413), the
//! timeout (408), a caught panic (500) — into the same shape.
//!
//! Mapping of the library's errors (see [`ApiError::from`] impls and `openapi.yaml`):
//!
//! | error | status | type |
//! |---|---|---|
//! | decode: unknown format, unsupported content | 415 | `unsupported-image-format` |
//! | decode: corrupt or truncated file | 422 | `corrupt-image` |
//! | decode: over the pixel limits | 413 | `image-too-large` |
//! | decode: zero size, NaN/Inf or negative samples | 422 | `invalid-image` |
//! | decode: bad `encoding` | 422 | `invalid-field` |
//! | geometry (bad circle or mask, detection failed) | 422 | `bad-geometry` |
//! | white reference | 422 | `bad-white` |
//! | unknown model / version | 404 | `model-not-found` / `version-not-found` |
//! | model file refused (schema, checksum, self-test) | 422 | `invalid-model` |
//! | deleting the active version | 409 | `version-active` |
//! | KServe V2 health "false" (loading, draining) | 400 | `v2-not-ready` |
//! | KServe V2 batch: one image refused (its index and its own problem in the detail) | 400 | `batch-item` |
//! | dataset archive: not tar/tar.gz/zip, unreadable | 422 | `invalid-archive` |
//! | dataset archive: over a size or member limit | 413 | `archive-too-large` |
//! | dataset: no usable image, too few illuminations | 422 | `unusable-dataset` |
//! | dataset: name taken / unknown / used by a job | 409 / 404 / 409 | `dataset-exists` / `dataset-not-found` / `dataset-in-use` |
//! | job refused at submission: a path missing or outside the data directory | 422 | `invalid-path` |
//! | job refused at submission: its parameters | 422 | `invalid-job` |
//! | writing the server's files: disk full (ENOSPC, EFBIG, EDQUOT) | 507 | `insufficient-storage` |
//! | writing the server's files: read-only or forbidden folder | 503 | `storage-unavailable` |

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use std::borrow::Cow;
use utoipa::ToSchema;

use reflectance_core::analysis::AnalysisError;
use reflectance_core::decode::DecodeError;
use reflectance_core::learn::LearnError;
use reflectance_core::locate::GeometryError;
use reflectance_core::model::ModelError;
use reflectance_core::model::registry::RegistryError;
use reflectance_core::white::WhiteError;

use super::jobs::{JobError, ManagerError, PersistError};
use super::store::StoreError;

pub const PROBLEM_JSON: &str = "application/problem+json";
const TYPE_PREFIX: &str = "urn:reflectance:problem:";

tokio::task_local! {
    /// The current request's id, set by the middleware around every request.
    pub static REQUEST_ID: String;
    /// Whether the current request is one of the Open Inference Protocol's (`/v2…`), whose
    /// clients read an error's message from an `error` member.
    pub static OPEN_INFERENCE: bool;
    /// The body limit of the current request's route (`None`: the route counts its own).
    pub static BODY_LIMIT: Option<usize>;
}

/// A 413's detail for the current request: the limit, and the setting that raises it.
fn body_too_large() -> String {
    match BODY_LIMIT.try_with(|limit| *limit).ok().flatten() {
        Some(limit) => over_limit("the request body", limit),
        None => "the request body is over the size limit".to_string(),
    }
}

/// `what` is over the body limit `limit`: the limit, and the setting that raises it.
fn over_limit(what: &str, limit: usize) -> String {
    format!(
        "{what} is over the server's limit of {} ({limit} bytes); the server's --body-limit \
         (REFLECTANCE_BODY_LIMIT) raises it",
        human_bytes(limit as u64)
    )
}

/// Bytes for people: 16 MiB, 1.5 GiB, 900 bytes.
fn human_bytes(n: u64) -> String {
    let units = [(1u64 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    for (size, unit) in units {
        if n >= size {
            let value = n as f64 / size as f64;
            return match value.fract() == 0.0 {
                true => format!("{value:.0} {unit}"),
                false => format!("{value:.1} {unit}"),
            };
        }
    }
    format!("{n} bytes")
}

/// The `error` member of a problem on the Open Inference Protocol's routes.
fn protocol_error(detail: &str) -> Option<String> {
    OPEN_INFERENCE
        .try_with(|&v2| v2.then(|| detail.to_string()))
        .ok()
        .flatten()
}

/// The current request's id (empty outside a request).
pub fn current_request_id() -> String {
    REQUEST_ID.try_with(Clone::clone).unwrap_or_default()
}

/// Every kind of failure the service reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    MalformedRequest,
    UnsupportedMediaType,
    MissingField,
    UnknownField,
    InvalidField,
    UnsupportedImageFormat,
    CorruptImage,
    ImageTooLarge,
    InvalidImage,
    BadGeometry,
    BadWhite,
    ModelNotFound,
    VersionNotFound,
    InvalidModel,
    VersionActive,
    JobNotFound,
    JobFinished,
    InvalidJob,
    InvalidPath,
    JobQueueFull,
    Unauthorized,
    Overloaded,
    NotFound,
    MethodNotAllowed,
    Timeout,
    BodyTooLarge,
    NotReady,
    NotReadyV2,
    StorageFull,
    StorageUnavailable,
    InvalidArchive,
    ArchiveTooLarge,
    UnusableDataset,
    DatasetExists,
    DatasetNotFound,
    DatasetInUse,
    BatchItem,
    Internal,
}

impl Kind {
    pub const ALL: [Kind; 38] = [
        Kind::MalformedRequest,
        Kind::UnsupportedMediaType,
        Kind::MissingField,
        Kind::UnknownField,
        Kind::InvalidField,
        Kind::UnsupportedImageFormat,
        Kind::CorruptImage,
        Kind::ImageTooLarge,
        Kind::InvalidImage,
        Kind::BadGeometry,
        Kind::BadWhite,
        Kind::ModelNotFound,
        Kind::VersionNotFound,
        Kind::InvalidModel,
        Kind::VersionActive,
        Kind::JobNotFound,
        Kind::JobFinished,
        Kind::InvalidJob,
        Kind::InvalidPath,
        Kind::JobQueueFull,
        Kind::Unauthorized,
        Kind::Overloaded,
        Kind::NotFound,
        Kind::MethodNotAllowed,
        Kind::Timeout,
        Kind::BodyTooLarge,
        Kind::NotReady,
        Kind::NotReadyV2,
        Kind::StorageFull,
        Kind::StorageUnavailable,
        Kind::InvalidArchive,
        Kind::ArchiveTooLarge,
        Kind::UnusableDataset,
        Kind::DatasetExists,
        Kind::DatasetNotFound,
        Kind::DatasetInUse,
        Kind::BatchItem,
        Kind::Internal,
    ];

    /// (slug, title, status)
    pub fn describe(self) -> (&'static str, &'static str, StatusCode) {
        use StatusCode as S;
        match self {
            Kind::MalformedRequest => ("malformed-request", "Malformed request", S::BAD_REQUEST),
            Kind::UnsupportedMediaType => (
                "unsupported-media-type",
                "Unsupported request content type",
                S::UNSUPPORTED_MEDIA_TYPE,
            ),
            Kind::MissingField => (
                "missing-field",
                "A required field is missing",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::UnknownField => ("unknown-field", "Unknown field", S::UNPROCESSABLE_ENTITY),
            Kind::InvalidField => (
                "invalid-field",
                "Invalid field value",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::UnsupportedImageFormat => (
                "unsupported-image-format",
                "Unsupported image format",
                S::UNSUPPORTED_MEDIA_TYPE,
            ),
            Kind::CorruptImage => (
                "corrupt-image",
                "Corrupt or truncated image",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::ImageTooLarge => (
                "image-too-large",
                "Image over the pixel limits",
                S::PAYLOAD_TOO_LARGE,
            ),
            Kind::InvalidImage => ("invalid-image", "Unusable image", S::UNPROCESSABLE_ENTITY),
            Kind::BadGeometry => (
                "bad-geometry",
                "Sphere circle or mask not usable",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::BadWhite => (
                "bad-white",
                "White reference not usable",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::ModelNotFound => ("model-not-found", "Unknown model", S::NOT_FOUND),
            Kind::VersionNotFound => ("version-not-found", "Unknown model version", S::NOT_FOUND),
            Kind::InvalidModel => (
                "invalid-model",
                "Model file refused",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::VersionActive => ("version-active", "Version is active", S::CONFLICT),
            Kind::JobNotFound => ("job-not-found", "Unknown job", S::NOT_FOUND),
            Kind::JobFinished => ("job-finished", "Job already finished", S::CONFLICT),
            Kind::InvalidJob => ("invalid-job", "Invalid job", S::UNPROCESSABLE_ENTITY),
            Kind::InvalidPath => (
                "invalid-path",
                "Path missing or outside the data directory",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::JobQueueFull => ("job-queue-full", "Job queue full", S::TOO_MANY_REQUESTS),
            Kind::Unauthorized => ("unauthorized", "Unauthorized", S::UNAUTHORIZED),
            Kind::Overloaded => ("overloaded", "Server busy", S::TOO_MANY_REQUESTS),
            Kind::NotFound => ("not-found", "Not found", S::NOT_FOUND),
            Kind::MethodNotAllowed => (
                "method-not-allowed",
                "Method not allowed",
                S::METHOD_NOT_ALLOWED,
            ),
            Kind::Timeout => ("timeout", "Request timed out", S::REQUEST_TIMEOUT),
            Kind::BodyTooLarge => (
                "body-too-large",
                "Request body too large",
                S::PAYLOAD_TOO_LARGE,
            ),
            Kind::NotReady => ("not-ready", "Service not ready", S::SERVICE_UNAVAILABLE),
            // The Open Inference Protocol's health endpoints answer "false" with a 4xx
            // (its reference server, Triton, uses 400).
            Kind::NotReadyV2 => ("v2-not-ready", "Not ready", S::BAD_REQUEST),
            Kind::StorageFull => (
                "insufficient-storage",
                "The server's disk is full",
                S::INSUFFICIENT_STORAGE,
            ),
            Kind::StorageUnavailable => (
                "storage-unavailable",
                "The server cannot write its files",
                S::SERVICE_UNAVAILABLE,
            ),
            Kind::InvalidArchive => (
                "invalid-archive",
                "Archive not readable",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::ArchiveTooLarge => (
                "archive-too-large",
                "Archive over a dataset limit",
                S::PAYLOAD_TOO_LARGE,
            ),
            Kind::UnusableDataset => (
                "unusable-dataset",
                "Nothing to learn from",
                S::UNPROCESSABLE_ENTITY,
            ),
            Kind::DatasetExists => ("dataset-exists", "Dataset name taken", S::CONFLICT),
            Kind::DatasetNotFound => ("dataset-not-found", "Unknown dataset", S::NOT_FOUND),
            Kind::DatasetInUse => ("dataset-in-use", "Dataset in use by a job", S::CONFLICT),
            // The protocol has no partial success: one image fails the whole batch, as a
            // client's mistake (Triton's status for a failed inference).
            Kind::BatchItem => (
                "batch-item",
                "An image of the batch is refused",
                S::BAD_REQUEST,
            ),
            Kind::Internal => (
                "internal",
                "Internal server error",
                S::INTERNAL_SERVER_ERROR,
            ),
        }
    }

    pub fn status(self) -> StatusCode {
        self.describe().2
    }

    pub fn type_uri(self) -> String {
        format!("{TYPE_PREFIX}{}", self.describe().0)
    }
}

/// An RFC 9457 problem document.
#[derive(Clone, Debug, Serialize, serde::Deserialize, ToSchema)]
#[schema(example = json!({
    "type": "urn:reflectance:problem:corrupt-image",
    "title": "Corrupt or truncated image",
    "status": 422,
    "detail": "corrupt or truncated PNG file: unexpected end of data",
    "request_id": "5f0c6a1e9b2d4c7a8e3f1a2b3c4d5e6f"
}))]
pub struct Problem {
    /// A URI naming the kind of problem: `urn:reflectance:problem:<slug>`.
    #[serde(rename = "type")]
    pub type_: String,
    pub title: String,
    /// The HTTP status code.
    pub status: u16,
    /// What went wrong with this request, for a human.
    pub detail: String,
    /// The request's id (also in the `x-request-id` header).
    pub request_id: String,
    /// The detail again, on the Open Inference Protocol's routes (`/v2…`): where its
    /// clients read the message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The problems every classification endpoint can answer with, for the OpenAPI document.
#[derive(utoipa::IntoResponses)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
pub enum ClassificationProblems {
    #[response(
        status = 408,
        description = "Timed out (`timeout`)",
        content_type = "application/problem+json"
    )]
    Timeout(Problem),
    #[response(
        status = 413,
        description = "Body over the size limit (`body-too-large`) or image over the pixel limits (`image-too-large`)",
        content_type = "application/problem+json"
    )]
    TooLarge(Problem),
    #[response(status = 429, description = "Saturated (`overloaded`); see Retry-After", content_type = "application/problem+json",
        headers(("retry-after" = u32, description = "Seconds")))]
    Overloaded(Problem),
    #[response(
        status = 503,
        description = "Models still loading (`not-ready`); see Retry-After",
        content_type = "application/problem+json"
    )]
    NotReady(Problem),
}

/// A missing or wrong admin token, for the OpenAPI document of every admin operation.
#[derive(utoipa::IntoResponses)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
#[response(
    status = 401,
    description = "Missing or wrong token (`unauthorized`)",
    content_type = "application/problem+json"
)]
pub struct Unauthorized(Problem);

/// A failure, on its way to becoming a problem+json response.
#[derive(Debug)]
pub struct ApiError {
    pub kind: Kind,
    pub detail: String,
    /// Seconds, for 429 and 503.
    pub retry_after: Option<u64>,
}

impl ApiError {
    pub fn new(kind: Kind, detail: impl Into<String>) -> ApiError {
        ApiError {
            kind,
            detail: detail.into(),
            retry_after: None,
        }
    }

    /// This error, of image `index` (from 0) of a batch of `n`: a client's mistake becomes
    /// a 400 naming the image and what was wrong; the server's own failures stay as they are.
    pub fn in_batch(self, index: usize, n: usize) -> ApiError {
        if !self.kind.status().is_client_error() || self.kind == Kind::Overloaded {
            return self;
        }
        let (slug, ..) = self.kind.describe();
        ApiError {
            kind: Kind::BatchItem,
            detail: format!(
                "image {index} of the batch of {n} (from 0): {} ({slug})",
                self.detail
            ),
            retry_after: None,
        }
    }

    pub fn retry_after(mut self, seconds: u64) -> ApiError {
        self.retry_after = Some(seconds);
        self
    }

    pub fn internal(detail: impl std::fmt::Display) -> ApiError {
        tracing::error!(error = %detail, "internal error");
        ApiError::new(
            Kind::Internal,
            "internal error; the request id identifies the log entry",
        )
    }

    /// A failed write of the server's own files: a full disk (507) or a read-only or
    /// forbidden folder (503) says so; anything else is internal.
    pub fn storage(e: &std::io::Error, detail: impl Into<String>) -> ApiError {
        use std::io::ErrorKind as E;
        let kind = match e.kind() {
            E::StorageFull | E::FileTooLarge | E::QuotaExceeded => Kind::StorageFull,
            E::ReadOnlyFilesystem | E::PermissionDenied => Kind::StorageUnavailable,
            _ => return ApiError::internal(detail.into()),
        };
        tracing::error!(error = %e, "storage failure");
        ApiError::new(kind, detail)
    }

    pub fn problem(&self, request_id: String) -> Problem {
        let (_, title, status) = self.kind.describe();
        Problem {
            type_: self.kind.type_uri(),
            title: title.to_string(),
            status: status.as_u16(),
            detail: self.detail.clone(),
            request_id,
            error: protocol_error(&self.detail),
        }
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.kind.describe().0, self.detail)
    }
}

/// The problem+json response of a problem.
pub fn problem_response(problem: &Problem, retry_after: Option<u64>) -> Response {
    let body = serde_json::to_vec(problem).unwrap_or_default();
    let status = StatusCode::from_u16(problem.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
    let mut response = (status, body).into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
    if let Some(seconds) = retry_after {
        headers.insert(header::RETRY_AFTER, HeaderValue::from(seconds));
    }
    if status == StatusCode::UNAUTHORIZED {
        headers.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
    }
    response
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        problem_response(&self.problem(current_request_id()), self.retry_after)
    }
}

impl From<DecodeError> for ApiError {
    fn from(e: DecodeError) -> ApiError {
        let kind = match &e {
            DecodeError::UnsupportedFormat
            | DecodeError::NotRead { .. }
            | DecodeError::Unsupported { .. } => Kind::UnsupportedImageFormat,
            DecodeError::Corrupt { .. } => Kind::CorruptImage,
            DecodeError::TooLarge { .. } | DecodeError::LimitExceeded(_) => Kind::ImageTooLarge,
            DecodeError::Empty { .. }
            | DecodeError::NonFinite { .. }
            | DecodeError::Negative { .. } => Kind::InvalidImage,
            DecodeError::BadEncoding(_) => Kind::InvalidField,
            // In-memory decoding reads no files: an I/O error here is ours.
            DecodeError::Io(_) => return ApiError::internal(e),
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<GeometryError> for ApiError {
    fn from(e: GeometryError) -> ApiError {
        let advice = match e {
            GeometryError::DetectionFailed { .. } => "; give cx, cy and r, or a mask",
            _ => "",
        };
        ApiError::new(Kind::BadGeometry, format!("{e}{advice}"))
    }
}

impl From<reflectance_core::analysis::InputError> for ApiError {
    fn from(e: reflectance_core::analysis::InputError) -> ApiError {
        use reflectance_core::analysis::InputError as E;
        let kind = match e {
            E::Geometry(e) => return e.into(),
            E::White(e) => return e.into(),
            E::EmptyImage => Kind::MissingField,
            E::SeveralWhites | E::ReflectanceWithoutCard => Kind::BadWhite,
            E::CircleAndMask | E::CircleAndNormals => Kind::BadGeometry,
            E::Coverage(_) => Kind::InvalidField,
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<crate::archive::ArchiveError> for ApiError {
    fn from(e: crate::archive::ArchiveError) -> ApiError {
        use crate::archive::ArchiveError as E;
        let kind = match &e {
            E::UnknownFormat | E::Corrupt(_) => Kind::InvalidArchive,
            E::TooManyMembers { .. } | E::TooLarge { .. } => Kind::ArchiveTooLarge,
            E::Io { source, .. } => return ApiError::storage(source, e.to_string()),
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<WhiteError> for ApiError {
    fn from(e: WhiteError) -> ApiError {
        ApiError::new(Kind::BadWhite, e.to_string())
    }
}

impl From<reflectance_core::material::InvalidWard> for ApiError {
    fn from(e: reflectance_core::material::InvalidWard) -> ApiError {
        ApiError::new(Kind::InvalidField, e.to_string())
    }
}

impl From<reflectance_render::preview::PreviewError> for ApiError {
    fn from(e: reflectance_render::preview::PreviewError) -> ApiError {
        ApiError::new(Kind::InvalidField, e.to_string())
    }
}

impl From<AnalysisError> for ApiError {
    fn from(e: AnalysisError) -> ApiError {
        match e {
            AnalysisError::Decode(e) => e.into(),
            AnalysisError::Geometry(e) => e.into(),
            AnalysisError::White(e) => e.into(),
            AnalysisError::Scale { .. } => ApiError::new(Kind::InvalidImage, e.to_string()),
            AnalysisError::Normals(e) => e.into(),
            AnalysisError::Observed(_) => ApiError::new(Kind::BadGeometry, e.to_string()),
        }
    }
}

impl From<reflectance_core::object::normals::NormalsError> for ApiError {
    fn from(e: reflectance_core::object::normals::NormalsError) -> ApiError {
        use reflectance_core::object::normals::NormalsError as E;
        match e {
            E::Decode(source) => {
                let mut e = ApiError::from(source);
                e.detail = format!("normals: {}", e.detail);
                e
            }
            other => ApiError::new(Kind::BadGeometry, format!("normals: {other}")),
        }
    }
}

impl From<reflectance_core::inference::InferenceError> for ApiError {
    fn from(e: reflectance_core::inference::InferenceError) -> ApiError {
        use reflectance_core::inference::InferenceError as E;
        match e {
            E::Decode { part, source } => {
                let mut e = ApiError::from(source);
                e.detail = format!("{part}{}", e.detail);
                e
            }
            E::Analysis(e) => e.into(),
            E::Normals(e) => e.into(),
            E::Model(e) => e.into(),
            E::Learn(e) => e.into(),
        }
    }
}

impl From<ModelError> for ApiError {
    fn from(e: ModelError) -> ApiError {
        ApiError::new(Kind::InvalidModel, e.to_string())
    }
}

impl From<RegistryError> for ApiError {
    fn from(e: RegistryError) -> ApiError {
        let kind = match &e {
            RegistryError::BadName(_)
            | RegistryError::UnknownModel(_)
            | RegistryError::NoFolder(_)
            | RegistryError::UnknownModelIn { .. } => Kind::ModelNotFound,
            RegistryError::UnknownVersion { .. } => Kind::VersionNotFound,
            RegistryError::ActiveVersion { .. } => Kind::VersionActive,
            RegistryError::Model { .. } => Kind::InvalidModel,
            RegistryError::Io { source, .. } => return ApiError::storage(source, e.to_string()),
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<StoreError> for ApiError {
    fn from(e: StoreError) -> ApiError {
        match e {
            StoreError::Registry(e) => e.into(),
            StoreError::Model(e) => e.into(),
            e @ StoreError::Unserved { .. } => ApiError::new(Kind::ModelNotFound, e.to_string()),
        }
    }
}

impl From<ManagerError> for ApiError {
    fn from(e: ManagerError) -> ApiError {
        use ManagerError as E;
        let kind = match e {
            E::Refused(e) => return (*e).into(),
            E::Persist(e) => return e.into(),
            E::ShuttingDown => return ApiError::new(Kind::NotReady, e.to_string()).retry_after(5),
            E::QueueFull => {
                return ApiError::new(Kind::JobQueueFull, e.to_string()).retry_after(10);
            }
            E::UnknownJob(_) => Kind::JobNotFound,
            E::Finished { .. } => Kind::JobFinished,
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<PersistError> for ApiError {
    fn from(e: PersistError) -> ApiError {
        ApiError::storage(&e.source, e.to_string())
    }
}

/// A job refused at submission, in the words of the layer that refused it: a path
/// (`invalid-path`) or a parameter (`invalid-job`). A job that fails later states the error
/// in its record instead; the job system's own failures (a panic, a job given to another
/// runner, an activation) are internal here.
impl From<JobError> for ApiError {
    fn from(e: JobError) -> ApiError {
        use JobError as E;
        let kind = match &e {
            E::Path(_) => Kind::InvalidPath,
            E::Dataset(_)
            | E::Learn(_)
            | E::Render(_)
            | E::RenderOptions(_)
            | E::Train(_)
            | E::Classes(_)
            | E::Features(_)
            | E::Name(_)
            | E::Refused(_) => Kind::InvalidJob,
            E::Activation { .. } | E::Panicked | E::WrongKind(_) => return ApiError::internal(e),
        };
        ApiError::new(kind, e.to_string())
    }
}

impl From<LearnError> for ApiError {
    fn from(e: LearnError) -> ApiError {
        match e {
            // Features of a pathological image (e.g. an absurd white value) overflowed.
            LearnError::NonFiniteInput { .. } => ApiError::new(
                Kind::InvalidImage,
                format!("the image's features are not usable: {e}"),
            ),
            other => ApiError::internal(other),
        }
    }
}

/// What a request sent, by its headers, for [`ApiError::unsupported_body`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Sent {
    /// No body at all.
    Nothing,
    /// A body of this media type (lower case, without its parameters), or none given.
    Body(Option<String>),
}

impl ApiError {
    /// 413 for `what` (e.g. "the decompressed body") over the body limit `limit`.
    pub fn over_body_limit(what: &str, limit: usize) -> ApiError {
        ApiError::new(Kind::BodyTooLarge, over_limit(what, limit))
    }

    /// 415 for a body a route cannot read, saying what was sent and what the route `takes`
    /// (the media types, the fields and a curl line).
    pub fn unsupported_body(sent: &Sent, takes: &str) -> ApiError {
        let what = match sent {
            Sent::Nothing => "the request has no body".to_string(),
            Sent::Body(None) => "the body has no Content-Type".to_string(),
            Sent::Body(Some(t)) if t == "multipart/form-data" => {
                "the body is multipart/form-data without a boundary (let the client build the \
                 form: do not set Content-Type yourself)"
                    .to_string()
            }
            Sent::Body(Some(t)) if t.ends_with("json") => format!("the body is JSON ({t})"),
            Sent::Body(Some(t)) if t == "application/x-www-form-urlencoded" => format!(
                "the body is {t} (what curl's --data and --data-binary send: a file goes in a \
                 form field, -F image=@photo.jpg)"
            ),
            Sent::Body(Some(t)) if t.starts_with("image/") || t == "application/octet-stream" => {
                format!("the body is raw bytes ({t}), not a form")
            }
            Sent::Body(Some(t)) => format!("the body is {t}"),
        };
        ApiError::new(
            Kind::UnsupportedMediaType,
            format!("{what}: this route takes {takes}"),
        )
    }
}

impl From<axum::extract::multipart::MultipartError> for ApiError {
    fn from(e: axum::extract::multipart::MultipartError) -> ApiError {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            return ApiError::new(Kind::BodyTooLarge, body_too_large());
        }
        ApiError::new(Kind::MalformedRequest, e.body_text())
    }
}

impl From<axum::extract::rejection::JsonRejection> for ApiError {
    fn from(e: axum::extract::rejection::JsonRejection) -> ApiError {
        use axum::extract::rejection::JsonRejection as J;
        let kind = match &e {
            J::MissingJsonContentType(_) => Kind::UnsupportedMediaType,
            J::JsonDataError(_) => Kind::InvalidField,
            J::JsonSyntaxError(_) => Kind::MalformedRequest,
            _ if e.status() == StatusCode::PAYLOAD_TOO_LARGE => {
                return ApiError::new(Kind::BodyTooLarge, body_too_large());
            }
            _ => Kind::MalformedRequest,
        };
        ApiError::new(kind, e.body_text())
    }
}

impl From<axum::extract::rejection::BytesRejection> for ApiError {
    fn from(e: axum::extract::rejection::BytesRejection) -> ApiError {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            return ApiError::new(Kind::BodyTooLarge, body_too_large());
        }
        ApiError::new(Kind::MalformedRequest, e.body_text())
    }
}

/// A path segment that cannot be parsed (e.g. a version that is not a positive integer)
/// names nothing that exists.
impl From<axum::extract::rejection::PathRejection> for ApiError {
    fn from(e: axum::extract::rejection::PathRejection) -> ApiError {
        ApiError::new(Kind::VersionNotFound, e.body_text())
    }
}

impl From<axum::extract::rejection::QueryRejection> for ApiError {
    fn from(e: axum::extract::rejection::QueryRejection) -> ApiError {
        ApiError::new(Kind::InvalidField, e.body_text())
    }
}

/// The kind of an error status produced outside the handlers.
fn kind_of_status(status: StatusCode) -> Kind {
    match status {
        StatusCode::NOT_FOUND => Kind::NotFound,
        StatusCode::METHOD_NOT_ALLOWED => Kind::MethodNotAllowed,
        StatusCode::PAYLOAD_TOO_LARGE => Kind::BodyTooLarge,
        StatusCode::REQUEST_TIMEOUT => Kind::Timeout,
        StatusCode::UNSUPPORTED_MEDIA_TYPE => Kind::UnsupportedMediaType,
        StatusCode::UNPROCESSABLE_ENTITY => Kind::InvalidField,
        StatusCode::UNAUTHORIZED => Kind::Unauthorized,
        StatusCode::TOO_MANY_REQUESTS => Kind::Overloaded,
        StatusCode::SERVICE_UNAVAILABLE => Kind::NotReady,
        s if s.is_client_error() => Kind::MalformedRequest,
        _ => Kind::Internal,
    }
}

fn default_detail(kind: Kind) -> Cow<'static, str> {
    match kind {
        Kind::NotFound => "no such route".into(),
        Kind::MethodNotAllowed => "this route does not accept that method".into(),
        Kind::Timeout => "the request did not complete within the time limit".into(),
        Kind::BodyTooLarge => "the request body is over the size limit".into(),
        Kind::Internal => "internal error; the request id identifies the log entry".into(),
        other => other.describe().1.into(),
    }
}

/// Turn an error response that is not already problem+json into one (keeping a short
/// plain-text body as the detail). Other responses pass through.
pub async fn normalize(response: Response, request_id: &str) -> Response {
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let is_problem = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(PROBLEM_JSON.as_bytes()));
    if is_problem {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, 4096).await.unwrap_or_default();
    let kind = kind_of_status(status);
    let detail = match std::str::from_utf8(&text) {
        _ if kind == Kind::BodyTooLarge => body_too_large(),
        Ok(t) if !t.trim().is_empty() && kind != Kind::Internal => t.trim().to_string(),
        _ => default_detail(kind).into_owned(),
    };
    let (_, title, _) = kind.describe();
    let problem = Problem {
        type_: kind.type_uri(),
        title: title.to_string(),
        status: status.as_u16(),
        error: protocol_error(&detail),
        detail,
        request_id: request_id.to_string(),
    };
    let mut out = problem_response(&problem, None);
    // Keep headers such as Allow (405) and Retry-After.
    for (name, value) in parts.headers.iter() {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            out.headers_mut().insert(name.clone(), value.clone());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_have_distinct_slugs_and_error_statuses() {
        let mut slugs: Vec<&str> = Kind::ALL.iter().map(|k| k.describe().0).collect();
        slugs.sort_unstable();
        slugs.dedup();
        assert_eq!(slugs.len(), Kind::ALL.len());
        for kind in Kind::ALL {
            let status = kind.status();
            assert!(
                status.is_client_error() || status.is_server_error(),
                "{kind:?}"
            );
            // Only our own failures are 5xx.
            if status.is_server_error() {
                assert!(
                    matches!(
                        kind,
                        Kind::Internal
                            | Kind::NotReady
                            | Kind::StorageFull
                            | Kind::StorageUnavailable
                    ),
                    "{kind:?}"
                );
            }
        }
    }

    #[test]
    fn sizes_are_written_for_people() {
        assert_eq!(human_bytes(16 * 1024 * 1024), "16 MiB");
        assert_eq!(human_bytes(200_000), "195.3 KiB");
        assert_eq!(human_bytes(900), "900 bytes");
        let detail = over_limit("the request body", 16 * 1024 * 1024);
        assert!(
            detail.contains("16 MiB (16777216 bytes)") && detail.contains("--body-limit"),
            "{detail}"
        );
    }

    #[test]
    fn library_errors_map_to_client_errors() {
        let decode = [
            (DecodeError::UnsupportedFormat, 415),
            (
                DecodeError::NotRead {
                    name: "a GIF image",
                    advice: "",
                },
                415,
            ),
            (
                DecodeError::Corrupt {
                    format: reflectance_core::decode::Format::Png,
                    detail: "x".into(),
                },
                422,
            ),
            (
                DecodeError::TooLarge {
                    width: 1,
                    height: 1,
                    limits: Default::default(),
                },
                413,
            ),
            (DecodeError::LimitExceeded("x".into()), 413),
            (
                DecodeError::Empty {
                    width: 0,
                    height: 1,
                },
                422,
            ),
            (DecodeError::NonFinite { count: 1 }, 422),
            (DecodeError::BadEncoding("x".into()), 422),
        ];
        for (e, status) in decode {
            assert_eq!(ApiError::from(e).kind.status().as_u16(), status);
        }
        assert_eq!(
            ApiError::from(GeometryError::Incomplete).kind,
            Kind::BadGeometry
        );
        assert_eq!(
            ApiError::from(WhiteError::NotPositive(0.0)).kind,
            Kind::BadWhite
        );
        assert_eq!(
            ApiError::from(RegistryError::UnknownModel("x".into())).kind,
            Kind::ModelNotFound
        );
        assert_eq!(
            ApiError::from(RegistryError::UnknownVersion {
                name: "x".into(),
                version: 2
            })
            .kind,
            Kind::VersionNotFound
        );
        assert_eq!(
            ApiError::from(RegistryError::ActiveVersion {
                name: "x".into(),
                version: 2
            })
            .kind,
            Kind::VersionActive
        );
        assert_eq!(
            ApiError::from(ModelError::SelfTest(1.0)).kind,
            Kind::InvalidModel
        );
    }
}
