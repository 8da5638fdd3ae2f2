//! The Open Inference Protocol (KServe V2) over HTTP/REST, as its reference clients speak
//! it (tritonclient): server and model metadata, health, and `infer` for the active version
//! or any version the registry holds, with JSON tensors or the binary tensor data extension
//! (`Inference-Header-Content-Length`), the `outputs` filter, gzip or deflate request
//! bodies, and errors whose message is in an `error` member (beside the problem's own).
//!
//! What a model takes and gives, and how its answer becomes tensors: [`protocol`]; the
//! tensors themselves: [`tensor`]. The gRPC service (`server::grpc`) shares both.

pub mod protocol;
pub mod tensor;

use super::classify;
use crate::server::error::{ApiError, ClassificationProblems, Kind};
use crate::server::state::{LoadedModel, SharedState};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use protocol::TensorMetadata;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::io::Read;
use std::sync::Arc;
use tensor::{Datatype, Elements, Tensor, TensorError};
use utoipa::ToSchema;

/// The header that splits a body into its JSON and its binary tensor data.
pub const HEADER_LENGTH: &str = "inference-header-content-length";
/// The protocol extensions this server supports.
pub const EXTENSIONS: [&str; 1] = ["binary_tensor_data"];

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ServerMetadata {
    pub name: String,
    pub version: String,
    pub extensions: Vec<String>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Live {
    pub live: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Ready {
    pub ready: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelReady {
    pub name: String,
    pub ready: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelMetadata {
    pub name: String,
    /// Every version the registry holds (as strings, per the protocol).
    pub versions: Vec<String>,
    pub platform: String,
    pub inputs: Vec<TensorMetadata>,
    pub outputs: Vec<TensorMetadata>,
    /// The most images one infer request may hold: an `image` input of shape [N] or
    /// [N, 1] (N > 1) is a batch, answered with every output's shape led by N.
    pub max_batch_size: usize,
}

/// One input tensor.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferInput {
    /// `image` (required), `white`, `white_image`, `white_rect`, `white_reflectance`, `cx`,
    /// `cy`, `r`, `mask`, `normals` (an object's normal map, instead of a circle), `encoding` or
    /// `coverage`.
    #[schema(min_length = 1)]
    pub name: String,
    pub shape: Vec<i64>,
    /// `BYTES` for files and text; a number type (`FP64`, `FP32`, `INT32`, …) for numbers.
    #[schema(
        pattern = "^(BOOL|UINT8|UINT16|UINT32|UINT64|INT8|INT16|INT32|INT64|FP16|FP32|FP64|BYTES)$"
    )]
    pub datatype: String,
    /// `binary_data_size`: the element bytes are in the binary part of the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Map<String, Value>>,
    /// The elements, flat or nested by the shape: files as base64 strings, text as
    /// strings, numbers as numbers. Absent with `binary_data_size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Value>>)]
    pub data: Option<Value>,
}

/// An output the client asks for.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct RequestedOutput {
    pub name: String,
    /// `binary_data`: return it in the binary part of the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Map<String, Value>>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferRequest {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// `binary_data_output`: every output in the binary part unless it says otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Map<String, Value>>,
    #[schema(min_items = 1)]
    pub inputs: Vec<InferInput>,
    /// The outputs to return (all when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outputs: Option<Vec<RequestedOutput>>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferOutput {
    pub name: String,
    pub shape: Vec<i64>,
    pub datatype: String,
    /// `binary_data_size` when the elements are in the binary part of the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
    /// Strings (BYTES), numbers (FP64) or booleans (BOOL); absent when binary.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Value>>)]
    pub data: Option<Vec<Value>>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferResponse {
    pub model_name: String,
    pub model_version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    pub outputs: Vec<InferOutput>,
}

/// A body of the binary tensor data extension: the request's (or answer's) JSON, its length
/// in `Inference-Header-Content-Length`, then the tensors' bytes.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
pub struct BinaryTensorData(Vec<u8>);

/// A problem on the protocol's routes: the problem document with the message again in
/// `error`, where the protocol's clients read it.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct V2Problem {
    #[serde(rename = "type")]
    pub type_: String,
    pub title: String,
    pub status: u16,
    pub detail: String,
    pub request_id: String,
    /// The detail again (the protocol's error member).
    pub error: String,
}

