//! Estimating the Ward parameters (ρd, ρs, α) themselves, with intervals, rather than naming
//! a class.
//!
//! The regressor (gradient-boosted trees, [`boost`], or the kernel ridge of
//! [`regress`]) predicts four outputs in well-conditioned spaces: the total reflectance
//! t = ρd + ρs, the specular fraction ρs / t, a mirror score (+1 for α = 0, −1 otherwise) and
//! log10 α (mirrors placed at [`MIRROR_LOG_ALPHA`], below the glossy range). When the
//! cosine-weighted centre [`TOTAL_ANCHOR`] is among the inputs, the total is predicted as
//! log10 t minus it: that measurement is already t under most light (docs/design.md §8), and
//! the regression only corrects it where the light or the camera make it err. An estimate
//! turns the outputs back into (ρd, ρs, α). Its 90 % intervals are split-conformal:
//! their half-widths are quantiles of the leave-one-illumination-out errors of ρd, ρs and
//! log10 α, so they hold for illuminations the model never saw.

pub mod boost;
mod fit;
pub mod regress;

pub use fit::{
    Errors, EstimateDetails, EstimateReport, Fit, HeldOut, IlluminationErrors, fit, fit_observed,
};

use crate::learn::Inconsistent;

use crate::learn::error::LearnError;
use crate::learn::feature_set::FeatureSet;
use crate::learn::matrix::Dataset;
use crate::learn::scaler::Scaler;
use crate::material::{Material, Ward};
use crate::util::progress::{Observer, Silent};
use boost::{BoostSpec, Boosted};
use ndarray::{Array2, Axis};
use regress::{Ridge, RidgeSpec};
use serde::{Deserialize, Serialize};

/// log10 α of a mirror on the regression's axis: half the smallest glossy α (0.005).
pub const MIRROR_LOG_ALPHA: f64 = -2.602_059_991_327_962;
/// The narrowest and broadest α an estimate reports (the design's glossy range).
pub const ALPHA_RANGE: (f64, f64) = (0.005, 0.2);
/// The coverage of the intervals.
pub const COVERAGE: f64 = 0.9;
/// Random Fourier features of the regression, by default.
pub const DEFAULT_RIDGE_FEATURES: usize = 1500;
/// Its ridge penalty λ, by default.
pub const DEFAULT_RIDGE_LAMBDA: f64 = 1e-2;
/// The feature set of the shipped estimators and of `report`'s estimate.
pub const SHIPPED_FEATURES: &str = "estimator";
/// The input the total reflectance is predicted relative to, when present: the centre's
/// cosine-weighted mean over white, log10 (features::families::centre).
pub const TOTAL_ANCHOR: &str = "ctr.cos";
/// The smallest total reflectance the anchored output takes the logarithm of.
const TOTAL_FLOOR: f64 = 1e-4;

/// Which regression an estimator uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Gradient-boosted trees (with `BoostSpec::default`).
    #[default]
    Boost,
    /// Kernel ridge on random Fourier features (the first estimators').
    Ridge,
}

/// How a Ward-parameter estimator regresses, as a user chooses it: one definition for the
/// command line (flattened into its arguments, feature `cli`) and the service's jobs (JSON
/// keys, feature `openapi` for the schema).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EstimatorOptions {
    /// The Ward-parameter regression: gradient-boosted trees, or the kernel ridge of the
    /// ridge options (the first estimators').
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Method::Boost))]
    pub regressor: Method,
    /// Random Fourier features of a ridge regression (≥ 1).
    #[serde(default = "default_ridge_features")]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_RIDGE_FEATURES))]
    pub ridge_features: usize,
    /// Ridge penalty λ of a ridge regression (> 0).
    #[serde(default = "default_ridge_lambda")]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_RIDGE_LAMBDA))]
    pub ridge_lambda: f64,
    /// RBF γ of a ridge regression (> 0; default: the classifier's γ, else 1 / number of
    /// inputs).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub ridge_gamma: Option<f64>,
}

fn default_ridge_features() -> usize {
    DEFAULT_RIDGE_FEATURES
}

fn default_ridge_lambda() -> f64 {
    DEFAULT_RIDGE_LAMBDA
}

