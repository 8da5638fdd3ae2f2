//! The classification request's fields as they arrive, texts and files, from the multipart
//! form of `POST /v1/classify`, its JSON (files base64) or a V2 request's tensors and
//! parameters: the wire type the protocols share. [`RawInput::validate`] makes the core's `Input` of them.

use crate::server::error::{ApiError, Kind, Sent};
use axum::body::{Bytes, HttpBody};
use axum::extract::multipart::Multipart;
use axum::extract::{FromRequest, Request};
use axum::http::header;
use reflectance_core::analysis::{Placement, WhiteSpec};
use reflectance_core::decode::Encoding;
use reflectance_core::inference::{Answer, Input};
use reflectance_core::white::Rect;
use serde_json::Value;
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
    /// The photograph or rendering (PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM or OpenEXR).
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
    /// The numeric fields' wire names.
    pub const NUMBERS: [&'static str; 6] =
        ["white", "white_reflectance", "cx", "cy", "r", "coverage"];

    /// The text of the numeric field `name`, one of [`Self::NUMBERS`] (any other: `coverage`).
    pub fn number_mut(&mut self, name: &str) -> &mut Option<String> {
        match name {
            "white" => &mut self.white,
            "white_reflectance" => &mut self.white_reflectance,
            "cx" => &mut self.cx,
            "cy" => &mut self.cy,
            "r" => &mut self.r,
            _ => &mut self.coverage,
        }
    }

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

/// The fields of the classification request, in the words of its errors.
const FIELDS: &str = "image, white, white_image, white_rect, white_reflectance, cx, cy, r, \
                      mask, normals, encoding, include, coverage";

/// A classification request as JSON: the form's fields as members, the files base64 (no
/// other members are accepted; `null` is absent).
// For the OpenAPI document; [`Body::read`] reads the JSON into a `RawInput`.
#[derive(ToSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code, reason = "a type for the OpenAPI document, never built")]
#[schema(as = ClassifyJson, example = json!({"image": "iVBORw0KGgoAAAANSUhEUgAA…", "white": 0.8, "cx": 96.5, "cy": 94.25, "r": 85}))]
pub struct JsonInput {
    /// The photograph's bytes, base64 (standard or URL-safe alphabet, padding and line
    /// breaks optional; a `data:…;base64,` URL too). PNG, JPEG, WebP, TIFF, PNM, Radiance
    /// HDR, PFM or OpenEXR.
    #[schema(value_type = String, format = Byte)]
    image: String,
    /// Linear luminance of an ideal white surface at the sphere (finite, > 0).
    #[schema(value_type = f64, required = false, exclusive_minimum = 0.0)]
    white: Option<f64>,
    /// A crop of a white card, base64; not with `white`.
    #[schema(value_type = String, format = Byte, required = false)]
    white_image: Option<String>,
    /// Reflectance of the white card in (0, 1] (default 1); only with `white_image` or
    /// `white_rect`.
    #[schema(value_type = f64, required = false, exclusive_minimum = 0.0, maximum = 1.0)]
    white_reflectance: Option<f64>,
    /// A white card inside the photograph: `[x, y, w, h]` in pixels (or the form's text
    /// `"x,y,w,h"`); not with `white` or `white_image`.
    #[schema(value_type = Vec<f64>, required = false, min_items = 4, max_items = 4, example = json!([40, 300, 120, 80]))]
    white_rect: Option<Vec<f64>>,
    /// Sphere centre x (column) in pixels; give cx, cy and r together.
    #[schema(value_type = f64, required = false)]
    cx: Option<f64>,
    /// Sphere centre y (row) in pixels.
    #[schema(value_type = f64, required = false)]
    cy: Option<f64>,
    /// Sphere radius in pixels (≥ 32).
    #[schema(value_type = f64, required = false, minimum = 32.0)]
    r: Option<f64>,
    /// A mask image of the sphere, base64 (same size; alpha, or luminance ≥ 0.5); not with
    /// cx/cy/r.
    #[schema(value_type = String, format = Byte, required = false)]
    mask: Option<String>,
    /// The object's camera-space normal map, base64 (as the form's `normals`).
    #[schema(value_type = String, format = Byte, required = false)]
    normals: Option<String>,
    /// How integer samples are linearized: `srgb` (default), `linear` or `gamma:<g>`.
    #[schema(value_type = String, required = false, example = "srgb", pattern = "^(srgb|linear|gamma:[0-9]+(\\.[0-9]+)?)$")]
    encoding: Option<String>,
    /// Extra output: `features`, `explain` and/or `images` (a list, or the form's
    /// comma-separated text).
    #[schema(value_type = Vec<String>, required = false, example = json!(["features", "explain"]))]
    include: Option<Vec<String>>,
    /// The prediction set's coverage, from 0.5 to 0.999 (default 0.95).
    #[schema(value_type = f64, required = false, example = 0.9, minimum = 0.5, maximum = 0.999)]
    coverage: Option<f64>,
}

/// What a request sent: the media type of its body (lower case, without its parameters), or
/// no body at all.
fn sent(request: &Request) -> Sent {
    let media = request
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|t| t.split(';').next())
        .map(|t| t.trim().to_ascii_lowercase());
    let empty = request.body().size_hint().upper() == Some(0);
    match media {
        None if empty => Sent::Nothing,
        media => Sent::Body(media),
    }
}

