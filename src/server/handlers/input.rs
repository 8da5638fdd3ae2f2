//! The classification request's fields as they arrive, texts and files, from the multipart
//! form of `POST /v1/classify` or from a V2 request's tensors and parameters: the wire type
//! the three protocols share. [`RawInput::validate`] makes the core's `Input` of them.

use crate::server::error::{ApiError, Kind};
use axum::body::Bytes;
use axum::extract::multipart::Multipart;
use reflectance_core::analysis::{Placement, WhiteSpec};
use reflectance_core::decode::Encoding;
use reflectance_core::inference::{Answer, Input};
use reflectance_core::white::Rect;
use utoipa::ToSchema;

/// Parse a finite number field; a failure is a problem of `kind` (the field's subject).
fn number(kind: Kind, field: &str, text: &str) -> Result<f64, ApiError> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            ApiError::new(
                kind,
                format!("{field} must be a finite number, not {text:?}"),
            )
        })
}

/// The multipart form of a classification request (no other fields are accepted).
// The fields as received, texts and files, from the form or from a KServe V2 request's
// parameters; `validate` makes an `Input` of them. The schema is the form's.
#[derive(Default, ToSchema)]
#[schema(as = ClassifyForm)]
#[serde(deny_unknown_fields)]
pub struct RawInput {
    /// The photograph or rendering (PNG, JPEG, TIFF, PNM, Radiance HDR, PFM or OpenEXR).
    #[schema(value_type = String, format = Binary, required = true)]
    pub image: Option<Bytes>,
    /// Linear luminance of an ideal white surface at the sphere (finite, > 0).
    #[schema(value_type = f64, required = false, exclusive_minimum = 0.0)]
    pub white: Option<String>,
    /// A crop of a white card (its median luminance is the white reference); not with `white`.
    #[schema(value_type = String, format = Binary, required = false)]
    pub white_image: Option<Bytes>,
    /// Reflectance of the white card in (0, 1] (default 1); only with `white_image` or
    /// `white_rect`.
    #[schema(value_type = f64, required = false, exclusive_minimum = 0.0, maximum = 1.0)]
    pub white_reflectance: Option<String>,
    /// A white card inside the photograph: the rectangle `x,y,w,h` in pixels (left, top,
    /// width, height; every pixel it touches counts); not with `white` or `white_image`.
    #[schema(value_type = String, required = false, example = "40,300,120,80",
        pattern = "^ *-?[0-9]+(\\.[0-9]+)? *, *-?[0-9]+(\\.[0-9]+)? *, *[0-9]+(\\.[0-9]+)? *, *[0-9]+(\\.[0-9]+)? *$")]
    pub white_rect: Option<String>,
    /// Sphere centre x (column) in pixels; give cx, cy and r together.
    #[schema(value_type = f64, required = false)]
    pub cx: Option<String>,
    /// Sphere centre y (row) in pixels.
    #[schema(value_type = f64, required = false)]
    pub cy: Option<String>,
    /// Sphere radius in pixels (≥ 32).
    #[schema(value_type = f64, required = false, minimum = 32.0)]
    pub r: Option<String>,
    /// A mask image of the sphere (same size; alpha, or luminance ≥ 0.5); not with cx/cy/r.
    #[schema(value_type = String, format = Binary, required = false)]
    pub mask: Option<Bytes>,
    /// An object of any shape instead of a sphere: its camera-space unit normals per pixel,
    /// the image's size (+X right, +Y up, +Z toward the camera), as an 8- or 16-bit PNG
    /// (n = 2v/max − 1; background (0, 0, 0) or alpha 0) or an OpenEXR file (float R, G, B =
    /// X, Y, Z; background the zero vector); with it, `mask` is the object's pixels. Not with
    /// cx/cy/r.
    #[schema(value_type = String, format = Binary, required = false)]
    pub normals: Option<Bytes>,
    /// How integer samples are linearized: `srgb` (default), `linear` or `gamma:<g>`.
    #[schema(value_type = String, required = false, example = "srgb", pattern = "^(srgb|linear|gamma:[0-9]+(\\.[0-9]+)?)$")]
    pub encoding: Option<String>,
    /// Extra output: `features` (all extracted features), `explain` (nearest training
    /// images, with thumbnails) and/or `images` (the unwrapped annulus and the subbands as
    /// PNG); comma-separated or repeated.
    #[schema(value_type = String, required = false, example = "features,explain,images",
        pattern = "^[ ,]*((features|explain|images)[ ,]*)*$")]
    pub include: Vec<String>,
    /// The prediction set's coverage, from 0.5 to 0.999 (default 0.95).
    #[schema(value_type = f64, required = false, example = 0.9, minimum = 0.5, maximum = 0.999)]
    pub coverage: Option<String>,
}

