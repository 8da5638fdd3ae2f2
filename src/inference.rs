//! One photograph through the whole pipeline: decode → locate → white → features →
//! classify, and the answer's JSON. No HTTP here: `POST /v1/classify`, the KServe endpoint
//! and `reflectance classify` all call [`classify`] and give the same [`ClassifyResponse`].

use crate::features::Extractor;
use crate::features::analysis::{self, Analysis, AnalysisError, Locate, WhiteInput};
use crate::image::decode::{self, DecodeError, DecodeOptions, Encoding};
use crate::image::display;
use crate::image::geometry::{self, Method as GeometryMethod};
use crate::image::white::{Method as WhiteMethod, Rect};
use crate::learn::LearnError;
use crate::learn::estimate::WardEstimate;
use crate::model::{ClassInfo, ModelError, ModelFile};
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Instant;
use utoipa::ToSchema;

/// A verified model version, ready to classify: the file and its feature extractor.
#[derive(Debug)]
pub struct LoadedModel {
    pub file: ModelFile,
    pub extractor: Extractor,
    /// The canonical feature names of the model's extraction configuration.
    pub feature_names: Vec<String>,
    /// The features the classifier and the estimator read (`None`: all of them, e.g. for
    /// PCA): a request that does not ask for every feature extracts only these.
    pub needed: Option<Vec<usize>>,
}

impl LoadedModel {
    /// Build the extractor for a verified model file.
    pub fn new(file: ModelFile) -> Result<LoadedModel, ModelError> {
        let extractor = Extractor::new(file.features.config)?;
        let feature_names = file.features.config.names();
        let classifier = &file.classifier;
        let mut read = classifier.selected_indices.clone();
        if let Some(estimator) = &file.estimator {
            read.extend(&estimator.input_indices);
        }
        read.sort_unstable();
        read.dedup();
        let needed = (classifier.pca.is_none() && read.len() < feature_names.len()).then_some(read);
        Ok(LoadedModel {
            file,
            extractor,
            feature_names,
            needed,
        })
    }

    pub fn name(&self) -> &str {
        &self.file.name
    }

    pub fn version(&self) -> u32 {
        self.file.version
    }

    /// The class (index in the classifier's order) nearest to an estimate, when the model
    /// has an estimator and knows every class's Ward parameters.
    pub fn nearest_class(&self, estimate: &WardEstimate) -> Option<usize> {
        let estimator = self.file.estimator.as_ref()?;
        let wards: Option<Vec<(f64, f64, f64)>> = self
            .file
            .classifier
            .classes
            .iter()
            .map(|name| {
                let info = self.file.classes.iter().find(|c| &c.name == name)?;
                info.ward.as_ref().map(|w| (w.rho_d, w.rho_s, w.alpha))
            })
            .collect();
        crate::learn::estimate::nearest_class(estimate, &estimator.half_widths, &wards?)
    }
}

/// How white is given, before decoding.
pub enum WhiteSpec {
    Value(f64),
    Card {
        bytes: Bytes,
        reflectance: f64,
    },
    /// A white card inside the photograph.
    Rect {
        rect: Rect,
        reflectance: f64,
    },
    Missing,
}

/// Where the sphere is, before decoding.
pub enum LocateSpec {
    Circle(geometry::Circle),
    Mask(Bytes),
    Auto,
}

