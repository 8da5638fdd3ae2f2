//! The Open Inference Protocol over gRPC: `inference.GRPCInferenceService` (server and model
//! liveness, readiness and metadata, `ModelInfer`) on its own port (`--grpc-listen`), with
//! the REST handlers' work behind it ([`crate::server::handlers::v2`]): the same models,
//! versions, inputs, outputs and checks. Inputs arrive as raw contents or typed contents;
//! outputs leave as raw contents, as Triton's do. Failures become gRPC statuses here, in
//! one place ([`status`]).

pub mod messages;

use crate::server::error::{ApiError, Kind};
use crate::server::handlers::v2::{self, protocol, tensor};
use crate::server::state::SharedState;
use messages::*;
use std::convert::Infallible;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use tensor::{Datatype, Elements, Tensor, TensorError};
use tonic::{Code, Status};

/// The service's name, the first part of every method's path.
pub const SERVICE: &str = "inference.GRPCInferenceService";

type BoxFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;

/// The gRPC status of a failure, by its kind (the HTTP status's counterpart).
pub fn status(e: ApiError) -> Status {
    let code = match e.kind {
        Kind::ModelNotFound | Kind::VersionNotFound | Kind::NotFound => Code::NotFound,
        Kind::NotReady | Kind::NotReadyV2 | Kind::StorageUnavailable => Code::Unavailable,
        Kind::Overloaded | Kind::ImageTooLarge | Kind::BodyTooLarge | Kind::StorageFull => {
            Code::ResourceExhausted
        }
        Kind::Timeout => Code::DeadlineExceeded,
        Kind::InvalidModel => Code::FailedPrecondition,
        Kind::Unauthorized => Code::Unauthenticated,
        Kind::Internal => Code::Internal,
        _ => Code::InvalidArgument,
    };
    Status::new(code, e.detail)
}

/// One unary call, taken once: a `tower::Service` that tonic's unary handling drives.
struct Unary<F>(Option<F>);

impl<Q, R, F, Fut> tower::Service<tonic::Request<Q>> for Unary<F>
where
    F: FnOnce(Q) -> Fut,
    Fut: Future<Output = Result<R, Status>> + Send + 'static,
{
    type Response = tonic::Response<R>;
    type Error = Status;
    type Future = BoxFuture<Result<tonic::Response<R>, Status>>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Status>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, request: tonic::Request<Q>) -> Self::Future {
        match self.0.take() {
            Some(f) => {
                let answer = f(request.into_inner());
                Box::pin(async move { answer.await.map(tonic::Response::new) })
            }
            None => Box::pin(async { Err(Status::internal("a unary call answered twice")) }),
        }
    }
}

/// Decode the request `Q`, answer with `f`, encode the `R`.
async fn unary<Q, R, F, Fut>(
    limit: usize,
    request: axum::http::Request<tonic::body::Body>,
    f: F,
) -> axum::http::Response<tonic::body::Body>
where
    Q: prost::Message + Default + Send + 'static,
    R: prost::Message + Send + 'static,
    F: FnOnce(Q) -> Fut,
    Fut: Future<Output = Result<R, Status>> + Send + 'static,
{
    let codec = tonic_prost::ProstCodec::<R, Q>::default();
    let mut grpc = tonic::server::Grpc::new(codec).max_decoding_message_size(limit);
    grpc.unary(Unary(Some(f)), request).await
}

/// The service, for tonic's server.
#[derive(Clone)]
pub struct InferenceService {
    state: SharedState,
}

impl InferenceService {
    pub fn new(state: SharedState) -> InferenceService {
        InferenceService { state }
    }
}

impl tower::Service<axum::http::Request<tonic::body::Body>> for InferenceService {
    type Response = axum::http::Response<tonic::body::Body>;
    type Error = Infallible;
    type Future = BoxFuture<Result<Self::Response, Infallible>>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, request: axum::http::Request<tonic::body::Body>) -> Self::Future {
        let state = self.state.clone();
        Box::pin(async move { Ok(route(state, request).await) })
    }
}

async fn route(
    state: SharedState,
    request: axum::http::Request<tonic::body::Body>,
) -> axum::http::Response<tonic::body::Body> {
    let limit = state.config.body_limit;
    let path = request.uri().path().to_string();
    let method = path
        .strip_prefix('/')
        .and_then(|p| p.strip_prefix(SERVICE))
        .and_then(|p| p.strip_prefix('/'))
        .unwrap_or_default();
    let s = state.clone();
    match method {
        "ServerLive" => {
            unary(limit, request, |_: ServerLiveRequest| async {
                Ok(ServerLiveResponse { live: true })
            })
            .await
        }
        "ServerReady" => {
            unary(limit, request, move |_: ServerReadyRequest| async move {
                let ready = v2::readiness(&s).is_ok();
                Ok(ServerReadyResponse { ready })
            })
            .await
        }
        "ModelReady" => unary(limit, request, move |q| model_ready(s, q)).await,
        "ServerMetadata" => {
            unary(limit, request, |_: ServerMetadataRequest| async {
                Ok(server_metadata())
            })
            .await
        }
        "ModelMetadata" => unary(limit, request, move |q| model_metadata(s, q)).await,
        "ModelInfer" => unary(limit, request, move |q| infer(s, q)).await,
        _ => Status::unimplemented(format!("{path} is not a method of {SERVICE}")).into_http(),
    }
}

fn server_metadata() -> ServerMetadataResponse {
    ServerMetadataResponse {
        name: "reflectance".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        extensions: Vec::new(),
    }
}

