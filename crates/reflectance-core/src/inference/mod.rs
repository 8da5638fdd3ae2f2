//! One photograph through the whole pipeline: decode → locate → white → features →
//! classify, and the answer's JSON. No HTTP here: `POST /v1/classify`, the KServe endpoint
//! and `reflectance classify` all call [`classify`] and give the same [`ClassifyResponse`].

use crate::analysis::{self, AnalysisError, InputError, PartError, Placement, WhiteSpec};
use crate::classify::conformal;
use crate::classify::domain::Verdict;
use crate::decode::{self, DecodeError, DecodeOptions, Photo};
use crate::estimate::WardEstimate;
use crate::features::Extractor;
use crate::features::lighting::Shading;
use crate::image::display;
use crate::learn::LearnError;
use crate::locate;
use crate::material::Ward;
use crate::model::{Head, ModelError, ModelFile, Request};
use crate::object::normals::NormalsError;
use crate::white::Method as WhiteMethod;
use std::sync::Arc;
use std::time::Instant;

mod input;
mod response;

use response::images_of;

pub use input::Input;
pub use response::{
    COLOUR_UNKNOWN, CandidateOut, ClassOut, ClassifyResponse, ColourOut, DomainCheckOut, DomainOut,
    FeaturesOut, GeometryOut, ImagesOut, LabelProbability, LocateResponse, MaterialOut,
    MaterialsOut, ModelId, NO_SETS_WARNING, NamedValues, Neighbour, OUT_OF_DOMAIN_WARNING,
    PredictionSetOut, SubbandImage, TimingMs, WITHOUT_WHITE_WARNING, WhiteOut, wire_name,
};

/// A verified model version, ready to classify: the file and its feature extractor.
#[derive(Debug)]
pub struct LoadedModel {
    file: ModelFile,
    extractor: Extractor,
    feature_names: Vec<String>,
    needed: Option<Vec<usize>>,
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
        for head in file.stored_heads() {
            read.extend(&head.classifier.selected_indices);
        }
        let domains = [file.domain.as_ref()]
            .into_iter()
            .chain(file.stored_heads().map(|h| h.domain.as_ref()));
        read.extend(
            domains
                .flatten()
                .flat_map(|d| d.checks.iter().filter_map(|c| c.index)),
        );
        read.sort_unstable();
        read.dedup();
        let pca =
            classifier.pca.is_some() || file.stored_heads().any(|h| h.classifier.pca.is_some());
        let needed = (!pca && read.len() < feature_names.len()).then_some(read);
        Ok(LoadedModel {
            file,
            extractor,
            feature_names,
            needed,
        })
    }

    /// The model file, its checksum and self-test passed.
    pub fn file(&self) -> &ModelFile {
        &self.file
    }

    /// The feature extractor of the file's extraction configuration.
    pub fn extractor(&self) -> &Extractor {
        &self.extractor
    }

    /// The canonical feature names of the model's extraction configuration.
    pub fn feature_names(&self) -> &[String] {
        &self.feature_names
    }

    /// The features the classifier and the estimator read (`None`: all of them, e.g. for
    /// PCA): a request that does not ask for every feature extracts only these.
    pub fn needed(&self) -> Option<&[usize]> {
        self.needed.as_deref()
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
        let wards: Option<Vec<Ward>> = self
            .file
            .classifier
            .classes
            .iter()
            .map(|name| self.file.ward_of(name))
            .collect();
        crate::estimate::nearest_class(estimate, &estimator.half_widths, &wards?)
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
    /// The normal map does not decode or does not fit the photograph.
    #[error("normals: {0}")]
    Normals(#[from] NormalsError),
    /// The classifier or estimator refused the feature row.
    #[error(transparent)]
    Learn(#[from] LearnError),
}

/// What a model decides about one feature row: the class, how sure it can be, and whether
/// the input is one it knows.
#[derive(Clone, Debug)]
pub struct Decision {
    /// Which classifier answered: the request it was chosen for.
    pub request: Request,
    /// Classified by the classifier without white.
    pub without_white: bool,
    /// Classified by the classifier for objects.
    pub objects: bool,
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
    /// The sphere's shading fitted by one light, when the capture was measured (the lighting
    /// check: [`Decision::beyond_any_light`]).
    pub shading: Option<Shading>,
    /// The set took in glossy classes because the sphere shows a highlight ([`add_glossy`]).
    pub glossy_added: bool,
    /// The set took in classes that differ only in a blur the sphere is too small to show
    /// ([`add_blur_alike`]): the radius it was read at, and the radius below which the
    /// unwrap upsamples (px).
    pub blur_added: Option<(f64, f64)>,
    /// The classifier's standardized inputs.
    pub z: Vec<f64>,
}

impl Decision {
    /// The classifier that decided.
    pub fn head<'a>(&self, file: &'a ModelFile) -> Head<'a> {
        file.head(self.request)
    }

    /// Out of domain: a check failed, or the capture is outside the envelope. The one
    /// source of the verdict: every surface (`/v1`'s [`Decision::domain`], V2 and gRPC's
    /// `in_domain`, `reflectance predict`'s CSV, the command line and Python) reads it here.
    pub fn in_domain(&self) -> bool {
        self.verdict.as_ref().is_none_or(Verdict::in_domain)
            && self.envelope.is_empty()
            && !self.beyond_any_light()
    }

    /// The lighting check: shading that only one small lamp in the dark makes, on pixels
    /// steeper than sRGB ([`Shading::beyond_any_light`]).
    pub fn beyond_any_light(&self) -> bool {
        self.shading.is_some_and(|s| s.beyond_any_light())
    }
}