/// Server metadata.
#[utoipa::path(get, operation_id = "v2_server_metadata", path = "/v2", tag = "kserve-v2",
    responses((status = 200, description = "Server metadata", body = ServerMetadata)))]
pub async fn server_metadata() -> Json<ServerMetadata> {
    Json(ServerMetadata {
        name: "reflectance".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        extensions: EXTENSIONS.iter().map(|e| e.to_string()).collect(),
    })
}

/// Server liveness.
#[utoipa::path(get, operation_id = "v2_live", path = "/v2/health/live", tag = "kserve-v2",
    responses((status = 200, description = "Alive", body = Live)))]
pub async fn health_live() -> Json<Live> {
    Json(Live { live: true })
}

/// The protocol's "false": a 4xx (its health section: "A 200 status code indicates true
/// and a 4xx status code indicates false").
pub fn readiness(state: &SharedState) -> Result<(), ApiError> {
    super::health::readiness(state).map_err(|e| ApiError::new(Kind::NotReadyV2, e.detail))
}

/// Server readiness (200: ready; 400: not ready, as the protocol answers "false" with a 4xx).
#[utoipa::path(get, operation_id = "v2_ready", path = "/v2/health/ready", tag = "kserve-v2",
    responses(
        (status = 200, description = "Ready", body = Ready),
        (status = 400, description = "Loading or draining (`v2-not-ready`): the protocol's \"false\"", body = V2Problem, content_type = "application/problem+json")))]
pub async fn health_ready(State(state): State<SharedState>) -> Result<Json<Ready>, ApiError> {
    readiness(&state)?;
    Ok(Json(Ready { ready: true }))
}

/// A version named in a path: a whole number ≥ 1 (else no such version).
fn parse_version(name: &str, text: &str) -> Result<u32, ApiError> {
    text.parse::<u32>().ok().filter(|&v| v >= 1).ok_or_else(|| {
        ApiError::new(
            Kind::VersionNotFound,
            format!("model {name:?} has no version {text:?}"),
        )
    })
}

/// The model a request names: the active version, or the version given (read from the
/// registry off the runtime's threads when it is not loaded).
pub async fn model(
    state: &SharedState,
    name: &str,
    version: Option<&str>,
) -> Result<Arc<LoadedModel>, ApiError> {
    state.models.served(name)?;
    let Some(version) = version.map(|v| parse_version(name, v)).transpose()? else {
        return Ok(state.models.get(name, None)?);
    };
    let (state, name) = (state.clone(), name.to_string());
    let model = tokio::task::spawn_blocking(move || state.models.get(&name, Some(version)))
        .await
        .map_err(ApiError::internal)?;
    Ok(model?)
}

/// Every version the registry holds of a served model, as the protocol lists them.
pub async fn versions(state: &SharedState, name: &str) -> Result<Vec<String>, ApiError> {
    let registry = state.models.registry().clone();
    let name = name.to_string();
    let mut versions = tokio::task::spawn_blocking(move || registry.versions(&name))
        .await
        .map_err(ApiError::internal)??;
    versions.sort_unstable();
    Ok(versions.iter().map(u32::to_string).collect())
}

async fn metadata(
    state: &SharedState,
    name: String,
    version: Option<&str>,
) -> Result<Json<ModelMetadata>, ApiError> {
    let model = model(state, &name, version).await?;
    Ok(Json(ModelMetadata {
        versions: versions(state, &name).await?,
        name,
        platform: "reflectance".into(),
        inputs: protocol::inputs(),
        outputs: protocol::outputs(&model),
        max_batch_size: protocol::max_batch(state.config.max_inflight),
    }))
}

/// Model metadata.
#[utoipa::path(get, operation_id = "v2_model_metadata", path = "/v2/models/{name}", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "Model metadata", body = ModelMetadata),
        (status = 404, description = "Unknown model (`model-not-found`)", body = V2Problem, content_type = "application/problem+json")))]
