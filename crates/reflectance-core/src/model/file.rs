//! The model file (docs/design.md §4): everything needed to classify — the feature-extraction
//! configuration, the feature set, the fitted classifier and its calibration — with the
//! classes, training provenance, a self-test vector and a SHA-256 of the content.
//!
//! The checksum covers the canonical JSON of the document without its `sha256` field
//! (object keys sorted, numbers in shortest round-trip form), so it does not depend on
//! formatting. Loading verifies schema, checksum, feature configuration and names, the
//! classifier's shapes, and the self-test; a file failing any of these is refused.

use crate::classify::Classifier;
use crate::classify::conformal::PredictionSets;
use crate::classify::domain::DomainCheck;
use crate::estimate::WardRegressor;
use crate::features::{ConfigError, FeatureConfig};
use crate::learn::LearnError;
use crate::material::{CaptureEnvelope, Ward};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};

/// The `schema` every model file states (docs/design.md §4).
pub const SCHEMA: &str = "reflectance.model";
/// The schema version this build reads and writes.
pub const SCHEMA_VERSION: u32 = 1;
/// The self-test must reproduce the stored probabilities to this precision.
const SELF_TEST_TOLERANCE: f64 = 1e-9;

/// A class the model knows: its name, and its Ward parameters when rendered from them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassInfo {
    /// The class's name, as answers spell the label.
    pub name: String,
    /// The Ward parameters the class was rendered with, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ward: Option<Ward>,
}

impl ClassInfo {
    /// The class in words: from its Ward parameters when known, else its name.
    pub fn description(&self) -> String {
        match &self.ward {
            Some(ward) => ward.describe(),
            None => self.name.replace('_', " "),
        }
    }
}

/// How the model's features are extracted and which of them the classifier reads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureSpec {
    /// The extraction constants (unwrap grid, levels).
    pub config: FeatureConfig,
    /// The feature set as specified (`hand6`, `auto6`, `pca6`, a list…).
    pub set: String,
    /// The classifier's inputs.
    pub selected: Vec<String>,
}

/// The part of a leave-one-illumination-out cross-validation summary a model file keeps
/// (and the service shows with the version).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StoredCv {
    /// Fraction of held-out images classified correctly, in [0, 1].
    pub accuracy: f64,
    /// Number of held-out images.
    pub n: usize,
    /// Mean negative log-probability of the true class (nats).
    pub log_loss: f64,
    /// Expected calibration error, in [0, 1].
    pub ece: f64,
    /// Each class's held-out images and accuracy, in class order.
    pub per_class: Vec<crate::classify::cv::ClassScore>,
    /// `confusion[truth][predicted]`, class order.
    pub confusion: Vec<Vec<usize>>,
}

impl From<&crate::classify::CvSummary> for StoredCv {
    fn from(cv: &crate::classify::CvSummary) -> Self {
        StoredCv {
            accuracy: cv.accuracy,
            n: cv.n,
            log_loss: cv.log_loss,
            ece: cv.ece,
            per_class: cv.per_class.clone(),
            confusion: cv.confusion.clone(),
        }
    }
}

/// Where a model came from: its training data, options and cross-validation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// Where the training data came from (manifest or table path, as given).
    pub dataset: String,
    /// SHA-256 of the training feature table (CSV as written by `features --out`).
    pub dataset_sha256: String,
    /// Number of training images (augmented views included).
    pub images: usize,
    /// Number of distinct illuminations (an augmented `probe@…` counts as its probe).
    pub illuminations: usize,
    /// The seed of every random choice of training (splits, grid, augmentation).
    pub seed: u64,
    /// Training options as given (classifier, C, γ, grid, augmentation handling).
    pub options: Value,
    /// The leave-one-illumination-out cross-validation, when training ran one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cv: Option<StoredCv>,
}

/// A training image in the classifier's (standardized) input space, for explanations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Exemplar {
    /// The image's path, as its manifest gives it.
    pub path: String,
    /// Its class.
    pub class: String,
    /// Its illumination (light probe).
    pub illumination: String,
    /// The classifier's standardized inputs for it.
    pub inputs: Vec<f64>,
    /// A small picture of the training image (a PNG data URL), when training could read it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thumbnail: Option<String>,
}

