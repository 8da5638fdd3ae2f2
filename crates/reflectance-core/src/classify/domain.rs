//! The domain check (docs/design.md §3 "Domain"): is an input like the images the model was
//! trained and calibrated on — a sphere, its circle on it, a sensible white, light like
//! the training light — or not, in which case its class and set say little.
//!
//! Two checks are statistics with a tail that means "unlike training":
//! * `typicality`: the mean Euclidean distance to the [`K`] nearest of a sample of training
//!   images in the classifier's standardized input space (upper tail);
//! * `outline`: `dom.outline`, how well the circle follows a sphere's outline (lower tail).
//!
//! Each statistic's distribution on images of illuminations held out of training (the
//! classifier's calibration folds, captures included) is kept as a quantile table, which
//! turns a value into a p-value. Fisher's method combines them, −2 Σ ln p, and the
//! threshold is the (1 − [`FALSE_ALARM`]) quantile of that combination over the same
//! held-out images: valid images are flagged at about that rate, whatever the checks'
//! dependence.
//!
//! The third is a bound, because only a gross error should trip it: `brightness`,
//! `ctr.mean`, the centre's brightness over white, fails above [`BRIGHTNESS_MARGIN`] times
//! the brightest held-out sphere's (its 99.9th percentile). A white far too small makes the
//! sphere brighter than any reflectance can be; a brighter light than any training probe's
//! only comes near.

use crate::learn::Inconsistent;

use super::svm::squared_distance;
use crate::util::rng::Rng;
use serde::{Deserialize, Serialize};

/// Neighbours averaged by the typicality check.
pub const K: usize = 5;
/// Training images kept as the typicality check's reference, at most.
pub const REFERENCE: usize = 1000;
/// The rate at which held-out valid images are flagged.
pub const FALSE_ALARM: f64 = 0.01;
/// The levels of the stored quantile tables.
pub const LEVELS: [f64; 21] = [
    0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.98,
    0.99, 0.995, 0.998, 0.999,
];
/// The smallest p-value a check gives.
const P_FLOOR: f64 = 1e-12;
/// How many times brighter than the brightest held-out sphere a centre may be, over white,
/// before the white is taken to be wrong.
pub const BRIGHTNESS_MARGIN: f64 = 2.0;

/// What a check measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CheckKind {
    /// Mean distance to the [`K`] nearest reference images (statistical, upper tail).
    Typicality,
    /// `dom.outline`: how well the circle follows a sphere's outline (statistical, lower tail).
    Outline,
    /// `ctr.mean`, the centre over white (a bound: [`BRIGHTNESS_MARGIN`] × the brightest
    /// held-out sphere's).
    Brightness,
}

impl CheckKind {
    /// The feature a check reads (`None`: the distance to the reference).
    pub fn feature(self) -> Option<&'static str> {
        match self {
            CheckKind::Typicality => None,
            CheckKind::Outline => Some("dom.outline"),
            CheckKind::Brightness => Some("ctr.mean"),
        }
    }

    /// Whether large values are unlike training (else small ones are).
    fn upper(self) -> bool {
        self != CheckKind::Outline
    }

    /// Why an input failed this check, in words.
    pub fn reason(self) -> &'static str {
        match self {
            CheckKind::Typicality => {
                "its statistics are unlike those of every training sphere: it may not be a \
                 sphere, or be lit unlike any natural light the model knows (one small lamp \
                 in the dark, say)"
            }
            CheckKind::Outline => {
                "no sphere's outline follows the circle: the circle may miss the sphere (moved, \
                 too large or too small), or this is not a sphere"
            }
            CheckKind::Brightness => {
                "the sphere is brighter than any reflectance could make it under the white given: \
                 the white reference is probably far too small"
            }
        }
    }
}

/// A statistic's distribution on held-out valid images.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// What it measures.
    pub kind: CheckKind,
    /// For feature checks: the feature's index in the model's full row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<usize>,
    /// The statistic's quantiles at [`LEVELS`] (statistical checks).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub quantiles: Vec<f64>,
    /// The largest value that passes (bounds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit: Option<f64>,
}

impl Check {
    fn fit(kind: CheckKind, index: Option<usize>, values: &[f64]) -> Check {
        let quantiles = crate::features::stats::percentiles(values, LEVELS.map(|l| 100.0 * l));
        Check {
            kind,
            index,
            quantiles: quantiles.to_vec(),
            limit: None,
        }
    }

    /// A bound at [`BRIGHTNESS_MARGIN`] times the 99.9th percentile of `values` (log10).
    fn bound(kind: CheckKind, index: usize, values: &[f64]) -> Check {
        let top = crate::features::stats::percentiles(values, [99.9])[0];
        Check {
            kind,
            index: Some(index),
            quantiles: Vec::new(),
            limit: Some(top + BRIGHTNESS_MARGIN.log10()),
        }
    }

