//! `POST /v1/locate`: where the sphere of a photograph is, without classifying it. The page
//! draws this circle for the user to check or correct before classifying.

use super::classify::MultipartProblems;
use super::input::{self, RawInput};
use crate::server::error::{ApiError, ClassificationProblems, Kind, Problem};
use crate::server::state::SharedState;
use axum::Json;
use axum::extract::State;
use reflectance_core::decode::{DecodeOptions, Encoding};
use reflectance_core::inference::{self, LocateResponse};
use serde::Deserialize;
use utoipa::ToSchema;

/// The multipart form of a locate request.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub struct LocateForm {
    /// The photograph (PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM or OpenEXR).
    #[schema(value_type = String, format = Binary)]
    image: Vec<u8>,
    /// How integer samples are linearized: `srgb` (default), `linear` or `gamma:<g>`.
    #[schema(value_type = String, required = false, example = "srgb", pattern = "^(srgb|linear|gamma:[0-9]+(\\.[0-9]+)?)$")]
    encoding: Option<String>,
    /// `preview`: also return the image as a grey PNG (for formats browsers cannot show).
    #[schema(value_type = String, required = false, example = "preview",
        pattern = "^[ ,]*(preview[ ,]*)*$")]
    include: Option<String>,
}

/// The fields of the classification form that locating does not take.
fn refuse_classification_fields(raw: &RawInput) -> Result<(), ApiError> {
    let given = [
        ("white", raw.white.is_some()),
        ("white_image", raw.white_image.is_some()),
        ("white_rect", raw.white_rect.is_some()),
        ("white_reflectance", raw.white_reflectance.is_some()),
        ("cx", raw.cx.is_some()),
        ("cy", raw.cy.is_some()),
        ("r", raw.r.is_some()),
        ("mask", raw.mask.is_some()),
    ];
    match given.iter().find(|(_, present)| *present) {
        Some((name, _)) => Err(ApiError::new(
            Kind::UnknownField,
            format!("unknown field {name:?} (expected image, encoding, include)"),
        )),
        None => Ok(()),
    }
}

/// Find the sphere as classification does when no circle is given (with the default model's
/// annulus, which the circle must fit).
#[utoipa::path(
    post,
    operation_id = "locate", path = "/v1/locate",
    tag = "classification",
    request_body(content = LocateForm, content_type = "multipart/form-data"),
    responses(
        (status = 200, description = "The image's size and the sphere found (absent, with a warning, when none)", body = LocateResponse),
        MultipartProblems,
        (status = 422, description = "Missing image (`missing-field`), unknown or invalid field (`unknown-field`, `invalid-field`), corrupt or unusable image (`corrupt-image`, `invalid-image`)", body = Problem, content_type = "application/problem+json"),
        ClassificationProblems,
    )
)]
pub async fn locate(
    State(state): State<SharedState>,
    form: Result<input::Form, ApiError>,
) -> Result<Json<LocateResponse>, ApiError> {
    super::health::serving(&state)?;
    let raw = input::read_form(form?.0).await?;
    refuse_classification_fields(&raw)?;
    let [preview] = input::includes(&raw.include, ["preview"])?;
    let image = raw
        .image
        .filter(|bytes| !bytes.is_empty())
        .ok_or_else(|| ApiError::new(Kind::MissingField, "the image field is required"))?;
    let encoding = raw
        .encoding
        .as_deref()
        .map(str::parse::<Encoding>)
        .transpose()?;
    let options = DecodeOptions {
        encoding,
        limits: state.config.limits,
        colour: false,
    };
    let permit = state.cpu.admit()?;
    let worker_state = state.clone();
    let mut located = state
        .cpu
        .run(permit, move || {
            let name = &worker_state.config.default_model;
            let model = worker_state.models.get(name, None)?;
            Ok(inference::locate(&model, &image, &options, preview)?)
        })
        .await?;
    located.request_id = crate::server::error::current_request_id();
    Ok(Json(located))
}
