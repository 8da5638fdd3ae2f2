//! `GET /v1/material.gltf`: a sphere with the glTF 2.0 material of given Ward parameters
//! (an estimate or a class), for a renderer. The mapping: [`reflectance_core::material::gltf`].

use crate::server::error::{ApiError, Kind, Problem};
use axum::extract::Query;
use axum::extract::rejection::QueryRejection;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use reflectance_core::material::gltf::{Container, parse_colour, sphere};
use reflectance_core::material::{Material, Ward};
use serde::Deserialize;
use serde_json::json;
use utoipa::IntoParams;

#[derive(Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct MaterialQuery {
    /// Diffuse reflectance ρd ≥ 0 (ρd + ρs ≤ 1).
    #[param(minimum = 0.0, maximum = 1.0)]
    rho_d: f64,
    /// Specular reflectance ρs ≥ 0.
    #[param(minimum = 0.0, maximum = 1.0)]
    rho_s: f64,
    /// Ward roughness α, 0 (a mirror) to 1.
    #[param(minimum = 0.0, maximum = 1.0)]
    alpha: f64,
    /// The material's name in the asset and the file name (default `material`).
    #[param(pattern = "^[a-z0-9_-]{1,64}$", min_length = 1, max_length = 64)]
    name: Option<String>,
    /// The material's colour: linear `r,g,b` relative to white (any scale; the grey
    /// value keeps its luminance). Default: grey.
    #[param(
        example = "0.62,0.31,0.22",
        pattern = "^ *[0-9]+(\\.[0-9]+)? *, *[0-9]+(\\.[0-9]+)? *, *[0-9]+(\\.[0-9]+)? *$"
    )]
    colour: Option<String>,
    /// `gltf` (JSON with the buffer embedded, the default) or `glb` (binary glTF).
    #[param(inline)]
    format: Option<Format>,
}

/// The file format of an exported material.
#[derive(Clone, Copy, Debug, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    Gltf,
    Glb,
}

/// A sphere with the material of these Ward parameters, as glTF 2.0 (`pbrMetallicRoughness`,
/// with `KHR_materials_ior` and `KHR_materials_specular` where needed); the parameters and
/// the colour are kept in the asset's `extras`.
#[utoipa::path(
    get,
    operation_id = "material_gltf", path = "/v1/material.gltf",
    tag = "classification",
    params(MaterialQuery),
    responses(
        (status = 200, description = "A self-contained glTF 2.0 asset: JSON with its buffer embedded, or binary glTF with `format=glb`",
         content(
            (Object = "model/gltf+json"),
            (Vec<u8> = "model/gltf-binary"))),
        (status = 422, description = "Missing, unknown or invalid parameter (`invalid-field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn gltf(
    query: Result<Query<MaterialQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query?;
    let name = q.name.unwrap_or_else(|| "material".into());
    if !reflectance_core::model::registry::valid_name(&name) {
        return Err(ApiError::new(
            Kind::InvalidField,
            format!("invalid name {name:?} (use 1–64 of a-z, 0-9, '_' and '-')"),
        ));
    }
    let colour = q
        .colour
        .as_deref()
        .map(|text| {
            parse_colour(text).map_err(|e| ApiError::new(Kind::InvalidField, e.to_string()))
        })
        .transpose()?;
    let material = Material::new(name, Ward::new(q.rho_d, q.rho_s, q.alpha)?);
    let container = match q.format {
        Some(Format::Glb) => Container::Glb,
        Some(Format::Gltf) | None => Container::Gltf,
    };
    let about = json!({"source": "GET /v1/material.gltf"});
    let body = sphere(&material, colour, about).encode(container);
    let disposition = format!(
        "attachment; filename=\"{}.{}\"",
        material.name,
        container.extension()
    );
    let headers = [
        (header::CONTENT_TYPE, container.media_type().to_string()),
        (header::CONTENT_DISPOSITION, disposition),
        (header::CACHE_CONTROL, "public, max-age=86400".to_string()),
    ];
    Ok((headers, body).into_response())
}