    /// The probability that a valid image is at least this far in the check's tail.
    pub fn p_value(&self, value: f64) -> f64 {
        let q = &self.quantiles;
        if value.is_nan() {
            return 1.0;
        }
        // Work in the upper tail: mirror a lower-tail check.
        let (q, v, levels): (Vec<f64>, f64, Vec<f64>) = if self.kind.upper() {
            (q.clone(), value, LEVELS.to_vec())
        } else {
            let q = q.iter().rev().map(|x| -x).collect();
            (q, -value, LEVELS.iter().rev().map(|l| 1.0 - l).collect())
        };
        let last = q.len() - 1;
        if v <= q[0] {
            return 1.0 - levels[0];
        }
        if v >= q[last] {
            // Beyond the table: an exponential tail with the scale of its last step.
            let scale = (q[last] - q[last - 1]).max(1e-12);
            return ((1.0 - levels[last]) * (-(v - q[last]) / scale).exp()).max(P_FLOOR);
        }
        let i = q.partition_point(|&x| x <= v) - 1;
        let t = if q[i + 1] > q[i] {
            (v - q[i]) / (q[i + 1] - q[i])
        } else {
            1.0
        };
        1.0 - (levels[i] + t * (levels[i + 1] - levels[i]))
    }
}

/// One check's verdict on one input.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckResult {
    /// What it measured.
    pub kind: CheckKind,
    /// The measured value (a distance, the outline's fit, or log10 of the centre over white).
    pub value: f64,
    /// Statistical checks: how often a valid image is at least this unusual.
    pub p_value: Option<f64>,
    /// Bounds: the largest value that passes.
    pub limit: Option<f64>,
}

impl CheckResult {
    /// A bound the value exceeds.
    fn broken(&self) -> bool {
        self.limit.is_some_and(|l| self.value > l)
    }
}

/// The domain check's verdict on one input.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// −2 Σ ln p over the checks (Fisher); larger is less like training.
    pub score: f64,
    /// The score above which the input is out of domain.
    pub threshold: f64,
    /// Each check's measurement, in the model's check order.
    pub checks: Vec<CheckResult>,
}

impl Verdict {
    /// In domain: the score at most the threshold, and no bound broken.
    pub fn in_domain(&self) -> bool {
        self.score <= self.threshold && !self.checks.iter().any(CheckResult::broken)
    }

    /// The checks that explain a flagged input: the bounds it breaks, and when the
    /// statistics flag it, those with p below the false-alarm rate, else the least likely.
    pub fn failed(&self) -> Vec<CheckKind> {
        let mut failed: Vec<CheckKind> = self
            .checks
            .iter()
            .filter(|c| c.broken())
            .map(|c| c.kind)
            .collect();
        if self.score > self.threshold {
            let mut unlikely: Vec<(f64, CheckKind)> = self
                .checks
                .iter()
                .filter_map(|c| c.p_value.map(|p| (p, c.kind)))
                .collect();
            unlikely.sort_by(|a, b| a.0.total_cmp(&b.0));
            let below = unlikely.iter().filter(|(p, _)| *p < FALSE_ALARM).count();
            failed.extend(unlikely.iter().take(below.max(1)).map(|&(_, kind)| kind));
        }
        failed
    }
}

/// A model's domain check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DomainCheck {
    /// Training images in the classifier's standardized input space.
    pub reference: Vec<Vec<f64>>,
    /// Neighbours the typicality check averages ([`K`] when trained).
    pub k: usize,
    /// The checks, typicality first.
    pub checks: Vec<Check>,
    /// On the Fisher combination.
    pub threshold: f64,
    /// The rate the threshold was set to flag held-out valid images at.
    pub false_alarm: f64,
    /// Held-out images that calibrated it, and the fraction of them flagged (with each
    /// fold's reference drawn from the other folds).
    pub n: usize,
    /// The fraction of those held-out images flagged, near `false_alarm`.
    pub held_out_flagged: f64,
}

/// What the calibration needs of each training row.
pub struct Rows<'a> {
    /// The classifier's standardized inputs.
    pub z: &'a [Vec<f64>],
    /// The full feature rows.
    pub values: &'a [Vec<f64>],
    /// The calibration fold that held each row out (`None`: it always trained).
    pub fold: &'a [Option<usize>],
}

/// The mean distance from `z` to its `k` nearest rows of `reference`.
fn knn_distance(reference: &[Vec<f64>], z: &[f64], k: usize) -> f64 {
    let k = k.min(reference.len()).max(1);
    let mut nearest = vec![f64::INFINITY; k];
    for r in reference {
        let d = squared_distance(r, z);
        if d < nearest[k - 1] {
            let at = nearest.partition_point(|&x| x <= d);
            nearest.insert(at, d);
            nearest.truncate(k);
        }
    }
    nearest.iter().map(|d| d.sqrt()).sum::<f64>() / k as f64
}