/// A validated classification request.
pub struct Input {
    pub image: Bytes,
    pub white: WhiteSpec,
    pub locate: LocateSpec,
    pub encoding: Option<Encoding>,
    pub include_features: bool,
    pub include_explain: bool,
    pub include_images: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum InferenceError {
    /// A file of the request does not decode; `part` is empty for the image, else
    /// `"white_image: "` or `"mask: "`.
    #[error("{part}{source}")]
    Decode {
        part: &'static str,
        source: DecodeError,
    },
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Learn(#[from] LearnError),
}

/// What the CPU work produced.
pub struct Classified {
    pub model: Arc<LoadedModel>,
    pub class: usize,
    pub probabilities: Vec<f64>,
    pub analysis: analysis::Analysis,
    /// The classifier's inputs (the selected features, or the principal components).
    pub selected: Vec<f64>,
    pub explain: Option<Vec<Neighbour>>,
    pub images: Option<ImagesOut>,
    pub ward: Option<WardEstimate>,
    pub include_features: bool,
    pub decode_ms: f64,
    pub features_ms: f64,
    pub predict_ms: f64,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

fn decode_part(
    part: &'static str,
    bytes: &[u8],
    options: &DecodeOptions,
) -> Result<decode::LinearImage, InferenceError> {
    decode::decode(bytes, options).map_err(|source| InferenceError::Decode { part, source })
}

/// Decode, locate, extract and classify (blocking).
pub fn classify(
    model: Arc<LoadedModel>,
    input: Input,
    limits: decode::Limits,
) -> Result<Classified, InferenceError> {
    let t = Instant::now();
    let options = DecodeOptions {
        encoding: input.encoding,
        limits,
    };
    let image = decode_part("", &input.image, &options)?;
    drop(input.image);
    let white = match input.white {
        WhiteSpec::Value(v) => WhiteInput::Value(v),
        WhiteSpec::Card { bytes, reflectance } => WhiteInput::Card {
            image: decode_part("white_image: ", &bytes, &options)?,
            reflectance,
        },
        WhiteSpec::Rect { rect, reflectance } => WhiteInput::Rect { rect, reflectance },
        WhiteSpec::Missing => WhiteInput::Missing,
    };
    let locate = match input.locate {
        LocateSpec::Circle(c) => Locate::Circle(c),
        LocateSpec::Mask(bytes) => {
            // A mask holds coverage, not light: its samples are read as stored.
            let as_stored = DecodeOptions {
                encoding: Some(Encoding::Linear),
                ..options
            };
            let mask = decode_part("mask: ", &bytes, &as_stored)?;
            Locate::Mask(analysis::mask_from_image(&mask))
        }
        LocateSpec::Auto => Locate::Auto,
    };
    let decode_ms = ms(t);
    let t = Instant::now();
    // Unless every feature is asked for, extract only those the classifier reads.
    let wanted = match &model.needed {
        Some(needed) if !input.include_features => Some(needed.as_slice()),
        _ => None,
    };
    let envelope = model.file.capture.as_ref();
    let mut analysis = analysis::analyze_subset(
        &model.extractor,
        &image,
        &locate,
        &white,
        wanted,
        envelope.is_some(),
    )?;
    let images = input
        .include_images
        .then(|| images_of(&model.extractor, &image, &analysis));
    drop(image);
    let features_ms = ms(t);
    let t = Instant::now();
    let classifier = &model.file.classifier;
    let z = classifier.transform(&analysis.values)?;
    let output = classifier.classify_transformed(&z);
    if let (Some(envelope), Some(measured)) = (envelope, &analysis.measured) {
        let radius = analysis.geometry.circle().r;
        let working_radius = model.file.features.config.working_radius;
        let class = &classifier.classes[output.class];
        let outside = envelope.outside(radius, working_radius, class, measured);
        analysis.warnings.extend(outside);
    }
    let selected = if classifier.pca.is_some() {
        z
    } else {
        classifier
            .selected_indices
            .iter()
            .map(|&i| analysis.values[i])
            .collect()
    };
    let explain = if input.include_explain {
        let nearest = model.file.nearest(&analysis.values, 3)?;
        Some(
            nearest
                .into_iter()
                .map(|(e, distance)| Neighbour {
                    path: e.path.clone(),
                    class: e.class.clone(),
                    illumination: e.illumination.clone(),
                    distance,
                    thumbnail: e.thumbnail.clone(),
                })
                .collect(),
        )
    } else {
        None
    };
    let ward = model
        .file
        .estimator
        .as_ref()
        .map(|e| e.estimate(&analysis.values));
    let predict_ms = ms(t);
    Ok(Classified {
        class: output.class,
        probabilities: output.probabilities,
        analysis,
        selected,
        explain,
        images,
        ward,
        include_features: input.include_features,
        decode_ms,
        features_ms,
        predict_ms,
        model,
    })
}

/// Where the sphere is in a photograph, before classifying it.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct LocateResponse {
    pub request_id: String,
    /// The image's size in pixels (after its EXIF orientation), the circle's coordinate frame.
    pub width: usize,
    pub height: usize,
    /// The detected sphere (or the image's alpha channel's); absent when none was found or
    /// its annulus would not fit the image (a warning says why).
    pub geometry: Option<GeometryOut>,
    pub warnings: Vec<String>,
    /// With `include=preview`: the image as a grey PNG data URL (longest side at most
    /// 1024 px, brightest 1 % clipped), for formats a browser cannot show (HDR, PFM, EXR,
    /// TIFF).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
}

/// Longest side of a located image's preview, in pixels.
pub const PREVIEW_SIDE: usize = 1024;

/// Decode and find the sphere as classification would without a circle (blocking).
pub fn locate(
    model: &LoadedModel,
    bytes: &[u8],
    options: &DecodeOptions,
    preview: bool,
) -> Result<LocateResponse, InferenceError> {
    let image = decode_part("", bytes, options)?;
    let mut warnings = image.warnings.clone();
    let geometry = match analysis::locate(&image, &Locate::Auto, &model.extractor) {
        Ok((g, more)) => {
            warnings.extend(more);
            Some(GeometryOut::from(&g))
        }
        Err(e) => {
            warnings.push(format!("no usable sphere found: {e}"));
            None
        }
    };
    Ok(LocateResponse {
        request_id: String::new(),
        width: image.width(),
        height: image.height(),
        geometry,
        warnings,
        preview: preview.then(|| {
            display::data_url(&display::preview_png(image.luminance.view(), PREVIEW_SIDE))
        }),
    })
}

/// The served model version.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ModelId {
    pub name: String,
    pub version: u32,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct LabelProbability {
    pub label: String,
    pub p: f64,
}

/// Ward reflectance parameters of a rendered class.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct WardParams {
    pub rho_d: f64,
    pub rho_s: f64,
    pub alpha: f64,
}

/// A class of the model, for people.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct ClassOut {
    pub name: String,
    /// In words (from the Ward parameters when known), e.g. "white, glossy: sharp
    /// reflections".
    pub description: String,
    /// Known when the class was rendered from Ward parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ward: Option<WardParams>,
}

