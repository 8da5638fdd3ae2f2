//! Probability calibration: one Platt sigmoid per class, P(class k | f_k) =
//! 1 / (1 + exp(A_k f_k + B_k)), fitted on decision values of a 5-fold internal
//! cross-validation, then normalized across classes to sum to 1.
//!
//! The fit is the method of libsvm's `sigmoid_train` (Lin, Lin & Weng 2007, "A note on
//! Platt's probabilistic outputs for support vector machines"): Newton's method with a
//! backtracking line search on the cross-entropy with Platt's prior-corrected targets
//! (N₊ + 1)/(N₊ + 2) and 1/(N₋ + 2), Hessian regularized by σ = 1e-12, stopping when both
//! gradient components are below 1e-5 (at most 100 iterations, minimum step 1e-10).

use crate::util::rng::Rng;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sigmoid {
    pub a: f64,
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

/// Per-class sigmoids.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    pub sigmoids: Vec<Sigmoid>,
}

impl Calibration {
    /// Normalized probabilities from decision values; a class whose decision value is −∞
    /// (no training rows) gets 0.
    pub fn probabilities(&self, dec: &[f64]) -> Vec<f64> {
        let raw: Vec<f64> = self
            .sigmoids
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
        let cal = Calibration {
            sigmoids: vec![Sigmoid { a: -1.0, b: 0.0 }; 3],
        };
        let p = cal.probabilities(&[1.0, 1.0, f64::NEG_INFINITY]);
        assert_eq!(p, [0.5, 0.5, 0.0]);
        let p = cal.probabilities(&[2.0, -1.0, 0.0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(p[0] > p[2] && p[2] > p[1]);
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