/// What a route that reads a form takes, in words, by its path: the form, and for
/// classification JSON too.
fn takes(path: &str) -> &'static str {
    if path.starts_with("/admin/") {
        "multipart/form-data: the field name and the archive in the field archive (curl -F \
         name=mine -F archive=@photos.zip …)"
    } else if path == "/v1/locate" {
        "multipart/form-data: the photograph in the field image (curl -F image=@photo.jpg …); \
         JSON with a base64 image goes to POST /v1/classify"
    } else {
        "multipart/form-data, the photograph in the field image and the other fields beside it \
         (curl -F image=@photo.jpg -F white=0.8 …), or application/json with the files \
         base64 ({\"image\": \"<base64 of the file>\", \"white\": 0.8, …}); the Open \
         Inference Protocol's POST /v2/models/{name}/infer takes JSON tensors"
    }
}

fn is_json(media: &str) -> bool {
    media == "application/json" || (media.starts_with("application/") && media.ends_with("+json"))
}

/// A multipart/form-data body; anything else is refused with a 415 that says what was sent
/// and what the route takes ([`ApiError::unsupported_body`]).
pub struct Form(pub Multipart);

impl<S: Send + Sync> FromRequest<S> for Form {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &S) -> Result<Form, ApiError> {
        let sent = sent(&request);
        let path = request.uri().path().to_string();
        match Multipart::from_request(request, state).await {
            Ok(multipart) => Ok(Form(multipart)),
            Err(_) => Err(ApiError::unsupported_body(&sent, takes(&path))),
        }
    }
}

/// The body of a classification request: the multipart form, or JSON with the files base64.
/// Anything else is refused with a 415 that says what to send. Read by [`Body::read`] (after
/// the route's own checks).
pub enum Body {
    Form(Multipart),
    Json(Box<Request>),
}

impl<S: Send + Sync> FromRequest<S> for Body {
    type Rejection = ApiError;

    async fn from_request(request: Request, state: &S) -> Result<Body, ApiError> {
        if matches!(sent(&request), Sent::Body(Some(ref media)) if is_json(media)) {
            return Ok(Body::Json(Box::new(request)));
        }
        Form::from_request(request, state)
            .await
            .map(|Form(multipart)| Body::Form(multipart))
    }
}

impl Body {
    /// The fields as received.
    pub async fn read(self) -> Result<RawInput, ApiError> {
        match self {
            Body::Form(multipart) => read_form(multipart).await,
            Body::Json(request) => from_json(&Bytes::from_request(*request, &()).await?),
        }
    }
}

/// How a JSON classification request looks, for its errors.
const JSON_SHAPE: &str = "send an object with the form's fields, the files base64: \
                          {\"image\": \"<base64 of the file>\", \"white\": 0.8, …}";

fn invalid(detail: String) -> ApiError {
    ApiError::new(Kind::InvalidField, detail)
}