impl From<&ClassInfo> for ClassOut {
    fn from(c: &ClassInfo) -> ClassOut {
        ClassOut {
            name: c.name.clone(),
            description: c.description(),
            ward: c.ward.as_ref().map(|w| WardParams {
                rho_d: w.rho_d,
                rho_s: w.rho_s,
                alpha: w.alpha,
            }),
        }
    }
}

/// Names and values, index by index.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct NamedValues {
    pub names: Vec<String>,
    pub values: Vec<f64>,
}

/// The classifier's inputs (the model's selected features, raw; for `pca<N>` models the
/// standardized principal components `pc1…`), and with `include=features` every extracted
/// feature in canonical order (117 with the default configuration).
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct FeaturesOut {
    pub names: Vec<String>,
    pub values: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub all: Option<NamedValues>,
}

#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct GeometryOut {
    pub cx: f64,
    pub cy: f64,
    pub r: f64,
    /// `given`, `mask` (mask image), `alpha` (the image's alpha channel) or `auto`.
    #[schema(value_type = String, example = "given")]
    pub method: GeometryMethod,
    /// Automatic detection only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confidence: Option<f64>,
}

impl From<&geometry::Geometry> for GeometryOut {
    fn from(g: &geometry::Geometry) -> GeometryOut {
        GeometryOut {
            cx: g.cx,
            cy: g.cy,
            r: g.r,
            method: g.method,
            confidence: g.confidence,
        }
    }
}

#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct WhiteOut {
    pub value: f64,
    /// `given`, `white_image` or `none` (no reference: the image is taken as normalized).
    #[schema(value_type = String, example = "given")]
    pub method: WhiteMethod,
}

/// Milliseconds per stage.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct TimingMs {
    pub decode: f64,
    pub features: f64,
    pub predict: f64,
    pub total: f64,
}