/// A feature vector and the probabilities the model must give it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SelfTest {
    /// A feature row in canonical order.
    pub features: Vec<f64>,
    /// The probabilities the classifier must give it, in class order.
    pub probabilities: Vec<f64>,
    /// What the classifier without white gives it, when the model has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_white_probabilities: Option<Vec<f64>>,
    /// What the classifier for objects gives it, when the model has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objects_probabilities: Option<Vec<f64>>,
}

/// A classifier a model answers some requests with instead of its own, with prediction
/// sets and a domain check of its own: the one without white (it reads only features that do
/// not change when the image is multiplied by a constant, docs/design.md §3 "Without white")
/// and the one for objects (fitted on objects' equivalent spheres as well as spheres,
/// docs/design.md §8).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoredHead {
    /// The classifier.
    pub classifier: Classifier,
    /// Its prediction sets, calibrated on held-out illuminations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction_sets: Option<PredictionSets>,
    /// Its domain check.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub domain: Option<DomainCheck>,
    /// What it was trained on, when not the model's own data (the classifier for objects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training: Option<Provenance>,
}

/// A classifier with what it knows of its own reliability: the model's own, the one
/// without white or the one for objects.
#[derive(Clone, Copy, Debug)]
pub struct Head<'a> {
    /// The classifier.
    pub classifier: &'a Classifier,
    /// Its prediction sets, when calibrated.
    pub prediction_sets: Option<&'a PredictionSets>,
    /// Its domain check, when calibrated.
    pub domain: Option<&'a DomainCheck>,
    /// The classifier without white.
    pub without_white: bool,
    /// The classifier for objects.
    pub objects: bool,
}

impl<'a> Head<'a> {
    /// Which classifier it is: `with_white`, `without_white` or `objects`.
    pub fn name(&self) -> &'static str {
        match (self.without_white, self.objects) {
            (true, _) => "without_white",
            (_, true) => "objects",
            _ => "with_white",
        }
    }

    fn stored(head: &'a StoredHead, without_white: bool, objects: bool) -> Head<'a> {
        Head {
            classifier: &head.classifier,
            prediction_sets: head.prediction_sets.as_ref(),
            domain: head.domain.as_ref(),
            without_white,
            objects,
        }
    }
}

/// What decides which classifier answers a request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Request {
    /// The request gave a white reference.
    pub white_given: bool,
    /// The request gave the object's normals (an object read as its equivalent sphere).
    pub object: bool,
}

/// A trained model version as stored (docs/design.md §4): checksummed JSON, verified on
/// load by schema, checksum and self-test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// Always [`SCHEMA`].
    pub schema: String,
    /// [`SCHEMA_VERSION`] when written; loading refuses any other.
    pub schema_version: u32,
    /// The model's name in its registry, e.g. `ward11`.
    pub name: String,
    /// Its version in the registry (1, 2, …).
    pub version: u32,
    /// RFC 3339, UTC.
    pub created: String,
    /// The classes, in no particular order (the classifier holds the class order).
    pub classes: Vec<ClassInfo>,
    /// The extraction configuration and the classifier's inputs.
    pub features: FeatureSpec,
    /// The classifier answering with a white reference.
    pub classifier: Classifier,
    /// The training data and options.
    pub training: Provenance,
    /// A feature row and its probabilities, checked on every load.
    pub self_test: SelfTest,
    /// The original (non-augmented) training images, for `explain`.
    #[serde(default)]
    pub exemplars: Vec<Exemplar>,
    /// The captures the model was trained for, when its training data had `@cap` views:
    /// serving warns about inputs outside them. Absent in older model files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture: Option<CaptureEnvelope>,
    /// The Ward-parameter estimator, when trained with one (`train --estimator-table`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimator: Option<WardRegressor>,
    /// Prediction sets for the classifier, calibrated on held-out illuminations. Absent in
    /// older model files (answers then carry no set, and say so).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction_sets: Option<PredictionSets>,
    /// The classifier's domain check. Absent in older model files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub domain: Option<DomainCheck>,
    /// The classifier used without a white reference. Absent in older model files and in
    /// models without the log-domain features.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_white: Option<StoredHead>,
    /// The classifier used for objects located by their normals, with a white reference
    /// (`train-objects`). Absent: objects are answered as spheres are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objects: Option<StoredHead>,
    /// SHA-256 (hex) of the canonical JSON of the document without this field.
    #[serde(default)]
    pub sha256: String,
}