/// Up to [`REFERENCE`] of `rows`, drawn without replacement.
fn sample(rows: &[usize], rng: &mut Rng) -> Vec<usize> {
    let mut rows = rows.to_vec();
    rng.shuffle(&mut rows);
    rows.truncate(REFERENCE);
    rows.sort_unstable();
    rows
}

impl DomainCheck {
    /// Calibrates on the rows of a fit; `features` maps the feature checks to their column
    /// (absent columns: no such check). `None` when no row was held out.
    pub fn calibrate(
        rows: &Rows,
        features: impl Fn(&str) -> Option<usize>,
        seed: u64,
    ) -> Option<DomainCheck> {
        let n = rows.z.len();
        let held: Vec<usize> = (0..n).filter(|&i| rows.fold[i].is_some()).collect();
        if held.is_empty() {
            return None;
        }
        let folds = rows.fold.iter().flatten().max().map_or(0, |&f| f + 1);
        let mut rng = Rng::fork(seed, 0x646f6d61);
        let mut distance = vec![f64::NAN; n];
        for f in 0..folds {
            let train: Vec<usize> = (0..n).filter(|&i| rows.fold[i] != Some(f)).collect();
            let reference: Vec<Vec<f64>> = sample(&train, &mut rng)
                .into_iter()
                .map(|i| rows.z[i].clone())
                .collect();
            for i in (0..n).filter(|&i| rows.fold[i] == Some(f)) {
                distance[i] = knn_distance(&reference, &rows.z[i], K);
            }
        }
        let all: Vec<usize> = (0..n).collect();
        let reference = sample(&all, &mut rng)
            .into_iter()
            .map(|i| rows.z[i].clone())
            .collect();
        let mut checks = vec![Check::fit(
            CheckKind::Typicality,
            None,
            &held.iter().map(|&i| distance[i]).collect::<Vec<_>>(),
        )];
        for kind in [CheckKind::Outline, CheckKind::Brightness] {
            let Some(index) = kind.feature().and_then(&features) else {
                continue;
            };
            let values: Vec<f64> = held.iter().map(|&i| rows.values[i][index]).collect();
            checks.push(match kind {
                CheckKind::Brightness => Check::bound(kind, index, &values),
                _ => Check::fit(kind, Some(index), &values),
            });
        }
        let mut check = DomainCheck {
            reference,
            k: K,
            checks,
            threshold: f64::INFINITY,
            false_alarm: FALSE_ALARM,
            n: held.len(),
            held_out_flagged: 0.0,
        };
        let verdicts: Vec<Verdict> = held
            .iter()
            .map(|&i| check.score_with(distance[i], &rows.values[i]))
            .collect();
        let scores: Vec<f64> = verdicts.iter().map(|v| v.score).collect();
        check.threshold =
            crate::features::stats::percentiles(&scores, [100.0 * (1.0 - FALSE_ALARM)])[0];
        let flagged = verdicts
            .iter()
            .filter(|v| v.score > check.threshold || v.checks.iter().any(CheckResult::broken))
            .count();
        check.held_out_flagged = flagged as f64 / verdicts.len() as f64;
        Some(check)
    }

    /// The verdict on an input: its classifier inputs `z` and full feature row.
    pub fn verdict(&self, z: &[f64], row: &[f64]) -> Verdict {
        self.score_with(knn_distance(&self.reference, z, self.k), row)
    }

    fn score_with(&self, distance: f64, row: &[f64]) -> Verdict {
        let checks: Vec<CheckResult> = self
            .checks
            .iter()
            .map(|check| {
                let value = match check.index {
                    None => distance,
                    Some(i) => row.get(i).copied().unwrap_or(f64::NAN),
                };
                CheckResult {
                    kind: check.kind,
                    value,
                    p_value: check.limit.is_none().then(|| check.p_value(value)),
                    limit: check.limit,
                }
            })
            .collect();
        let score = checks
            .iter()
            .filter_map(|c| c.p_value)
            .map(|p| -2.0 * p.ln())
            .sum();
        Verdict {
            score,
            threshold: self.threshold,
            checks,
        }
    }

