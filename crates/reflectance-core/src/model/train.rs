//! From a feature table to a verified model file: fit the pipeline, cross-validate it,
//! and record provenance and a self-test vector.

use crate::classify::conformal::PredictionSets;
use crate::classify::domain::{self, DomainCheck};
use crate::classify::pipeline::{HeldOut, fit_rows_observed};
use crate::classify::{self, Classifier, CvReport, TrainSpec};
use crate::dataset::{Entry, FeatureTable, Manifest, Sample};
use crate::decode::{self, DecodeOptions};
use crate::estimate::{self, EstimateReport, WardRegressor};
use crate::features::families::LOG;
use crate::features::stats;
use crate::features::{CAPTURE_NAMES, Families, FeatureConfig, Preprocessing};
use crate::image::display;
use crate::learn::{Dataset, FeatureSet, LearnError};
use crate::material::{CaptureEnvelope, CaptureRanges, Material, VIEW_TAG};
use crate::model::{
    self, ClassInfo, Exemplar, FeatureSpec, ModelError, ModelFile, Provenance, SelfTest, StoredCv,
    StoredHead,
};
use crate::util::progress::{Observer, Silent};
use rayon::prelude::*;
use serde_json::json;
use std::collections::BTreeMap;
use std::collections::HashMap;

/// Why a model cannot be trained, checked or published.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Training or cross-validation failed.
    #[error(transparent)]
    Learn(#[from] LearnError),
    /// The trained model fails its own checks.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A feature table whose columns are not the configuration's canonical features.
    #[error(
        "the feature table's columns are not the canonical features of the extraction configuration"
    )]
    Columns,
    /// An estimator table whose columns are not the model's features: the table.
    #[error(
        "{0}: its columns are not the model's features (extract it with the same flags; \
         --domain-features may be left out)"
    )]
    EstimatorColumns(String),
    /// Data for a classifier for objects that do not have the model's classes.
    #[error(
        "the data's classes ({data}) are not the model's ({model}): a classifier for objects \
         answers with the model's classes, and needs images of each"
    )]
    ObjectsClasses {
        /// The data's classes, comma-separated.
        data: String,
        /// The model's.
        model: String,
    },
    /// A model whose estimator and classifier for objects cannot be carried into this one.
    #[error("cannot carry {what} from {from}: {why}")]
    Carry {
        /// What was to be carried.
        what: &'static str,
        /// The model it was to come from (name and version).
        from: String,
        /// Why not.
        why: &'static str,
    },
    /// A manifest or table cannot be read.
    #[error(transparent)]
    Dataset(#[from] crate::dataset::DatasetError),
    /// The registry refuses the new version.
    #[error("cannot publish a new version: {0}")]
    Publish(#[from] crate::model::registry::RegistryError),
    /// The cross-validation report cannot be written.
    #[error("cannot write the cross-validation report: {0}")]
    Report(#[from] serde_json::Error),
}

/// What to train: the model's name, its classifier, seed and options.
pub struct TrainOptions {
    /// The model's name in its registry (see [`crate::model::registry::valid_name`]).
    pub name: String,
    /// The features, the classifier and its hyper-parameters.
    pub spec: TrainSpec,
    /// The seed of every random choice (reproducible training).
    pub seed: u64,
    /// Run leave-one-illumination-out CV and store its summary (and return the report).
    pub cross_validate: bool,
    /// Ward parameters of the classes, when known.
    pub classes: Option<Vec<Material>>,
    /// How the training spheres were preprocessed (working radius, saturation), recorded
    /// so that serving does the same (the table must have been extracted with it).
    pub preprocessing: Preprocessing,
    /// The manifest the table was extracted from: exemplars get thumbnails of its images,
    /// and the classifier without white is fitted on their features without white (`None`:
    /// neither).
    pub images: Option<Manifest>,
    /// How the manifest's images decode.
    pub decode: DecodeOptions,
    /// Fit a Ward-parameter estimator next to the classifier.
    pub estimator: Option<EstimatorData>,
    /// Fit the classifier without white on the classes' reference materials only, leaving
    /// out the images of their members ([`crate::material::names_a_member`]): without white a
    /// dark glossy member is a dim mirror, which the classifier without white cannot tell
    /// from the metals (docs/design.md §8, "Real materials and the classes").
    pub no_white_references_only: bool,
}

/// What a Ward-parameter estimator is fitted on.
pub struct EstimatorData {
    /// Rows of materials (any, not only the classifier's classes), with the model's columns.
    pub table: FeatureTable,
    /// Names the table (a path as given).
    pub label: String,
    /// The Ward parameters of the table's classes.
    pub materials: Vec<Material>,
    /// The estimator's inputs (`None`: the classifier's feature set).
    pub features: Option<FeatureSet>,
    /// The regression.
    pub regression: estimate::EstimatorOptions,
    /// A ridge's RBF γ when the options give none (the classifier's; `None`: 1 / number of
    /// inputs).
    pub gamma: Option<f64>,
}

/// A trained model, before publication: the file, and the reports of its cross-validation.
pub struct Trained {
    /// The model file, checksummed and self-tested.
    pub model: ModelFile,
    /// The leave-one-illumination-out report, when `cross_validate` was asked for.
    pub report: Option<CvReport>,
    /// The estimator's leave-one-illumination-out errors, when one was fitted.
    pub estimate: Option<EstimateReport>,
}

/// The captures a table's model is trained for, when it has capture views: the ranges
/// `render --captures` draws from, and per class the 99th percentiles of its capture
/// measurements.
fn capture_envelope(table: &FeatureTable) -> Option<CaptureEnvelope> {
    let captured = |s: &Sample| s.illumination.contains(VIEW_TAG);
    if !table.samples.iter().any(captured) {
        return None;
    }
    let p99 = |name: &str, of: fn(f64) -> f64| {
        let Some(column) = table.names.iter().position(|n| n == name) else {
            return BTreeMap::new();
        };
        let mut by_class: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for s in &table.samples {
            let values = by_class.entry(s.class.clone()).or_default();
            values.push(of(s.values[column]));
        }
        by_class
            .into_iter()
            .map(|(class, values)| (class, stats::percentiles(&values, [99.0])[0]))
            .filter(|(_, p)| p.is_finite())
            .collect()
    };
    Some(CaptureEnvelope {
        ranges: CaptureRanges::default(),
        noise_p99: p99(CAPTURE_NAMES[0], |log| 10f64.powf(log)),
        clipped_p99: p99(CAPTURE_NAMES[1], |fraction| fraction),
    })
}

/// Longer side of an exemplar's thumbnail, in pixels.
pub const THUMBNAIL_SIDE: usize = 48;

/// A thumbnail of each exemplar whose manifest row's image decodes (the others keep none).
fn attach_thumbnails(exemplars: &mut [Exemplar], manifest: &Manifest) {
    let rows: HashMap<&str, &Entry> = manifest
        .entries
        .iter()
        .map(|e| (e.path.as_str(), e))
        .collect();
    exemplars.par_iter_mut().for_each(|e| {
        e.thumbnail = rows.get(e.path.as_str()).and_then(|row| thumbnail(row));
    });
}

/// The sphere of a manifest row (its circle with a margin, or the whole image) divided by
/// the row's white, as a PNG data URL.
fn thumbnail(row: &Entry) -> Option<String> {
    let options = DecodeOptions {
        encoding: row.encoding,
        ..Default::default()
    };
    let image = decode::decode_file(&row.file, &options).ok()?;
    let luminance = image.luminance.view();
    let (h, w) = luminance.dim();
    let crop = match row.circle {
        Some(c) => {
            let reach = 1.05 * c.r;
            let span = |centre: f64, n: usize| {
                let lo = (centre - reach).floor().clamp(0.0, n as f64) as usize;
                let hi = (centre + reach).ceil().clamp(0.0, n as f64) as usize;
                lo..hi.max(lo + 1).min(n)
            };
            luminance.slice_move(ndarray::s![span(c.cy, h), span(c.cx, w)])
        }
        None => luminance,
    };
    let white = row.white.unwrap_or(1.0);
    let normalized = crop.mapv(|v| v / white);
    Some(display::data_url(&display::thumbnail_png(
        normalized.view(),
        THUMBNAIL_SIDE,
    )))
}

/// Fit a model on `table`; `dataset` names the data (a path as given).
pub fn train(
    table: &FeatureTable,
    dataset: &str,
    options: &TrainOptions,
) -> Result<Trained, TrainError> {
    train_with(table, dataset, options, &Silent)
}

/// [`train`] with stages (`"fit"`, `"cross_validate"`, `"estimate"`), fold progress and
/// cooperative cancellation (before the fit, between folds and before the estimator:
/// [`LearnError::Cancelled`]).
pub fn train_with(
    table: &FeatureTable,
    dataset: &str,
    options: &TrainOptions,
    observer: &dyn Observer,
) -> Result<Trained, TrainError> {
    // The table decides: 117 columns, more with the optional families.
    let families = Families::of_names(table.names.iter().map(String::as_str));
    let config = FeatureConfig::extended(families, options.preprocessing);
    if table.names != config.names() {
        return Err(TrainError::Columns);
    }
    let ds = Dataset::from_table(table)?;
    let column = |name: &str| table.names.iter().position(|n| n == name);
    let (classifier, prediction_sets, domain) =
        fit_classifier(&ds, &options.spec, options.seed, &column, observer)?;
    let no_white = match (&options.images, config.families.contains(&LOG)) {
        (Some(manifest), true) => {
            let manifest = match options.no_white_references_only {
                true => references_only(manifest),
                false => manifest.clone(),
            };
            let table = without_white(&manifest, config, &options.decode, observer)?;
            observer.stage("fit_without_white");
            fit_no_white(&Dataset::from_table(&table)?, options, &column, observer)?
        }
        _ => None,
    };
    let report = if options.cross_validate {
        observer.stage("cross_validate");
        Some(classify::cross_validate_with(
            &ds,
            &options.spec,
            options.seed,
            observer,
        )?)
    } else {
        None
    };
    let (estimator, estimate) = options
        .estimator
        .as_ref()
        .map(|data| fit_estimator(data, table, options, observer))
        .transpose()?
        .unzip();
    let model = ModelFile {
        schema: model::SCHEMA.into(),
        schema_version: model::SCHEMA_VERSION,
        name: options.name.clone(),
        version: 1,
        created: model::now_rfc3339(),
        classes: class_infos(&classifier.classes, options.classes.as_deref()),
        features: FeatureSpec {
            config,
            set: classifier.feature_set.clone(),
            selected: classifier.selected.clone(),
        },
        training: provenance(
            table,
            &ds,
            dataset,
            (&options.spec, options.seed),
            report.as_ref(),
        ),
        self_test: self_test(&ds, &classifier, no_white.as_ref())?,
        exemplars: exemplars(table, &ds, &classifier, options.images.as_ref())?,
        classifier,
        capture: capture_envelope(table),
        estimator,
        prediction_sets,
        domain,
        no_white,
        objects: None,
        sha256: String::new(),
    };
    model.verify()?;
    Ok(Trained {
        model,
        report,
        estimate,
    })
}

/// The classifier on every row, with its prediction sets and domain check.
fn fit_classifier(
    ds: &Dataset,
    spec: &TrainSpec,
    seed: u64,
    column: &dyn Fn(&str) -> Option<usize>,
    observer: &dyn Observer,
) -> Result<(Classifier, Option<PredictionSets>, Option<DomainCheck>), TrainError> {
    if observer.cancelled() {
        return Err(LearnError::Cancelled.into());
    }
    // The classifier: its calibration folds and calibration, as units that finish.
    observer.stage("fit");
    let rows: Vec<usize> = (0..ds.n_rows()).collect();
    let (classifier, held_out) = fit_rows_observed(ds, &rows, spec, seed, observer)?;
    if observer.cancelled() {
        return Err(LearnError::Cancelled.into());
    }
    observer.stage("prediction_sets");
    observer.progress(0, 1);
    let (prediction_sets, domain) =
        reliability(ds, &rows, &classifier, held_out.as_ref(), column, seed)?;
    observer.progress(1, 1);
    Ok((classifier, prediction_sets, domain))
}

/// The classes in the classifier's order, with their Ward parameters when a class file
/// gave them.
fn class_infos(names: &[String], materials: Option<&[Material]>) -> Vec<ClassInfo> {
    let ward_of = |name: &str| Some(crate::material::reference(materials?, name)?.ward);
    names
        .iter()
        .map(|name| ClassInfo {
            name: name.clone(),
            ward: ward_of(name),
        })
        .collect()
}

/// What the model learned from, and how.
fn provenance(
    table: &FeatureTable,
    ds: &Dataset,
    dataset: &str,
    (spec, seed): (&TrainSpec, u64),
    report: Option<&CvReport>,
) -> Provenance {
    Provenance {
        dataset: dataset.to_string(),
        dataset_sha256: model::sha256_hex(&table.to_csv()),
        images: table.samples.len(),
        illuminations: ds.group_names.len(),
        seed,
        options: json!({
            "features": spec.features.to_string(),
            "classifier": spec.classifier.to_string(),
            "c": spec.c,
            "gamma": spec.gamma,
            "grid": spec.grid,
        }),
        cv: report.map(|r| StoredCv::from(&r.summary)),
    }
}

/// The self-test: the first original (non-augmented) training image and its answers.
fn self_test(
    ds: &Dataset,
    classifier: &Classifier,
    no_white: Option<&StoredHead>,
) -> Result<SelfTest, LearnError> {
    let probe = ds.augmented.iter().position(|a| !a).unwrap_or(0);
    let features = ds.x.row(probe).to_vec();
    Ok(SelfTest {
        probabilities: classifier.predict_proba(&features)?,
        no_white_probabilities: no_white
            .map(|n| n.classifier.predict_proba(&features))
            .transpose()?,
        objects_probabilities: None,
        features,
    })
}

/// The original (non-augmented) training images, with their thumbnails when the images
/// are at hand, for `explain`.
fn exemplars(
    table: &FeatureTable,
    ds: &Dataset,
    classifier: &Classifier,
    images: Option<&Manifest>,
) -> Result<Vec<Exemplar>, LearnError> {
    let mut exemplars = Vec::new();
    for (i, sample) in table
        .samples
        .iter()
        .enumerate()
        .filter(|(i, _)| !ds.augmented[*i])
    {
        exemplars.push(Exemplar {
            path: sample.path.clone(),
            class: sample.class.clone(),
            illumination: sample.illumination.clone(),
            inputs: classifier.transform(&ds.x.row(i).to_vec())?,
            thumbnail: None,
        });
    }
    if let Some(manifest) = images {
        attach_thumbnails(&mut exemplars, manifest);
    }
    Ok(exemplars)
}

/// The prediction sets and the domain check of a classifier, from the rows its calibration
/// held out (none for classifiers without calibration folds: k-NN, chance). `column` finds
/// a feature's column (the domain check's feature checks read those that exist).
fn reliability(
    ds: &Dataset,
    rows: &[usize],
    classifier: &Classifier,
    held_out: Option<&HeldOut>,
    column: &dyn Fn(&str) -> Option<usize>,
    seed: u64,
) -> Result<(Option<PredictionSets>, Option<DomainCheck>), LearnError> {
    let (Some(held_out), Some(calibration)) = (held_out, &classifier.calibration) else {
        return Ok((None, None));
    };
    // Positions in `rows` (the fit's order, which `held_out` follows).
    let held: Vec<usize> = (0..rows.len())
        .filter(|&i| held_out.fold[i].is_some())
        .collect();
    if held.is_empty() {
        return Ok((None, None));
    }
    let probabilities: Vec<Vec<f64>> = held
        .iter()
        .map(|&i| calibration.probabilities(&held_out.decision[i]))
        .collect();
    let truth: Vec<usize> = held.iter().map(|&i| ds.labels[rows[i]]).collect();
    let fold: Vec<usize> = held.iter().filter_map(|&i| held_out.fold[i]).collect();
    let sets = PredictionSets::calibrate(&probabilities, &truth, &fold, held_out.by_illumination);
    let values: Vec<Vec<f64>> = rows.iter().map(|&r| ds.x.row(r).to_vec()).collect();
    let z: Vec<Vec<f64>> = values
        .iter()
        .map(|row| classifier.transform(row))
        .collect::<Result<_, _>>()?;
    let rows = domain::Rows {
        z: &z,
        values: &values,
        fold: &held_out.fold,
    };
    Ok((Some(sets), DomainCheck::calibrate(&rows, column, seed)))
}

/// `manifest` without the rows of classes' members.
fn references_only(manifest: &Manifest) -> Manifest {
    Manifest {
        source: manifest.source.clone(),
        entries: (manifest.entries.iter())
            .filter(|e| !crate::material::names_a_member(&e.path))
            .cloned()
            .collect(),
    }
}

/// The features of a manifest's images as a request without white gives them (white = 1):
/// what the classifier without white is fitted and calibrated on.
fn without_white(
    manifest: &Manifest,
    config: FeatureConfig,
    decode: &DecodeOptions,
    observer: &dyn Observer,
) -> Result<FeatureTable, TrainError> {
    let mut manifest = manifest.clone();
    manifest.entries.iter_mut().for_each(|e| e.white = None);
    let extractor = crate::features::Extractor::new(config).map_err(ModelError::from)?;
    observer.stage("features_without_white");
    Ok(crate::dataset::extract_manifest_with(
        &extractor, &manifest, decode, observer,
    )?)
}

/// The training rows the classifier without white is fitted on, at most (an evenly spaced
/// subset of more).
pub const NO_WHITE_ROWS: usize = 7000;

/// The classifier without white: the model's kind of classifier on the `scale_free`
/// features of the images without white, when the table has them (the log-domain
/// features), with its own prediction sets and domain check (which cannot read the
/// brightness against white).
fn fit_no_white(
    ds: &Dataset,
    options: &TrainOptions,
    column: &dyn Fn(&str) -> Option<usize>,
    observer: &dyn Observer,
) -> Result<Option<StoredHead>, LearnError> {
    let names = crate::features::named_set("scale_free").unwrap_or_default();
    if options.spec.classifier != classify::ClassifierKind::Svm
        || names.iter().any(|n| column(n).is_none())
    {
        return Ok(None);
    }
    let spec = TrainSpec {
        features: FeatureSet::parse_with("scale_free", &ds.names)?,
        gamma: None,
        grid: None,
        ..options.spec.clone()
    };
    // Without brightness the classes overlap, and an SVM keeps most rows of an overlap as
    // support vectors: every k-th row keeps its cost per request near the classifier's.
    let k = ds.n_rows().div_ceil(NO_WHITE_ROWS).max(1);
    let rows: Vec<usize> = (0..ds.n_rows()).step_by(k).collect();
    let (classifier, held_out) = fit_rows_observed(ds, &rows, &spec, options.seed, observer)?;
    let without_brightness = |name: &str| column(name).filter(|_| name != "ctr.mean");
    let (prediction_sets, domain) = reliability(
        ds,
        &rows,
        &classifier,
        held_out.as_ref(),
        &without_brightness,
        options.seed,
    )?;
    Ok(Some(StoredHead {
        classifier,
        prediction_sets,
        domain,
        training: None,
    }))
}

/// `base` with a classifier for objects (docs/design.md §9): the base's classifier kind,
/// features, C and γ, fitted on `table` (spheres and objects' equivalent spheres, extracted
/// with the base's configuration), with prediction sets and a domain check calibrated over
/// `calibration_folds` folds of illuminations (0: one per illumination); `dataset` names the
/// data. Everything else of the base is kept, so spheres are answered exactly as before.
pub fn add_objects(
    base: &ModelFile,
    table: &FeatureTable,
    dataset: &str,
    (calibration_folds, seed): (usize, u64),
    observer: &dyn Observer,
) -> Result<Trained, TrainError> {
    if table.names != base.features.config.names() {
        return Err(TrainError::Columns);
    }
    let (c, gamma) = match base.classifier.model() {
        classify::pipeline::Model::Svm(svm) => (svm.c, Some(svm.gamma)),
        _ => (classify::DEFAULT_C, None),
    };
    let options = classify::ClassifierOptions {
        features: base.features.set.clone(),
        classifier: base.classifier.kind(),
        c,
        gamma,
        grid: false,
        calibration_folds,
        seed,
    };
    let spec = options.spec(&table.names)?;
    let ds = Dataset::from_table(table)?;
    if ds.classes != base.classifier.classes {
        return Err(TrainError::ObjectsClasses {
            data: ds.classes.join(", "),
            model: base.classifier.classes.join(", "),
        });
    }
    let column = |name: &str| table.names.iter().position(|n| n == name);
    let (classifier, prediction_sets, domain) =
        fit_classifier(&ds, &spec, seed, &column, observer)?;
    let mut model = base.clone();
    model.self_test.objects_probabilities =
        Some(classifier.predict_proba(&model.self_test.features)?);
    model.objects = Some(StoredHead {
        classifier,
        prediction_sets,
        domain,
        training: Some(provenance(table, &ds, dataset, (&spec, seed), None)),
    });
    model.created = model::now_rfc3339();
    model.verify()?;
    Ok(Trained {
        model,
        report: None,
        estimate: None,
    })
}

/// `model` with the Ward-parameter estimator and the classifier for objects of `from`, a
/// model of the same feature configuration and classes (what it lacks stays absent; an
/// estimator `model` has already is kept). Both read only features, which the two models
/// extract alike, so they answer in `model` exactly as in `from`: a retrained classifier
/// need not refit them.
pub fn carry_heads(model: &mut ModelFile, from: &ModelFile) -> Result<(), TrainError> {
    check_carry(&model.features.config, from)?;
    if model.estimator.is_none() {
        model.estimator = from.estimator.clone();
    }
    if let Some(objects) = &from.objects {
        if objects.classifier.classes != model.classifier.classes {
            return Err(refused(
                from,
                "its classifier for objects",
                "its classes differ",
            ));
        }
        model.self_test.objects_probabilities = Some(
            objects
                .classifier
                .predict_proba(&model.self_test.features)?,
        );
        model.objects = Some(objects.clone());
    }
    model.verify()?;
    Ok(())
}

/// Whether a model extracted with `config` can take `from`'s estimator and classifier for
/// objects ([`carry_heads`]), before it is trained.
pub fn check_carry(config: &FeatureConfig, from: &ModelFile) -> Result<(), TrainError> {
    match from.features.config == *config {
        true => Ok(()),
        false => Err(refused(
            from,
            "its estimator and classifier for objects",
            "its feature configuration differs",
        )),
    }
}

fn refused(from: &ModelFile, what: &'static str, why: &'static str) -> TrainError {
    TrainError::Carry {
        what,
        from: format!("{} version {}", from.name, from.version),
        why,
    }
}

/// The estimator of `data` for a model of `table`'s columns and `options`' feature set.
fn fit_estimator(
    data: &EstimatorData,
    table: &FeatureTable,
    options: &TrainOptions,
    observer: &dyn Observer,
) -> Result<(WardRegressor, EstimateReport), TrainError> {
    // The domain measurement comes last and no estimator reads it: a table extracted
    // without it has the model's columns up to it, at the same places.
    let without_domain = table
        .names
        .strip_suffix(&crate::features::DOMAIN_NAMES.map(String::from)[..])
        .unwrap_or(&table.names);
    if data.table.names != table.names && data.table.names != without_domain {
        return Err(TrainError::EstimatorColumns(data.label.clone()));
    }
    if observer.cancelled() {
        return Err(LearnError::Cancelled.into());
    }
    observer.stage("estimate");
    let ds = Dataset::from_table(&data.table)?;
    let features = data.features.as_ref().unwrap_or(&options.spec.features);
    let spec = (data.regression).regression_spec(features, &ds.names, data.gamma, options.seed)?;
    let fit = estimate::fit_observed(&ds, &data.label, &data.materials, features, &spec, observer)?;
    Ok((fit.regressor, fit.report))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(illumination_of: impl Fn(usize) -> String) -> FeatureTable {
        let samples = (0..200)
            .map(|i| Sample {
                path: format!("{i}.png"),
                class: ["matte", "mirror"][i % 2].into(),
                illumination: illumination_of(i),
                // cap.noise is log10: 10^-2 for every matte row, 10^-1 for every mirror row.
                values: vec![-1.0 - (i % 2 == 0) as u8 as f64, (i / 2) as f64 / 99.0],
            })
            .collect();
        FeatureTable {
            names: vec!["cap.noise".into(), "cap.clipped".into()],
            samples,
        }
    }

    #[test]
    fn the_envelope_holds_per_class_percentiles_of_tables_with_captures() {
        assert_eq!(capture_envelope(&table(|i| format!("probe{i}"))), None);
        let envelope = capture_envelope(&table(|i| format!("probe{i}@cap1"))).unwrap();
        assert_eq!(envelope.ranges, CaptureRanges::default());
        assert!((envelope.noise_p99["matte"] - 0.01).abs() < 1e-12);
        assert!((envelope.noise_p99["mirror"] - 0.1).abs() < 1e-12);
        // 100 clipped fractions 0, 1/99, …, 1 per class: numpy's linear 99th percentile.
        assert!((envelope.clipped_p99["matte"] - 0.99).abs() < 1e-12);
    }
}