/// Why a model file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file is not JSON of a model (the parser's message).
    #[error("not a model file: {0}")]
    Json(String),
    /// Another schema or schema version than this build reads.
    #[error(
        "unsupported model schema {found:?} version {version} (expected {SCHEMA:?} version {SCHEMA_VERSION})"
    )]
    Schema {
        /// The file's `schema`.
        found: String,
        /// The file's `schema_version`.
        version: u32,
    },
    /// The stored checksum does not match the content.
    #[error(
        "checksum mismatch: the file says {stored}, its content hashes to {actual} (corrupt or edited)"
    )]
    Checksum {
        /// The file's `sha256`.
        stored: String,
        /// SHA-256 of its canonical content.
        actual: String,
    },
    /// The feature configuration is invalid.
    #[error("invalid feature configuration: {0}")]
    Config(#[from] ConfigError),
    /// Parts of the file disagree (class lists, feature counts, indices).
    #[error("inconsistent model: {0}")]
    Inconsistent(String),
    /// The classifier (or estimator) is invalid.
    #[error("invalid classifier: {0}")]
    Classifier(#[from] LearnError),
    /// The self-test's probabilities differ from the stored ones by this much.
    #[error("self-test failed: probabilities differ from the stored ones by {0:e}")]
    SelfTest(f64),
}

/// Canonical JSON: object keys sorted, no whitespace, serde_json's number formatting.
fn canonical(value: &Value, out: &mut Vec<u8>) {
    match value {
        Value::Object(map) => {
            let mut keys: Vec<&String> = map.keys().collect();
            keys.sort();
            out.push(b'{');
            for (i, key) in keys.into_iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                out.extend(serde_json::to_vec(key).unwrap_or_default());
                out.push(b':');
                canonical(&map[key], out);
            }
            out.push(b'}');
        }
        Value::Array(items) => {
            out.push(b'[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                canonical(item, out);
            }
            out.push(b']');
        }
        scalar => out.extend(serde_json::to_vec(scalar).unwrap_or_default()),
    }
}

/// SHA-256 (hex) of a document without its `sha256` field: the value a model file's
/// `sha256` must hold (public for tools that edit model files, e.g. the fuzz targets).
pub fn checksum(mut document: Value) -> String {
    if let Value::Object(map) = &mut document {
        map.remove("sha256");
    }
    digest(&document)
}

/// SHA-256 (hex) of a document's canonical form.
fn digest(document: &Value) -> String {
    let mut bytes = Vec::new();
    canonical(document, &mut bytes);
    hex(&Sha256::digest(&bytes))
}

/// Lower-case hex of bytes, two digits a byte.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 (hex) of arbitrary bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

impl ModelFile {
    /// Serialize with a fresh checksum.
    pub fn to_json(&mut self) -> Result<Vec<u8>, ModelError> {
        self.sha256.clear();
        let value = serde_json::to_value(&*self).map_err(|e| ModelError::Json(e.to_string()))?;
        self.sha256 = checksum(value);
        // Compact: most of a model is long arrays of numbers, which pretty-printing puts one
        // per indented line (`jq . model.json` shows it laid out).
        serde_json::to_vec(self).map_err(|e| ModelError::Json(e.to_string()))
    }

