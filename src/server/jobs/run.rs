//! What the jobs do: validation at submission (so that mistakes are 422 at once), then
//! execution on a worker thread with progress and cancellation.

use super::paths::{DataDir, PathError};
use super::{JobRequest, LearnParams};
use crate::server::store::{ModelStore, StoreError};
use reflectance_core::classify::{self, CvSummary, TrainSpec};
use reflectance_core::dataset::{self, DatasetError, FeatureTable, Manifest};
use reflectance_core::decode::{DecodeOptions, Limits};
use reflectance_core::estimate::{self, EstimateReport};
use reflectance_core::features::families::DOMAIN;
use reflectance_core::features::{ConfigError, Extractor, FeatureConfig, Preprocessing};
use reflectance_core::learn::{Dataset, FeatureSet, LearnError};
use reflectance_core::material::{ClassFileError, load_classes};
use reflectance_core::model::publish::{Activate, Current, Published};
use reflectance_core::model::registry::{self, RegistryError};
use reflectance_core::model::train::{self, TrainError, TrainOptions};
use reflectance_core::util::progress::Observer;
use reflectance_render::Quality;
use reflectance_render::batch::{self, Augment, BatchSpec, OptionsError, RenderError};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A model version.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ModelRef {
    pub name: String,
    pub version: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RenderResult {
    /// The written manifest, relative to the data directory.
    pub manifest: String,
    pub images: usize,
    pub rendered: usize,
    /// Images already complete (resumed).
    pub skipped: usize,
}

/// What a job produced (the fields of its type).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobResult {
    /// `train`: the version written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelRef>,
    /// `train`: whether the new version was activated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activated: Option<bool>,
    /// `train`: why it was (not) activated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activation: Option<String>,
    /// `train` (unless `cross_validate: false`) and `cross_validate`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cv: Option<CvSummary>,
    /// `cross_validate` with `ward_classes`, and `train` with `estimator_table`: the
    /// Ward-parameter estimate's leave-one-illumination-out errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimate: Option<EstimateReport>,
    /// `render`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub render: Option<RenderResult>,
    /// Number of images or table rows the job learned from (`train`, `cross_validate`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<usize>,
}

/// How a job ended, when not successfully.
pub enum Failure {
    Cancelled,
    Error(Box<JobError>),
    /// Failed after producing something (e.g. published, then activation refused).
    Partial(Box<JobError>, Box<JobResult>),
}