impl RawInput {
    /// Parse the fields' text and check the request's rules ([`Input::new`]), before any
    /// decoding.
    pub fn validate(self) -> Result<Input, ApiError> {
        let image = self
            .image
            .ok_or_else(|| ApiError::new(Kind::MissingField, "the image field is required"))?;
        let parse_as = |kind: Kind, f: &str, t: &Option<String>| {
            t.as_deref().map(|t| number(kind, f, t)).transpose()
        };
        let white_number = |f: &str, t: &Option<String>| parse_as(Kind::BadWhite, f, t);
        let circle_number = |f: &str, t: &Option<String>| parse_as(Kind::BadGeometry, f, t);
        let white = WhiteSpec::new(
            white_number("white", &self.white)?,
            self.white_image,
            self.white_rect
                .as_deref()
                .map(str::parse::<Rect>)
                .transpose()?,
            white_number("white_reflectance", &self.white_reflectance)?,
        )?;
        let locate = Placement::new(
            circle_number("cx", &self.cx)?,
            circle_number("cy", &self.cy)?,
            circle_number("r", &self.r)?,
            self.mask,
        )?
        .with_normals(self.normals)?;
        let encoding = self
            .encoding
            .as_deref()
            .map(|t| t.parse::<Encoding>())
            .transpose()?;
        let [include_features, include_explain, include_images] =
            includes(&self.include, ["features", "explain", "images"])?;
        let answer = Answer {
            include_features,
            include_explain,
            include_images,
            coverage: parse_as(Kind::InvalidField, "coverage", &self.coverage)?,
        };
        Ok(Input::new(image, white, locate, encoding, answer)?)
    }
}

/// Which of `known` the `include` values (comma-separated or repeated) name.
pub fn includes<const N: usize>(
    values: &[String],
    known: [&str; N],
) -> Result<[bool; N], ApiError> {
    let mut wanted = [false; N];
    for item in values.iter().flat_map(|s| s.split(',')).map(str::trim) {
        match known.iter().position(|k| *k == item) {
            Some(i) => wanted[i] = true,
            None if item.is_empty() => {}
            None => {
                return Err(ApiError::new(
                    Kind::InvalidField,
                    format!(
                        "include: unknown value {item:?} (expected {})",
                        known.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(wanted)
}

const TEXT_FIELD_LIMIT: usize = 1024;

pub(crate) async fn read_form(mut multipart: Multipart) -> Result<RawInput, ApiError> {
    let mut raw = RawInput::default();
    while let Some(field) = multipart.next_field().await? {
        let name = field.name().unwrap_or_default().to_string();
        let duplicate = || {
            ApiError::new(
                Kind::InvalidField,
                format!("field {name:?} is given more than once"),
            )
        };
        match name.as_str() {
            "image" | "white_image" | "mask" | "normals" => {
                let bytes = field.bytes().await?;
                let slot = match name.as_str() {
                    "image" => &mut raw.image,
                    "white_image" => &mut raw.white_image,
                    "normals" => &mut raw.normals,
                    _ => &mut raw.mask,
                };
                if slot.replace(bytes).is_some() {
                    return Err(duplicate());
                }
            }
            "white" | "white_reflectance" | "white_rect" | "cx" | "cy" | "r" | "encoding"
            | "include" | "coverage" => {
                let bytes = field.bytes().await?;
                if bytes.len() > TEXT_FIELD_LIMIT {
                    return Err(ApiError::new(
                        Kind::InvalidField,
                        format!("field {name:?} is too long"),
                    ));
                }
                let text = String::from_utf8(bytes.to_vec()).map_err(|_| {
                    ApiError::new(
                        Kind::InvalidField,
                        format!("field {name:?} is not UTF-8 text"),
                    )
                })?;
                let slot = match name.as_str() {
                    "white" => &mut raw.white,
                    "white_reflectance" => &mut raw.white_reflectance,
                    "white_rect" => &mut raw.white_rect,
                    "cx" => &mut raw.cx,
                    "cy" => &mut raw.cy,
                    "r" => &mut raw.r,
                    "encoding" => &mut raw.encoding,
                    "coverage" => &mut raw.coverage,
                    _ => {
                        raw.include.push(text);
                        continue;
                    }
                };
                if slot.replace(text).is_some() {
                    return Err(duplicate());
                }
            }
            other => {
                return Err(ApiError::new(
                    Kind::UnknownField,
                    format!(
                        "unknown field {other:?} (expected image, white, white_image, \
                         white_rect, white_reflectance, cx, cy, r, mask, normals, encoding, \
                         include, coverage)"
                    ),
                ));
            }
        }
    }
    Ok(raw)
}