pub async fn model_metadata(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<ModelMetadata>, ApiError> {
    metadata(&state, name, None).await
}

/// Metadata of one version of a model.
#[utoipa::path(get, operation_id = "v2_model_version_metadata", path = "/v2/models/{name}/versions/{version}", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6"),
           ("version" = String, Path, description = "A version the registry holds", example = "1", pattern = "^[1-9][0-9]{0,8}$")),
    responses(
        (status = 200, description = "Model metadata", body = ModelMetadata),
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 422, description = "The version's file is refused (`invalid-model`)", body = V2Problem, content_type = "application/problem+json")))]
pub async fn model_version_metadata(
    State(state): State<SharedState>,
    Path((name, version)): Path<(String, String)>,
) -> Result<Json<ModelMetadata>, ApiError> {
    metadata(&state, name, Some(&version)).await
}

/// Model readiness (200: ready; 400 while the server loads or drains; 404: unknown model).
#[utoipa::path(get, operation_id = "v2_model_ready", path = "/v2/models/{name}/ready", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "Ready", body = ModelReady),
        (status = 400, description = "Loading or draining (`v2-not-ready`): the protocol's \"false\"", body = V2Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model (`model-not-found`)", body = V2Problem, content_type = "application/problem+json")))]
pub async fn model_ready(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<ModelReady>, ApiError> {
    readiness(&state)?;
    model(&state, &name, None).await?;
    Ok(Json(ModelReady { name, ready: true }))
}

/// Readiness of one version: it is ready when it loads and passes its checks.
#[utoipa::path(get, operation_id = "v2_model_version_ready", path = "/v2/models/{name}/versions/{version}/ready", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6"),
           ("version" = String, Path, description = "A version the registry holds", example = "1", pattern = "^[1-9][0-9]{0,8}$")),
    responses(
        (status = 200, description = "Ready", body = ModelReady),
        (status = 400, description = "Loading or draining (`v2-not-ready`): the protocol's \"false\"", body = V2Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 422, description = "The version's file is refused (`invalid-model`)", body = V2Problem, content_type = "application/problem+json")))]
pub async fn model_version_ready(
    State(state): State<SharedState>,
    Path((name, version)): Path<(String, String)>,
) -> Result<Json<ModelReady>, ApiError> {
    readiness(&state)?;
    model(&state, &name, Some(&version)).await?;
    Ok(Json(ModelReady { name, ready: true }))
}

fn malformed(detail: impl Into<String>) -> ApiError {
    ApiError::new(Kind::MalformedRequest, detail)
}

fn invalid(detail: impl Into<String>) -> ApiError {
    ApiError::new(Kind::InvalidField, detail)
}

/// The body as sent: JSON, or JSON and binary data; gzip or deflate undone (to the body
/// limit).
fn body_bytes(headers: &HeaderMap, body: Bytes, limit: usize) -> Result<Bytes, ApiError> {
    if let Some(kind) = headers.get(header::CONTENT_TYPE) {
        let kind = kind.to_str().unwrap_or_default().to_ascii_lowercase();
        let essence = kind.split(';').next().unwrap_or_default().trim();
        if !matches!(essence, "application/json" | "application/octet-stream") {
            return Err(ApiError::new(
                Kind::UnsupportedMediaType,
                format!(
                    "send application/json (or the binary tensor data extension's application/octet-stream), not {essence:?}"
                ),
            ));
        }
    }
    let encoding = headers
        .get(header::CONTENT_ENCODING)
        .map(|v| v.to_str().unwrap_or_default().trim().to_ascii_lowercase());
    let reader: Box<dyn Read> = match encoding.as_deref() {
        None | Some("identity") => return Ok(body),
        Some("gzip") => Box::new(flate2::read::GzDecoder::new(&body[..])),
        Some("deflate") => Box::new(flate2::read::ZlibDecoder::new(&body[..])),
        Some(other) => {
            return Err(ApiError::new(
                Kind::UnsupportedMediaType,
                format!("content encoding {other:?} (expected gzip or deflate)"),
            ));
        }
    };
    let mut out = Vec::new();
    reader
        .take(limit as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| malformed(format!("the compressed body does not decompress: {e}")))?;
    if out.len() > limit {
        return Err(ApiError::over_body_limit("the decompressed body", limit));
    }
    Ok(out.into())
}

