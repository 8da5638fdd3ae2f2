//! The answers' wire types (the JSON the service sends and `reflectance classify --json`
//! prints) and how a classification becomes one.

use super::{Classified, Decision, LoadedModel};
use crate::analysis::{Analysis, Read};
use crate::estimate::{StatedEstimate, WardEstimate};
use crate::features::Extractor;
use crate::features::lighting::{AMBIENT_LIMIT, MIN_FIT, Shading};
use crate::image::colour::{self, Rgb};
use crate::image::display;
use crate::locate::{self, Method as GeometryMethod};
use crate::material::Ward;
use crate::material::gltf::METAL_RATIO;
use crate::model::{ClassInfo, Head};
use crate::white::Method as WhiteMethod;
use serde::{Deserialize, Serialize};

/// Where the sphere is in a photograph, before classifying it.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct LocateResponse {
    /// The request's id (empty here: the service fills it in).
    pub request_id: String,
    /// The image's size in pixels (after its EXIF orientation), the circle's coordinate frame.
    pub width: usize,
    /// The image's height in pixels (after its EXIF orientation).
    pub height: usize,
    /// The detected sphere (or the image's alpha channel's); absent when none was found or
    /// its annulus would not fit the image (a warning says why).
    pub geometry: Option<GeometryOut>,
    /// Up to 3 circles detection found that fit the image, most confident first (the chosen
    /// `geometry` among them when there is one): what to offer when the first is not the
    /// sphere. Empty for an image with an alpha channel.
    pub candidates: Vec<CandidateOut>,
    /// Why the sphere may be missing or unusable, and what decoding noticed.
    pub warnings: Vec<String>,
    /// With `include=preview`: the image as a grey PNG data URL (longest side at most
    /// 1024 px, brightest 1 % clipped), for formats a browser cannot show (HDR, PFM, EXR,
    /// TIFF).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
}

/// A circle detection found, and how much of it the image shows.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CandidateOut {
    /// The circle.
    #[serde(flatten)]
    pub geometry: GeometryOut,
    /// The fraction of the circle's circumference inside the image (1: the whole rim).
    pub rim_visible: f64,
}

/// The served model version.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ModelId {
    /// The model's name, e.g. `ward11`.
    pub name: String,
    /// Its version in the registry (1, 2, …).
    pub version: u32,
}

/// A class and its probability.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct LabelProbability {
    /// The class's name.
    pub label: String,
    /// Its probability, in [0, 1]; an answer's sum to 1.
    pub p: f64,
}

/// A material a renderer can be given: the class's or the estimate's Ward parameters.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct MaterialOut {
    /// `class` (the predicted class's parameters) or `estimate` (the estimated ones).
    pub source: String,
    /// Its name in an exported file: the class's name, or `estimate`.
    pub name: String,
    /// ρd, ρs and α.
    pub ward: Ward,
    /// For the estimate: the class its parameters are nearest to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nearest_class: Option<String>,
    /// Its colour (the answer's `colour.rgb`), when known: an export is tinted by it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<[f64; 3]>,
}

/// The surface's colour, measured against a white card's colour.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ColourOut {
    /// Linear RGB relative to white, scaled to a Rec. 709 luminance of 1: the diffuse
    /// albedo (a metal's F0) is its grey value times this. Absent when unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rgb: Option<[f64; 3]>,
    /// rg chromaticity, r / (r + g + b) and g / (r + g + b).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chromaticity: Option<[f64; 2]>,
    /// The albedo of the material a download holds (its grey value times `rgb`) as 8-bit
    /// sRGB, `#rrggbb`: a swatch.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub srgb: Option<String>,
    /// What the colour is of (`diffuse`, or `specular` for a metal), or why it is unknown.
    pub note: String,
}

/// Why a colour is unknown without a white card's colour.
pub const COLOUR_UNKNOWN: &str = "unknown: the colour needs a white card in colour \
    (white_rect in an RGB photograph, or an RGB white_image); exports are grey";