/// What the decision needs besides the feature row.
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    /// Whether the request gave a white reference (else the classifier without white answers,
    /// when the model has one), and an object's normals (the classifier for objects then
    /// answers, when the model has one).
    pub request: Request,
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
    let head = model.head(context.request);
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
    let mut set = prediction_set(
        model,
        &head,
        &output.probabilities,
        context.coverage,
        context.request.white_given,
    );
    let shading = context.measured.and_then(|m| m.shading);
    let glossy_added = match (&mut set, shading) {
        (Some(set), Some(s)) if s.shows_highlight() => add_glossy(model, &head, output.class, set),
        _ => false,
    };
    let read_at = match model.features.config.working_radius {
        Some(working) => context.radius.min(working),
        None => context.radius,
    };
    let upsampled_below = model.features.config.unwrap.r0;
    let blur_added = match &mut set {
        Some(set) if read_at < upsampled_below => {
            add_blur_alike(model, &head, read_at, set).then_some((read_at, upsampled_below))
        }
        _ => None,
    };
    let verdict = head.domain.map(|d| d.verdict(&z, values));
    Ok(Decision {
        request: context.request,
        without_white: head.without_white,
        objects: head.objects,
        class: output.class,
        probabilities: output.probabilities,
        set,
        coverage: context.coverage,
        verdict,
        envelope,
        shading,
        glossy_added,
        blur_added,
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
    /// Of `predict_ms`, the Ward estimate's (ms).
    pub estimate_ms: f64,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl From<PartError> for InferenceError {
    fn from(e: PartError) -> InferenceError {
        match e {
            PartError::Mask(source) => InferenceError::Decode {
                part: "mask: ",
                source,
            },
            PartError::WhiteCard(source) => InferenceError::Decode {
                part: "white_image: ",
                source,
            },
            PartError::Normals(e) => InferenceError::Normals(e),
        }
    }
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
        // A colour is read only against a card's colour.
        colour: input.white.is_card(),
    };
    let photo = Photo::open(&input.image, &options)
        .map_err(|source| InferenceError::Decode { part: "", source })?;
    let white = input.white.decode(&options)?;
    let placement = input.locate.decode(&options)?;
    classify_photo(model, &photo, &placement, &white, &input.answer, ms(t))
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

/// An object showing less than this fraction of the sphere's annulus gets the widest
/// prediction set ([`PARTIAL_COVERAGE`]).
pub const WHOLE_OBSERVED: f64 = 0.95;

/// Normals that stray from their smoothed field by more than this RMS angle (degrees) get the
/// widest prediction set ([`PARTIAL_COVERAGE`]): exact and 16-bit maps stray by under 0.5°.
pub const MAX_SCATTER_DEG: f64 = 2.0;

/// An object with more than this share of its pixels left out because it shadows and lights
/// itself there (saddles, hollows, its own shadow) gets the widest prediction set
/// ([`PARTIAL_COVERAGE`]): it likely does so a little where it was kept too, which no sphere
/// does (path-traced objects, docs/accuracy.md).
pub const MAX_SELF_SHADOWED: f64 = 0.1;

/// Why an object's answer is outside what the prediction sets were calibrated on (part of
/// the sphere, scattered normals, a surface that shadows itself), if it is.
fn uncalibrated_object(analysis: &analysis::Analysis) -> Option<String> {
    let sphere = analysis.equivalent.as_ref()?;
    let partly = analysis
        .observed
        .filter(|&f| f < WHOLE_OBSERVED)
        .map(|f| format!("the object shows {:.0} % of the sphere", f * 100.0));
    let scattered = (sphere.scatter_deg > MAX_SCATTER_DEG).then(|| {
        format!(
            "its normals stray by {:.1}° (RMS) from a smooth surface",
            sphere.scatter_deg
        )
    });
    let hollow =
        (sphere.not_convex_fraction + sphere.shadowed_fraction > MAX_SELF_SHADOWED).then(|| {
            format!(
                "{:.0} % of its surface is not convex and {:.0} % in its own shadow (it shadows \
                 and lights itself)",
                sphere.not_convex_fraction * 100.0,
                sphere.shadowed_fraction * 100.0
            )
        });
    let reasons: Vec<String> = [partly, scattered, hollow].into_iter().flatten().collect();
    (!reasons.is_empty()).then(|| reasons.join(" and "))
}

/// The prediction set's coverage: the one asked for (else the default), widened to
/// [`PARTIAL_COVERAGE`] with a warning for an object outside what the sets were calibrated on.
fn widened_for_objects(analysis: &mut analysis::Analysis, asked: Option<f64>) -> f64 {
    let coverage = asked.unwrap_or(conformal::DEFAULT_COVERAGE);
    let Some(why) = uncalibrated_object(analysis) else {
        return coverage;
    };
    analysis.warnings.push(format!(
        "{why}: the prediction set is widened to {} % coverage (the sets are calibrated on \
         whole spheres of exact geometry)",
        PARTIAL_COVERAGE * 100.0
    ));
    coverage.max(PARTIAL_COVERAGE)
}

/// The coverage of a partly seen object's prediction set: the sets are calibrated on whole
/// spheres, and on the centre quarters of rendered objects the 95 % set missed the true class
/// 10 times in 96 where the 99.9 % set missed it once (docs/accuracy.md).
pub const PARTIAL_COVERAGE: f64 = 0.999;

/// Locate, extract and classify an image already decoded (or handed over as an array,
/// [`decode::from_luminance`]); `decode_ms` is what its decoding took.
pub fn classify_decoded(
    model: Arc<LoadedModel>,
    image: decode::LinearImage,
    locate: &Placement,
    white: &WhiteSpec,
    answer: &Answer,
    decode_ms: f64,
) -> Result<Classified, InferenceError> {
    classify_photo(
        model,
        &Photo::decoded(image),
        locate,
        white,
        answer,
        decode_ms,
    )
}

/// Locate, extract and classify a photograph, decoding what each step reads
/// ([`analysis::analyze_photo`]); `decode_ms` is what opening it took.
pub fn classify_photo(
    model: Arc<LoadedModel>,
    photo: &Photo,
    locate: &Placement,
    white: &WhiteSpec,
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
    let (mut analysis, read) = analysis::analyze_photo(
        &model.extractor,
        photo,
        locate,
        white,
        wanted,
        envelope.is_some(),
    )?;
    let images = answer
        .include_images
        .then(|| images_of(&model.extractor, &read, &analysis));
    drop(read);
    let features_ms = ms(t);
    let t = Instant::now();
    let coverage = widened_for_objects(&mut analysis, answer.coverage);
    let context = Context {
        request: Request {
            white_given: analysis.white.method != WhiteMethod::None,
            object: analysis.equivalent.is_some(),
        },
        radius: analysis.geometry.circle().r,
        measured: analysis.measured.as_ref(),
        coverage,
    };
    let decision = decide(&model.file, &analysis.values, context)?;
    // Outside the predicted class's envelope but not the model's: a warning, not a reason.
    if let (Some(envelope), Some(measured), true) =
        (envelope, &analysis.measured, decision.envelope.is_empty())
    {
        let class = &decision.head(&model.file).classifier.classes[decision.class];
        let working_radius = model.file.features.config.working_radius;
        let radius = context.radius;
        analysis
            .warnings
            .extend(envelope.outside(radius, working_radius, class, measured));
    }
    let classifier = decision.head(&model.file).classifier;
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
    let t_estimate = Instant::now();
    let ward = estimate(&model.file, &decision, &analysis.values);
    let estimate_ms = ms(t_estimate);
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
        estimate_ms,
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
    let classes = &decision.head(file).classifier.classes;
    let named = match &decision.set {
        Some(set) => set.clone(),
        None => vec![decision.class],
    };
    let parameters = named.iter().filter_map(|&k| file.ward_of(&classes[k]));
    Some(estimate.holding(parameters))
}

/// The prediction set of a classification: the head's calibrated set, and, when there is no
/// white reference, every class that differs from a member mainly by a brightness scale
/// ([`Ward::same_up_to_scale`], [`Ward::mirror_alike`]): the exposure of a photograph without
/// a white card hides that difference, whatever the training captures' exposures taught.
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
        let ward = |k: usize| file.ward_of(&classes[k]);
        let alike = |set: &[usize], k: usize, rule: fn(&Ward, &Ward) -> bool| {
            set.iter().any(|&m| match (ward(m), ward(k)) {
                (Some(a), Some(b)) => rule(&a, &b),
                _ => false,
            })
        };
        // Each rule looks at the calibrated set only: a class one rule adds does not bring in
        // the classes alike to it by the other (a dim mirror's brightness twins, or chrome
        // for a glossy class added as a twin).
        let calibrated = set.clone();
        for rule in [Ward::same_up_to_scale, Ward::mirror_alike] {
            for k in 0..classes.len() {
                if !set.contains(&k) && alike(&calibrated, k, rule) {
                    set.push(k);
                }
            }
        }
    }
    Some(set)
}