/// Split a body at its header length: (JSON, binary data).
fn split(headers: &HeaderMap, body: Bytes) -> Result<(Bytes, Bytes), ApiError> {
    let Some(value) = headers.get(HEADER_LENGTH) else {
        return Ok((body, Bytes::new()));
    };
    let length = value
        .to_str()
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n <= body.len())
        .ok_or_else(|| {
            malformed(format!(
                "Inference-Header-Content-Length must be a whole number of bytes within the \
                 {}-byte body",
                body.len()
            ))
        })?;
    Ok((body.slice(..length), body.slice(length..)))
}

fn parse_request(json: &[u8]) -> Result<InferRequest, ApiError> {
    serde_json::from_slice(json).map_err(|e| {
        let text = format!("the request is not an inference request: {e}");
        match e.classify() {
            serde_json::error::Category::Data => invalid(text),
            _ => malformed(text),
        }
    })
}

fn flatten(value: Value, out: &mut Vec<Value>) {
    match value {
        Value::Array(items) => items.into_iter().for_each(|v| flatten(v, out)),
        other => out.push(other),
    }
}

/// JSON `data`, flat or nested, as elements of `datatype`.
fn json_elements(datatype: Datatype, data: Value) -> Result<Elements, TensorError> {
    let mut values = Vec::new();
    flatten(data, &mut values);
    let wrong = |v: &Value| TensorError::Holds {
        datatype: datatype.name(),
        value: v.to_string(),
    };
    Ok(match datatype {
        Datatype::Bytes => Elements::Text(
            values
                .into_iter()
                .map(|v| match v {
                    Value::String(s) => Ok(s),
                    other => Err(wrong(&other)),
                })
                .collect::<Result<_, _>>()?,
        ),
        Datatype::Bool => Elements::Bool(
            values
                .iter()
                .map(|v| v.as_bool().ok_or_else(|| wrong(v)))
                .collect::<Result<_, _>>()?,
        ),
        _ => Elements::Numbers(
            values
                .iter()
                .map(|v| v.as_f64().ok_or_else(|| wrong(v)))
                .collect::<Result<_, _>>()?,
        ),
    })
}

fn binary_size(parameters: &Option<Map<String, Value>>) -> Result<Option<usize>, ApiError> {
    let Some(value) = parameters.as_ref().and_then(|p| p.get("binary_data_size")) else {
        return Ok(None);
    };
    value
        .as_u64()
        .and_then(|n| usize::try_from(n).ok())
        .map(Some)
        .ok_or_else(|| {
            invalid(format!(
                "binary_data_size must be a whole number, not {value}"
            ))
        })
}

/// The request's inputs as tensors, their bytes taken in order from `binary`.
fn tensors(inputs: Vec<InferInput>, binary: Bytes) -> Result<Vec<Tensor>, ApiError> {
    let mut at = 0;
    let mut tensors = Vec::with_capacity(inputs.len());
    enum Contents {
        Raw(Bytes),
        Json(Value),
    }
    for input in inputs {
        let name = &input.name;
        let elements = match (binary_size(&input.parameters)?, input.data) {
            (Some(size), _) => {
                let Some(raw) = binary.get(at..).filter(|rest| rest.len() >= size) else {
                    return Err(malformed(format!(
                        "input {name:?} has binary_data_size {size}, but the binary data \
                         holds {} more bytes",
                        binary.len().saturating_sub(at)
                    )));
                };
                let raw = binary.slice_ref(&raw[..size]);
                at += size;
                Contents::Raw(raw)
            }
            (None, Some(data)) => Contents::Json(data),
            (None, None) => {
                return Err(invalid(format!(
                    "input {name:?} has neither data nor binary_data_size"
                )));
            }
        };
        let tensor =
            Tensor::input(
                input.name,
                &input.datatype,
                input.shape,
                |datatype| match elements {
                    Contents::Raw(raw) => Elements::from_raw(datatype, &raw),
                    Contents::Json(data) => json_elements(datatype, data),
                },
            );
        tensors.push(tensor.map_err(|e| invalid(e.to_string()))?);
    }
    if at != binary.len() {
        return Err(malformed(format!(
            "the binary data holds {} bytes more than the inputs' binary_data_size",
            binary.len() - at
        )));
    }
    Ok(tensors)
}