impl Default for EstimatorOptions {
    fn default() -> Self {
        EstimatorOptions {
            regressor: Method::default(),
            ridge_features: DEFAULT_RIDGE_FEATURES,
            ridge_lambda: DEFAULT_RIDGE_LAMBDA,
            ridge_gamma: None,
        }
    }
}

impl EstimatorOptions {
    /// The keys of these options in JSON, sorted (for callers that refuse unknown keys).
    pub fn keys() -> Vec<String> {
        crate::util::json_keys::<Self>()
    }

    /// Whether the ridge's numbers are usable (checked whatever the regressor, so that a
    /// mistake is caught before a long run).
    pub fn check(&self) -> Result<(), LearnError> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if self.ridge_features == 0 {
            return Err(LearnError::InvalidParameter(
                "ridge_features must be at least 1".into(),
            ));
        }
        if !positive(self.ridge_lambda) {
            return Err(LearnError::InvalidParameter(format!(
                "ridge_lambda must be a finite number > 0, not {}",
                self.ridge_lambda
            )));
        }
        match self.ridge_gamma {
            Some(g) if !positive(g) => Err(LearnError::InvalidParameter(format!(
                "ridge_gamma must be a finite number > 0, not {g}"
            ))),
            _ => Ok(()),
        }
    }

    /// The regression of `features` over the table's columns `names` (a ridge's γ: the
    /// ridge's own, else `gamma`, else 1 / number of inputs).
    pub fn regression_spec(
        &self,
        features: &FeatureSet,
        names: &[String],
        gamma: Option<f64>,
        seed: u64,
    ) -> Result<RegressionSpec, LearnError> {
        self.check()?;
        let size = (self.ridge_features, self.ridge_lambda);
        regression_spec(
            self.regressor,
            features,
            names,
            size,
            self.ridge_gamma.or(gamma),
            seed,
        )
    }
}

/// How to fit an estimator's regression.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RegressionSpec {
    /// Gradient-boosted trees.
    Boost(BoostSpec),
    /// Kernel ridge regression on random Fourier features.
    Ridge(RidgeSpec),
}

/// A fitted regression (the model file's fields: `spec` and `ridge`, or `boost` and `trees`).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Regression {
    /// Gradient-boosted trees.
    Boost {
        /// How they were fitted.
        boost: BoostSpec,
        /// The fitted ensembles, one per output.
        trees: Boosted,
    },
    /// Kernel ridge regression on random Fourier features.
    Ridge {
        /// How it was fitted.
        spec: RidgeSpec,
        /// The fitted regression.
        ridge: Ridge,
    },
}

impl Regression {
    fn predict(&self, z: &[f64]) -> Vec<f64> {
        match self {
            Regression::Boost { trees, .. } => trees.predict(z),
            Regression::Ridge { ridge, .. } => ridge.predict(z),
        }
    }

    /// Whether its parts fit `inputs` inputs and four outputs, with finite numbers.
    fn is_consistent(&self, inputs: usize) -> bool {
        match self {
            Regression::Boost { trees, .. } => {
                trees.inputs == inputs && trees.outputs() == 4 && trees.is_consistent()
            }
            Regression::Ridge { ridge, .. } => {
                let features = ridge.map.phase.len();
                ridge.map.inputs == inputs
                    && ridge.map.omega.len() == features * inputs
                    && ridge.outputs == 4
                    && ridge.weights.len() == (features + 1) * 4
                    && ridge
                        .weights
                        .iter()
                        .chain(&ridge.map.omega)
                        .all(|v| v.is_finite())
            }
        }
    }
}

/// The regression `method` of `features` over the table's columns `names`: boosted trees
/// with their defaults, or the ridge of [`ridge_spec`].
pub fn regression_spec(
    method: Method,
    features: &FeatureSet,
    names: &[String],
    size: (usize, f64),
    gamma: Option<f64>,
    seed: u64,
) -> Result<RegressionSpec, LearnError> {
    Ok(match method {
        Method::Boost => RegressionSpec::Boost(BoostSpec::default()),
        Method::Ridge => RegressionSpec::Ridge(ridge_spec(features, names, size, gamma, seed)?),
    })
}