fn version(text: &str) -> Option<&str> {
    (!text.is_empty()).then_some(text)
}

/// Ready when the server is and the model (version) loads; false, not a failure, for an
/// unknown one (as the REST route's 4xx reads in the clients).
async fn model_ready(
    state: SharedState,
    q: ModelReadyRequest,
) -> Result<ModelReadyResponse, Status> {
    let ready = v2::readiness(&state).is_ok()
        && v2::model(&state, &q.name, version(&q.version))
            .await
            .is_ok();
    Ok(ModelReadyResponse { ready })
}

async fn model_metadata(
    state: SharedState,
    q: ModelMetadataRequest,
) -> Result<ModelMetadataResponse, Status> {
    let model = v2::model(&state, &q.name, version(&q.version))
        .await
        .map_err(status)?;
    let metadata = |t: protocol::TensorMetadata| TensorMetadata {
        name: t.name,
        datatype: t.datatype,
        shape: t.shape,
    };
    Ok(ModelMetadataResponse {
        versions: v2::versions(&state, &q.name).await.map_err(status)?,
        name: q.name,
        platform: "reflectance".into(),
        inputs: protocol::inputs().into_iter().map(metadata).collect(),
        outputs: protocol::outputs(&model)
            .into_iter()
            .map(metadata)
            .collect(),
    })
}

fn invalid(detail: String) -> Status {
    Status::invalid_argument(detail)
}

/// An input's elements from the typed field of its datatype.
fn typed_elements(datatype: Datatype, c: InferTensorContents) -> Result<Elements, TensorError> {
    let numbers = |v: Vec<f64>| Ok(Elements::Numbers(v));
    match datatype {
        Datatype::Bool => Ok(Elements::Bool(c.bool_contents)),
        Datatype::Bytes => Ok(Elements::Bytes(c.bytes_contents)),
        Datatype::Int8 | Datatype::Int16 | Datatype::Int32 => {
            numbers(c.int_contents.into_iter().map(f64::from).collect())
        }
        Datatype::Int64 => numbers(c.int64_contents.into_iter().map(|v| v as f64).collect()),
        Datatype::Uint8 | Datatype::Uint16 | Datatype::Uint32 => {
            numbers(c.uint_contents.into_iter().map(f64::from).collect())
        }
        Datatype::Uint64 => numbers(c.uint64_contents.into_iter().map(|v| v as f64).collect()),
        Datatype::Fp32 => numbers(c.fp32_contents.into_iter().map(f64::from).collect()),
        Datatype::Fp64 => numbers(c.fp64_contents),
        Datatype::Fp16 => Err(TensorError::TypedFp16),
    }
}

/// The request's inputs as tensors: raw contents in the order of the inputs, or each
/// input's typed contents.
fn tensors(inputs: Vec<InferInputTensor>, raw: Vec<bytes::Bytes>) -> Result<Vec<Tensor>, Status> {
    if !raw.is_empty() && raw.len() != inputs.len() {
        return Err(invalid(format!(
            "{} raw_input_contents for {} inputs",
            raw.len(),
            inputs.len()
        )));
    }
    let mut raw = raw.into_iter();
    let mut tensors = Vec::with_capacity(inputs.len());
    for input in inputs {
        let contents = match (raw.next(), input.contents) {
            (Some(_), Some(_)) => {
                return Err(invalid(format!(
                    "input {:?} has contents, beside raw_input_contents",
                    input.name
                )));
            }
            (raw, typed) => (raw, typed),
        };
        let elements = |datatype| match contents {
            (Some(bytes), None) => Elements::from_raw(datatype, &bytes),
            (None, Some(contents)) => typed_elements(datatype, contents),
            _ => Err(TensorError::Empty),
        };
        let tensor = Tensor::input(input.name, &input.datatype, input.shape, elements)
            .map_err(|e| invalid(e.to_string()))?;
        tensors.push(tensor);
    }
    Ok(tensors)
}

async fn infer(state: SharedState, q: ModelInferRequest) -> Result<ModelInferResponse, Status> {
    let inputs = tensors(q.inputs, q.raw_input_contents)?;
    let requested: Vec<String> = q.outputs.into_iter().map(|o| o.name).collect();
    let (model, outputs) = v2::classify_tensors(
        &state,
        &q.model_name,
        version(&q.model_version),
        inputs,
        &requested,
    )
    .await
    .map_err(status)?;
    let mut response = ModelInferResponse {
        model_name: q.model_name,
        model_version: model.version().to_string(),
        id: q.id,
        ..ModelInferResponse::default()
    };
    for t in outputs {
        response
            .raw_output_contents
            .push(t.elements.to_raw(t.datatype).into());
        response.outputs.push(InferOutputTensor {
            name: t.name,
            datatype: t.datatype.name().into(),
            shape: t.shape,
            ..InferOutputTensor::default()
        });
    }
    Ok(response)
}

/// Serve the service on `listener` until `shutdown` resolves.
pub async fn serve(
    state: SharedState,
    listener: tokio::net::TcpListener,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), tonic::transport::Error> {
    let timeout = state.config.request_timeout;
    // Without TCP_NODELAY a small answer waits for the client's delayed ACK: about 40 ms a
    // request, unary calls one after another.
    let incoming = tonic::transport::server::TcpIncoming::from(listener).with_nodelay(Some(true));
    tonic::transport::Server::builder()
        .timeout(timeout)
        .serve_with_incoming_shutdown(InferenceService::new(state), incoming, shutdown)
        .await
}
