//! `GET /v1/material.gltf`: a sphere with the glTF 2.0 material of given Ward parameters
//! (an estimate or a class), for a renderer. The mapping: [`crate::material::gltf`].

use crate::material::Material;
use crate::material::gltf::sphere_asset;
use crate::server::error::{ApiError, Kind, Problem};
use axum::extract::Query;
use axum::extract::rejection::QueryRejection;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::json;
use utoipa::IntoParams;

#[derive(Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct MaterialQuery {
    /// Diffuse reflectance ρd ≥ 0 (ρd + ρs ≤ 1).
    rho_d: f64,
    /// Specular reflectance ρs ≥ 0.
    rho_s: f64,
    /// Ward roughness α, 0 (a mirror) to 1.
    alpha: f64,
    /// The material's name in the asset and the file name (1–64 of a-z, 0-9, '_', '-';
    /// default `material`).
    name: Option<String>,
}

/// A sphere with the material of these Ward parameters, as glTF 2.0 (`pbrMetallicRoughness`,
/// with `KHR_materials_ior` and `KHR_materials_specular` where needed); the parameters are
/// kept in the asset's `extras`.
#[utoipa::path(
    get,
    operation_id = "material_gltf", path = "/v1/material.gltf",
    tag = "classification",
    params(MaterialQuery),
    responses(
        (status = 200, description = "A self-contained glTF 2.0 asset (JSON, its buffer embedded)", content_type = "model/gltf+json", body = Object),
        (status = 422, description = "Missing, unknown or invalid parameter (`invalid-field`)", body = Problem, content_type = "application/problem+json"),
    )
)]
pub async fn gltf(
    query: Result<Query<MaterialQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query?;
    let name = q.name.unwrap_or_else(|| "material".into());
    if !crate::model::registry::valid_name(&name) {
        return Err(ApiError::new(
            Kind::InvalidField,
            format!("invalid name {name:?} (use 1–64 of a-z, 0-9, '_' and '-')"),
        ));
    }
    let material = Material {
        name,
        rho_d: q.rho_d,
        rho_s: q.rho_s,
        alpha: q.alpha,
    };
    material.validate().map_err(|_| {
        ApiError::new(
            Kind::InvalidField,
            format!(
                "need 0 ≤ rho_d, 0 ≤ rho_s, rho_d + rho_s ≤ 1 and 0 ≤ alpha ≤ 1, not rho_d {}, rho_s {}, alpha {}",
                q.rho_d, q.rho_s, q.alpha
            ),
        )
    })?;
    let about = json!({"source": "GET /v1/material.gltf"});
    let asset = sphere_asset(&material.name, q.rho_d, q.rho_s, q.alpha, about);
    let body = serde_json::to_vec(&asset).map_err(ApiError::internal)?;
    let disposition = format!("attachment; filename=\"{}.gltf\"", material.name);
    let headers = [
        (header::CONTENT_TYPE, "model/gltf+json".to_string()),
        (header::CONTENT_DISPOSITION, disposition),
        (header::CACHE_CONTROL, "public, max-age=86400".to_string()),
    ];
    Ok((headers, body).into_response())
}