/// The regression of `features` over the table's columns `names`, with `count` random
/// Fourier features and penalty `lambda`; γ = `gamma`, else 1 / number of inputs.
pub fn ridge_spec(
    features: &FeatureSet,
    names: &[String],
    (count, lambda): (usize, f64),
    gamma: Option<f64>,
    seed: u64,
) -> Result<RidgeSpec, LearnError> {
    let inputs = features.resolve(names)?.map_or(names.len(), |i| i.len());
    Ok(RidgeSpec {
        features: count,
        gamma: gamma.unwrap_or(1.0 / inputs.max(1) as f64),
        lambda,
        seed,
    })
}

/// The regression targets of Ward parameters: [t, ρs / t, mirror ±1, log10 α].
pub fn targets(w: &Ward) -> [f64; 4] {
    let total = w.rho_d + w.rho_s;
    let fraction = if total > 0.0 { w.rho_s / total } else { 0.0 };
    let (mirror, log_alpha) = match w.alpha > 0.0 {
        true => (-1.0, w.alpha.log10()),
        false => (1.0, MIRROR_LOG_ALPHA),
    };
    [total, fraction, mirror, log_alpha]
}

/// The Ward parameters of a prediction of the four outputs, with its log10 α on the
/// regression's axis (between [`MIRROR_LOG_ALPHA`] and log10 of the broadest α, also for a
/// mirror).
pub fn parameters(prediction: &[f64]) -> (Ward, f64) {
    let total = prediction[0].clamp(0.0, 1.0);
    let rho_s = total * prediction[1].clamp(0.0, 1.0);
    let (lo, hi) = (ALPHA_RANGE.0.log10(), ALPHA_RANGE.1.log10());
    let log_alpha = prediction[3].clamp(MIRROR_LOG_ALPHA, hi);
    let alpha = match prediction[2] > 0.0 {
        true => 0.0,
        false => 10f64.powf(log_alpha.max(lo)),
    };
    let ward = Ward {
        rho_d: total - rho_s,
        rho_s,
        alpha,
    };
    (ward, log_alpha)
}

/// A parameter with its interval.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Interval {
    /// The estimate, between `low` and `high`.
    pub value: f64,
    /// The interval's lower end (clamped to the parameter's range).
    pub low: f64,
    /// The interval's upper end (clamped to the parameter's range).
    pub high: f64,
}

/// The Ward parameters estimated from one photograph, each with its 90 % interval (α = 0
/// is an ideal mirror).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct WardEstimate {
    /// Diffuse reflectance ρd, in [0, 1].
    pub rho_d: Interval,
    /// Specular reflectance ρs, in [0, 1].
    pub rho_s: Interval,
    /// Roughness α (0: an ideal mirror).
    pub alpha: Interval,
}

/// Why an answer without a white reference states no ρd and ρs.
pub const TOTAL_UNKNOWN: &str = "no white reference: the total reflectance ρd + ρs is unknown (the \
    photograph's exposure sets the sphere's brightness), so ρd and ρs are not stated; the \
    specular fraction ρs / (ρd + ρs) and α do not depend on it";

/// An estimate as an answer states it: ρd and ρs only when a white reference fixes the total
/// reflectance; the specular fraction and α always.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StatedEstimate {
    /// Absent without a white reference (see `unknown`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rho_d: Option<Interval>,
    /// Absent without a white reference (see `unknown`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rho_s: Option<Interval>,
    /// Roughness α (0: an ideal mirror).
    pub alpha: Interval,
    /// ρs / (ρd + ρs), 0 for a black surface; its interval holds every ratio the intervals
    /// of ρd and ρs allow.
    pub specular_fraction: Interval,
    /// Why ρd and ρs are absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unknown: Option<String>,
}

impl WardEstimate {
    /// The specular fraction ρs / (ρd + ρs), with the range of ratios the intervals allow.
    pub fn specular_fraction(&self) -> Interval {
        let ratio = |s: f64, d: f64, empty: f64| if s + d > 0.0 { s / (s + d) } else { empty };
        let (d, s) = (&self.rho_d, &self.rho_s);
        let low = ratio(s.low, d.high, 0.0);
        let high = ratio(s.high, d.low, 1.0);
        Interval {
            value: ratio(s.value, d.value, 0.0).clamp(low, high),
            low,
            high,
        }
    }

    /// The estimated parameters themselves, without their intervals.
    pub fn value(&self) -> Ward {
        Ward {
            rho_d: self.rho_d.value,
            rho_s: self.rho_s.value,
            alpha: self.alpha.value,
        }
    }

