//! `GET /v1/preview`: a sphere of given Ward parameters, rendered, as a PNG (what an
//! estimate or a class looks like). Renders run on the CPU pool behind admission; the last
//! answers are kept, since the same parameters always give the same picture.

use crate::server::error::{ApiError, ClassificationProblems, Problem};
use crate::server::state::SharedState;
use axum::body::Bytes;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use reflectance_render::preview;
use reflectance_render::ward::Ward;
use serde::Deserialize;
use std::collections::VecDeque;
use std::sync::Mutex;
use utoipa::IntoParams;

#[derive(Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct PreviewQuery {
    /// Diffuse reflectance ρd ≥ 0 (ρd + ρs ≤ 1).
    #[param(minimum = 0.0, maximum = 1.0)]
    rho_d: f64,
    /// Specular reflectance ρs ≥ 0.
    #[param(minimum = 0.0, maximum = 1.0)]
    rho_s: f64,
    /// Ward roughness α: 0 is a mirror; at most 0.5.
    #[param(minimum = 0.0, maximum = 0.5)]
    alpha: f64,
    /// The illumination: `sky-1` (default) … `sky-4`, procedural maps with the statistics of
    /// natural light.
    #[param(pattern = "^sky-[1-4]$")]
    probe: Option<String>,
    /// Image size in pixels, 72–384 (default 192); the sphere's radius is size / 2.2.
    #[param(minimum = 72, maximum = 384)]
    size: Option<usize>,
}

const DEFAULT_SIZE: usize = 192;
const CACHED: usize = 64;

/// (ρd, ρs, α as bits, probe, size).
type Key = (u64, u64, u64, String, usize);
type Entry = (Key, Bytes);

/// The most recently used previews, oldest first.
fn cache() -> &'static Mutex<VecDeque<Entry>> {
    static CACHE: Mutex<VecDeque<Entry>> = Mutex::new(VecDeque::new());
    &CACHE
}

fn cached(key: &Key) -> Option<Bytes> {
    let mut cache = cache().lock().unwrap_or_else(|e| e.into_inner());
    let at = cache.iter().position(|(k, _)| k == key)?;
    let entry = cache.remove(at)?;
    let png = entry.1.clone();
    cache.push_back(entry);
    Some(png)
}

fn remember(key: Key, png: Bytes) {
    let mut cache = cache().lock().unwrap_or_else(|e| e.into_inner());
    if cache.len() >= CACHED {
        cache.pop_front();
    }
    cache.push_back((key, png));
}

/// A sphere of these Ward parameters, rendered under a built-in illumination.
#[utoipa::path(
    get,
    operation_id = "preview", path = "/v1/preview",
    tag = "classification",
    params(PreviewQuery),
    responses(
        (status = 200, description = "The rendered sphere, 8-bit grey sRGB (an ideal white surface at 70 % of full scale)", content_type = "image/png", body = Vec<u8>),
        (status = 422, description = "Missing, unknown or invalid parameter (`invalid-field`)", body = Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    )
)]
pub async fn preview(
    State(state): State<SharedState>,
    query: Result<Query<PreviewQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query?;
    let ward = Ward {
        rho_d: q.rho_d,
        rho_s: q.rho_s,
        alpha: q.alpha,
    };
    let probe = q.probe.unwrap_or_else(|| preview::PROBES[0].to_string());
    let size = q.size.unwrap_or(DEFAULT_SIZE);
    preview::check(&ward, &probe, size)?;
    let key = (
        ward.rho_d.to_bits(),
        ward.rho_s.to_bits(),
        ward.alpha.to_bits(),
        probe.clone(),
        size,
    );
    let png = match cached(&key) {
        Some(png) => png,
        None => {
            let permit = state.cpu.admit()?;
            let png = state
                .cpu
                .run(permit, move || Ok(preview::png(&ward, &probe, size)?))
                .await?;
            let png = Bytes::from(png);
            remember(key, png.clone());
            png
        }
    };
    let headers = [
        (header::CONTENT_TYPE, "image/png"),
        (header::CACHE_CONTROL, "public, max-age=86400"),
    ];
    Ok((headers, png).into_response())
}
