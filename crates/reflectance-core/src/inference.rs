//! One photograph through the whole pipeline: decode → locate → white → features →
//! classify, and the answer's JSON. No HTTP here: `POST /v1/classify`, the KServe endpoint
//! and `reflectance classify` all call [`classify`] and give the same [`ClassifyResponse`].

use crate::features::Extractor;
use crate::features::analysis::{self, Analysis, AnalysisError, Locate, WhiteInput};
use crate::image::colour::{self, Rgb};
use crate::image::decode::{self, DecodeError, DecodeOptions, Encoding};
use crate::image::display;
use crate::image::geometry::{self, GeometryError, Method as GeometryMethod};
use crate::image::white::{Method as WhiteMethod, Rect, WhiteError};
use crate::learn::LearnError;
use crate::learn::conformal;
use crate::learn::domain::Verdict;
use crate::learn::estimate::{StatedEstimate, WardEstimate};
use crate::material::gltf::METAL_RATIO;
use crate::model::{ClassInfo, Head, ModelError, ModelFile, Ward};
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Instant;

/// A verified model version, ready to classify: the file and its feature extractor.
#[derive(Debug)]
pub struct LoadedModel {
    /// The model file, its checksum and self-test passed.
    pub file: ModelFile,
    /// The feature extractor of the file's extraction configuration.
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
        if let Some(no_white) = &file.no_white {
            read.extend(&no_white.classifier.selected_indices);
        }
        let domains = [file.domain.as_ref()]
            .into_iter()
            .chain([file.no_white.as_ref().and_then(|n| n.domain.as_ref())]);
        read.extend(
            domains
                .flatten()
                .flat_map(|d| d.checks.iter().filter_map(|c| c.index)),
        );
        read.sort_unstable();
        read.dedup();
        let pca = classifier.pca.is_some()
            || file
                .no_white
                .as_ref()
                .is_some_and(|n| n.classifier.pca.is_some());
        let needed = (!pca && read.len() < feature_names.len()).then_some(read);
        Ok(LoadedModel {
            file,
            extractor,
            feature_names,
            needed,
        })
    }

    /// The model's name, e.g. `ward11`.
    pub fn name(&self) -> &str {
        &self.file.name
    }

    /// The model's version in its registry (1, 2, …).
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
#[derive(Debug)]
pub enum WhiteSpec {
    /// A number: the linear luminance of white at the sphere (finite, > 0).
    Value(f64),
    /// A separate photograph of a white card (its encoded bytes).
    Card {
        /// The card's encoded photograph, decoded like the image.
        bytes: Bytes,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// A white card inside the photograph.
    Rect {
        /// The card's rectangle, in the photograph's pixels.
        rect: Rect,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// No white reference: the image is taken as normalized (white = 1).
    Missing,
}

impl WhiteSpec {
    /// A white reference given as a number: finite and positive.
    pub fn value(value: f64) -> Result<WhiteSpec, WhiteError> {
        crate::image::white::given(value).map(|_| WhiteSpec::Value(value))
    }

    /// The white reference of a request: at most one of a value, a card's crop and a card
    /// inside the photograph; the card's reflectance (in (0, 1], default 1) only with a card.
    pub fn new(
        value: Option<f64>,
        card: Option<Bytes>,
        rect: Option<Rect>,
        reflectance: Option<f64>,
    ) -> Result<WhiteSpec, InputError> {
        let given = [value.is_some(), card.is_some(), rect.is_some()];
        if given.iter().filter(|&&g| g).count() > 1 {
            return Err(InputError::SeveralWhites);
        }
        if reflectance.is_some() && !(given[1] || given[2]) {
            return Err(InputError::ReflectanceWithoutCard);
        }
        let reflectance = reflectance.unwrap_or(1.0);
        if !(reflectance > 0.0 && reflectance <= 1.0) {
            return Err(WhiteError::BadReflectance(reflectance).into());
        }
        Ok(match (value, card, rect) {
            (Some(value), _, _) => WhiteSpec::value(value)?,
            (_, Some(bytes), _) => WhiteSpec::Card { bytes, reflectance },
            (_, _, Some(rect)) => WhiteSpec::Rect { rect, reflectance },
            (None, None, None) => WhiteSpec::Missing,
        })
    }
}

/// Where the sphere is, before decoding: a circle, a mask (`M`: the mask as the caller
/// holds it, bytes of a file or an array), or found in the image.
#[derive(Debug)]
pub enum Placement<M> {
    /// A circle given in the image's pixels.
    Circle(geometry::Circle),
    /// A mask image of the sphere (its alpha, else luminance ≥ 0.5); the circle is fitted to
    /// its edge.
    Mask(M),
    /// Found by detection (or the image's alpha channel).
    Auto,
}

impl<M> Placement<M> {
    /// The placement of a request: `cx`, `cy` and `r` all or none (checked as far as they can
    /// be without the image), or a mask, not both.
    pub fn new(
        cx: Option<f64>,
        cy: Option<f64>,
        r: Option<f64>,
        mask: Option<M>,
    ) -> Result<Placement<M>, InputError> {
        Ok(match (geometry::given(cx, cy, r)?, mask) {
            (Some(_), Some(_)) => return Err(InputError::CircleAndMask),
            (Some(given), None) => Placement::Circle(given.circle()),
            (None, Some(mask)) => Placement::Mask(mask),
            (None, None) => Placement::Auto,
        })
    }
}

/// Where the sphere is in an encoded photograph.
pub type LocateSpec = Placement<Bytes>;

/// A request's input that breaks a rule of the request itself (before any decoding).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InputError {
    /// The image has no bytes.
    #[error("the image is empty")]
    EmptyImage,
    /// More than one white reference was given.
    #[error("give one of white, white_image and white_rect")]
    SeveralWhites,
    /// A card's reflectance without a card.
    #[error("white_reflectance applies to white_image or white_rect only")]
    ReflectanceWithoutCard,
    /// The white reference breaks its own rule (not positive, reflectance outside (0, 1]).
    #[error(transparent)]
    White(#[from] WhiteError),
    /// The circle is incomplete or not a circle (non-finite, r ≤ 0).
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// Both a circle and a mask were given.
    #[error("give cx, cy and r, or a mask, not both")]
    CircleAndMask,
    /// A prediction-set coverage outside [0.5, 0.999].
    #[error("coverage must be a number from 0.5 to 0.999, not {0}")]
    Coverage(f64),
}

/// A validated classification request: [`Input::new`] is the only way to make one.
#[derive(Debug)]
pub struct Input {
    image: Bytes,
    white: WhiteSpec,
    locate: LocateSpec,
    encoding: Option<Encoding>,
    answer: Answer,
}

impl Input {
    /// A request of an encoded photograph: not empty, with a prediction-set coverage (when
    /// given) in [0.5, 0.999].
    ///
    /// The request's rules are checked here, before any decoding: its parts are built by
    /// [`WhiteSpec::new`] and [`Placement::new`], which hold their own rules.
    ///
    /// ```
    /// use bytes::Bytes;
    /// use reflectance_core::inference::{Answer, Input, InputError, LocateSpec, WhiteSpec};
    ///
    /// let photo = Bytes::from_static(b"the bytes of a PNG, JPEG, HDR, PFM, EXR or TIFF");
    /// // White measured beside the sphere: a number, and the circle given.
    /// let white = WhiteSpec::new(Some(0.8), None, None, None)?;
    /// let locate = LocateSpec::new(Some(120.0), Some(110.0), Some(90.0), None)?;
    /// let answer = Answer { coverage: Some(0.9), ..Answer::default() };
    /// let input = Input::new(photo, white, locate, None, answer)?;
    /// # drop(input);
    ///
    /// // The rules: an image, a coverage the prediction sets offer, one white, …
    /// let empty = Input::new(Bytes::new(), WhiteSpec::Missing, LocateSpec::Auto, None, answer);
    /// assert_eq!(empty.unwrap_err(), InputError::EmptyImage);
    /// let loose = Answer { coverage: Some(0.3), ..Answer::default() };
    /// let photo = Bytes::from_static(b"...");
    /// let refused = Input::new(photo, WhiteSpec::Missing, LocateSpec::Auto, None, loose);
    /// assert_eq!(refused.unwrap_err(), InputError::Coverage(0.3));
    /// let two = WhiteSpec::new(Some(0.8), None, Some("10,10,20,20".parse()?), None);
    /// assert_eq!(two.unwrap_err(), InputError::SeveralWhites);
    /// let partial = LocateSpec::new(Some(120.0), None, Some(90.0), None);
    /// assert!(matches!(partial, Err(InputError::Geometry(_))));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        image: Bytes,
        white: WhiteSpec,
        locate: LocateSpec,
        encoding: Option<Encoding>,
        answer: Answer,
    ) -> Result<Input, InputError> {
        if image.is_empty() {
            return Err(InputError::EmptyImage);
        }
        answer.checked()?;
        Ok(Input {
            image,
            white,
            locate,
            encoding,
            answer,
        })
    }
}

/// Why a validated request gives no answer: a part that does not decode, no usable sphere
/// or white in the image, a model that cannot be read or a classifier that refuses the row.
#[derive(Debug, thiserror::Error)]
pub enum InferenceError {
    /// A file of the request does not decode; `part` is empty for the image, else
    /// `"white_image: "` or `"mask: "`.
    #[error("{part}{source}")]
    Decode {
        /// Which part: `""` (the image), `"white_image: "` or `"mask: "`, prefixed to the message.
        part: &'static str,
        /// Why it does not decode.
        source: DecodeError,
    },
    /// The image decoded but gave no features: no sphere found, a bad white or circle.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    /// The model file's configuration or consistency.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The classifier or estimator refused the feature row.
    #[error(transparent)]
    Learn(#[from] LearnError),
}

/// What a model decides about one feature row: the class, how sure it can be, and whether
/// the input is one it knows.
#[derive(Clone, Debug)]
pub struct Decision {
    /// Classified by the classifier without white.
    pub without_white: bool,
    /// The most probable class (index in class order).
    pub class: usize,
    /// In class order.
    pub probabilities: Vec<f64>,
    /// The prediction set (class indices, most probable first) at `coverage`, when the
    /// classifier has a calibration.
    pub set: Option<Vec<usize>>,
    /// The prediction set's target coverage, in [0.5, 0.999].
    pub coverage: f64,
    /// The domain check's verdict, when calibrated.
    pub verdict: Option<Verdict>,
    /// Why the input is outside the capture envelope the model was trained for, whatever
    /// its class.
    pub envelope: Vec<String>,
    /// The classifier's standardized inputs.
    pub z: Vec<f64>,
}

impl Decision {
    /// Out of domain: a check failed, or the capture is outside the envelope. The one
    /// source of the verdict: every surface (`/v1`'s [`Decision::domain`], V2 and gRPC's
    /// `in_domain`, `reflectance predict`'s CSV, the command line and Python) reads it here.
    pub fn in_domain(&self) -> bool {
        self.verdict.as_ref().is_none_or(Verdict::in_domain) && self.envelope.is_empty()
    }
}

/// What the decision needs besides the feature row.
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    /// Whether the request gave a white reference (else the classifier without white answers,
    /// when the model has one).
    pub white_given: bool,
    /// The sphere's radius as given (px).
    pub radius: f64,
    /// The capture measurements (size, exposure), for the capture-envelope check; `None` skips it.
    pub measured: Option<&'a crate::features::CaptureMeasurements>,
    /// The prediction set's target coverage, in [0.5, 0.999].
    pub coverage: f64,
}

/// Classify a feature row (canonical order, the model's configuration) as the service
/// does: the classifier for the white given or not, the prediction set, the domain check
/// and the capture envelope.
pub fn decide(model: &ModelFile, values: &[f64], context: Context) -> Result<Decision, LearnError> {
    let head = model.head(context.white_given);
    let classifier = head.classifier;
    let z = classifier.transform(values)?;
    let output = classifier.classify_transformed(&z);
    let envelope = match (&model.capture, context.measured) {
        (Some(envelope), Some(measured)) => envelope.outside_every_class(
            context.radius,
            model.features.config.working_radius,
            measured,
        ),
        _ => Vec::new(),
    };
    let set = prediction_set(
        model,
        &head,
        &output.probabilities,
        context.coverage,
        context.white_given,
    );
    let verdict = head.domain.map(|d| d.verdict(&z, values));
    Ok(Decision {
        without_white: head.without_white,
        class: output.class,
        probabilities: output.probabilities,
        set,
        coverage: context.coverage,
        verdict,
        envelope,
        z,
    })
}

/// What the CPU work produced.
pub struct Classified {
    /// The model that classified.
    pub model: Arc<LoadedModel>,
    /// The class, probabilities, prediction set and domain verdict.
    pub decision: Decision,
    /// The features, the located circle and the white reference used.
    pub analysis: analysis::Analysis,
    /// The classifier's inputs (the selected features, or the principal components).
    pub selected: Vec<f64>,
    /// The nearest training images, with `include=explain`.
    pub explain: Option<Vec<Neighbour>>,
    /// The annulus and the pyramid's subbands, with `include=images`.
    pub images: Option<ImagesOut>,
    /// The Ward parameters estimated directly, when the model has an estimator.
    pub ward: Option<WardEstimate>,
    /// Whether the answer lists every extracted feature (`include=features`).
    pub include_features: bool,
    /// Decoding time (ms).
    pub decode_ms: f64,
    /// Locating, white, feature extraction and the `include=images` pictures (ms).
    pub features_ms: f64,
    /// Classification, estimation and explanation time (ms).
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
    // A colour is read only against a card's colour.
    let colour = matches!(input.white, WhiteSpec::Card { .. } | WhiteSpec::Rect { .. });
    let options = DecodeOptions {
        encoding: input.encoding,
        limits,
        colour,
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
                colour: false,
                ..options
            };
            let mask = decode_part("mask: ", &bytes, &as_stored)?;
            Locate::Mask(analysis::mask_from_image(&mask))
        }
        LocateSpec::Auto => Locate::Auto,
    };
    classify_decoded(model, image, &locate, &white, &input.answer, ms(t))
}