fn flag(parameters: &Option<Map<String, Value>>, name: &str) -> Result<Option<bool>, ApiError> {
    match parameters.as_ref().and_then(|p| p.get(name)) {
        None => Ok(None),
        Some(Value::Bool(b)) => Ok(Some(*b)),
        Some(other) => Err(invalid(format!(
            "{name} must be true or false, not {other}"
        ))),
    }
}

/// The response: JSON, or JSON and the binary data of the outputs that asked for it.
fn respond(mut head: InferResponse, outputs: Vec<(Tensor, bool)>) -> Response {
    let mut binary = Vec::new();
    for (tensor, as_binary) in outputs {
        let mut output = InferOutput {
            name: tensor.name,
            shape: tensor.shape,
            datatype: tensor.datatype.name().into(),
            parameters: None,
            data: None,
        };
        if as_binary {
            let raw = tensor.elements.to_raw(tensor.datatype);
            output.parameters = Some(serde_json::json!({"binary_data_size": raw.len()}));
            binary.extend(raw);
        } else {
            output.data = Some(json_values(tensor.elements));
        }
        head.outputs.push(output);
    }
    if binary.is_empty() {
        return Json(head).into_response();
    }
    let mut body = serde_json::to_vec(&head).unwrap_or_default();
    let length = body.len();
    body.extend(binary);
    let mut response = body.into_response();
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/octet-stream"),
    );
    headers.insert(HEADER_LENGTH, HeaderValue::from(length));
    response
}

fn json_values(elements: Elements) -> Vec<Value> {
    use base64::Engine;
    match elements {
        Elements::Text(v) => v.into_iter().map(Value::String).collect(),
        Elements::Bytes(v) => v
            .iter()
            .map(|b| match std::str::from_utf8(b) {
                Ok(s) => Value::String(s.to_string()),
                Err(_) => Value::String(base64::engine::general_purpose::STANDARD.encode(b)),
            })
            .collect(),
        Elements::Numbers(v) => v.into_iter().map(Value::from).collect(),
        Elements::Bool(v) => v.into_iter().map(Value::Bool).collect(),
    }
}

async fn infer_with(
    state: SharedState,
    name: String,
    version: Option<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let body = body_bytes(&headers, body, state.config.body_limit)?;
    let (json, binary) = split(&headers, body)?;
    let request = parse_request(&json)?;
    let default_binary = flag(&request.parameters, "binary_data_output")?.unwrap_or(false);
    let requested = request.outputs.unwrap_or_default();
    let mut binary_of = Vec::with_capacity(requested.len());
    for output in requested {
        let binary = flag(&output.parameters, "binary_data")?.unwrap_or(default_binary);
        binary_of.push((output.name, binary));
    }
    let names: Vec<String> = binary_of.iter().map(|(n, _)| n.clone()).collect();
    let inputs = tensors(request.inputs, binary)?;
    let (model, selected) =
        classify_tensors(&state, &name, version.as_deref(), inputs, &names).await?;
    let outputs = selected
        .into_iter()
        .map(|t| {
            let binary = binary_of
                .iter()
                .find(|(n, _)| *n == t.name)
                .map_or(default_binary, |(_, b)| *b);
            (t, binary)
        })
        .collect();
    let head = InferResponse {
        model_name: name,
        model_version: model.version().to_string(),
        id: request.id,
        outputs: Vec::new(),
    };
    let mut response = respond(head, outputs);
    response
        .headers_mut()
        .insert("x-model-version", HeaderValue::from(model.version()));
    Ok(response)
}