/// Why a job is refused at submission or fails when it runs: the error of the layer that
/// refused or failed, kept typed. `server::error` maps a refused job to its problem; a
/// failed job's record states the error.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error(transparent)]
    Dataset(DatasetError),
    #[error(transparent)]
    Learn(LearnError),
    #[error(transparent)]
    Render(RenderError),
    /// A render job's options out of range (refused as the command line refuses them).
    #[error(transparent)]
    RenderOptions(#[from] OptionsError),
    #[error(transparent)]
    Train(TrainError),
    #[error(transparent)]
    Path(#[from] PathError),
    #[error(transparent)]
    Classes(#[from] ClassFileError),
    #[error(transparent)]
    Features(#[from] ConfigError),
    /// A model name outside the registry's alphabet.
    #[error(transparent)]
    Name(RegistryError),
    /// Parameters that go against each other.
    #[error(transparent)]
    Refused(#[from] Refusal),
    #[error("version {version} was published but its activation failed: {cause}")]
    Activation { version: u32, cause: StoreError },
    #[error("the job panicked")]
    Panicked,
    #[error("a {0} job was given to another job's runner")]
    WrongKind(&'static str),
}

/// A job's parameters that go against each other.
#[derive(Debug, thiserror::Error)]
pub enum Refusal {
    #[error("activate: if_better compares cross-validated accuracy; it needs cross_validate: true")]
    IfBetterWithoutCv,
    #[error("give exactly one of dataset (a manifest) or table")]
    Data,
    #[error("estimator_features needs estimator_table")]
    EstimatorFeatures,
    #[error("estimator_table and estimator_classes go together: give both or neither")]
    EstimatorHalf,
}

impl From<TrainError> for JobError {
    fn from(e: TrainError) -> JobError {
        match e {
            TrainError::Learn(e) => JobError::Learn(e),
            other => JobError::Train(other),
        }
    }
}

impl From<DatasetError> for JobError {
    fn from(e: DatasetError) -> JobError {
        JobError::Dataset(e)
    }
}

impl From<LearnError> for JobError {
    fn from(e: LearnError) -> JobError {
        JobError::Learn(e)
    }
}

impl From<RenderError> for JobError {
    fn from(e: RenderError) -> JobError {
        JobError::Render(e)
    }
}

impl JobError {
    /// Whether the layer stopped because the job was cancelled.
    fn cancels(&self) -> bool {
        matches!(
            self,
            JobError::Dataset(DatasetError::Cancelled)
                | JobError::Learn(LearnError::Cancelled)
                | JobError::Render(RenderError::Cancelled)
        )
    }
}

impl From<JobError> for Failure {
    /// A cancelled run of any layer is a cancelled job; any other error fails it.
    fn from(e: JobError) -> Failure {
        match e.cancels() {
            true => Failure::Cancelled,
            false => Failure::Error(Box::new(e)),
        }
    }
}

/// `?` on any layer's error in a job's run.
macro_rules! fails_a_job {
    ($($error:ty),*) => {$(
        impl From<$error> for Failure {
            fn from(e: $error) -> Failure {
                JobError::from(e).into()
            }
        }
    )*};
}

fails_a_job!(
    DatasetError,
    LearnError,
    RenderError,
    TrainError,
    PathError,
    ClassFileError,
    ConfigError
);

/// The extraction configuration of a learning job (as `reflectance train` chooses it).
fn config_of(p: &LearnParams) -> Result<FeatureConfig, ConfigError> {
    p.extraction.config(&p.options.features)
}

/// The training specification of learning parameters (feature names are those of the
/// job's extraction configuration).
fn spec_of(p: &LearnParams) -> Result<TrainSpec, JobError> {
    let names = config_of(p)?.names();
    Ok(p.options.spec(&names)?)
}

fn check_data(p: &LearnParams, data: &DataDir) -> Result<(), JobError> {
    match (&p.dataset, &p.table) {
        (Some(m), None) => data.existing("dataset", m)?,
        (None, Some(t)) => data.existing("table", t)?,
        _ => return Err(Refusal::Data.into()),
    };
    Ok(())
}

/// An estimator's options, and its features among the columns the job extracts.
fn check_estimator(p: &LearnParams, features: Option<&str>) -> Result<(), JobError> {
    p.estimator.check()?;
    if let Some(spec) = features {
        let names = train_config(p, features)?.names();
        FeatureSet::parse_with(spec, &names)?;
    }
    Ok(())
}

/// The checks of a `train` job at submission, beyond its learning parameters'.
fn check_train(request: &JobRequest, data: &DataDir) -> Result<(), JobError> {
    let JobRequest::Train {
        name,
        data: p,
        activate,
        classes,
        cross_validate,
        estimator_table,
        estimator_classes,
        estimator_features,
        no_white_references_only: _,
    } = request
    else {
        return Err(JobError::WrongKind("train"));
    };
    registry::check_name(name).map_err(JobError::Name)?;
    if *activate == Activate::IfBetter && !cross_validate {
        return Err(Refusal::IfBetterWithoutCv.into());
    }
    spec_of(p)?;
    check_data(p, data)?;
    if let Some(c) = classes {
        data.existing("classes", c)?;
    }
    match (estimator_table, estimator_classes) {
        (Some(t), Some(c)) => {
            data.existing("estimator_table", t)?;
            data.existing("estimator_classes", c)?;
            check_estimator(p, estimator_features.as_deref())
        }
        (None, None) if estimator_features.is_some() => Err(Refusal::EstimatorFeatures.into()),
        (None, None) => Ok(()),
        _ => Err(Refusal::EstimatorHalf.into()),
    }
}

/// Checks at submission: parameters, and that every path exists inside the data directory.
pub fn validate(request: &JobRequest, data: &DataDir) -> Result<(), JobError> {
    match request {
        JobRequest::Train { .. } => check_train(request, data),
        JobRequest::CrossValidate {
            data: p,
            ward_classes,
        } => {
            spec_of(p)?;
            check_data(p, data)?;
            if let Some(c) = ward_classes {
                data.existing("ward_classes", c)?;
                check_estimator(p, None)?;
            }
            Ok(())
        }
        JobRequest::Render {
            probes,
            classes,
            out,
            size,
            captures,
            ..
        } => {
            let (quality, augment) = render_options(*captures);
            batch::check_options(*size, &quality, &augment)?;
            data.existing("probes", probes)?;
            data.existing("classes", classes)?;
            // The output folder is created when the job runs.
            Ok(data.check_output("out", out)?)
        }
    }
}

/// The quality and augmentation of a render job: the defaults, with its captures.
fn render_options(captures: usize) -> (Quality, Augment) {
    let augment = Augment {
        captures,
        ..Augment::default()
    };
    (Quality::default(), augment)
}

/// What a `train` job extracts (as `reflectance train`): the families its features and its
/// estimator's name, and the outline, which a model's domain check reads.
fn train_config(
    p: &LearnParams,
    estimator_features: Option<&str>,
) -> Result<FeatureConfig, ConfigError> {
    let config = config_of(p)?;
    let config = match estimator_features {
        Some(features) => config.with_families_of(features),
        None => config,
    };
    Ok(config.with(&DOMAIN))
}

/// What a `train` job fits its Ward-parameter estimator on, when it asks for one, for a
/// model of the columns `names`.
fn estimator_data(
    p: &LearnParams,
    (table, classes, features): (&Option<String>, &Option<String>, &Option<String>),
    names: &[String],
    data: &DataDir,
) -> Result<Option<train::EstimatorData>, Failure> {
    let (Some(table), Some(classes)) = (table, classes) else {
        return Ok(None);
    };
    let table_path = data.existing("estimator_table", table)?;
    let classes_path = data.existing("estimator_classes", classes)?;
    let features = features
        .as_deref()
        .map(|spec| FeatureSet::parse_with(spec, names))
        .transpose()?;
    Ok(Some(train::EstimatorData {
        table: FeatureTable::read(&table_path)?,
        label: table.clone(),
        materials: load_classes(&classes_path)?,
        features,
        regression: p.estimator,
        gamma: p.options.gamma,
    }))
}

/// The feature table of a learning job (extracting features from a manifest's images).
fn load_table(
    p: &LearnParams,
    config: FeatureConfig,
    data: &DataDir,
    limits: &Limits,
    observer: &dyn Observer,
) -> Result<(FeatureTable, String, Option<Manifest>), Failure> {
    if let Some(t) = &p.table {
        let path = data.existing("table", t)?;
        let table = FeatureTable::read(&path)?;
        return Ok((table, t.clone(), None));
    }
    let rel = p.dataset.as_deref().unwrap_or_default();
    let path = data.existing("dataset", rel)?;
    let manifest = dataset::read_manifest(&path)?;
    manifest.require_labels()?;
    for entry in &manifest.entries {
        let line = entry.line;
        data.check_resolved(&format!("manifest line {line} image"), &entry.file)?;
        for (what, beside) in [("normals", &entry.normals), ("mask", &entry.mask)] {
            if let Some(beside) = beside {
                data.check_resolved(&format!("manifest line {line} {what}"), &beside.file)?;
            }
        }
    }
    let extractor = Extractor::new(config)?;
    let options = DecodeOptions {
        encoding: None,
        limits: *limits,
        colour: false,
    };
    observer.stage("features");
    let table = dataset::extract_manifest_with(&extractor, &manifest, &options, observer)?;
    Ok((table, rel.to_string(), Some(manifest)))
}

/// What a running job works with.
struct Context<'a> {
    data: &'a DataDir,
    limits: &'a Limits,
    models: &'a ModelStore,
    observer: &'a dyn Observer,
}

/// Run a job to completion (or cancellation).
pub fn execute(
    request: &JobRequest,
    data: &DataDir,
    limits: &Limits,
    models: &ModelStore,
    observer: &dyn Observer,
) -> Result<JobResult, Failure> {
    let job = Context {
        data,
        limits,
        models,
        observer,
    };
    match request {
        JobRequest::Train { .. } => job.train(request),
        JobRequest::CrossValidate {
            data: p,
            ward_classes: Some(classes),
        } => job.cross_validate_estimate(p, classes),
        JobRequest::CrossValidate { data: p, .. } => job.cross_validate(p),
        JobRequest::Render {
            probes,
            classes,
            out,
            size,
            seed,
            captures,
        } => job.render(probes, classes, out, (*size, *seed, *captures)),
    }
}

impl Context<'_> {
    /// Fit, publish and activate by policy.
    fn train(&self, request: &JobRequest) -> Result<JobResult, Failure> {
        let JobRequest::Train {
            name,
            data: p,
            activate,
            classes,
            cross_validate,
            estimator_table,
            estimator_classes,
            estimator_features,
            no_white_references_only,
        } = request
        else {
            return Err(JobError::WrongKind("train").into());
        };
        let (data, observer) = (self.data, self.observer);
        let spec = spec_of(p)?;
        let classes = match classes {
            Some(c) => Some(load_classes(&data.existing("classes", c)?)?),
            None => None,
        };
        let config = train_config(p, estimator_features.as_deref())?;
        let (table, label, manifest) = load_table(p, config, data, self.limits, observer)?;
        let options = TrainOptions {
            name: name.clone(),
            spec,
            seed: p.options.seed,
            cross_validate: *cross_validate,
            classes,
            // Recorded only when this job extracted the features itself.
            preprocessing: match p.dataset {
                Some(_) => p.extraction.preprocessing,
                None => Preprocessing::default(),
            },
            images: manifest,
            decode: DecodeOptions {
                encoding: None,
                limits: *self.limits,
                colour: false,
            },
            estimator: estimator_data(
                p,
                (estimator_table, estimator_classes, estimator_features),
                &table.names,
                data,
            )?,
            no_white_references_only: *no_white_references_only,
        };
        let mut trained = train::train_with(&table, &label, &options, observer)?;
        if observer.cancelled() {
            return Err(Failure::Cancelled);
        }
        observer.stage("publish");
        let published = self.publish(name, &mut trained, *activate)?;
        let result = JobResult {
            model: Some(ModelRef {
                name: name.clone(),
                version: published.version,
            }),
            cv: trained.report.as_ref().map(|r| r.summary.clone()),
            estimate: trained.estimate.take(),
            images: Some(table.samples.len()),
            ..JobResult::default()
        };
        self.activate(name, &published, result)
    }

    /// Publish under the registry's lock, against the version served (else the registry's).
    fn publish(
        &self,
        name: &str,
        trained: &mut train::Trained,
        activate: Activate,
    ) -> Result<Published, Failure> {
        let _serial = self.models.lock_registry();
        let registry = self.models.registry();
        let served = self.models.active(name).map(|m| Current {
            version: m.version(),
            accuracy: m.file().training.cv.as_ref().map(|cv| cv.accuracy),
        });
        let current = served.or_else(|| Current::in_registry(registry, name));
        let published = trained.publish_by(registry, current, activate)?;
        if let Some(e) = &published.pin_failed {
            tracing::warn!(model = %name, error = %e, "could not pin the active version");
        }
        Ok(published)
    }

    /// Activate a published version when its policy says so; `result` records what happened.
    fn activate(
        &self,
        name: &str,
        published: &Published,
        mut result: JobResult,
    ) -> Result<JobResult, Failure> {
        let reason = published.decision.to_string();
        result.activated = Some(false);
        if !published.decision.activates() {
            result.activation = Some(reason);
            return Ok(result);
        }
        self.observer.stage("activate");
        match self.models.activate(name, published.version) {
            Ok(done) => {
                result.activated = Some(true);
                result.activation = Some(match done.warning {
                    Some(w) => format!("{reason}; {w}"),
                    None => reason,
                });
                Ok(result)
            }
            Err(cause) => {
                result.activation = Some(cause.to_string());
                let e = JobError::Activation {
                    version: published.version,
                    cause,
                };
                Err(Failure::Partial(Box::new(e), Box::new(result)))
            }
        }
    }

    /// The Ward-parameter estimate, leave-one-illumination-out.
    fn cross_validate_estimate(
        &self,
        p: &LearnParams,
        classes: &str,
    ) -> Result<JobResult, Failure> {
        let spec = spec_of(p)?;
        let materials = load_classes(&self.data.existing("ward_classes", classes)?)?;
        let config = config_of(p)?;
        let (table, label, _) = load_table(p, config, self.data, self.limits, self.observer)?;
        let ds = Dataset::from_table(&table)?;
        self.observer.stage("cross_validate");
        let (gamma, seed) = (p.options.gamma, p.options.seed);
        let regression = (p.estimator).regression_spec(&spec.features, &ds.names, gamma, seed)?;
        let fit = estimate::fit_observed(
            &ds,
            &label,
            &materials,
            &spec.features,
            &regression,
            self.observer,
        )?;
        Ok(JobResult {
            estimate: Some(fit.report),
            images: Some(table.samples.len()),
            ..JobResult::default()
        })
    }

    /// The classifier, leave-one-illumination-out.
    fn cross_validate(&self, p: &LearnParams) -> Result<JobResult, Failure> {
        let spec = spec_of(p)?;
        let config = config_of(p)?;
        let (table, _, _) = load_table(p, config, self.data, self.limits, self.observer)?;
        let ds = Dataset::from_table(&table)?;
        self.observer.stage("cross_validate");
        let seed = p.options.seed;
        let report = classify::cross_validate_with(&ds, &spec, seed, self.observer)?;
        Ok(JobResult {
            cv: Some(report.summary),
            images: Some(table.samples.len()),
            ..JobResult::default()
        })
    }

    /// Ward spheres under the probes, into a dataset with a manifest.
    fn render(
        &self,
        probes: &str,
        classes: &str,
        out: &str,
        (size, seed, captures): (usize, u64, usize),
    ) -> Result<JobResult, Failure> {
        let data = self.data;
        let probes_path = data.existing("probes", probes)?;
        let classes_path = data.existing("classes", classes)?;
        let out_path = data.output_dir("out", out)?;
        let probe_files = batch::probe_list(&probes_path)?;
        for probe in &probe_files {
            data.check_resolved("probe", probe)?;
        }
        let (quality, augment) = render_options(captures);
        let spec = BatchSpec {
            probes: probe_files,
            classes: load_classes(&classes_path)?,
            out: out_path,
            size,
            seed,
            quality,
            augment,
            shard: None,
        };
        self.observer.stage("render");
        let summary = batch::render_dataset_with(&spec, self.observer)?;
        Ok(JobResult {
            render: Some(RenderResult {
                manifest: data.display(&summary.manifest),
                images: summary.images,
                rendered: summary.rendered,
                skipped: summary.skipped,
            }),
            ..JobResult::default()
        })
    }
}