/// `#rrggbb` of linear RGB in [0, 1].
fn srgb_hex(rgb: [f64; 3]) -> String {
    let encode = |v: f64| {
        let v = v.clamp(0.0, 1.0);
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    let [r, g, b] = rgb.map(encode);
    format!("#{r:02x}{g:02x}{b:02x}")
}

impl ColourOut {
    /// The colour of `material` (its diffuse, or its specular for a metal) from an
    /// appearance relative to white; unknown without one.
    fn of(appearance: Option<Rgb>, material: Option<&MaterialOut>) -> ColourOut {
        let unknown = || ColourOut {
            rgb: None,
            chromaticity: None,
            srgb: None,
            note: COLOUR_UNKNOWN.into(),
        };
        let Some(appearance) = appearance else {
            return unknown();
        };
        let ward = material.map(|m| &m.ward);
        let metal = ward.is_some_and(|w| w.rho_s > 0.0 && w.rho_d < METAL_RATIO * w.rho_s);
        let Some(rgb) = colour::surface_colour(appearance) else {
            return unknown();
        };
        let sum: f64 = rgb.iter().sum();
        let grey = ward.map_or(1.0, |w| if metal { w.rho_s } else { w.rho_d });
        ColourOut {
            chromaticity: Some([rgb[0] / sum, rgb[1] / sum]),
            srgb: Some(srgb_hex(rgb.map(|c| grey * c))),
            rgb: Some(rgb),
            note: if metal { "specular" } else { "diffuse" }.into(),
        }
    }
}

/// What an exported material holds (`GET /v1/material.gltf`, `classify --gltf`, the page's
/// download): the estimate when it agrees with the class named (it is the finer), else the
/// class's material, with the estimate offered beside it and a note saying why.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct MaterialsOut {
    /// The material a download holds.
    pub download: MaterialOut,
    /// The other one, when the estimate is nearest another class than the one named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alternative: Option<MaterialOut>,
    /// Which material the download holds, and why, for people.
    pub note: String,
}

fn name_the(w: &Ward) -> String {
    format!("ρd {:.2}, ρs {:.2}, α {:.3}", w.rho_d, w.rho_s, w.alpha)
}

impl MaterialsOut {
    /// The choice between `class` (the predicted class's material, when known) and
    /// `estimate` (a whole estimate, with the class it is nearest).
    pub fn choose(
        class: Option<MaterialOut>,
        estimate: Option<MaterialOut>,
    ) -> Option<MaterialsOut> {
        match (class, estimate) {
            (None, None) => None,
            (Some(class), None) => Some(MaterialsOut {
                note: format!("the download holds class {}'s material", class.name),
                download: class,
                alternative: None,
            }),
            (None, Some(estimate)) => Some(MaterialsOut {
                note: format!(
                    "the download holds the estimate ({})",
                    name_the(&estimate.ward)
                ),
                download: estimate,
                alternative: None,
            }),
            (Some(class), Some(estimate)) => {
                let nearest = estimate.nearest_class.clone().unwrap_or_default();
                if nearest == class.name {
                    return Some(MaterialsOut {
                        note: format!(
                            "the download holds the estimate ({}), which is nearest {}, the class named",
                            name_the(&estimate.ward),
                            class.name
                        ),
                        download: estimate,
                        alternative: None,
                    });
                }
                Some(MaterialsOut {
                    note: format!(
                        "the estimate ({}) is nearest {nearest}, not {}: the download holds class \
                         {}'s material; the estimate is offered beside it",
                        name_the(&estimate.ward),
                        class.name,
                        class.name
                    ),
                    download: class,
                    alternative: Some(estimate),
                })
            }
        }
    }
}

/// A class of the model, for people.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClassOut {
    /// The class's name, as the answer's `label` spells it.
    pub name: String,
    /// In words (from the Ward parameters when known), e.g. "white, glossy: sharp
    /// reflections".
    pub description: String,
    /// Known when the class was rendered from Ward parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ward: Option<Ward>,
}

impl From<&ClassInfo> for ClassOut {
    fn from(c: &ClassInfo) -> ClassOut {
        ClassOut {
            name: c.name.clone(),
            description: c.description(),
            ward: c.ward,
        }
    }
}

/// Names and values, index by index.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct NamedValues {
    /// Feature names (canonical, e.g. `wav.s1.h.var`), or `pc1…` for principal components.
    pub names: Vec<String>,
    /// Their values, index by index with `names`.
    pub values: Vec<f64>,
}

/// The classifier's inputs (the model's selected features, raw; for `pca<N>` models the
/// standardized principal components `pc1…`), and with `include=features` every extracted
/// feature in canonical order (117 with the default configuration).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FeaturesOut {
    /// The classifier's inputs' names.
    pub names: Vec<String>,
    /// Their values, raw (standardized for principal components).
    pub values: Vec<f64>,
    /// Every extracted feature in canonical order, with `include=features`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub all: Option<NamedValues>,
}

