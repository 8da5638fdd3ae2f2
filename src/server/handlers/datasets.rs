//! `/admin/v1/datasets`: labelled photographs uploaded as an archive, checked and stored
//! for training and cross-validation jobs ([`crate::server::datasets`]).

use super::admin::blocking;
use super::classify::MultipartProblems;
use super::input::Form;
use crate::server::datasets::{DatasetDetail, DatasetInfo, DatasetList, DatasetStore, Incoming};
use crate::server::error::{ApiError, Kind, Problem, Unauthorized};
use crate::server::state::SharedState;
use axum::Json;
use axum::extract::multipart::Field;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use reflectance_core::decode::DecodeOptions;
use serde::Deserialize;
use std::sync::Arc;
use tokio::io::AsyncWriteExt;
use utoipa::ToSchema;

/// Room for the form's own bytes (boundaries, headers, the name) beside the archive.
const FORM_OVERHEAD: u64 = 64 * 1024;
const NAME_LIMIT: usize = 256;

/// The multipart form of a dataset upload.
#[derive(Deserialize, ToSchema)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
pub struct DatasetForm {
    /// The dataset's name (1–64 of a-z, 0-9, '_' and '-'); send it before the archive.
    #[schema(example = "my-spheres")]
    name: String,
    /// A `.tar`, `.tar.gz` or `.zip` with `manifest.csv` at its root
    /// (`path,class,illumination[,cx,cy,r,white,encoding]`, paths relative to the root)
    /// and the images it names.
    #[schema(value_type = String, format = Binary)]
    archive: Vec<u8>,
}

fn store(state: &SharedState) -> Result<Arc<DatasetStore>, ApiError> {
    state
        .datasets
        .clone()
        .ok_or_else(|| ApiError::internal("the dataset store is not open"))
}

fn too_large(limit: u64) -> ApiError {
    ApiError::new(
        Kind::ArchiveTooLarge,
        format!("the archive is over the limit of {limit} bytes (see --dataset-max-archive)"),
    )
}

async fn read_name(mut field: Field<'_>) -> Result<String, ApiError> {
    let mut bytes = Vec::new();
    while let Some(chunk) = field.chunk().await? {
        bytes.extend_from_slice(&chunk);
        if bytes.len() > NAME_LIMIT {
            return Err(ApiError::new(
                Kind::InvalidField,
                "field \"name\" is too long",
            ));
        }
    }
    String::from_utf8(bytes)
        .map(|s| s.trim().to_string())
        .map_err(|_| ApiError::new(Kind::InvalidField, "field \"name\" is not UTF-8 text"))
}

/// Stream the archive to its file, at most `limit` bytes.
async fn receive(mut field: Field<'_>, incoming: &Incoming, limit: u64) -> Result<(), ApiError> {
    let storage =
        |e: std::io::Error| ApiError::storage(&e, format!("cannot store the archive: {e}"));
    let mut file = tokio::fs::File::create(incoming.archive())
        .await
        .map_err(storage)?;
    let mut received = 0u64;
    while let Some(chunk) = field.chunk().await? {
        received += chunk.len() as u64;
        if received > limit {
            return Err(too_large(limit));
        }
        file.write_all(&chunk).await.map_err(storage)?;
    }
    file.flush().await.map_err(storage)?;
    Ok(())
}

