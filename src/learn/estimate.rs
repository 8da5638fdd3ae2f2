//! Estimating the Ward parameters (ρd, ρs, α) themselves, with intervals, rather than naming
//! a class.
//!
//! The regressor ([`super::regress`]) predicts four outputs in well-conditioned spaces: the
//! total reflectance t = ρd + ρs, the specular fraction ρs / t, a mirror score (+1 for α = 0,
//! −1 otherwise) and log10 α (mirrors placed at [`MIRROR_LOG_ALPHA`], below the glossy
//! range). An estimate turns them back into (ρd, ρs, α). Its 90 % intervals are split-conformal:
//! their half-widths are quantiles of the leave-one-illumination-out errors of ρd, ρs and
//! log10 α, so they hold for illuminations the model never saw.

use super::error::LearnError;
use super::feature_set::FeatureSet;
use super::matrix::Dataset;
use super::regress::{self, Ridge, RidgeSpec};
use super::scaler::Scaler;
use crate::render::ward::Material;
use ndarray::{Array2, Axis};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// log10 α of a mirror on the regression's axis: half the smallest glossy α (0.005).
pub const MIRROR_LOG_ALPHA: f64 = -2.602_059_991_327_962;
/// The narrowest and broadest α an estimate reports (the design's glossy range).
pub const ALPHA_RANGE: (f64, f64) = (0.005, 0.2);
/// The coverage of the intervals.
pub const COVERAGE: f64 = 0.9;

/// The regression targets of a material: [t, ρs / t, mirror ±1, log10 α].
pub fn targets(m: &Material) -> [f64; 4] {
    let total = m.rho_d + m.rho_s;
    let fraction = if total > 0.0 { m.rho_s / total } else { 0.0 };
    let (mirror, log_alpha) = match m.alpha > 0.0 {
        true => (-1.0, m.alpha.log10()),
        false => (1.0, MIRROR_LOG_ALPHA),
    };
    [total, fraction, mirror, log_alpha]
}

/// (ρd, ρs, α, log10 α) of a prediction of the four outputs.
pub fn parameters(prediction: &[f64]) -> (f64, f64, f64, f64) {
    let total = prediction[0].clamp(0.0, 1.0);
    let rho_s = total * prediction[1].clamp(0.0, 1.0);
    let (lo, hi) = (ALPHA_RANGE.0.log10(), ALPHA_RANGE.1.log10());
    let log_alpha = prediction[3].clamp(MIRROR_LOG_ALPHA, hi);
    let alpha = match prediction[2] > 0.0 {
        true => 0.0,
        false => 10f64.powf(log_alpha.max(lo)),
    };
    (total - rho_s, rho_s, alpha, log_alpha)
}

/// A parameter with its interval.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Interval {
    pub value: f64,
    pub low: f64,
    pub high: f64,
}

/// The Ward parameters estimated from one photograph, each with its 90 % interval (α = 0
/// is an ideal mirror).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct WardEstimate {
    pub rho_d: Interval,
    pub rho_s: Interval,
    pub alpha: Interval,
}

/// Conformal half-widths at [`COVERAGE`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HalfWidths {
    pub rho_d: f64,
    pub rho_s: f64,
    pub log10_alpha: f64,
}

/// A fitted estimator: the inputs it reads, their standardization, the ridge, the widths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WardRegressor {
    pub inputs: Vec<String>,
    pub input_indices: Vec<usize>,
    pub scaler: Scaler,
    pub spec: RidgeSpec,
    pub ridge: Ridge,
    pub half_widths: HalfWidths,
    /// Its leave-one-illumination-out accuracy, on the data it was fitted to.
    pub cv: EstimateReport,
    /// The feature table it was fitted to (as given).
    pub dataset: String,
}

