//! From a feature table to a verified model file: fit the pipeline, cross-validate it,
//! and record provenance and a self-test vector.

use crate::dataset::FeatureTable;
use crate::features::{Extensions, FeatureConfig};
use crate::learn::{self, CvReport, Dataset, LearnError, TrainSpec};
use crate::model::{
    self, ClassInfo, CvSummary, Exemplar, FeatureSpec, ModelError, ModelFile, Provenance, SelfTest,
    Ward,
};
use crate::progress::{Observer, Silent};
use crate::render::ward::Material;
use serde_json::json;

#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error(transparent)]
    Learn(#[from] LearnError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(
        "the feature table's columns are not the canonical features of the extraction configuration"
    )]
    Columns,
}

pub struct TrainOptions {
    pub name: String,
    pub spec: TrainSpec,
    pub seed: u64,
    /// Run leave-one-illumination-out CV and store its summary (and return the report).
    pub cross_validate: bool,
    /// Ward parameters of the classes, when known.
    pub classes: Option<Vec<Material>>,
    /// The radius the training spheres were extracted at, recorded so that serving
    /// reduces larger spheres to it (the table must have been extracted with it).
    pub working_radius: Option<f64>,
}

pub struct Trained {
    pub model: ModelFile,
    pub report: Option<CvReport>,
}

/// Fit a model on `table`; `dataset` names the data (a path as given).
pub fn train(
    table: &FeatureTable,
    dataset: &str,
    options: &TrainOptions,
) -> Result<Trained, TrainError> {
    train_with(table, dataset, options, &Silent)
}

/// [`train`] with stages (`"fit"`, `"cross_validate"`), fold progress and cooperative
/// cancellation (before the fit and between folds: [`LearnError::Cancelled`]).
pub fn train_with(
    table: &FeatureTable,
    dataset: &str,
    options: &TrainOptions,
    observer: &dyn Observer,
) -> Result<Trained, TrainError> {
    // The table decides: 117 columns, more with extensions.
    let extensions = Extensions::of_names(table.names.iter().map(String::as_str));
    let config = FeatureConfig::extended(extensions, options.working_radius);
    if table.names != config.names() {
        return Err(TrainError::Columns);
    }
    let ds = Dataset::from_table(table)?;
    if observer.cancelled() {
        return Err(LearnError::Cancelled.into());
    }
    observer.stage("fit");
    observer.progress(0, 1);
    let classifier = learn::fit(&ds, &options.spec, options.seed)?;
    observer.progress(1, 1);
    let report = if options.cross_validate {
        observer.stage("cross_validate");
        Some(learn::cross_validate_with(
            &ds,
            &options.spec,
            options.seed,
            observer,
        )?)
    } else {
        None
    };
    // Self-test: the first original (non-augmented) training image.
    let probe = ds.augmented.iter().position(|a| !a).unwrap_or(0);
    let features = ds.x.row(probe).to_vec();
    let probabilities = classifier.predict_proba(&features)?;
    let ward_of = |name: &str| {
        options
            .classes
            .as_ref()?
            .iter()
            .find(|m| m.name == name)
            .map(|m| Ward {
                rho_d: m.rho_d,
                rho_s: m.rho_s,
                alpha: m.alpha,
            })
    };
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
        });
    }
    let spec = &options.spec;
    let model = ModelFile {
        schema: model::SCHEMA.into(),
        schema_version: model::SCHEMA_VERSION,
        name: options.name.clone(),
        version: 1,
        created: model::now_rfc3339(),
        classes: classifier
            .classes
            .iter()
            .map(|name| ClassInfo {
                name: name.clone(),
                ward: ward_of(name),
            })
            .collect(),
        features: FeatureSpec {
            config,
            set: classifier.feature_set.clone(),
            selected: classifier.selected.clone(),
        },
        training: Provenance {
            dataset: dataset.to_string(),
            dataset_sha256: model::sha256_hex(&table.to_csv()),
            images: table.samples.len(),
            illuminations: ds.group_names.len(),
            seed: options.seed,
            options: json!({
                "features": spec.features.to_string(),
                "classifier": spec.classifier.to_string(),
                "c": spec.c,
                "gamma": spec.gamma,
                "grid": spec.grid,
            }),
            cv: report.as_ref().map(|r| CvSummary {
                accuracy: r.accuracy,
                n: r.n,
                log_loss: r.log_loss,
                ece: r.ece,
                per_class: r.per_class.clone(),
                confusion: r.confusion.clone(),
            }),
        },
        classifier,
        self_test: SelfTest {
            features,
            probabilities,
        },
        exemplars,
        sha256: String::new(),
    };
    model.verify()?;
    Ok(Trained { model, report })
}