/// The sphere's circle in the image's pixels (x across, y down), and how it was found.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GeometryOut {
    /// Centre's x (px, from the left edge).
    pub cx: f64,
    /// Centre's y (px, from the top edge).
    pub cy: f64,
    /// Radius (px, > 0).
    pub r: f64,
    /// `given`, `mask` (mask image), `alpha` (the image's alpha channel), `auto` or
    /// `normals` (an object's equivalent sphere).
    #[cfg_attr(feature = "openapi", schema(value_type = String, example = "given"))]
    pub method: GeometryMethod,
    /// Automatic detection only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confidence: Option<f64>,
}

impl From<&locate::Geometry> for GeometryOut {
    fn from(g: &locate::Geometry) -> GeometryOut {
        GeometryOut {
            cx: g.cx,
            cy: g.cy,
            r: g.r,
            method: g.method,
            confidence: g.confidence,
        }
    }
}

/// The white reference used: the linear luminance of a white surface at the sphere.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct WhiteOut {
    /// The white value, linear luminance (> 0; 1 without a reference).
    pub value: f64,
    /// `given`, `white_image` or `none` (no reference: the image is taken as normalized).
    #[cfg_attr(feature = "openapi", schema(value_type = String, example = "given"))]
    pub method: WhiteMethod,
}

/// Milliseconds per stage.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TimingMs {
    /// Decoding the image (and a card and a mask).
    pub decode: f64,
    /// Locating the sphere, the white reference and extracting the features.
    pub features: f64,
    /// Classifying, estimating and explaining.
    pub predict: f64,
    /// The whole request.
    pub total: f64,
}

/// A training image near the classified one, in the classifier's standardized input space.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Neighbour {
    /// The training image's path, as the training manifest gives it.
    pub path: String,
    /// Its class.
    pub class: String,
    /// Its illumination (light probe).
    pub illumination: String,
    /// Euclidean distance to the classified image in standardized input space.
    pub distance: f64,
    /// A small picture of the training image (PNG data URL), when the model has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thumbnail: Option<String>,
}

/// With `include=images`: what the features see, as 8-bit grey PNG data URLs.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ImagesOut {
    /// The unwrapped annulus divided by white (angle across, radius down, at the model's
    /// working radius and saturation; white is full brightness, brighter clips).
    pub annulus: String,
    /// The wavelet pyramid's oriented subbands, finest scale first; mid-grey is 0 and each is
    /// scaled to its own 99th percentile of |value|.
    pub subbands: Vec<SubbandImage>,
    /// An object's equivalent sphere divided by white (the photograph's pixels placed by
    /// their normals; black where the object shows no normal), for objects given with
    /// normals.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub equivalent_sphere: Option<String>,
}

/// One oriented subband of the pyramid, as a picture.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SubbandImage {
    /// 1 is the finest.
    pub scale: usize,
    /// `h` (horizontal structure), `v` (vertical: radial on the sphere) or `d` (diagonal),
    /// as in the feature names (`wav.s1.h.var`).
    #[cfg_attr(feature = "openapi", schema(example = "h"))]
    pub orientation: String,
    /// A signed grey PNG data URL (mid-grey 0).
    pub image: String,
}

/// A unit variant's name as the JSON answer spells it (`given`, `typicality`).
pub fn wire_name(value: &impl Serialize) -> String {
    match serde_json::to_value(value) {
        Ok(serde_json::Value::String(name)) => name,
        _ => String::new(),
    }
}

/// The annulus and subbands that `analysis` came from.
pub(super) fn images_of(extractor: &Extractor, read: &Read, analysis: &Analysis) -> ImagesOut {
    let white = analysis.white.value;
    let stages = match &analysis.equivalent {
        Some(sphere) => extractor.stages_of_equivalent(sphere, white),
        None => extractor.stages(read.copy.image.luminance.view(), &read.circle, white),
    };
    let equivalent_sphere = analysis.equivalent.as_ref().map(|sphere| {
        let seen = sphere.luminance.mapv(|v| v / white);
        display::data_url(&display::luminance_png(seen.view()))
    });
    let picture =
        |values: &ndarray::Array2<f64>| display::data_url(&display::signed_png(values.view()));
    let subbands = stages
        .pyramid
        .levels
        .iter()
        .enumerate()
        .flat_map(|(level, bands)| {
            [("h", &bands.h), ("v", &bands.v), ("d", &bands.d)].map(|(orientation, values)| {
                SubbandImage {
                    scale: level + 1,
                    orientation: orientation.to_string(),
                    image: picture(values),
                }
            })
        })
        .collect();
    ImagesOut {
        annulus: display::data_url(&display::luminance_png(stages.unwrapped.view())),
        subbands,
        equivalent_sphere,
    }
}