/// What an answer includes beyond the class, and the prediction set's coverage.
#[derive(Clone, Copy, Debug, Default)]
pub struct Answer {
    /// List every extracted feature, not only the classifier's inputs.
    pub include_features: bool,
    /// List the nearest training images.
    pub include_explain: bool,
    /// Include the unwrapped annulus and the subbands as PNG data URLs.
    pub include_images: bool,
    /// `None`: [`conformal::DEFAULT_COVERAGE`].
    pub coverage: Option<f64>,
}

impl Answer {
    /// The answer, if its coverage (when given) is one the prediction sets offer.
    pub fn checked(self) -> Result<Answer, InputError> {
        match self.coverage {
            Some(c) if conformal::check_coverage(c).is_err() => Err(InputError::Coverage(c)),
            _ => Ok(self),
        }
    }
}

/// Locate, extract and classify an image already decoded (or handed over as an array,
/// [`decode::from_luminance`]); `decode_ms` is what its decoding took.
pub fn classify_decoded(
    model: Arc<LoadedModel>,
    image: decode::LinearImage,
    locate: &Locate,
    white: &WhiteInput,
    answer: &Answer,
    decode_ms: f64,
) -> Result<Classified, InferenceError> {
    let t = Instant::now();
    // Unless every feature is asked for, extract only those the classifier reads.
    let wanted = match &model.needed {
        Some(needed) if !answer.include_features => Some(needed.as_slice()),
        _ => None,
    };
    let envelope = model.file.capture.as_ref();
    let mut analysis = analysis::analyze_subset(
        &model.extractor,
        &image,
        locate,
        white,
        wanted,
        envelope.is_some(),
    )?;
    let images = answer
        .include_images
        .then(|| images_of(&model.extractor, &image, &analysis));
    drop(image);
    let features_ms = ms(t);
    let t = Instant::now();
    let context = Context {
        white_given: analysis.white.method != WhiteMethod::None,
        radius: analysis.geometry.circle().r,
        measured: analysis.measured.as_ref(),
        coverage: answer.coverage.unwrap_or(conformal::DEFAULT_COVERAGE),
    };
    let decision = decide(&model.file, &analysis.values, context)?;
    // Outside the predicted class's envelope but not the model's: a warning, not a reason.
    if let (Some(envelope), Some(measured), true) =
        (envelope, &analysis.measured, decision.envelope.is_empty())
    {
        let class = &model.file.head(context.white_given).classifier.classes[decision.class];
        let working_radius = model.file.features.config.working_radius;
        let radius = context.radius;
        analysis
            .warnings
            .extend(envelope.outside(radius, working_radius, class, measured));
    }
    let classifier = model.file.head(!decision.without_white).classifier;
    let selected = if classifier.pca.is_some() {
        decision.z.clone()
    } else {
        classifier
            .selected_indices
            .iter()
            .map(|&i| analysis.values[i])
            .collect()
    };
    let explain = if answer.include_explain {
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
    let ward = estimate(&model.file, &decision, &analysis.values);
    let predict_ms = ms(t);
    Ok(Classified {
        decision,
        analysis,
        selected,
        explain,
        images,
        ward,
        include_features: answer.include_features,
        decode_ms,
        features_ms,
        predict_ms,
        model,
    })
}

/// The Ward-parameter estimate of a classification, when the model has an estimator: the
/// regression's, with its intervals widened to hold the parameters of every class of the
/// prediction set (of the predicted class without one). The set holds the true class as
/// often as its coverage says, the regression's intervals a material's parameters 90 % of the
/// time: their union holds the truth when either does, so the estimate never contradicts the
/// classes the answer names.
pub fn estimate(file: &ModelFile, decision: &Decision, values: &[f64]) -> Option<WardEstimate> {
    let estimate = file.estimator.as_ref()?.estimate(values);
    let classes = &file.head(!decision.without_white).classifier.classes;
    let named = match &decision.set {
        Some(set) => set.clone(),
        None => vec![decision.class],
    };
    let parameters = named.iter().filter_map(|&k| {
        let info = file.classes.iter().find(|c| c.name == classes[k])?;
        info.ward.as_ref().map(|w| (w.rho_d, w.rho_s, w.alpha))
    });
    Some(estimate.holding(parameters))
}

/// The prediction set of a classification: the head's calibrated set, and, when there is no
/// white reference, every class that differs from a member mainly by a brightness scale
/// ([`crate::model::Ward::same_up_to_scale`]): the exposure of a photograph without a white
/// card hides that difference, whatever the training captures' exposures taught.
fn prediction_set(
    file: &ModelFile,
    head: &Head,
    probabilities: &[f64],
    coverage: f64,
    white_given: bool,
) -> Option<Vec<usize>> {
    let mut set = head.prediction_sets?.set(probabilities, coverage);
    if !white_given {
        let classes = &head.classifier.classes;
        let ward = |k: usize| {
            let info = file.classes.iter().find(|c| c.name == classes[k])?;
            info.ward.clone()
        };
        for k in 0..classes.len() {
            let alike = set.iter().any(|&m| match (ward(m), ward(k)) {
                (Some(a), Some(b)) => a.same_up_to_scale(&b),
                _ => false,
            });
            if alike && !set.contains(&k) {
                set.push(k);
            }
        }
    }
    Some(set)
}

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

/// Candidates a locate answer offers.
pub const CANDIDATES: usize = 3;

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
    let (chosen, ranked) = analysis::locate_ranked(&image, &model.extractor);
    let (width, height) = (image.width(), image.height());
    let candidates = ranked
        .iter()
        .take(CANDIDATES)
        .map(|g| CandidateOut {
            geometry: GeometryOut::from(g),
            rim_visible: geometry::visible_rim(&g.circle(), width, height),
        })
        .collect();
    let geometry = match chosen {
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
        candidates,
        warnings,
        preview: preview.then(|| {
            display::data_url(&display::preview_png(image.luminance.view(), PREVIEW_SIDE))
        }),
    })
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
            ward: c.ward.clone(),
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
    /// `given`, `mask` (mask image), `alpha` (the image's alpha channel) or `auto`.
    #[cfg_attr(feature = "openapi", schema(value_type = String, example = "given"))]
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
    /// follows a sphere's outline) or `brightness` (log10 of the centre over white).
    #[cfg_attr(feature = "openapi", schema(example = "outline"))]
    pub check: String,
    /// The measured value (`typicality`: a distance; `outline`: a fit; `brightness`: log10).
    pub value: f64,
    /// Statistical checks: how often an image of a sphere under held-out light is at least
    /// this unusual.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p_value: Option<f64>,
    /// Bounds (`brightness`): the largest value that passes.
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
/// The warning of an answer given without a white reference by the classifier without white.
pub const WITHOUT_WHITE_WARNING: &str = "answered without a white reference: only features that \
    do not depend on the image's brightness were read, so classes that differ mainly in \
    brightness (black, grey and white) may share the prediction set; a white card would tell them \
    apart";
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
    /// The sphere's circle and how it was found.
    pub geometry: GeometryOut,
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
fn materials(
    model: &LoadedModel,
    class: &ClassOut,
    estimate: Option<&WardEstimate>,
    white_given: bool,
) -> Option<MaterialsOut> {
    let class = class.ward.clone().map(|ward| MaterialOut {
        source: "class".into(),
        name: class.name.clone(),
        ward,
        nearest_class: None,
        colour: None,
    });
    let estimate = estimate.filter(|_| white_given).map(|e| MaterialOut {
        source: "estimate".into(),
        name: "estimate".into(),
        ward: Ward {
            rho_d: e.rho_d.value,
            rho_s: e.rho_s.value,
            alpha: e.alpha.value,
        },
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
        self.model.file.head(!self.decision.without_white)
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
                .collect(),
        }
    }
}