/// The fields of a JSON classification request: numbers as numbers or as the form's text,
/// files base64, `include` a list or the form's text; `null` is absent.
fn from_json(body: &[u8]) -> Result<RawInput, ApiError> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Err(ApiError::new(
            Kind::MalformedRequest,
            format!("the JSON body is empty: {JSON_SHAPE}"),
        ));
    }
    let fields = match serde_json::from_slice::<Value>(body) {
        Ok(Value::Object(fields)) => fields,
        Ok(other) => {
            return Err(invalid(format!(
                "the JSON body is {}, not an object: {JSON_SHAPE}",
                json_kind(&other)
            )));
        }
        Err(e) => {
            return Err(ApiError::new(
                Kind::MalformedRequest,
                format!("the body is not valid JSON ({e}): {JSON_SHAPE}"),
            ));
        }
    };
    let mut raw = RawInput::default();
    for (name, value) in fields {
        if value.is_null() {
            continue;
        }
        match name.as_str() {
            "image" | "white_image" | "mask" | "normals" => {
                let Value::String(text) = value else {
                    return Err(invalid(format!(
                        "{name} must be a string, the file's bytes base64, not {}",
                        json_kind(&value)
                    )));
                };
                let bytes = Some(base64_file(&name, &text)?);
                match name.as_str() {
                    "image" => raw.image = bytes,
                    "white_image" => raw.white_image = bytes,
                    "normals" => raw.normals = bytes,
                    _ => raw.mask = bytes,
                }
            }
            n if RawInput::NUMBERS.contains(&n) => {
                let text = match value {
                    Value::Number(n) => n.to_string(),
                    Value::String(text) => short_text(&name, text)?,
                    other => {
                        return Err(invalid(format!(
                            "{name} must be a number, not {}",
                            json_kind(&other)
                        )));
                    }
                };
                *raw.number_mut(&name) = Some(text);
            }
            "white_rect" => {
                let text = match value {
                    Value::String(text) => short_text(&name, text)?,
                    Value::Array(items)
                        if items.len() == 4 && items.iter().all(Value::is_number) =>
                    {
                        let items: Vec<String> = items.iter().map(Value::to_string).collect();
                        items.join(",")
                    }
                    _ => {
                        return Err(invalid(
                            "white_rect must be [x, y, w, h], four numbers (or the text \
                             \"x,y,w,h\")"
                                .to_string(),
                        ));
                    }
                };
                raw.white_rect = Some(text);
            }
            "encoding" => match value {
                Value::String(text) => raw.encoding = Some(short_text(&name, text)?),
                other => {
                    return Err(invalid(format!(
                        "encoding must be a string (srgb, linear or gamma:<g>), not {}",
                        json_kind(&other)
                    )));
                }
            },
            "include" => match value {
                Value::String(text) => raw.include.push(short_text(&name, text)?),
                Value::Array(items) => {
                    for item in items {
                        let Value::String(text) = item else {
                            return Err(invalid(
                                "include must be a list of strings (features, explain, images)"
                                    .to_string(),
                            ));
                        };
                        raw.include.push(short_text(&name, text)?);
                    }
                }
                other => {
                    return Err(invalid(format!(
                        "include must be a list of strings, not {}",
                        json_kind(&other)
                    )));
                }
            },
            other => {
                return Err(ApiError::new(
                    Kind::UnknownField,
                    format!("unknown field {other:?} (expected {FIELDS})"),
                ));
            }
        }
    }
    Ok(raw)
}

/// A text field's value, at most [`TEXT_FIELD_LIMIT`] bytes.
fn short_text(name: &str, text: String) -> Result<String, ApiError> {
    match text.len() > TEXT_FIELD_LIMIT {
        true => Err(invalid(format!("field {name:?} is too long"))),
        false => Ok(text),
    }
}

/// JSON's name for a value's type.
fn json_kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// A file sent base64: the standard or the URL-safe alphabet, padded or not, line breaks
/// ignored, or a `data:…;base64,` URL.
fn base64_file(name: &str, text: &str) -> Result<Bytes, ApiError> {
    use base64::Engine;
    use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};
    let payload = match text.trim_start().strip_prefix("data:") {
        Some(url) => match url.split_once(',') {
            Some((meta, payload)) if meta.ends_with(";base64") => payload,
            _ => {
                return Err(invalid(format!(
                    "{name}: a data: URL must hold base64 (data:image/jpeg;base64,…)"
                )));
            }
        },
        None => text,
    };
    let compact: Vec<u8> = payload
        .bytes()
        .filter(|b| !b.is_ascii_whitespace())
        .collect();
    if compact.is_empty() {
        return Err(invalid(format!(
            "{name} is empty: give the file's bytes base64"
        )));
    }
    let alphabet = match compact.iter().any(|b| matches!(b, b'-' | b'_')) {
        true => &base64::alphabet::URL_SAFE,
        false => &base64::alphabet::STANDARD,
    };
    let config =
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent);
    GeneralPurpose::new(alphabet, config)
        .decode(&compact)
        .map(Bytes::from)
        .map_err(|e| {
            invalid(format!(
                "{name} is not base64 ({e}): give the file's bytes base64-encoded (base64 -w0 \
                 photo.jpg), not a path or a URL"
            ))
        })
}

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
                    format!("unknown field {other:?} (expected {FIELDS})"),
                ));
            }
        }
    }
    Ok(raw)
}