/// A training image near the classified one, in the classifier's standardized input space.
#[derive(Clone, Debug, Serialize, Deserialize, ToSchema)]
pub struct Neighbour {
    pub path: String,
    pub class: String,
    pub illumination: String,
    pub distance: f64,
    /// A small picture of the training image (PNG data URL), when the model has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thumbnail: Option<String>,
}

/// With `include=images`: what the features see, as 8-bit grey PNG data URLs.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct ImagesOut {
    /// The unwrapped annulus divided by white (angle across, radius down, at the model's
    /// working radius and saturation; white is full brightness, brighter clips).
    pub annulus: String,
    /// The wavelet pyramid's oriented subbands, finest scale first; mid-grey is 0 and each is
    /// scaled to its own 99th percentile of |value|.
    pub subbands: Vec<SubbandImage>,
}

#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct SubbandImage {
    /// 1 is the finest.
    pub scale: usize,
    /// `h` (horizontal structure), `v` (vertical: radial on the sphere) or `d` (diagonal),
    /// as in the feature names (`wav.s1.h.var`).
    #[schema(example = "h")]
    pub orientation: String,
    pub image: String,
}

/// The annulus and subbands that `analysis` came from.
fn images_of(extractor: &Extractor, image: &decode::LinearImage, analysis: &Analysis) -> ImagesOut {
    let circle = analysis.geometry.circle();
    let stages = extractor.stages(image.luminance.view(), &circle, analysis.white.value);
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
    }
}

#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct ClassifyResponse {
    pub request_id: String,
    pub model: ModelId,
    /// The predicted class.
    pub label: String,
    /// The predicted class in words, with its Ward parameters when known.
    pub class: ClassOut,
    /// Every class, most probable first.
    pub probabilities: Vec<LabelProbability>,
    pub features: FeaturesOut,
    pub geometry: GeometryOut,
    pub white: WhiteOut,
    pub warnings: Vec<String>,
    pub timing_ms: TimingMs,
    /// With `include=explain`: the 3 nearest training images, nearest first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub explain: Option<Vec<Neighbour>>,
    /// With `include=images`: the unwrapped annulus and the pyramid's subbands.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<ImagesOut>,
    /// The Ward parameters estimated directly, with 90 % intervals, when the model has an
    /// estimator.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ward: Option<WardEstimate>,
}

impl Classified {
    /// The answer, as the service sends it; `total_ms` is the whole request's time.
    pub fn response(self, request_id: String, total_ms: f64) -> ClassifyResponse {
        let model = &self.model;
        let classes = &model.file.classifier.classes;
        let mut probabilities: Vec<LabelProbability> = classes
            .iter()
            .zip(&self.probabilities)
            .map(|(label, &p)| LabelProbability {
                label: label.clone(),
                p,
            })
            .collect();
        probabilities.sort_by(|a, b| b.p.total_cmp(&a.p));
        let predicted = match model.file.classes.get(self.class) {
            Some(info) => ClassOut::from(info),
            None => ClassOut::from(&ClassInfo {
                name: classes[self.class].clone(),
                ward: None,
            }),
        };
        ClassifyResponse {
            request_id,
            model: ModelId {
                name: model.name().to_string(),
                version: model.version(),
            },
            label: classes[self.class].clone(),
            class: predicted,
            probabilities,
            features: FeaturesOut {
                names: model.file.classifier.selected.clone(),
                values: self.selected,
                all: self.include_features.then(|| NamedValues {
                    names: model.feature_names.clone(),
                    values: self.analysis.values.clone(),
                }),
            },
            geometry: GeometryOut::from(&self.analysis.geometry),
            white: WhiteOut {
                value: self.analysis.white.value,
                method: self.analysis.white.method,
            },
            warnings: self.analysis.warnings,
            timing_ms: TimingMs {
                decode: self.decode_ms,
                features: self.features_ms,
                predict: self.predict_ms,
                total: total_ms,
            },
            explain: self.explain,
            images: self.images,
            ward: self.ward,
        }
    }
}