/// The smallest set of classes that holds the true class with probability at least
/// `coverage`, for a photograph under light the model never saw (split conformal,
/// calibrated on held-out illuminations).
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PredictionSetOut {
    /// The target coverage, in [0.5, 0.999].
    #[cfg_attr(feature = "openapi", schema(example = 0.95))]
    pub coverage: f64,
    /// Most probable first; the label is always the first.
    pub labels: Vec<String>,
}

/// One domain check's measurement.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DomainCheckOut {
    /// `typicality` (distance to the training images), `outline` (how well the circle
    /// follows a sphere's outline), `brightness` (log10 of the centre over white) or
    /// `lighting` (the ambient share of one light's fit to the shading, listed when that
    /// fit explains at least 90 % of it).
    #[cfg_attr(feature = "openapi", schema(example = "outline"))]
    pub check: String,
    /// The measured value (`typicality`: a distance; `outline`: a fit; `brightness`: log10;
    /// `lighting`: the dimmest side's share of the brightest).
    pub value: f64,
    /// Statistical checks: how often an image of a sphere under held-out light is at least
    /// this unusual.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p_value: Option<f64>,
    /// Bounds: the largest value that passes (`brightness`), the smallest (`lighting`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit: Option<f64>,
}

/// Whether the input is like what the model was trained on: a sphere, the circle on it, a
/// plausible white, natural light, a capture within the trained envelope.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DomainOut {
    /// The input passed every check and is within the capture envelope.
    pub in_domain: bool,
    /// Fisher's −2 Σ ln p over the checks; out of domain above `threshold`. Absent for a
    /// model without a domain calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score: Option<f64>,
    /// Fisher's score above which the input is out of domain (its calibrated quantile over
    /// held-out light).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold: Option<f64>,
    /// Why the input is out of domain, in words (empty when in domain).
    pub reasons: Vec<String>,
    /// Each check's measurement.
    pub checks: Vec<DomainCheckOut>,
}

/// The model's own warning when it cannot say how sure it is.
pub const NO_SETS_WARNING: &str = "this model version has no prediction-set calibration (it was \
    trained before prediction sets existed): the answer has no prediction set; retrain it for one";
/// The set took in glossy classes because the sphere shows a highlight.
pub const HIGHLIGHT_WARNING: &str = "the sphere shows a highlight brighter than its diffuse \
    shading, which no matte surface makes: the prediction set also holds the glossy classes \
    alike to its matte ones";
/// The set took in classes that differ only in a blur the sphere is too small to show: read
/// at `read_at` px, below the `upsampled_below` px under which the unwrap upsamples.
pub fn blur_warning(read_at: f64, upsampled_below: f64) -> String {
    let alpha = crate::inference::RESOLVED_BLUR_PX / read_at;
    format!(
        "the sphere's radius ({read_at:.0} px) is below the {upsampled_below:.0} px the model \
         reads without upsampling: a blur of α up to {alpha:.3} spans under 2 px there, so the \
         prediction set also holds the classes that differ only in such a blur"
    )
}

/// The warning of an answer given without a white reference by the classifier without white.
pub const WITHOUT_WHITE_WARNING: &str = "answered without a white reference: only features that \
    do not depend on the image's brightness were read, so classes that differ mainly in \
    brightness (black, grey and white; a chrome mirror and a black glossy ball, a dim mirror) \
    may share the prediction set; a white card would tell them apart";
/// The warning heading an answer whose input is out of domain.
pub const OUT_OF_DOMAIN_WARNING: &str =
    "out of domain: the class and its probabilities are unreliable";