/// Classify one image, or a batch (an `image` input of shape [N]), with the model's active
/// version. The body is JSON, or with the
/// binary tensor data extension the JSON (its length in the `Inference-Header-Content-Length`
/// header) followed by the inputs' bytes; gzip or deflate (`Content-Encoding`) bodies are
/// read too.
#[utoipa::path(post, operation_id = "v2_infer", path = "/v2/models/{name}/infer", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    request_body(content(
        (InferRequest = "application/json"),
        (BinaryTensorData = "application/octet-stream"))),
    responses(
        (status = 200, description = "Inference result: JSON, or (outputs asked for as binary data) the JSON followed by their bytes, its length in `Inference-Header-Content-Length`",
         content(
            (InferResponse = "application/json"),
            (BinaryTensorData = "application/octet-stream")),
         headers(("x-model-version" = u32, description = "The model version that answered"),
                 ("inference-header-content-length" = Option<u64>, description = "With binary outputs: the length of the JSON part"))),
        (status = 400, description = "Malformed JSON or binary data (`malformed-request`), or an image of a batch refused (`batch-item`: its index and its own problem in the detail)", body = V2Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model (`model-not-found`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 415, description = "Neither JSON nor binary tensor data (`unsupported-media-type`), or unknown image format (`unsupported-image-format`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 422, description = "Missing image, unknown or invalid inputs or outputs, corrupt or unusable image, bad circle or white (`missing-field`, `unknown-field`, `invalid-field`, `corrupt-image`, `invalid-image`, `bad-geometry`, `bad-white`)", body = V2Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    ))]
pub async fn infer(
    State(state): State<SharedState>,
    Path(name): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    infer_with(state, name, None, headers, body).await
}

/// Classify one image, or a batch, with a version the registry holds.
#[utoipa::path(post, operation_id = "v2_infer_version", path = "/v2/models/{name}/versions/{version}/infer", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6"),
           ("version" = String, Path, description = "A version the registry holds", example = "1", pattern = "^[1-9][0-9]{0,8}$")),
    request_body(content(
        (InferRequest = "application/json"),
        (BinaryTensorData = "application/octet-stream"))),
    responses(
        (status = 200, description = "Inference result (as for the active version)",
         content(
            (InferResponse = "application/json"),
            (BinaryTensorData = "application/octet-stream")),
         headers(("x-model-version" = u32, description = "The model version that answered"),
                 ("inference-header-content-length" = Option<u64>, description = "With binary outputs: the length of the JSON part"))),
        (status = 400, description = "Malformed JSON or binary data (`malformed-request`), or an image of a batch refused (`batch-item`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model or version (`model-not-found`, `version-not-found`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 415, description = "Neither JSON nor binary tensor data (`unsupported-media-type`), or unknown image format (`unsupported-image-format`)", body = V2Problem, content_type = "application/problem+json"),
        (status = 422, description = "As for the active version, and a refused model file (`invalid-model`)", body = V2Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    ))]
pub async fn infer_version(
    State(state): State<SharedState>,
    Path((name, version)): Path<(String, String)>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    infer_with(state, name, Some(version), headers, body).await
}

/// The inputs of a request, checked and classified by `name`'s `version` (or its active
/// one), with the tensors of the answer it asks for: the work of both transports.
pub async fn classify_tensors(
    state: &SharedState,
    name: &str,
    version: Option<&str>,
    inputs: Vec<Tensor>,
    requested: &[String],
) -> Result<(Arc<LoadedModel>, Vec<Tensor>), ApiError> {
    super::health::serving(state)?;
    let model = model(state, name, version).await?;
    let (raw, batched) =
        protocol::raw_inputs(inputs, protocol::max_batch(state.config.max_inflight))?;
    let version = Some(model.version());
    if !batched {
        let input = raw.into_iter().next().unwrap_or_default().validate()?;
        let c = classify::run(state, name, version, input).await?;
        let selected = protocol::select(&c.model, protocol::answer(&c), requested)?;
        return Ok((c.model.clone(), selected));
    }
    let n = raw.len();
    let inputs = raw
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.validate().map_err(|e| e.in_batch(i, n)))
        .collect::<Result<Vec<_>, _>>()?;
    let classified = classify::run_batch(state, name, version, inputs).await?;
    let answers: Vec<_> = classified.iter().map(protocol::answer).collect();
    let selected = protocol::select(&model, protocol::stack(&model, &answers), requested)?;
    Ok((model, selected))
}
