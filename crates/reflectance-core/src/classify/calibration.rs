//! Probability calibration of the one-against-all SVM's decision values f.
//!
//! * **Softmax** (models trained now): P_k = exp(T f_k) / Σ_j exp(T f_j), one temperature
//!   T > 0 fitted by maximum likelihood on held-out decision values. It is monotone in f,
//!   so the most probable class is always the largest decision value: the label and the
//!   probabilities cannot disagree.
//! * **Platt** (older model files): one sigmoid per class, P(class k | f_k) =
//!   1 / (1 + exp(A_k f_k + B_k)), then normalized across classes to sum to 1. The
//!   sigmoids differ per class, so their most probable class can differ from the largest
//!   decision value; the label is then the most probable class.
//!
//! The fit is the method of libsvm's `sigmoid_train` (Lin, Lin & Weng 2007, "A note on
//! Platt's probabilistic outputs for support vector machines"): Newton's method with a
//! backtracking line search on the cross-entropy with Platt's prior-corrected targets
//! (N₊ + 1)/(N₊ + 2) and 1/(N₋ + 2), Hessian regularized by σ = 1e-12, stopping when both
//! gradient components are below 1e-5 (at most 100 iterations, minimum step 1e-10).

use crate::util::rng::Rng;
use serde::{Deserialize, Serialize};

/// A Platt sigmoid: P(class | f) = 1 / (1 + exp(a·f + b)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sigmoid {
    /// Slope A (negative when a larger decision value is more probable).
    pub a: f64,
    /// Offset B.
    pub b: f64,
}

/// log(1 + exp(x)) without overflow.
fn softplus(x: f64) -> f64 {
    if x > 0.0 {
        x + (-x).exp().ln_1p()
    } else {
        x.exp().ln_1p()
    }
}

impl Sigmoid {
    /// 1 / (1 + exp(A f + B)), evaluated without overflow.
    pub fn probability(&self, f: f64) -> f64 {
        let t = self.a * f + self.b;
        if t >= 0.0 {
            let e = (-t).exp();
            e / (1.0 + e)
        } else {
            1.0 / (1.0 + t.exp())
        }
    }

    /// Fits A, B to decision values `dec` of examples whose class is `positive`.
    pub fn fit(dec: &[f64], positive: &[bool]) -> Sigmoid {
        const MAX_ITER: usize = 100;
        const MIN_STEP: f64 = 1e-10;
        const SIGMA: f64 = 1e-12;
        const EPS: f64 = 1e-5;
        let n_pos = positive.iter().filter(|&&p| p).count() as f64;
        let n_neg = positive.len() as f64 - n_pos;
        let hi = (n_pos + 1.0) / (n_pos + 2.0);
        let lo = 1.0 / (n_neg + 2.0);
        let t: Vec<f64> = positive.iter().map(|&p| if p { hi } else { lo }).collect();
        // Negative log-likelihood: Σ t·(Af+B) + log(1 + exp(−(Af+B))).
        let objective = |a: f64, b: f64| -> f64 {
            dec.iter()
                .zip(&t)
                .map(|(&f, &ti)| {
                    let z = a * f + b;
                    ti * z + softplus(-z)
                })
                .sum()
        };
        let mut a = 0.0;
        let mut b = ((n_neg + 1.0) / (n_pos + 1.0)).ln();
        let mut fval = objective(a, b);
        for _ in 0..MAX_ITER {
            let (mut h11, mut h22, mut h21, mut g1, mut g2) = (SIGMA, SIGMA, 0.0, 0.0, 0.0);
            for (&f, &ti) in dec.iter().zip(&t) {
                let z = a * f + b;
                let (p, q) = if z >= 0.0 {
                    let e = (-z).exp();
                    (e / (1.0 + e), 1.0 / (1.0 + e))
                } else {
                    let e = z.exp();
                    (1.0 / (1.0 + e), e / (1.0 + e))
                };
                let d2 = p * q;
                h11 += f * f * d2;
                h22 += d2;
                h21 += f * d2;
                let d1 = ti - p;
                g1 += f * d1;
                g2 += d1;
            }
            if g1.abs() < EPS && g2.abs() < EPS {
                break;
            }
            let det = h11 * h22 - h21 * h21;
            let da = -(h22 * g1 - h21 * g2) / det;
            let db = -(-h21 * g1 + h11 * g2) / det;
            let gd = g1 * da + g2 * db;
            let mut step = 1.0;
            let mut accepted = false;
            while step >= MIN_STEP {
                let (na, nb) = (a + step * da, b + step * db);
                let nf = objective(na, nb);
                if nf < fval + 1e-4 * step * gd {
                    a = na;
                    b = nb;
                    fval = nf;
                    accepted = true;
                    break;
                }
                step /= 2.0;
            }
            if !accepted {
                break;
            }
        }
        Sigmoid { a, b }
    }
}