impl WardRegressor {
    /// Check the parts against each other and against the model's feature `names`.
    pub fn validate(&self, names: &[String]) -> Result<(), String> {
        let d = self.input_indices.len();
        let features = self.ridge.map.phase.len();
        let consistent = self.inputs.len() == d
            && self.scaler.dim() == d
            && self.ridge.map.inputs == d
            && self.ridge.map.omega.len() == features * d
            && self.ridge.outputs == 4
            && self.ridge.weights.len() == (features + 1) * 4;
        if !consistent {
            return Err("the estimator's parts do not fit together".into());
        }
        let named = self
            .input_indices
            .iter()
            .zip(&self.inputs)
            .all(|(&i, name)| names.get(i) == Some(name));
        if !named {
            return Err("the estimator's inputs are not this configuration's features".into());
        }
        let w = &self.half_widths;
        let widths = [w.rho_d, w.rho_s, w.log10_alpha];
        let numbers = self
            .ridge
            .weights
            .iter()
            .chain(&self.ridge.map.omega)
            .chain(&widths);
        if numbers.chain(&self.scaler.mean).any(|v| !v.is_finite()) {
            return Err("the estimator holds a number that is not finite".into());
        }
        Ok(())
    }

    /// The estimate from a row of every extracted feature (canonical order).
    pub fn estimate(&self, values: &[f64]) -> WardEstimate {
        let mut z: Vec<f64> = self.input_indices.iter().map(|&i| values[i]).collect();
        self.scaler.apply(&mut z);
        estimate_of(&self.ridge.predict(&z), &self.half_widths)
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
    let (rho_d, rho_s, alpha, log_alpha) = parameters(prediction);
    let log_high = 10f64.powf(log_alpha + widths.log10_alpha);
    let alpha = match alpha > 0.0 {
        true => Interval {
            value: alpha,
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
        rho_d: interval(rho_d, widths.rho_d, (0.0, 1.0)),
        rho_s: interval(rho_s, widths.rho_s, (0.0, 1.0)),
        alpha,
    }
}

/// Leave-one-illumination-out accuracy of an estimator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimateReport {
    /// Rows evaluated, and how many are augmented views (captures, rotations, …).
    pub n: usize,
    pub augmented: usize,
    pub mae_total: f64,
    pub mae_rho_d: f64,
    pub mae_rho_s: f64,
    /// Mirror (α = 0) or not, right.
    pub mirror_accuracy: f64,
    /// |log10 α error| over the true non-mirrors the estimate also calls non-mirrors (none
    /// when there are none).
    pub mae_log10_alpha: Option<f64>,
    /// Coverage of the 90 % intervals, each illumination's with half-widths from the others'
    /// errors only.
    pub coverage_rho_d: f64,
    pub coverage_rho_s: f64,
    pub coverage_alpha: f64,
    pub half_widths: HalfWidths,
}

/// Per row: |errors| of ρd, ρs, t and log10 α, whether the mirror call is right, and
/// whether the sphere is glossy (not a mirror).
struct RowErrors {
    rho_d: f64,
    rho_s: f64,
    total: f64,
    log_alpha: f64,
    mirror_right: bool,
    glossy: bool,
}

fn row_errors(prediction: &[f64], truth: &Material) -> RowErrors {
    let (rho_d, rho_s, _, log_alpha) = parameters(prediction);
    let predicted_mirror = prediction[2] > 0.0;
    let true_mirror = truth.alpha == 0.0;
    // A mirror's α interval is [0, high]: its error is how far the estimate's log α reaches
    // above the mirror point, and a glossy α's, against its true log α.
    let log_error = match (true_mirror, predicted_mirror) {
        (true, _) => (log_alpha - MIRROR_LOG_ALPHA).max(0.0),
        (false, _) => (log_alpha - truth.alpha.log10()).abs(),
    };
    RowErrors {
        rho_d: (rho_d - truth.rho_d).abs(),
        rho_s: (rho_s - truth.rho_s).abs(),
        total: (rho_d + rho_s - truth.rho_d - truth.rho_s).abs(),
        log_alpha: log_error,
        mirror_right: predicted_mirror == true_mirror,
        glossy: !true_mirror,
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// Fit an estimator on `ds` (from the table named `dataset`), whose classes are materials of
/// `materials` (by name), reading the features of `features`; also its
/// leave-one-illumination-out report.
pub fn fit(
    ds: &Dataset,
    dataset: &str,
    materials: &[Material],
    features: &FeatureSet,
    spec: &RidgeSpec,
) -> Result<(WardRegressor, EstimateReport), LearnError> {
    let material_of_class: Vec<&Material> = ds
        .classes
        .iter()
        .map(|c| {
            materials.iter().find(|m| &m.name == c).ok_or_else(|| {
                LearnError::InvalidParameter(format!("class {c:?} has no Ward parameters"))
            })
        })
        .collect::<Result<_, _>>()?;
    let input_indices = features.resolve(&ds.names)?.ok_or_else(|| {
        LearnError::InvalidParameter("estimation needs a fixed feature set".into())
    })?;
    let x = ds.x.select(Axis(1), &input_indices);
    let scaler = Scaler::fit(x.view());
    let z = scaler.transform(x.view());
    let y = Array2::from_shape_fn((ds.n_rows(), 4), |(i, o)| {
        targets(material_of_class[ds.labels[i]])[o]
    });
    let fitted = regress::fit(z.view(), y.view(), Some(&ds.groups), spec)?;
    let held_out = fitted.held_out.unwrap_or_else(|| y.clone());
    let errors: Vec<RowErrors> = (0..ds.n_rows())
        .map(|i| row_errors(&held_out.row(i).to_vec(), material_of_class[ds.labels[i]]))
        .collect();
    let report = report(ds, &errors);
    let regressor = WardRegressor {
        inputs: input_indices.iter().map(|&i| ds.names[i].clone()).collect(),
        input_indices,
        scaler,
        spec: *spec,
        ridge: fitted.ridge,
        half_widths: report.half_widths,
        cv: report.clone(),
        dataset: dataset.to_string(),
    };
    Ok((regressor, report))
}

fn widths(errors: &[&RowErrors]) -> HalfWidths {
    let q = |f: fn(&RowErrors) -> f64| {
        let values: Vec<f64> = errors.iter().map(|e| f(e)).collect();
        regress::conformal_half_width(&values, COVERAGE)
    };
    HalfWidths {
        rho_d: q(|e| e.rho_d),
        rho_s: q(|e| e.rho_s),
        log10_alpha: q(|e| e.log_alpha),
    }
}

fn report(ds: &Dataset, errors: &[RowErrors]) -> EstimateReport {
    let all: Vec<&RowErrors> = errors.iter().collect();
    // Each illumination's coverage with widths from the other illuminations' errors.
    let (mut covered, mut n) = ([0usize; 3], 0usize);
    for g in 0..ds.group_names.len() {
        let others: Vec<&RowErrors> = (0..errors.len())
            .filter(|&i| ds.groups[i] != g)
            .map(|i| &errors[i])
            .collect();
        let w = widths(&others);
        for e in (0..errors.len())
            .filter(|&i| ds.groups[i] == g)
            .map(|i| &errors[i])
        {
            covered[0] += usize::from(e.rho_d <= w.rho_d);
            covered[1] += usize::from(e.rho_s <= w.rho_s);
            covered[2] += usize::from(e.log_alpha <= w.log10_alpha);
            n += 1;
        }
    }
    let share = |k: usize| covered[k] as f64 / n.max(1) as f64;
    EstimateReport {
        n: errors.len(),
        augmented: ds.augmented.iter().filter(|&&a| a).count(),
        mae_total: mean(errors.iter().map(|e| e.total)),
        mae_rho_d: mean(errors.iter().map(|e| e.rho_d)),
        mae_rho_s: mean(errors.iter().map(|e| e.rho_s)),
        mirror_accuracy: mean(errors.iter().map(|e| f64::from(u8::from(e.mirror_right)))),
        mae_log10_alpha: Some(mean(
            errors
                .iter()
                .filter(|e| e.glossy && e.mirror_right)
                .map(|e| e.log_alpha),
        ))
        .filter(|v| v.is_finite()),
        coverage_rho_d: share(0),
        coverage_rho_s: share(1),
        coverage_alpha: share(2),
        half_widths: widths(&all),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(rho_d: f64, rho_s: f64, alpha: f64) -> Material {
        Material {
            name: "m".into(),
            rho_d,
            rho_s,
            alpha,
        }
    }

    #[test]
    fn targets_and_parameters_round_trip() {
        for m in [
            material(0.3, 0.2, 0.02),
            material(0.0, 0.75, 0.0),
            material(0.9, 0.0, 0.1),
        ] {
            let (rho_d, rho_s, alpha, _) = parameters(&targets(&m));
            assert!((rho_d - m.rho_d).abs() < 1e-12, "{m:?}");
            assert!((rho_s - m.rho_s).abs() < 1e-12, "{m:?}");
            assert!((alpha - m.alpha).abs() < 1e-12, "{m:?}");
        }
        // Out-of-range predictions land on valid parameters.
        let (rho_d, rho_s, alpha, _) = parameters(&[1.3, -0.2, -0.4, 0.5]);
        assert_eq!((rho_d, rho_s), (1.0, 0.0));
        assert!((alpha - 0.2).abs() < 1e-12);
    }

    /// Materials of the design under 6 illuminations, seen through features that are smooth
    /// functions of the parameters, disturbed per illumination and per row.
    fn dataset(materials: &[Material]) -> Dataset {
        use crate::dataset::{FeatureTable, Sample};
        let mut rng = crate::util::rng::Rng::new(5);
        let mut samples = Vec::new();
        for g in 0..6 {
            let shift: Vec<f64> = (0..5).map(|_| 0.05 * (rng.next_f64() - 0.5)).collect();
            for m in materials {
                let log_alpha = if m.alpha > 0.0 { m.alpha.log10() } else { -3.0 };
                let clean = [
                    m.rho_d + m.rho_s,
                    m.rho_s,
                    m.rho_d,
                    log_alpha,
                    m.rho_s * (-2.0 - log_alpha),
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
        let table = FeatureTable {
            names: (0..5).map(|j| format!("f{j}")).collect(),
            samples,
        };
        Dataset::from_table(&table).unwrap()
    }

    #[test]
    fn estimates_held_out_illuminations_with_calibrated_intervals() {
        let design = crate::render::design::continuous(60, 2, &Default::default());
        let ds = dataset(&design);
        let spec = RidgeSpec {
            features: 300,
            gamma: 0.2,
            lambda: 1e-2,
            seed: 1,
        };
        let (regressor, report) = fit(&ds, "test", &design, &FeatureSet::All, &spec).unwrap();
        assert_eq!(report.n, 360);
        assert!(report.mae_total < 0.05, "{report:?}");
        assert!(report.mae_rho_s < 0.05, "{report:?}");
        assert!(report.mirror_accuracy > 0.95, "{report:?}");
        assert!(report.mae_log10_alpha.unwrap() < 0.2, "{report:?}");
        for c in [
            report.coverage_rho_d,
            report.coverage_rho_s,
            report.coverage_alpha,
        ] {
            assert!((0.8..=0.97).contains(&c), "{report:?}");
        }
        // The fitted estimator answers for a row of the table as the report's widths say.
        let row = ds.x.row(0).to_vec();
        let e = regressor.estimate(&row);
        assert!(e.rho_d.low <= e.rho_d.value && e.rho_d.value <= e.rho_d.high);
        assert!((e.rho_s.high - e.rho_s.value) <= report.half_widths.rho_s + 1e-12);
        regressor.validate(&ds.names).unwrap();
        let mut broken = regressor.clone();
        broken.ridge.weights.pop();
        assert!(broken.validate(&ds.names).is_err());
        let renamed: Vec<String> = ds.names.iter().map(|n| format!("{n}x")).collect();
        assert!(regressor.validate(&renamed).is_err());
        let unknown = [Material {
            name: "other".into(),
            ..design[0].clone()
        }];
        assert!(fit(&ds, "test", &unknown, &FeatureSet::All, &spec).is_err());
    }

    #[test]
    fn intervals_stay_in_range_and_mirrors_start_at_zero() {
        let widths = HalfWidths {
            rho_d: 0.05,
            rho_s: 0.1,
            log10_alpha: 0.3,
        };
        let glossy = estimate_of(&targets(&material(0.02, 0.95, 0.01)), &widths);
        assert_eq!(glossy.rho_d.low, 0.0);
        assert_eq!(glossy.rho_s.high, 1.0);
        assert!((glossy.alpha.low - 0.01 / 10f64.powf(0.3)).abs() < 1e-12);
        assert!((glossy.alpha.high - 0.01 * 10f64.powf(0.3)).abs() < 1e-12);
        let mirror = estimate_of(&targets(&material(0.0, 0.8, 0.0)), &widths);
        assert_eq!((mirror.alpha.value, mirror.alpha.low), (0.0, 0.0));
        assert!((mirror.alpha.high - 10f64.powf(MIRROR_LOG_ALPHA + 0.3)).abs() < 1e-12);
    }
}