/// A blur of α spans about α·r pixels at the centre of a sphere of radius r: under this
/// many the pyramid's finest scale does not show it.
pub const RESOLVED_BLUR_PX: f64 = 2.0;

/// A sphere read at radius `read_at` (px) below the unwrap's `r0` (its image upsampled, its
/// finest scales interpolated) cannot show a blur of α below [`RESOLVED_BLUR_PX`] /
/// `read_at`: every class that differs from a member of `set` only by such a blur
/// ([`Ward::blur_alike`]) joins it. Whether one did.
fn add_blur_alike(file: &ModelFile, head: &Head, read_at: f64, set: &mut Vec<usize>) -> bool {
    let classes = &head.classifier.classes;
    let ward = |k: usize| file.ward_of(&classes[k]);
    let unresolved = RESOLVED_BLUR_PX / read_at;
    let members = set.clone();
    for k in 0..classes.len() {
        let alike = members.iter().any(|&m| match (ward(m), ward(k)) {
            (Some(a), Some(b)) => a.blur_alike(&b, unresolved),
            _ => false,
        });
        if alike && !set.contains(&k) {
            set.push(k);
        }
    }
    set.len() > members.len()
}

/// A sphere that shows a highlight brighter than its diffuse shading is not matte: when the
/// `label` is a matte class, every glossy class alike to a matte member of `set`
/// ([`Ward::glossy_alike`]) joins it. Whether one did.
fn add_glossy(file: &ModelFile, head: &Head, label: usize, set: &mut Vec<usize>) -> bool {
    let classes = &head.classifier.classes;
    let ward = |k: usize| file.ward_of(&classes[k]);
    if !ward(label).is_some_and(|w| w.rho_s <= 0.0) {
        return false;
    }
    let members = set.clone();
    let before = set.len();
    for k in 0..classes.len() {
        let alike = members.iter().any(|&m| match (ward(m), ward(k)) {
            (Some(a), Some(b)) => a.glossy_alike(&b),
            _ => false,
        });
        if alike && !set.contains(&k) {
            set.push(k);
        }
    }
    set.len() > before
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
    let decode_error = |source| InferenceError::Decode { part: "", source };
    let photo = Photo::open(bytes, options).map_err(decode_error)?;
    let (width, height) = photo.size();
    let side = preview.then_some(PREVIEW_SIDE.min(width.max(height)));
    let analysis::LocatedPhoto {
        chosen,
        alternatives: ranked,
        preview_png,
    } = analysis::locate_photo_ranked(&photo, &model.extractor, side).map_err(decode_error)?;
    let mut warnings = photo.warnings().to_vec();
    let candidates = ranked
        .iter()
        .take(CANDIDATES)
        .map(|g| CandidateOut {
            geometry: GeometryOut::from(g),
            rim_visible: locate::visible_rim(&g.circle(), width, height),
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
        width,
        height,
        geometry,
        candidates,
        warnings,
        preview: preview_png.map(|png| display::data_url(&png)),
    })
}