    /// The estimate with each interval widened to hold `materials`' parameters.
    pub fn holding(mut self, materials: impl IntoIterator<Item = Ward>) -> WardEstimate {
        let widen = |i: &mut Interval, v: f64| {
            i.low = i.low.min(v);
            i.high = i.high.max(v);
        };
        for w in materials {
            widen(&mut self.rho_d, w.rho_d);
            widen(&mut self.rho_s, w.rho_s);
            widen(&mut self.alpha, w.alpha);
        }
        self
    }

    /// What an answer states: everything with a white reference, else the fraction and α.
    pub fn stated(&self, white_given: bool) -> StatedEstimate {
        StatedEstimate {
            rho_d: white_given.then_some(self.rho_d),
            rho_s: white_given.then_some(self.rho_s),
            alpha: self.alpha,
            specular_fraction: self.specular_fraction(),
            unknown: (!white_given).then(|| TOTAL_UNKNOWN.to_string()),
        }
    }
}

/// Conformal half-widths at [`COVERAGE`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct HalfWidths {
    /// Of ρd (absolute).
    pub rho_d: f64,
    /// Of ρs (absolute).
    pub rho_s: f64,
    /// Of log10 α (decades).
    pub log10_alpha: f64,
}

/// A fitted estimator: the inputs it reads, their standardization, the regression, the
/// widths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "WardRegressorFields")]
pub struct WardRegressor {
    /// The feature names it reads, in its input order.
    pub inputs: Vec<String>,
    /// Their indices in the model's full feature row.
    pub input_indices: Vec<usize>,
    /// The standardization of its inputs.
    pub scaler: Scaler,
    /// The fitted regression.
    #[serde(flatten)]
    pub regression: Regression,
    /// Which input (of `inputs`) the total reflectance is predicted relative to
    /// ([`TOTAL_ANCHOR`]); none in estimators fitted before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total_anchor: Option<usize>,
    /// The intervals' half-widths at [`COVERAGE`].
    pub half_widths: HalfWidths,
    /// Its leave-one-illumination-out accuracy, on the data it was fitted to.
    pub cv: EstimateReport,
    /// The feature table it was fitted to (as given).
    pub dataset: String,
}

/// A model file's estimator as written. Its regression is read field by field: an untagged,
/// flattened enum would make serde buffer the whole ensemble once more while it tries each
/// variant (7 MB more at load for the shipped models).
#[derive(Deserialize)]
struct WardRegressorFields {
    inputs: Vec<String>,
    input_indices: Vec<usize>,
    scaler: Scaler,
    boost: Option<BoostSpec>,
    trees: Option<Boosted>,
    spec: Option<RidgeSpec>,
    ridge: Option<Ridge>,
    #[serde(default)]
    total_anchor: Option<usize>,
    half_widths: HalfWidths,
    cv: EstimateReport,
    dataset: String,
}

impl TryFrom<WardRegressorFields> for WardRegressor {
    type Error = Inconsistent;

    fn try_from(f: WardRegressorFields) -> Result<Self, Inconsistent> {
        let regression = match (f.boost, f.trees, f.spec, f.ridge) {
            (Some(boost), Some(trees), None, None) => Regression::Boost { boost, trees },
            (None, None, Some(spec), Some(ridge)) => Regression::Ridge { spec, ridge },
            _ => {
                return Err(Inconsistent(
                    "an estimator holds either boost and trees or spec and ridge".into(),
                ));
            }
        };
        Ok(WardRegressor {
            inputs: f.inputs,
            input_indices: f.input_indices,
            scaler: f.scaler,
            regression,
            total_anchor: f.total_anchor,
            half_widths: f.half_widths,
            cv: f.cv,
            dataset: f.dataset,
        })
    }
}