/// How decision values become probabilities (serialized untagged: `{"temperature": T}` or
/// `{"sigmoids": […]}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Calibration {
    /// One temperature for every class: P_k = exp(T f_k) / Σ_j exp(T f_j).
    Softmax {
        /// T > 0, fitted by maximum likelihood on held-out decision values.
        temperature: f64,
    },
    /// One sigmoid per class, then normalized (older model files).
    Platt {
        /// Each class's sigmoid, in class order.
        sigmoids: Vec<Sigmoid>,
    },
}

impl Calibration {
    /// Probabilities from decision values, summing to 1; a class whose decision value is −∞
    /// (no training rows) gets 0.
    pub fn probabilities(&self, dec: &[f64]) -> Vec<f64> {
        match self {
            Calibration::Softmax { temperature } => softmax(*temperature, dec),
            Calibration::Platt { sigmoids } => {
                let raw: Vec<f64> = sigmoids
                    .iter()
                    .zip(dec)
                    .map(|(s, &f)| {
                        if f == f64::NEG_INFINITY {
                            0.0
                        } else {
                            s.probability(f)
                        }
                    })
                    .collect();
                normalize(raw)
            }
        }
    }

    /// The number of classes it calibrates (`None`: any).
    pub fn classes(&self) -> Option<usize> {
        match self {
            Calibration::Softmax { .. } => None,
            Calibration::Platt { sigmoids } => Some(sigmoids.len()),
        }
    }

    /// Every parameter finite (and the temperature positive).
    pub fn is_valid(&self) -> bool {
        match self {
            Calibration::Softmax { temperature } => temperature.is_finite() && *temperature > 0.0,
            Calibration::Platt { sigmoids } => {
                sigmoids.iter().all(|s| s.a.is_finite() && s.b.is_finite())
            }
        }
    }
}

/// exp(t·f_k) / Σ_j exp(t·f_j), shifted by the largest finite value so nothing overflows;
/// −∞ gives 0, and no finite value at all gives the uniform distribution.
pub fn softmax(t: f64, dec: &[f64]) -> Vec<f64> {
    let top = dec
        .iter()
        .copied()
        .filter(|f| f.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    if top == f64::NEG_INFINITY {
        return normalize(vec![0.0; dec.len()]);
    }
    let raw = dec
        .iter()
        .map(|&f| {
            if f.is_finite() {
                (t * (f - top)).exp()
            } else {
                0.0
            }
        })
        .collect();
    normalize(raw)
}

/// Mean negative log-likelihood of the labels under softmax(t·f), and its first and second
/// derivatives in t.
fn softmax_loss(t: f64, dec: &[Vec<f64>], labels: &[usize]) -> (f64, f64, f64) {
    let (mut loss, mut d1, mut d2) = (0.0, 0.0, 0.0);
    for (f, &y) in dec.iter().zip(labels) {
        let p = softmax(t, f);
        let finite = |k: usize| f[k].is_finite();
        let mean: f64 = (0..f.len())
            .filter(|&k| finite(k))
            .map(|k| p[k] * f[k])
            .sum();
        let second: f64 = (0..f.len())
            .filter(|&k| finite(k))
            .map(|k| p[k] * f[k] * f[k])
            .sum();
        loss -= p[y].max(1e-300).ln();
        d1 += mean - f[y];
        d2 += second - mean * mean;
    }
    let n = dec.len().max(1) as f64;
    (loss / n, d1 / n, d2 / n)
}

/// The temperature t ∈ [1e-3, 1e3] minimizing the mean log-loss of softmax(t·f) on
/// held-out decision values `dec` (one vector per row, class order) with true classes
/// `labels`: Newton's method on a convex function of t, safeguarded by bisection.
/// Rows whose true class has a decision value of −∞ are skipped.
pub fn fit_temperature(dec: &[Vec<f64>], labels: &[usize]) -> f64 {
    let (dec, labels): (Vec<Vec<f64>>, Vec<usize>) = dec
        .iter()
        .zip(labels)
        .filter(|(f, y)| f.get(**y).is_some_and(|v| v.is_finite()))
        .map(|(f, &y)| (f.clone(), y))
        .unzip();
    let (mut lo, mut hi) = (1e-3f64, 1e3f64);
    if dec.is_empty() {
        return 1.0;
    }
    let mut t = 1.0;
    for _ in 0..100 {
        let (_, g, h) = softmax_loss(t, &dec, &labels);
        if g > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        if g.abs() < 1e-10 || hi / lo < 1.0 + 1e-12 {
            break;
        }
        let newton = t - g / h;
        t = if h > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            (lo * hi).sqrt()
        };
    }
    t
}