    /// Parse and verify a model file.
    pub fn from_json(bytes: &[u8]) -> Result<ModelFile, ModelError> {
        let value: Value =
            serde_json::from_slice(bytes).map_err(|e| ModelError::Json(e.to_string()))?;
        let schema = value
            .get("schema")
            .and_then(Value::as_str)
            .unwrap_or_default()
            .to_string();
        let version = value
            .get("schema_version")
            .and_then(Value::as_u64)
            .unwrap_or(0) as u32;
        if schema != SCHEMA || version != SCHEMA_VERSION {
            return Err(ModelError::Schema {
                found: schema,
                version,
            });
        }
        // The checksum covers the document without its own field: take the field out for it
        // and put it back, rather than hash a copy of the whole model.
        let mut value = value;
        let field = match &mut value {
            Value::Object(map) => map.remove("sha256"),
            _ => None,
        };
        let stored = field
            .as_ref()
            .and_then(Value::as_str)
            .unwrap_or_default()
            .to_string();
        let actual = digest(&value);
        if stored != actual {
            return Err(ModelError::Checksum { stored, actual });
        }
        if let (Value::Object(map), Some(field)) = (&mut value, field) {
            map.insert("sha256".into(), field);
        }
        let model: ModelFile =
            serde_json::from_value(value).map_err(|e| ModelError::Json(e.to_string()))?;
        model.verify()?;
        Ok(model)
    }

    /// Consistency of the parts, then the self-test.
    pub fn verify(&self) -> Result<(), ModelError> {
        self.features.config.validate()?;
        let names = self.features.config.names();
        let inconsistent = |what: String| Err(ModelError::Inconsistent(what));
        if self.classifier.input_names != names {
            return inconsistent(
                "the classifier's inputs are not this configuration's features".into(),
            );
        }
        if self.classifier.selected != self.features.selected
            || self.classifier.feature_set != self.features.set
        {
            return inconsistent(
                "the feature set differs between the header and the classifier".into(),
            );
        }
        let class_names: Vec<&str> = self.classes.iter().map(|c| c.name.as_str()).collect();
        if self
            .classifier
            .classes
            .iter()
            .map(String::as_str)
            .ne(class_names)
        {
            return inconsistent(
                "the class list differs between the header and the classifier".into(),
            );
        }
        if self.name.is_empty() || self.version == 0 {
            return inconsistent("a model needs a name and a version ≥ 1".into());
        }
        self.classifier.validate()?;
        let row_len = names.len();
        if let Some(sets) = &self.prediction_sets {
            sets.validate().map_err(|e| ModelError::Inconsistent(e.0))?;
        }
        if let Some(domain) = &self.domain {
            domain
                .validate(self.classifier.dim(), row_len)
                .map_err(|e| ModelError::Inconsistent(e.0))?;
        }
        for (head, what) in [
            (&self.no_white, "the classifier without white"),
            (&self.objects, "the classifier for objects"),
        ] {
            let Some(head) = head else { continue };
            let c = &head.classifier;
            c.validate()?;
            if c.input_names != names || c.classes != self.classifier.classes {
                return inconsistent(format!("{what} has other inputs or classes"));
            }
            if let Some(sets) = &head.prediction_sets {
                sets.validate().map_err(|e| ModelError::Inconsistent(e.0))?;
            }
            if let Some(domain) = &head.domain {
                domain
                    .validate(c.dim(), row_len)
                    .map_err(|e| ModelError::Inconsistent(e.0))?;
            }
        }
        if let Some(estimator) = &self.estimator {
            estimator
                .validate(&names)
                .map_err(|e| ModelError::Inconsistent(e.0))?;
        }
        let dim = self.classifier.selected.len();
        if let Some(bad) = self
            .exemplars
            .iter()
            .find(|e| e.inputs.len() != dim || e.inputs.iter().any(|v| !v.is_finite()))
        {
            return inconsistent(format!(
                "exemplar {} does not match the classifier's {dim} inputs",
                bad.path
            ));
        }
        self.self_test()
    }

    /// Re-classify the stored feature vector and compare with the stored probabilities.
    /// The `k` training images nearest to a full feature row (in the classifier's
    /// standardized input space), nearest first.
    pub fn nearest(&self, row: &[f64], k: usize) -> Result<Vec<(&Exemplar, f64)>, ModelError> {
        let z = self.classifier.transform(row)?;
        let mut scored: Vec<(&Exemplar, f64)> = self
            .exemplars
            .iter()
            .map(|e| {
                (
                    e,
                    e.inputs
                        .iter()
                        .zip(&z)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        .sqrt(),
                )
            })
            .collect();
        scored.sort_by(|a, b| a.1.total_cmp(&b.1));
        scored.truncate(k);
        Ok(scored)
    }