/// Upload a dataset: an archive of labelled photographs with their manifest. Every image
/// is decoded and checked; spheres without a circle in the manifest are located; what
/// cannot be used is listed in `refused` and the rest is stored.
#[utoipa::path(
    post,
    operation_id = "upload_dataset",
    path = "/admin/v1/datasets",
    tag = "admin",
    security(("bearer" = [])),
    request_body(content = DatasetForm, content_type = "multipart/form-data"),
    responses(
        (status = 201, description = "Stored; `dataset` is the value a train or cross_validate job takes", body = DatasetInfo,
         headers(("location" = String, description = "/admin/v1/datasets/{name}"))),
        MultipartProblems,
        Unauthorized,
        (status = 408, description = "The upload took longer than --dataset-timeout (`timeout`); nothing was stored", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The name is taken (`dataset-exists`)", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "The archive is over a limit: its size, its unpacked size or its number of members (`archive-too-large`), named in the detail", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "Missing or unknown field (`missing-field`, `unknown-field`), a bad name (`invalid-field`), not a tar, tar.gz or zip archive (`invalid-archive`), or nothing to learn from: no manifest.csv, no usable image, fewer than 2 classes or a class under fewer than 3 illuminations (`unusable-dataset`)", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "The data directory is read-only or forbidden (`storage-unavailable`)", body = Problem, content_type = "application/problem+json"),
        (status = 507, description = "The disk filled up (`insufficient-storage`); nothing was stored", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn upload(
    State(state): State<SharedState>,
    headers: HeaderMap,
    multipart: Result<Form, ApiError>,
) -> Result<Response, ApiError> {
    let store = store(&state)?;
    let limit = store.limits().archive_bytes;
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok()?.parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit.saturating_add(FORM_OVERHEAD)) {
        return Err(too_large(limit));
    }
    let mut multipart = multipart?.0;
    let (mut name, mut received) = (None, false);
    let worker = store.clone();
    let incoming = blocking(move || worker.incoming()).await?;
    while let Some(field) = multipart.next_field().await? {
        let field_name = field.name().unwrap_or_default().to_string();
        let first = match field_name.as_str() {
            "name" => {
                let given = read_name(field).await?;
                store.check_free(&given)?;
                name.replace(given).is_none()
            }
            "archive" => {
                receive(field, &incoming, limit).await?;
                !std::mem::replace(&mut received, true)
            }
            other => {
                return Err(ApiError::new(
                    Kind::UnknownField,
                    format!("unknown field {other:?} (expected name, archive)"),
                ));
            }
        };
        if !first {
            return Err(ApiError::new(
                Kind::InvalidField,
                format!("field {field_name:?} is given more than once"),
            ));
        }
    }
    let name =
        name.ok_or_else(|| ApiError::new(Kind::MissingField, "the name field is required"))?;
    if !received {
        return Err(ApiError::new(
            Kind::MissingField,
            "the archive field is required",
        ));
    }
    let decode = DecodeOptions {
        encoding: None,
        limits: state.config.limits,
        colour: false,
    };
    // If this request is dropped (a timeout, the client gone), the checking stops and
    // nothing is stored.
    let _abandon = incoming.abandon_on_drop();
    let worker = store.clone();
    let task_name = name.clone();
    let info = blocking(move || worker.create(&task_name, &incoming, &decode)).await?;
    let mut response = (StatusCode::CREATED, Json(info)).into_response();
    if let Ok(v) = HeaderValue::from_str(&format!("/admin/v1/datasets/{name}")) {
        response.headers_mut().insert(header::LOCATION, v);
    }
    Ok(response)
}

/// The stored datasets.
#[utoipa::path(
    get,
    operation_id = "list_datasets",
    path = "/admin/v1/datasets",
    tag = "admin",
    security(("bearer" = [])),
    responses(
        (status = 200, description = "Datasets, by name", body = DatasetList),
        Unauthorized,
    )
)]
pub async fn list(State(state): State<SharedState>) -> Result<Json<DatasetList>, ApiError> {
    let store = store(&state)?;
    Ok(Json(blocking(move || store.list()).await?))
}

/// One dataset with its manifest (every row with its circle).
#[utoipa::path(
    get,
    operation_id = "get_dataset",
    path = "/admin/v1/datasets/{name}",
    tag = "admin",
    security(("bearer" = [])),
    params(("name" = String, Path, description = "Dataset name", example = "my-spheres")),
    responses(
        (status = 200, description = "The dataset", body = DatasetDetail),
        Unauthorized,
        (status = 404, description = "Unknown dataset (`dataset-not-found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn get(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<Json<DatasetDetail>, ApiError> {
    let store = store(&state)?;
    Ok(Json(blocking(move || store.get(&name)).await?))
}

/// Delete a dataset.
#[utoipa::path(
    delete,
    operation_id = "delete_dataset",
    path = "/admin/v1/datasets/{name}",
    tag = "admin",
    security(("bearer" = [])),
    params(("name" = String, Path, description = "Dataset name", example = "my-spheres")),
    responses(
        (status = 204, description = "Deleted"),
        Unauthorized,
        (status = 404, description = "Unknown dataset (`dataset-not-found`)", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "A queued or running job uses it (`dataset-in-use`)", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "The data directory is read-only or forbidden (`storage-unavailable`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn delete(
    State(state): State<SharedState>,
    Path(name): Path<String>,
) -> Result<StatusCode, ApiError> {
    let store = store(&state)?;
    let jobs = super::admin::jobs(&state)?;
    blocking(move || store.delete(&name, &jobs)).await?;
    Ok(StatusCode::NO_CONTENT)
}