impl WardRegressor {
    /// Check the parts against each other and against the model's feature `names`.
    pub fn validate(&self, names: &[String]) -> Result<(), Inconsistent> {
        let d = self.input_indices.len();
        let consistent = self.inputs.len() == d
            && self.scaler.dim() == d
            && self.total_anchor.is_none_or(|k| k < d);
        if !consistent || !self.regression.is_consistent(d) {
            return Err(Inconsistent(
                "the estimator's parts do not fit together".into(),
            ));
        }
        let named = self
            .input_indices
            .iter()
            .zip(&self.inputs)
            .all(|(&i, name)| names.get(i) == Some(name));
        if !named {
            return Err(Inconsistent(
                "the estimator's inputs are not this configuration's features".into(),
            ));
        }
        let w = &self.half_widths;
        let widths = [w.rho_d, w.rho_s, w.log10_alpha];
        if widths
            .iter()
            .chain(&self.scaler.mean)
            .any(|v| !v.is_finite())
        {
            return Err(Inconsistent(
                "the estimator holds a number that is not finite".into(),
            ));
        }
        Ok(())
    }

    /// The four outputs (see [`targets`]) for a row of every extracted feature (canonical
    /// order).
    pub fn predict(&self, values: &[f64]) -> Vec<f64> {
        let mut z: Vec<f64> = self.input_indices.iter().map(|&i| values[i]).collect();
        let anchor = self.total_anchor.map(|k| z[k]);
        self.scaler.apply(&mut z);
        let mut outputs = self.regression.predict(&z);
        if let Some(anchor) = anchor {
            outputs[0] = 10f64.powf(outputs[0] + anchor);
        }
        outputs
    }

    /// The estimate from a row of every extracted feature (canonical order).
    pub fn estimate(&self, values: &[f64]) -> WardEstimate {
        estimate_of(&self.predict(values), &self.half_widths)
    }
}

fn interval(value: f64, half_width: f64, bounds: (f64, f64)) -> Interval {
    Interval {
        value,
        low: (value - half_width).max(bounds.0),
        high: (value + half_width).min(bounds.1),
    }
}

/// The estimate of a prediction, with intervals of the given half-widths.
pub fn estimate_of(prediction: &[f64], widths: &HalfWidths) -> WardEstimate {
    let (ward, log_alpha) = parameters(prediction);
    let log_high = 10f64.powf(log_alpha + widths.log10_alpha);
    let alpha = match ward.alpha > 0.0 {
        true => Interval {
            value: ward.alpha,
            low: 10f64.powf(log_alpha - widths.log10_alpha),
            high: log_high,
        },
        false => Interval {
            value: 0.0,
            low: 0.0,
            high: log_high,
        },
    };
    WardEstimate {
        rho_d: interval(ward.rho_d, widths.rho_d, (0.0, 1.0)),
        rho_s: interval(ward.rho_s, widths.rho_s, (0.0, 1.0)),
        alpha,
    }
}

/// log10 α on the regression's axis (a mirror at [`MIRROR_LOG_ALPHA`]).
fn log_alpha_of(alpha: f64) -> f64 {
    match alpha > 0.0 {
        true => alpha.log10(),
        false => MIRROR_LOG_ALPHA,
    }
}

