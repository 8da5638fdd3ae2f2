//! Open Inference Protocol (KServe V2 REST) for the same models: server and model
//! metadata, health, and `infer` with the image as a BYTES input (base64 in JSON).
//!
//! Inputs of `POST /v2/models/{name}/infer`: `image` (BYTES, shape [1], base64), and
//! optionally `white`, `cx`, `cy`, `r` (FP64 or FP32, shape [1]) and `encoding` (BYTES).
//! Outputs: `label` (BYTES [1]), `probabilities` (FP64 [classes], model class order) and
//! `classes` (BYTES [classes]).

use super::classify::{self, RawInput};
use crate::image::white::Method as WhiteMethod;
use crate::learn::estimate::Interval;
use crate::server::error::{ApiError, ClassificationProblems, Kind, Problem};
use crate::server::state::SharedState;
use axum::Json;
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::HeaderValue;
use axum::response::{IntoResponse, Response};
use base64::Engine;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;

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

/// A tensor's name, type and shape (−1: variable).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct TensorMetadata {
    pub name: String,
    pub datatype: String,
    pub shape: Vec<i64>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelMetadata {
    pub name: String,
    /// The active version (as a string, per the protocol).
    pub versions: Vec<String>,
    pub platform: String,
    pub inputs: Vec<TensorMetadata>,
    pub outputs: Vec<TensorMetadata>,
}

/// One input tensor.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferInput {
    /// `image`, `white`, `cx`, `cy`, `r` or `encoding`.
    pub name: String,
    pub shape: Vec<i64>,
    /// `BYTES` for `image` and `encoding`; `FP64` or `FP32` for the numbers.
    pub datatype: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
    /// One element: a base64 string (`image`), a string (`encoding`) or a number.
    #[schema(value_type = Vec<Object>)]
    pub data: Vec<Value>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferRequest {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub parameters: Option<Value>,
    pub inputs: Vec<InferInput>,
    /// Ignored: every output is returned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<Object>>)]
    pub outputs: Option<Vec<Value>>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferOutput {
    pub name: String,
    pub shape: Vec<i64>,
    pub datatype: String,
    /// Strings (BYTES) or numbers (FP64).
    #[schema(value_type = Vec<Object>)]
    pub data: Vec<Value>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct InferResponse {
    pub model_name: String,
    pub model_version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    pub outputs: Vec<InferOutput>,
}

/// Server metadata.
#[utoipa::path(get, operation_id = "v2_server_metadata", path = "/v2", tag = "kserve-v2",
    responses((status = 200, description = "Server metadata", body = ServerMetadata)))]
pub async fn server_metadata() -> Json<ServerMetadata> {
    Json(ServerMetadata {
        name: "reflectance".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        extensions: vec![],
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
fn v2_readiness(state: &SharedState) -> Result<(), ApiError> {
    super::health::readiness(state).map_err(|e| ApiError::new(Kind::NotReadyV2, e.detail))
}

/// Server readiness (200: ready; 400: not ready, as the protocol answers "false" with a 4xx).
#[utoipa::path(get, operation_id = "v2_ready", path = "/v2/health/ready", tag = "kserve-v2",
    responses(
        (status = 200, description = "Ready", body = Ready),
        (status = 400, description = "Loading or draining (`v2-not-ready`): the protocol's \"false\"", body = Problem, content_type = "application/problem+json")))]
pub async fn health_ready(State(state): State<SharedState>) -> Result<Json<Ready>, ApiError> {
    v2_readiness(&state)?;
    Ok(Json(Ready { ready: true }))
}

fn unknown(name: &str) -> ApiError {
    ApiError::new(Kind::ModelNotFound, format!("unknown model {name:?}"))
}

/// Model metadata.
#[utoipa::path(get, operation_id = "v2_model_metadata", path = "/v2/models/{name}", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "Model metadata", body = ModelMetadata),
        (status = 404, description = "Unknown model (`model-not-found`)", body = Problem, content_type = "application/problem+json")))]