/// The answer of `POST /v1/classify` (and `reflectance classify --json`): the class, how
/// sure the model is, whether the input is one it knows, and what was measured.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClassifyResponse {
    /// The request's id (the service's `x-request-id`).
    pub request_id: String,
    /// The model version that answered.
    pub model: ModelId,
    /// Which of its classifiers answered: `with_white`, `without_white` (no white reference
    /// given) or `objects` (an object given with normals, when the model has a classifier
    /// for objects); the names of `GET /v1/models/{name}`'s `calibration`.
    pub classifier: &'static str,
    /// The predicted class: the most probable one (the first of `probabilities` and of the
    /// prediction set).
    pub label: String,
    /// The predicted class in words, with its Ward parameters when known.
    pub class: ClassOut,
    /// Every class, most probable first.
    pub probabilities: Vec<LabelProbability>,
    /// Absent for a model without a prediction-set calibration (a warning says so).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction_set: Option<PredictionSetOut>,
    /// Whether the input is like what the model was trained on.
    pub domain: DomainOut,
    /// The classifier's inputs, and every feature on request.
    pub features: FeaturesOut,
    /// The sphere's circle and how it was found (for an object given with normals, its
    /// equivalent sphere's, in that sphere's own pixels).
    pub geometry: GeometryOut,
    /// For an object given with normals: the fraction of the sphere's annulus its normals
    /// show, which the features read (at least 0.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observed_fraction: Option<f64>,
    /// For an object given with normals: how far they stray from their smoothed field, the
    /// RMS angle in degrees (noisy normals; above 2 the prediction set is the 99.9 % one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal_scatter_deg: Option<f64>,
    /// For an object given with normals: the share of its pixels left out of its equivalent
    /// sphere as saddles or hollows, where it shadows and lights itself (above 0.1 the
    /// prediction set is the 99.9 % one, with `shadowed_fraction` added).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_convex_fraction: Option<f64>,
    /// For an object given with normals: the share of its pixels left out of its equivalent
    /// sphere because, convex, they are in its own shadow: the surface the normals integrate
    /// to hides more than a tenth of their sky.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shadowed_fraction: Option<f64>,
    /// The white reference used.
    pub white: WhiteOut,
    /// What the caller should know: no white, out of domain, a clipped image, …
    pub warnings: Vec<String>,
    /// Milliseconds per stage.
    pub timing_ms: TimingMs,
    /// With `include=explain`: the 3 nearest training images, nearest first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub explain: Option<Vec<Neighbour>>,
    /// With `include=images`: the unwrapped annulus and the pyramid's subbands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<ImagesOut>,
    /// The Ward parameters estimated directly, with 90 % intervals, when the model has an
    /// estimator; ρd and ρs only with a white reference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ward: Option<StatedEstimate>,
    /// The material an export holds (and the other one when the estimate disagrees with
    /// the class named); absent when neither is known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialsOut>,
    /// The surface's colour, or why it is unknown.
    pub colour: ColourOut,
}

/// The materials of an answer: the class's, and the estimate's when it is whole (it needs a
/// white reference).
pub(super) fn materials(
    model: &LoadedModel,
    class: &ClassOut,
    estimate: Option<&WardEstimate>,
    white_given: bool,
) -> Option<MaterialsOut> {
    let class = class.ward.map(|ward| MaterialOut {
        source: "class".into(),
        name: class.name.clone(),
        ward,
        nearest_class: None,
        colour: None,
    });
    let estimate = estimate.filter(|_| white_given).map(|e| MaterialOut {
        source: "estimate".into(),
        name: "estimate".into(),
        ward: e.value(),
        nearest_class: model
            .nearest_class(e)
            .map(|k| model.file.classifier.classes()[k].clone()),
        colour: None,
    });
    MaterialsOut::choose(class, estimate)
}

impl Classified {
    /// The classifier that answered.
    fn head(&self) -> Head<'_> {
        self.decision.head(&self.model.file)
    }
}

impl Decision {
    /// The domain, with the envelope's warnings among the reasons; its verdict is
    /// [`Decision::in_domain`]'s.
    pub fn domain(&self) -> DomainOut {
        let mut reasons = Vec::new();
        if let Some(v) = &self.verdict {
            reasons.extend(v.failed().into_iter().map(|k| k.reason().to_string()));
        }
        reasons.extend(
            self.shading
                .filter(Shading::beyond_any_light)
                .map(|s| s.reason()),
        );
        reasons.extend(self.envelope.iter().cloned());
        DomainOut {
            in_domain: self.in_domain(),
            score: self.verdict.as_ref().map(|v| v.score),
            threshold: self.verdict.as_ref().map(|v| v.threshold),
            reasons,
            checks: self
                .verdict
                .iter()
                .flat_map(|v| &v.checks)
                .map(|c| DomainCheckOut {
                    check: wire_name(&c.kind),
                    value: c.value,
                    p_value: c.p_value,
                    limit: c.limit,
                })
                .chain(
                    self.shading
                        .filter(|s| s.fit >= MIN_FIT)
                        .map(|s| DomainCheckOut {
                            check: "lighting".into(),
                            value: s.ambient,
                            p_value: None,
                            limit: Some(AMBIENT_LIMIT),
                        }),
                )
                .collect(),
        }
    }
}