impl Classified {
    /// The answer, as the service sends it; `total_ms` is the whole request's time.
    pub fn response(self, request_id: String, total_ms: f64) -> ClassifyResponse {
        let model = &self.model;
        let head = self.head();
        let classes = &head.classifier.classes;
        let d = &self.decision;
        let domain = d.domain();
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
        warnings.extend(
            self.analysis
                .warnings
                .iter()
                .filter(|w| !(d.without_white && *w == crate::image::white::MISSING_WARNING))
                .cloned(),
        );
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

#[cfg(test)]
mod tests {
    use super::*;

    fn rect() -> Rect {
        Rect {
            x: 0.0,
            y: 0.0,
            w: 8.0,
            h: 8.0,
        }
    }

    #[test]
    fn white_is_one_of_a_value_a_card_and_a_rectangle() {
        let card = || Some(Bytes::from_static(b"card"));
        assert!(matches!(
            WhiteSpec::new(Some(0.5), None, None, None),
            Ok(WhiteSpec::Value(v)) if v == 0.5
        ));
        assert!(matches!(
            WhiteSpec::new(None, card(), None, Some(0.9)),
            Ok(WhiteSpec::Card { reflectance, .. }) if reflectance == 0.9
        ));
        assert!(matches!(
            WhiteSpec::new(None, None, Some(rect()), None),
            Ok(WhiteSpec::Rect { reflectance, .. }) if reflectance == 1.0
        ));
        assert!(matches!(
            WhiteSpec::new(None, None, None, None),
            Ok(WhiteSpec::Missing)
        ));
        assert_eq!(
            WhiteSpec::new(Some(0.5), None, Some(rect()), None).unwrap_err(),
            InputError::SeveralWhites
        );
        assert_eq!(
            WhiteSpec::new(Some(0.5), None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::new(None, None, None, Some(0.9)).unwrap_err(),
            InputError::ReflectanceWithoutCard
        );
        assert_eq!(
            WhiteSpec::new(None, card(), None, Some(1.5)).unwrap_err(),
            InputError::White(WhiteError::BadReflectance(1.5))
        );
        assert!(matches!(
            WhiteSpec::new(Some(-1.0), None, None, None),
            Err(InputError::White(_))
        ));
    }

    #[test]
    fn the_sphere_is_a_circle_or_a_mask_not_both() {
        let circle = Placement::<()>::new(Some(50.0), Some(50.0), Some(40.0), None);
        assert!(matches!(circle, Ok(Placement::Circle(c)) if c.r == 40.0));
        assert!(matches!(
            Placement::new(None, None, None, Some(())),
            Ok(Placement::Mask(()))
        ));
        assert!(matches!(
            Placement::<()>::new(None, None, None, None),
            Ok(Placement::Auto)
        ));
        assert_eq!(
            Placement::new(Some(50.0), Some(50.0), Some(40.0), Some(())).unwrap_err(),
            InputError::CircleAndMask
        );
        assert_eq!(
            Placement::<()>::new(Some(50.0), None, Some(40.0), None).unwrap_err(),
            InputError::Geometry(GeometryError::Incomplete)
        );
    }

    #[test]
    fn an_input_has_an_image_and_a_coverage_the_sets_offer() {
        let input = |image: &'static [u8], coverage| {
            let answer = Answer {
                coverage,
                ..Answer::default()
            };
            let image = Bytes::from_static(image);
            Input::new(image, WhiteSpec::Missing, Placement::Auto, None, answer)
        };
        assert!(input(b"png", Some(0.9)).is_ok());
        assert!(input(b"png", None).is_ok());
        assert_eq!(input(b"", None).unwrap_err(), InputError::EmptyImage);
        for bad in [0.4, 1.0, f64::NAN] {
            assert!(matches!(
                input(b"png", Some(bad)),
                Err(InputError::Coverage(_))
            ));
        }
    }
}