    /// Checks the stored calibration (after deserializing a model file) against the
    /// classifier's input dimension and the row length.
    pub fn validate(&self, dim: usize, row_len: usize) -> Result<(), Inconsistent> {
        if self.reference.is_empty() || self.reference.iter().any(|r| r.len() != dim) {
            return Err(Inconsistent(format!(
                "domain reference rows must have the classifier's {dim} inputs"
            )));
        }
        if self.reference.iter().flatten().any(|v| !v.is_finite()) || self.k == 0 {
            return Err(Inconsistent(
                "domain reference must be finite, with k ≥ 1".into(),
            ));
        }
        for check in &self.checks {
            let sorted = check.quantiles.windows(2).all(|w| w[0] <= w[1]);
            let statistical = check.quantiles.len() == LEVELS.len() && sorted;
            let bound = check.quantiles.is_empty() && check.limit.is_some_and(f64::is_finite);
            if statistical == bound {
                return Err(Inconsistent(format!(
                    "domain check {:?}: quantiles must be {} ascending values",
                    check.kind,
                    LEVELS.len()
                )));
            }
            if check.index.is_some_and(|i| i >= row_len)
                || check.index.is_some() == (check.kind == CheckKind::Typicality)
            {
                return Err(Inconsistent(format!(
                    "domain check {:?}: bad feature index",
                    check.kind
                )));
            }
        }
        if self.threshold.is_nan() {
            return Err(Inconsistent("domain threshold is not a number".into()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p_values_follow_the_quantile_table_and_its_tail() {
        let values: Vec<f64> = (0..=1000).map(|i| i as f64 / 100.0).collect();
        let upper = Check::fit(CheckKind::Typicality, None, &values);
        assert!((upper.p_value(5.0) - 0.5).abs() < 1e-9);
        assert!((upper.p_value(9.0) - 0.1).abs() < 1e-9);
        assert!(upper.p_value(9.99) <= 0.0011);
        // Beyond the table the p-value keeps falling.
        assert!(upper.p_value(10.5) < upper.p_value(10.1));
        assert!(upper.p_value(1e9) >= P_FLOOR);
        assert!((upper.p_value(-1.0) - 0.999).abs() < 1e-12);
        let lower = Check::fit(CheckKind::Outline, Some(0), &values);
        assert!((lower.p_value(1.0) - 0.1).abs() < 1e-9);
        assert!((lower.p_value(5.0) - 0.5).abs() < 1e-9);
        assert!(lower.p_value(-0.5) < lower.p_value(0.0));
        assert_eq!(upper.p_value(f64::NAN), 1.0);
    }

    #[test]
    fn calibration_flags_held_out_images_at_the_false_alarm_rate_and_outliers_always() {
        let mut rng = Rng::new(3);
        let n = 3000;
        let z: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..4).map(|_| rng.next_f64() * 2.0 - 1.0).collect())
            .collect();
        // Column 0: an outline-like feature near 0.8; column 1: a brightness near −0.5.
        let values: Vec<Vec<f64>> = (0..n)
            .map(|_| {
                vec![
                    0.8 + 0.1 * (rng.next_f64() - 0.5),
                    -0.5 + 0.2 * (rng.next_f64() - 0.5),
                ]
            })
            .collect();
        let fold: Vec<Option<usize>> = (0..n).map(|i| Some(i % 5)).collect();
        let names = |name: &str| match name {
            "dom.outline" => Some(0),
            "ctr.mean" => Some(1),
            _ => None,
        };
        let rows = Rows {
            z: &z,
            values: &values,
            fold: &fold,
        };
        let check = DomainCheck::calibrate(&rows, names, 1).unwrap();
        check.validate(4, 2).unwrap();
        assert_eq!(check.checks.len(), 3);
        assert!(
            check.held_out_flagged <= 2.0 * FALSE_ALARM,
            "{}",
            check.held_out_flagged
        );
        assert_eq!(check.reference.len(), REFERENCE);
        let typical = check.verdict(&[0.1, -0.2, 0.3, 0.0], &[0.8, -0.5]);
        assert!(
            typical.in_domain() && typical.failed().is_empty(),
            "{typical:?}"
        );
        // Each flagged input is out of domain, by the check that flags it.
        let far = check.verdict(&[5.0, 5.0, 5.0, 5.0], &[0.8, -0.5]);
        assert_eq!(far.failed(), [CheckKind::Typicality]);
        assert!(!far.in_domain(), "{far:?}");
        let no_outline = check.verdict(&[0.1, -0.2, 0.3, 0.0], &[0.1, -0.5]);
        assert_eq!(no_outline.failed(), [CheckKind::Outline]);
        assert!(!no_outline.in_domain(), "{no_outline:?}");
        // The brightness bound alone: the statistics pass, the bound is broken.
        let bright = check.verdict(&[0.1, -0.2, 0.3, 0.0], &[0.8, 1.0]);
        assert_eq!(bright.failed(), [CheckKind::Brightness]);
        assert!(bright.score <= bright.threshold, "{bright:?}");
        assert!(!bright.in_domain(), "{bright:?}");
        // Nothing held out: no check.
        let always: Vec<Option<usize>> = vec![None; n];
        let rows = Rows {
            z: &z,
            values: &values,
            fold: &always,
        };
        assert!(DomainCheck::calibrate(&rows, names, 1).is_none());
    }
}