pub async fn model_metadata(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<ModelMetadata>, ApiError> {
    let model = state.models.active(&name).ok_or_else(|| unknown(&name))?;
    let k = model.file.classifier.classes().len() as i64;
    let t = |name: &str, datatype: &str, shape: Vec<i64>| TensorMetadata {
        name: name.into(),
        datatype: datatype.into(),
        shape,
    };
    let mut outputs = vec![
        t("label", "BYTES", vec![1]),
        t("probabilities", "FP64", vec![k]),
        t("classes", "BYTES", vec![k]),
        t("prediction_set", "BYTES", vec![-1]),
        t("in_domain", "BOOL", vec![1]),
    ];
    if model.file.estimator.is_some() {
        // `ward` only when a white reference is given.
        outputs.push(t("ward", "FP64", vec![3, 3]));
        outputs.push(t("specular_fraction", "FP64", vec![3]));
    }
    Ok(Json(ModelMetadata {
        name: name.clone(),
        versions: vec![model.version().to_string()],
        platform: "reflectance".into(),
        inputs: vec![
            t("image", "BYTES", vec![1]),
            t("white", "FP64", vec![1]),
            t("cx", "FP64", vec![1]),
            t("cy", "FP64", vec![1]),
            t("r", "FP64", vec![1]),
            t("encoding", "BYTES", vec![1]),
            t("coverage", "FP64", vec![1]),
        ],
        outputs,
    }))
}

/// Model readiness (200: ready; 400 while the server loads or drains; 404: unknown model).
#[utoipa::path(get, operation_id = "v2_model_ready", path = "/v2/models/{name}/ready", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    responses(
        (status = 200, description = "Ready", body = ModelReady),
        (status = 400, description = "Loading or draining (`v2-not-ready`): the protocol's \"false\"", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model (`model-not-found`)", body = Problem, content_type = "application/problem+json")))]
pub async fn model_ready(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<ModelReady>, ApiError> {
    v2_readiness(&state)?;
    if !state.models.is_served(&name) {
        return Err(unknown(&name));
    }
    Ok(Json(ModelReady { name, ready: true }))
}

fn invalid(detail: String) -> ApiError {
    ApiError::new(Kind::InvalidField, detail)
}

fn single(input: &InferInput) -> Result<&Value, ApiError> {
    let count: i64 = input.shape.iter().product();
    if input.data.len() != 1 || count != 1 {
        return Err(invalid(format!(
            "input {:?} must hold exactly one element (shape [1])",
            input.name
        )));
    }
    Ok(&input.data[0])
}

fn number_text(input: &InferInput) -> Result<String, ApiError> {
    if !matches!(input.datatype.as_str(), "FP64" | "FP32") {
        return Err(invalid(format!(
            "input {:?} must be FP64 or FP32, not {}",
            input.name, input.datatype
        )));
    }
    match single(input)? {
        Value::Number(n) => Ok(n.to_string()),
        other => Err(invalid(format!(
            "input {:?} must be a number, not {other}",
            input.name
        ))),
    }
}

fn string(input: &InferInput) -> Result<String, ApiError> {
    if input.datatype != "BYTES" {
        return Err(invalid(format!(
            "input {:?} must be BYTES, not {}",
            input.name, input.datatype
        )));
    }
    match single(input)? {
        Value::String(s) => Ok(s.clone()),
        other => Err(invalid(format!(
            "input {:?} must be a string, not {other}",
            input.name
        ))),
    }
}

fn raw_input(request: &InferRequest) -> Result<RawInput, ApiError> {
    let mut raw = RawInput::default();
    for input in &request.inputs {
        let duplicate = || invalid(format!("input {:?} is given more than once", input.name));
        let slot = match input.name.as_str() {
            "image" => {
                let text = string(input)?;
                let bytes = base64::engine::general_purpose::STANDARD
                    .decode(text.trim())
                    .map_err(|e| invalid(format!("input \"image\" is not base64: {e}")))?;
                if raw.image.replace(bytes.into()).is_some() {
                    return Err(duplicate());
                }
                continue;
            }
            "encoding" => {
                if raw.encoding.replace(string(input)?).is_some() {
                    return Err(duplicate());
                }
                continue;
            }
            "white" => &mut raw.white,
            "cx" => &mut raw.cx,
            "cy" => &mut raw.cy,
            "r" => &mut raw.r,
            "coverage" => &mut raw.coverage,
            other => {
                return Err(ApiError::new(
                    Kind::UnknownField,
                    format!(
                        "unknown input {other:?} (expected image, white, cx, cy, r, encoding, \
                         coverage)"
                    ),
                ));
            }
        };
        if slot.replace(number_text(input)?).is_some() {
            return Err(duplicate());
        }
    }
    Ok(raw)
}

/// Classify one image.
#[utoipa::path(post, operation_id = "v2_infer", path = "/v2/models/{name}/infer", tag = "kserve-v2",
    params(("name" = String, Path, description = "Model name", example = "ward6")),
    request_body(content = InferRequest, content_type = "application/json"),
    responses(
        (status = 200, description = "Inference result", body = InferResponse,
         headers(("x-model-version" = u32, description = "The model version that answered"))),
        (status = 400, description = "Malformed JSON (`malformed-request`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "Unknown model (`model-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "Not application/json (`unsupported-media-type`) or unknown image format (`unsupported-image-format`)", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Missing image, unknown or invalid inputs, corrupt or unusable image, bad circle or white (`missing-field`, `unknown-field`, `invalid-field`, `corrupt-image`, `invalid-image`, `bad-geometry`, `bad-white`)", body = Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    ))]
pub async fn infer(
    State(state): State<SharedState>,
    Path(name): Path<String>,
    body: Result<Json<InferRequest>, JsonRejection>,
) -> Result<Response, ApiError> {
    super::health::serving(&state)?;
    if !state.models.is_served(&name) {
        return Err(unknown(&name));
    }
    let Json(request) = body?;
    let input = raw_input(&request)?.validate()?;
    let c = classify::run(&state, &name, None, input).await?;
    let classes = c.model.file.classifier.classes();
    let k = classes.len() as i64;
    let body = InferResponse {
        model_name: name,
        model_version: c.model.version().to_string(),
        id: request.id,
        outputs: vec![
            InferOutput {
                name: "label".into(),
                shape: vec![1],
                datatype: "BYTES".into(),
                data: vec![Value::String(classes[c.decision.class].clone())],
            },
            InferOutput {
                name: "probabilities".into(),
                shape: vec![k],
                datatype: "FP64".into(),
                data: c
                    .decision
                    .probabilities
                    .iter()
                    .map(|&p| Value::from(p))
                    .collect(),
            },
            InferOutput {
                name: "classes".into(),
                shape: vec![k],
                datatype: "BYTES".into(),
                data: classes.iter().map(|s| Value::String(s.clone())).collect(),
            },
        ],
    };
    let mut body = body;
    if let Some(set) = &c.decision.set {
        body.outputs.push(InferOutput {
            name: "prediction_set".into(),
            shape: vec![set.len() as i64],
            datatype: "BYTES".into(),
            data: set
                .iter()
                .map(|&i| Value::String(classes[i].clone()))
                .collect(),
        });
    }
    body.outputs.push(InferOutput {
        name: "in_domain".into(),
        shape: vec![1],
        datatype: "BOOL".into(),
        data: vec![Value::Bool(c.decision.in_domain())],
    });
    if let Some(w) = &c.ward {
        let rows = |intervals: &[Interval]| -> Vec<Value> {
            intervals
                .iter()
                .flat_map(|i| [i.value, i.low, i.high])
                .map(Value::from)
                .collect()
        };
        // Rows ρd, ρs, α; columns value, low, high. Only with a white reference: without
        // one the total reflectance is unknown.
        if c.analysis.white.method != WhiteMethod::None {
            body.outputs.push(InferOutput {
                name: "ward".into(),
                shape: vec![3, 3],
                datatype: "FP64".into(),
                data: rows(&[w.rho_d, w.rho_s, w.alpha]),
            });
        }
        // Value, low, high.
        body.outputs.push(InferOutput {
            name: "specular_fraction".into(),
            shape: vec![3],
            datatype: "FP64".into(),
            data: rows(&[w.specular_fraction()]),
        });
    }
    let mut response = Json(body).into_response();
    response
        .headers_mut()
        .insert("x-model-version", HeaderValue::from(c.model.version()));
    Ok(response)
}