/// Scales to sum 1 (uniform if the sum is not positive and finite).
pub fn normalize(mut p: Vec<f64>) -> Vec<f64> {
    let sum: f64 = p.iter().sum();
    if sum > 0.0 && sum.is_finite() {
        p.iter_mut().for_each(|v| *v /= sum);
    } else {
        let u = 1.0 / p.len().max(1) as f64;
        p.iter_mut().for_each(|v| *v = u);
    }
    p
}

/// Stratified fold assignment: each class's rows are shuffled with `rng` and dealt to the
/// folds in turn (the class's first row to fold 0, …), continuing the rotation across
/// classes so fold sizes stay balanced. Returns the fold of every row.
pub fn stratified_folds(labels: &[usize], n_classes: usize, k: usize, rng: &mut Rng) -> Vec<usize> {
    let mut fold = vec![0; labels.len()];
    let mut next = 0;
    for class in 0..n_classes {
        let mut members: Vec<usize> = (0..labels.len()).filter(|&i| labels[i] == class).collect();
        rng.shuffle(&mut members);
        for i in members {
            fold[i] = next % k;
            next += 1;
        }
    }
    fold
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_known_sigmoid() {
        // Labels drawn from P(+|f) = 1/(1 + exp(−2f + 0.5)) at many points.
        let mut rng = Rng::new(9);
        let truth = Sigmoid { a: -2.0, b: 0.5 };
        let mut dec = Vec::new();
        let mut pos = Vec::new();
        for _ in 0..40_000 {
            let f = rng.next_f64() * 6.0 - 3.0;
            dec.push(f);
            pos.push(rng.next_f64() < truth.probability(f));
        }
        let fit = Sigmoid::fit(&dec, &pos);
        assert!((fit.a - truth.a).abs() < 0.08, "{fit:?}");
        assert!((fit.b - truth.b).abs() < 0.05, "{fit:?}");
    }

    #[test]
    fn stationary_point_of_the_regularized_objective() {
        let dec = [-2.0, -1.5, -0.3, 0.1, 0.4, 1.2, 2.2, -0.8, 0.9, 1.7];
        let pos = [
            false, false, true, false, true, true, true, false, false, true,
        ];
        let s = Sigmoid::fit(&dec, &pos);
        // Gradient with the prior-corrected targets (5 positives, 5 negatives).
        let (hi, lo) = (6.0 / 7.0, 1.0 / 7.0);
        let (mut g1, mut g2) = (0.0, 0.0);
        for (&f, &p) in dec.iter().zip(&pos) {
            let t = if p { hi } else { lo };
            let d = t - s.probability(f);
            g1 += f * d;
            g2 += d;
        }
        assert!(g1.abs() < 1e-5 && g2.abs() < 1e-5, "{g1} {g2} {s:?}");
        assert!(s.a < 0.0);
        // Perfectly separable data stays finite thanks to the targets.
        let s = Sigmoid::fit(&[-3.0, -2.0, 2.0, 3.0], &[false, false, true, true]);
        assert!(s.a.is_finite() && s.b.is_finite() && s.a < 0.0);
        let p = s.probability(3.0);
        assert!(p > 0.5 && p < 1.0);
    }

    #[test]
    fn probabilities_normalize() {
        let cal = Calibration::Platt {
            sigmoids: vec![Sigmoid { a: -1.0, b: 0.0 }; 3],
        };
        let p = cal.probabilities(&[1.0, 1.0, f64::NEG_INFINITY]);
        assert_eq!(p, [0.5, 0.5, 0.0]);
        let p = cal.probabilities(&[2.0, -1.0, 0.0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(p[0] > p[2] && p[2] > p[1]);
    }

    #[test]
    fn softmax_is_monotone_in_the_decision_values_and_handles_absent_classes() {
        let cal = Calibration::Softmax { temperature: 2.0 };
        let p = cal.probabilities(&[0.5, -1.0, f64::NEG_INFINITY, 1.5]);
        assert_eq!(p[2], 0.0);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(p[3] > p[0] && p[0] > p[1]);
        // Known answer: exp(2·(f − 1.5)) normalized.
        let e = [(-2.0f64).exp(), (-5.0f64).exp(), 1.0];
        let sum: f64 = e.iter().sum();
        assert!((p[3] - 1.0 / sum).abs() < 1e-15);
        assert!((p[0] - e[0] / sum).abs() < 1e-15);
        // Huge decision values do not overflow; no finite value is uniform.
        let p = softmax(1e3, &[1e6, 1e6 - 1.0]);
        assert_eq!(p, [1.0, 0.0]);
        assert_eq!(softmax(1.0, &[f64::NEG_INFINITY; 2]), [0.5, 0.5]);
        let json = serde_json::to_string(&cal).unwrap();
        assert_eq!(json, r#"{"temperature":2.0}"#);
        assert_eq!(serde_json::from_str::<Calibration>(&json).unwrap(), cal);
        let platt: Calibration = serde_json::from_str(r#"{"sigmoids":[{"a":-1,"b":0}]}"#).unwrap();
        assert_eq!(platt.classes(), Some(1));
    }

    #[test]
    fn the_fitted_temperature_is_the_maximum_likelihood_one() {
        // Labels drawn from softmax(3·f): the fit recovers 3, and it is a minimum.
        let mut rng = Rng::new(4);
        let truth = 3.0;
        let (mut dec, mut labels) = (Vec::new(), Vec::new());
        for _ in 0..20_000 {
            let f: Vec<f64> = (0..4).map(|_| rng.next_f64() * 2.0 - 1.0).collect();
            let p = softmax(truth, &f);
            let u = rng.next_f64();
            let mut acc = 0.0;
            let y = p
                .iter()
                .position(|&q| {
                    acc += q;
                    u < acc
                })
                .unwrap_or(3);
            dec.push(f);
            labels.push(y);
        }
        let t = fit_temperature(&dec, &labels);
        assert!((t - truth).abs() < 0.15, "{t}");
        let loss = |t| softmax_loss(t, &dec, &labels).0;
        assert!(loss(t) <= loss(t * 1.01) && loss(t) <= loss(t / 1.01));
        // Separable data: the temperature grows until the loss stops changing, finite.
        let t = fit_temperature(&[vec![1.0, -1.0], vec![-1.0, 1.0]], &[0, 1]);
        assert!(t.is_finite() && t > 10.0, "{t}");
    }

    #[test]
    fn folds_are_stratified_and_seeded() {
        let labels: Vec<usize> = (0..53).map(|i| i % 4).collect();
        let a = stratified_folds(&labels, 4, 5, &mut Rng::new(1));
        let b = stratified_folds(&labels, 4, 5, &mut Rng::new(1));
        let c = stratified_folds(&labels, 4, 5, &mut Rng::new(2));
        assert_eq!(a, b);
        assert_ne!(a, c);
        for f in 0..5 {
            let size = a.iter().filter(|&&x| x == f).count();
            assert!((10..=11).contains(&size));
            for class in 0..4 {
                let n = (0..53).filter(|&i| a[i] == f && labels[i] == class).count();
                assert!((2..=3).contains(&n), "fold {f} class {class}: {n}");
            }
        }
    }
}