impl Classified {
    /// The answer's warnings: out of domain, without white, without sets, then the analysis's.
    fn warnings(&self, domain: &DomainOut) -> Vec<String> {
        let d = &self.decision;
        let mut warnings = Vec::new();
        if !domain.in_domain {
            warnings.push(format!(
                "{OUT_OF_DOMAIN_WARNING}: {}",
                domain.reasons.join("; ")
            ));
        }
        if d.without_white {
            warnings.push(WITHOUT_WHITE_WARNING.to_string());
        }
        if d.set.is_none() {
            warnings.push(NO_SETS_WARNING.to_string());
        }
        if d.glossy_added {
            warnings.push(HIGHLIGHT_WARNING.to_string());
        }
        if let Some((read_at, upsampled_below)) = d.blur_added {
            warnings.push(blur_warning(read_at, upsampled_below));
        }
        warnings.extend(
            self.analysis
                .warnings
                .iter()
                .filter(|w| !(d.without_white && *w == crate::white::MISSING_WARNING))
                .filter(|w| !domain.reasons.contains(w))
                .cloned(),
        );
        warnings
    }

    /// The answer, as the service sends it; `total_ms` is the whole request's time.
    pub fn response(self, request_id: String, total_ms: f64) -> ClassifyResponse {
        let model = &self.model;
        let head = self.head();
        let classifier = head.name();
        let classes = &head.classifier.classes;
        let d = &self.decision;
        let mut domain = d.domain();
        // A white far outside what the photograph can hold is the likeliest reason first.
        if !domain.in_domain {
            let white = self.analysis.warnings.iter();
            let white = white.filter(|w| w.starts_with(crate::white::IMPLAUSIBLE));
            domain.reasons.splice(0..0, white.cloned());
        }
        let equivalent = self.analysis.equivalent.as_ref();
        let warnings = self.warnings(&domain);
        let mut probabilities: Vec<LabelProbability> = classes
            .iter()
            .zip(&d.probabilities)
            .map(|(label, &p)| LabelProbability {
                label: label.clone(),
                p,
            })
            .collect();
        probabilities.sort_by(|a, b| b.p.total_cmp(&a.p));
        let white_given = self.analysis.white.method != WhiteMethod::None;
        let predicted = match model.file.classes.get(d.class) {
            Some(info) => ClassOut::from(info),
            None => ClassOut::from(&ClassInfo {
                name: classes[d.class].clone(),
                ward: None,
            }),
        };
        let mut material = materials(model, &predicted, self.ward.as_ref(), white_given);
        let colour = ColourOut::of(
            self.analysis.appearance,
            material.as_ref().map(|m| &m.download),
        );
        if let (Some(m), Some(rgb)) = (material.as_mut(), colour.rgb) {
            m.download.colour = Some(rgb);
            if let Some(other) = m.alternative.as_mut() {
                other.colour = Some(rgb);
            }
        }
        ClassifyResponse {
            request_id,
            model: ModelId {
                name: model.name().to_string(),
                version: model.version(),
            },
            label: classes[d.class].clone(),
            class: predicted,
            probabilities,
            prediction_set: d.set.as_ref().map(|set| PredictionSetOut {
                coverage: d.coverage,
                labels: set.iter().map(|&k| classes[k].clone()).collect(),
            }),
            domain,
            features: FeaturesOut {
                names: head.classifier.selected.clone(),
                values: self.selected,
                all: self.include_features.then(|| NamedValues {
                    names: model.feature_names.clone(),
                    values: self.analysis.values.clone(),
                }),
            },
            geometry: GeometryOut::from(&self.analysis.geometry),
            classifier,
            observed_fraction: self.analysis.observed,
            normal_scatter_deg: equivalent.map(|e| e.scatter_deg),
            not_convex_fraction: equivalent.map(|e| e.not_convex_fraction),
            shadowed_fraction: equivalent.map(|e| e.shadowed_fraction),
            white: WhiteOut {
                value: self.analysis.white.value,
                method: self.analysis.white.method,
            },
            warnings,
            timing_ms: TimingMs {
                decode: self.decode_ms,
                features: self.features_ms,
                predict: self.predict_ms,
                total: total_ms,
            },
            explain: self.explain,
            images: self.images,
            material,
            colour,
            ward: self.ward.map(|w| w.stated(white_given)),
        }
    }
}