/// The class (index into `classes`' parameters) nearest to an estimate, each parameter
/// measured in units of its interval half-width (ρd, ρs and log10 α), so that the parameters
/// the estimate knows well count most; none without classes.
pub fn nearest_class(
    estimate: &WardEstimate,
    widths: &HalfWidths,
    classes: &[Ward],
) -> Option<usize> {
    let unit = |w: f64| if w > 0.0 && w.is_finite() { w } else { 1.0 };
    let distance = |class: &Ward| {
        let d = (estimate.rho_d.value - class.rho_d) / unit(widths.rho_d);
        let s = (estimate.rho_s.value - class.rho_s) / unit(widths.rho_s);
        // A class without a specular part has no lobe, so no α to compare with.
        let a = match class.rho_s > 0.0 {
            true => {
                (log_alpha_of(estimate.alpha.value) - log_alpha_of(class.alpha))
                    / unit(widths.log10_alpha)
            }
            false => 0.0,
        };
        d * d + s * s + a * a
    };
    classes
        .iter()
        .map(distance)
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn within(value: f64, low: f64, high: f64) -> Interval {
        Interval { value, low, high }
    }

    #[test]
    fn the_specular_fraction_spans_every_ratio_the_intervals_allow() {
        let estimate = WardEstimate {
            rho_d: within(0.3, 0.2, 0.4),
            rho_s: within(0.1, 0.05, 0.2),
            alpha: within(0.01, 0.005, 0.02),
        };
        let f = estimate.specular_fraction();
        assert!((f.value - 0.25).abs() < 1e-12);
        assert!((f.low - 0.05 / 0.45).abs() < 1e-12 && (f.high - 0.2 / 0.4).abs() < 1e-12);
        let black = WardEstimate {
            rho_d: within(0.0, 0.0, 0.1),
            rho_s: within(0.0, 0.0, 0.1),
            ..estimate
        };
        let f = black.specular_fraction();
        assert_eq!((f.value, f.low, f.high), (0.0, 0.0, 1.0));
        let held = estimate.holding([ward(0.0, 0.75, 0.0)]);
        assert_eq!(
            (held.rho_d.low, held.rho_s.high, held.alpha.low),
            (0.0, 0.75, 0.0)
        );
        assert_eq!(
            held.rho_d.value, estimate.rho_d.value,
            "values stay the regression's"
        );
        let stated = estimate.stated(false);
        assert_eq!((stated.rho_d, stated.rho_s), (None, None));
        assert_eq!(stated.alpha, estimate.alpha);
        assert_eq!(stated.unknown.as_deref(), Some(TOTAL_UNKNOWN));
        let stated = estimate.stated(true);
        assert_eq!((stated.rho_d, stated.unknown), (Some(estimate.rho_d), None));
    }

    fn ward(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
        Ward {
            rho_d,
            rho_s,
            alpha,
        }
    }

    #[test]
    fn targets_and_parameters_round_trip() {
        for w in [
            ward(0.3, 0.2, 0.02),
            ward(0.0, 0.75, 0.0),
            ward(0.9, 0.0, 0.1),
        ] {
            let (back, _) = parameters(&targets(&w));
            assert!((back.rho_d - w.rho_d).abs() < 1e-12, "{w:?}");
            assert!((back.rho_s - w.rho_s).abs() < 1e-12, "{w:?}");
            assert!((back.alpha - w.alpha).abs() < 1e-12, "{w:?}");
        }
        // Out-of-range predictions land on valid parameters.
        let (w, _) = parameters(&[1.3, -0.2, -0.4, 0.5]);
        assert_eq!((w.rho_d, w.rho_s), (1.0, 0.0));
        assert!((w.alpha - 0.2).abs() < 1e-12);
        w.validate().unwrap();
    }

    /// Materials of the design under 6 illuminations, seen through features that are smooth
    /// functions of the parameters, disturbed per illumination and per row; `anchored`: the
    /// first is log10 of the total reflectance, named as [`TOTAL_ANCHOR`].
    fn dataset(materials: &[Material], anchored: bool) -> Dataset {
        use crate::dataset::{FeatureTable, Sample};
        let mut rng = crate::util::rng::Rng::new(5);
        let mut samples = Vec::new();
        for g in 0..6 {
            let shift: Vec<f64> = (0..5).map(|_| 0.05 * (rng.next_f64() - 0.5)).collect();
            for m in materials {
                let log_alpha = if m.ward.alpha > 0.0 {
                    m.ward.alpha.log10()
                } else {
                    -3.0
                };
                let total = m.ward.rho_d + m.ward.rho_s;
                let clean = [
                    if anchored { total.log10() } else { total },
                    m.ward.rho_s,
                    m.ward.rho_d,
                    log_alpha,
                    m.ward.rho_s * (-2.0 - log_alpha),
                ];
                let values = clean
                    .iter()
                    .zip(&shift)
                    .map(|(v, s)| v + s + 0.01 * (rng.next_f64() - 0.5))
                    .collect();
                samples.push(Sample {
                    path: format!("g{g}/{}.pfm", m.name),
                    class: m.name.clone(),
                    illumination: format!("g{g}"),
                    values,
                });
            }
        }
        let mut names: Vec<String> = (0..5).map(|j| format!("f{j}")).collect();
        if anchored {
            names[0] = TOTAL_ANCHOR.into();
        }
        let table = FeatureTable { names, samples };
        Dataset::from_table(&table).unwrap()
    }

    fn ridge() -> RegressionSpec {
        RegressionSpec::Ridge(RidgeSpec {
            features: 300,
            gamma: 0.2,
            lambda: 1e-2,
            seed: 1,
        })
    }

    fn boost() -> RegressionSpec {
        RegressionSpec::Boost(BoostSpec {
            trees: 150,
            depth: 3,
            min_leaf: 5,
            ..BoostSpec::default()
        })
    }

    #[test]
    fn estimates_held_out_illuminations_with_calibrated_intervals() {
        for spec in [ridge(), boost()] {
            estimates_with_calibrated_intervals(&spec);
        }
    }

    #[test]
    fn the_total_is_predicted_relative_to_the_anchor_when_it_is_an_input() {
        let design = crate::material::design::continuous(60, 2, &Default::default());
        for spec in [ridge(), boost()] {
            let plain = fit(
                &dataset(&design, false),
                "test",
                &design,
                &FeatureSet::All,
                &spec,
            );
            let ds = dataset(&design, true);
            let anchored = fit(&ds, "test", &design, &FeatureSet::All, &spec).unwrap();
            assert_eq!(plain.unwrap().regressor.total_anchor, None);
            assert_eq!(anchored.regressor.total_anchor, Some(0));
            assert!(
                anchored.report.errors.mae_total < 0.03,
                "{spec:?}: {:?}",
                anchored.report
            );
            // A row's estimate follows its anchor: a brighter centre, a larger total.
            let mut row = ds.x.row(7).to_vec();
            let before = anchored.regressor.predict(&row)[0];
            row[0] += 0.1;
            let after = anchored.regressor.predict(&row)[0];
            assert!(after > before, "{spec:?}: {before} → {after}");
            // The model file keeps the anchor (and one from before it existed reads as none).
            let json = serde_json::to_value(&anchored.regressor).unwrap();
            assert_eq!(json["total_anchor"], 0);
            let mut old = json.clone();
            old.as_object_mut().unwrap().remove("total_anchor");
            let read: WardRegressor = serde_json::from_value(old).unwrap();
            assert_eq!(read.total_anchor, None);
            let back: WardRegressor = serde_json::from_value(json.clone()).unwrap();
            assert_eq!(back, anchored.regressor);
            // Half a regression is no estimator.
            let mut half = json;
            for field in ["trees", "ridge"] {
                half.as_object_mut().unwrap().remove(field);
            }
            assert!(serde_json::from_value::<WardRegressor>(half).is_err());
        }
    }

    fn estimates_with_calibrated_intervals(spec: &RegressionSpec) {
        let design = crate::material::design::continuous(60, 2, &Default::default());
        let ds = dataset(&design, false);
        let Fit {
            regressor,
            report,
            details,
        } = fit(&ds, "test", &design, &FeatureSet::All, spec).unwrap();
        assert_eq!(report.errors.n, 360);
        // docs/accuracy.md reports the shipped estimator's total MAE at 0.028 and its log10 α
        // MAE at 0.151 on the originals of 80 materials under 70 probes (5 600 renders, an
        // hour to make): too large a setting for a unit test. These synthetic features are
        // easier (0.019 / 0.016 total, 0.015 / 0.013 log10 α measured for the ridge and the
        // trees), so the docs' figures bound them; ρs (docs 0.075) and mirror-or-not (docs
        // 91.2 %) are held tighter here.
        assert!(report.errors.mae_total <= 0.028, "{report:?}");
        assert!(report.errors.mae_rho_s < 0.05, "{report:?}");
        assert!(report.errors.mirror_accuracy > 0.95, "{report:?}");
        assert!(
            report.errors.mae_log10_alpha.unwrap() <= 0.151,
            "{report:?}"
        );
        for c in [
            report.errors.coverage_rho_d,
            report.errors.coverage_rho_s,
            report.errors.coverage_alpha,
        ] {
            assert!((0.8..=0.97).contains(&c), "{report:?}");
        }
        // The details add up to the report, and each row's intervals cover it as counted.
        assert_eq!((details.rows.len(), details.illuminations.len()), (360, 6));
        assert!(details.augmented.is_none());
        let originals = details.originals.as_ref().unwrap();
        assert!((originals.mae_total - report.errors.mae_total).abs() < 1e-12);
        let pooled: f64 = details
            .illuminations
            .iter()
            .map(|g| g.errors.mae_rho_s * g.errors.n as f64)
            .sum();
        assert!((pooled / 360.0 - report.errors.mae_rho_s).abs() < 1e-9);
        let inside = details
            .rows
            .iter()
            .filter(|r| {
                r.estimate.rho_s.low <= r.truth.rho_s && r.truth.rho_s <= r.estimate.rho_s.high
            })
            .count();
        assert!((inside as f64 / 360.0 - report.errors.coverage_rho_s).abs() <= 2.0 / 360.0);
        // The fitted estimator answers for a row of the table as the report's widths say.
        let row = ds.x.row(0).to_vec();
        let e = regressor.estimate(&row);
        assert!(e.rho_d.low <= e.rho_d.value && e.rho_d.value <= e.rho_d.high);
        assert!((e.rho_s.high - e.rho_s.value) <= report.half_widths.rho_s + 1e-12);
        regressor.validate(&ds.names).unwrap();
        let mut broken = regressor.clone();
        match &mut broken.regression {
            Regression::Ridge { ridge, .. } => drop(ridge.weights.pop()),
            Regression::Boost { trees, .. } => drop(trees.trees[2][0].leaf.pop()),
        }
        assert!(broken.validate(&ds.names).is_err());
        let renamed: Vec<String> = ds.names.iter().map(|n| format!("{n}x")).collect();
        assert!(regressor.validate(&renamed).is_err());
        let unknown = [Material {
            name: "other".into(),
            ..design[0].clone()
        }];
        assert!(fit(&ds, "test", &unknown, &FeatureSet::All, spec).is_err());
    }

    #[test]
    fn nearest_class_weighs_each_parameter_by_its_uncertainty() {
        let classes = [
            ward(0.1, 0.02, 0.1),
            ward(0.0, 0.8, 0.0),
            ward(0.4, 0.1, 0.02),
        ];
        let widths = HalfWidths {
            rho_d: 0.1,
            rho_s: 0.1,
            log10_alpha: 0.3,
        };
        let near =
            |m: Ward, w: &HalfWidths| nearest_class(&estimate_of(&targets(&m), w), w, &classes);
        assert_eq!(near(ward(0.12, 0.01, 0.09), &widths), Some(0));
        assert_eq!(near(ward(0.05, 0.7, 0.0), &widths), Some(1));
        assert_eq!(near(ward(0.35, 0.12, 0.03), &widths), Some(2));
        // Between classes 0 and 2 in ρd but with class 2's α: an α known well decides…
        let between = ward(0.25, 0.05, 0.02);
        assert_eq!(near(between, &widths), Some(2));
        // …and one known poorly does not: ρd then decides.
        let vague = HalfWidths {
            log10_alpha: 100.0,
            ..widths
        };
        assert_eq!(near(ward(0.2, 0.05, 0.02), &vague), Some(0));
        assert_eq!(
            nearest_class(&estimate_of(&targets(&between), &widths), &widths, &[]),
            None
        );
        // A matte class (no specular part) has no α: a sphere with hardly any gloss is
        // nearest to it whatever its α, though its α matches the shiny class exactly.
        let matte_or_shiny = [ward(0.1, 0.0, 0.0), ward(0.1, 0.1, 0.01)];
        let barely = estimate_of(&targets(&ward(0.1, 0.02, 0.01)), &widths);
        assert_eq!(nearest_class(&barely, &widths, &matte_or_shiny), Some(0));
        let shiny = estimate_of(&targets(&ward(0.1, 0.09, 0.01)), &widths);
        assert_eq!(nearest_class(&shiny, &widths, &matte_or_shiny), Some(1));
    }

    #[test]
    fn intervals_stay_in_range_and_mirrors_start_at_zero() {
        let widths = HalfWidths {
            rho_d: 0.05,
            rho_s: 0.1,
            log10_alpha: 0.3,
        };
        let glossy = estimate_of(&targets(&ward(0.02, 0.95, 0.01)), &widths);
        assert_eq!(glossy.rho_d.low, 0.0);
        assert_eq!(glossy.rho_s.high, 1.0);
        assert!((glossy.alpha.low - 0.01 / 10f64.powf(0.3)).abs() < 1e-12);
        assert!((glossy.alpha.high - 0.01 * 10f64.powf(0.3)).abs() < 1e-12);
        let mirror = estimate_of(&targets(&ward(0.0, 0.8, 0.0)), &widths);
        assert_eq!((mirror.alpha.value, mirror.alpha.low), (0.0, 0.0));
        assert!((mirror.alpha.high - 10f64.powf(MIRROR_LOG_ALPHA + 0.3)).abs() < 1e-12);
    }
}