    /// Check that the classifiers give the self-test's features their stored probabilities
    /// (to 1e-9).
    pub fn self_test(&self) -> Result<(), ModelError> {
        let features = &self.self_test.features;
        let mut pairs = vec![(
            self.classifier.predict_proba(features)?,
            Some(&self.self_test.probabilities),
        )];
        for (head, stored) in [
            (&self.no_white, &self.self_test.no_white_probabilities),
            (&self.objects, &self.self_test.objects_probabilities),
        ] {
            if let Some(head) = head {
                pairs.push((head.classifier.predict_proba(features)?, stored.as_ref()));
            }
        }
        for (got, stored) in pairs {
            let Some(stored) = stored.filter(|s| s.len() == got.len()) else {
                return Err(ModelError::SelfTest(f64::INFINITY));
            };
            let worst = got
                .iter()
                .zip(stored)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            if worst.is_nan() || worst > SELF_TEST_TOLERANCE {
                return Err(ModelError::SelfTest(worst));
            }
        }
        Ok(())
    }

    /// The classifier to answer a request with: without a white reference the one without
    /// white, for an object with one the one for objects, when the model has them; else
    /// its own.
    pub fn head(&self, request: Request) -> Head<'_> {
        match (&self.no_white, &self.objects, request.white_given) {
            (Some(n), _, false) => Head::stored(n, true, false),
            (_, Some(o), true) if request.object => Head::stored(o, false, true),
            _ => Head {
                classifier: &self.classifier,
                prediction_sets: self.prediction_sets.as_ref(),
                domain: self.domain.as_ref(),
                without_white: false,
                objects: false,
            },
        }
    }

    /// The extra classifiers the model carries (without white, for objects).
    pub fn stored_heads(&self) -> impl Iterator<Item = &StoredHead> {
        self.no_white.iter().chain(&self.objects)
    }

    /// The Ward parameters of the class named `class`, when the model knows them.
    pub fn ward_of(&self, class: &str) -> Option<Ward> {
        self.classes.iter().find(|c| c.name == class)?.ward
    }
}

/// Current time as RFC 3339 UTC (`2026-11-21T12:00:00Z`), or `SOURCE_DATE_EPOCH` when set
/// (reproducible builds: models rebuilt from the same data are then byte-identical).
pub fn now_rfc3339() -> String {
    let pinned = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok());
    let secs = pinned.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    });
    rfc3339(secs)
}

/// Seconds since the Unix epoch as RFC 3339 UTC (civil-from-days, H. Hinnant).
pub fn rfc3339(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_class_is_described_by_its_parameters_else_by_its_name() {
        let ward = Ward {
            rho_d: 0.1,
            rho_s: 0.0,
            alpha: 0.0,
        };
        let rendered = ClassInfo {
            name: "A".into(),
            ward: Some(ward),
        };
        assert_eq!(rendered.description(), "black matte");
        let named = ClassInfo {
            name: "white_shiny".into(),
            ward: None,
        };
        assert_eq!(named.description(), "white shiny");
    }

    #[test]
    fn rfc3339_known_dates() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00Z");
        assert_eq!(rfc3339(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(rfc3339(1_795_262_400), "2026-11-21T12:00:00Z");
    }

    #[test]
    fn canonical_json_sorts_keys_and_ignores_whitespace() {
        let a: Value =
            serde_json::from_str(r#"{"b": [1, 2.5, {"y": 1, "x": null}], "a": "t"}"#).unwrap();
        let b: Value = serde_json::from_str(r#"{"a":"t","b":[1,2.5,{"x":null,"y":1}]}"#).unwrap();
        let (mut ca, mut cb) = (Vec::new(), Vec::new());
        canonical(&a, &mut ca);
        canonical(&b, &mut cb);
        assert_eq!(ca, cb);
        assert_eq!(
            String::from_utf8(ca).unwrap(),
            r#"{"a":"t","b":[1,2.5,{"x":null,"y":1}]}"#
        );
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
