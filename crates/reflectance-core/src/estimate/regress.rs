//! Regression on the features, for estimating continuous reflectance parameters: ridge
//! regression on random Fourier features of the RBF kernel (Rahimi & Recht 2007), several
//! outputs sharing one solve, with exact leave-one-group-out predictions and split-conformal
//! interval half-widths from them.
//!
//! An RBF kernel ridge regression on n rows costs O(n³); the Fourier map z(x) =
//! √(2/D)·cos(Ωx + b), Ω ~ N(0, 2γ I), b ~ U[0, 2π), approximates the same kernel with D
//! features, so the fit costs O(nD² + D³) and stays practical at tens of thousands of rows.
//! A constant feature carries the intercept.
//!
//! Leaving a group G out of a ridge fit needs no refit: with A = (ZᵀZ + λI)⁻¹ and the
//! in-sample residuals r = y − Z A Zᵀ y, the held-out residuals of G are
//! (I − Z_G A Z_Gᵀ)⁻¹ r_G, exactly.

use crate::learn::error::LearnError;
use crate::util::rng::Rng;
use nalgebra::{DMatrix, DVector};
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How to fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RidgeSpec {
    /// Random Fourier features D.
    pub features: usize,
    /// RBF kernel exp(−γ‖x − x'‖²) the features approximate.
    pub gamma: f64,
    /// Ridge penalty λ.
    pub lambda: f64,
    /// The seed of the random frequencies and phases.
    pub seed: u64,
}

/// The random Fourier map of an RBF kernel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FourierMap {
    /// D × d frequencies, row-major.
    pub omega: Vec<f64>,
    /// D phases, uniform in [0, 2π).
    pub phase: Vec<f64>,
    /// Input dimension d.
    pub inputs: usize,
}

/// Standard normal by Box–Muller.
fn gaussian(rng: &mut Rng) -> f64 {
    let u = 1.0 - rng.next_f64();
    let v = rng.next_f64();
    (-2.0 * u.ln()).sqrt() * (2.0 * PI * v).cos()
}

impl FourierMap {
    /// D frequencies drawn from N(0, 2γ) per input and D uniform phases, from the spec's seed.
    pub fn new(inputs: usize, spec: &RidgeSpec) -> FourierMap {
        let mut rng = Rng::fork(spec.seed, 0x4646_5452);
        let scale = (2.0 * spec.gamma).sqrt();
        let omega = (0..spec.features * inputs)
            .map(|_| scale * gaussian(&mut rng))
            .collect();
        let phase = (0..spec.features)
            .map(|_| 2.0 * PI * rng.next_f64())
            .collect();
        FourierMap {
            omega,
            phase,
            inputs,
        }
    }

    fn features(&self) -> usize {
        self.phase.len()
    }

    /// z(x) and the constant 1: D + 1 values.
    pub fn map(&self, x: &[f64]) -> Vec<f64> {
        let d = self.features();
        let norm = (2.0 / d as f64).sqrt();
        let mut z: Vec<f64> = (0..d)
            .map(|k| {
                let w = &self.omega[k * self.inputs..(k + 1) * self.inputs];
                let dot: f64 = w.iter().zip(x).map(|(a, b)| a * b).sum();
                norm * (dot + self.phase[k]).cos()
            })
            .collect();
        z.push(1.0);
        z
    }

    fn map_rows(&self, x: ArrayView2<f64>) -> DMatrix<f64> {
        let rows: Vec<Vec<f64>> = (0..x.nrows())
            .into_par_iter()
            .map(|i| self.map(&x.row(i).to_vec()))
            .collect();
        let width = self.features() + 1;
        DMatrix::from_fn(rows.len(), width, |i, j| rows[i][j])
    }
}

/// A fitted multi-output ridge regression.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ridge {
    /// The random Fourier map of the inputs.
    pub map: FourierMap,
    /// (D + 1) × outputs, row-major.
    pub weights: Vec<f64>,
    /// Number of outputs.
    pub outputs: usize,
}

impl Ridge {
    /// Each output's prediction: the mapped row (with its constant 1) times the weights.
    pub fn predict(&self, x: &[f64]) -> Vec<f64> {
        let z = self.map.map(x);
        (0..self.outputs)
            .map(|o| {
                z.iter()
                    .enumerate()
                    .map(|(k, v)| v * self.weights[k * self.outputs + o])
                    .sum()
            })
            .collect()
    }
}

/// What a fit leaves behind: the model, and each row's prediction by the fit without its
/// group (when groups were given).
pub struct Fitted {
    /// The fitted regression.
    pub ridge: Ridge,
    /// Each row's prediction by the fit without its group (rows × outputs), when groups were
    /// given.
    pub held_out: Option<Array2<f64>>,
}

fn check(x: ArrayView2<f64>, y: ArrayView2<f64>, spec: &RidgeSpec) -> Result<(), LearnError> {
    let positive = |v: f64| v > 0.0;
    if spec.features == 0 || !positive(spec.gamma) || !positive(spec.lambda) {
        return Err(LearnError::InvalidParameter(format!(
            "regression needs D ≥ 1 features, γ > 0 and λ > 0, not {}, {} and {}",
            spec.features, spec.gamma, spec.lambda
        )));
    }
    check_data(x, y)
}

/// A regression's data: as many target rows as feature rows (> 0), every value finite.
pub(crate) fn check_data(x: ArrayView2<f64>, y: ArrayView2<f64>) -> Result<(), LearnError> {
    let bad = |what: String| Err(LearnError::InvalidParameter(what));
    if x.nrows() != y.nrows() || x.nrows() == 0 {
        return bad(format!(
            "regression needs as many target rows as feature rows (> 0), not {} and {}",
            y.nrows(),
            x.nrows()
        ));
    }
    if x.iter().chain(y.iter()).any(|v| !v.is_finite()) {
        return bad("regression inputs and targets must be finite".into());
    }
    Ok(())
}

/// Fit `y` (n × outputs) on `x` (n × inputs); with `groups` (one id per row), also every
/// row's prediction with its whole group left out.
pub fn fit(
    x: ArrayView2<f64>,
    y: ArrayView2<f64>,
    groups: Option<&[usize]>,
    spec: &RidgeSpec,
) -> Result<Fitted, LearnError> {
    check(x, y, spec)?;
    let map = FourierMap::new(x.ncols(), spec);
    let z = map.map_rows(x);
    let targets = DMatrix::from_fn(y.nrows(), y.ncols(), |i, j| y[[i, j]]);
    let mut gram = z.transpose() * &z;
    for k in 0..gram.nrows() {
        gram[(k, k)] += spec.lambda;
    }
    let inverse = gram
        .cholesky()
        .ok_or_else(|| LearnError::Numerical("the ridge system is not positive definite".into()))?
        .inverse();
    let weights = &inverse * (z.transpose() * &targets);
    let held_out = groups
        .map(|g| held_out_predictions(&z, &targets, &weights, &inverse, g))
        .transpose()?;
    let outputs = y.ncols();
    let ridge = Ridge {
        map,
        weights: (0..weights.nrows())
            .flat_map(|k| (0..outputs).map(move |o| (k, o)))
            .map(|(k, o)| weights[(k, o)])
            .collect(),
        outputs,
    };
    Ok(Fitted { ridge, held_out })
}

/// (row, its held-out prediction of every output) for the rows of one group.
type GroupPredictions = Vec<(usize, Vec<f64>)>;

/// Each row's prediction by the fit without its group: ŷ_G = y_G − (I − Z_G A Z_Gᵀ)⁻¹ r_G.
fn held_out_predictions(
    z: &DMatrix<f64>,
    y: &DMatrix<f64>,
    weights: &DMatrix<f64>,
    inverse: &DMatrix<f64>,
    groups: &[usize],
) -> Result<Array2<f64>, LearnError> {
    let residuals = y - z * weights;
    let mut ids: Vec<usize> = groups.to_vec();
    ids.sort_unstable();
    ids.dedup();
    let per_group: Vec<Result<GroupPredictions, LearnError>> = ids
        .par_iter()
        .map(|&g| {
            let rows: Vec<usize> = (0..groups.len()).filter(|&i| groups[i] == g).collect();
            group_predictions(z, y, &residuals, inverse, &rows, g)
        })
        .collect();
    let mut predictions = Array2::zeros((groups.len(), y.ncols()));
    for group in per_group {
        for (i, values) in group? {
            for (o, v) in values.into_iter().enumerate() {
                predictions[[i, o]] = v;
            }
        }
    }
    Ok(predictions)
}

fn group_predictions(
    z: &DMatrix<f64>,
    y: &DMatrix<f64>,
    residuals: &DMatrix<f64>,
    inverse: &DMatrix<f64>,
    rows: &[usize],
    group: usize,
) -> Result<GroupPredictions, LearnError> {
    let zg = z.select_rows(rows);
    let leverage = &zg * inverse * zg.transpose();
    let lu = (DMatrix::identity(rows.len(), rows.len()) - leverage).lu();
    let mut corrected = DMatrix::zeros(rows.len(), y.ncols());
    for o in 0..y.ncols() {
        let r = DVector::from_iterator(rows.len(), rows.iter().map(|&i| residuals[(i, o)]));
        let e = lu.solve(&r).ok_or_else(|| {
            LearnError::Numerical(format!(
                "group {group} cannot be left out: it alone determines the fit"
            ))
        })?;
        corrected.set_column(o, &e);
    }
    Ok(rows
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            (
                i,
                (0..y.ncols())
                    .map(|o| y[(i, o)] - corrected[(k, o)])
                    .collect(),
            )
        })
        .collect())
}

/// The split-conformal half-width for `coverage` from held-out absolute residuals: the
/// ⌈(n + 1)·coverage⌉-th smallest, or the largest when there are too few residuals for
/// that rank (then the coverage guarantee is weaker than asked); infinite for none.
pub fn conformal_half_width(abs_residuals: &[f64], coverage: f64) -> f64 {
    let n = abs_residuals.len();
    let rank = (((n as f64 + 1.0) * coverage).ceil() as usize).clamp(1, n.max(1));
    if n == 0 {
        return f64::INFINITY;
    }
    let mut sorted = abs_residuals.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[rank - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(features: usize) -> RidgeSpec {
        RidgeSpec {
            features,
            gamma: 0.5,
            lambda: 1e-3,
            seed: 3,
        }
    }

    /// n rows of 3 inputs in [−1.5, 1.5], targets sin(x0) + x1² and x2·x0, groups of 10.
    fn data(n: usize, seed: u64) -> (Array2<f64>, Array2<f64>, Vec<usize>) {
        let mut rng = Rng::new(seed);
        let x = Array2::from_shape_fn((n, 3), |_| 3.0 * rng.next_f64() - 1.5);
        let y = Array2::from_shape_fn((n, 2), |(i, o)| match o {
            0 => x[[i, 0]].sin() + x[[i, 1]].powi(2),
            _ => x[[i, 2]] * x[[i, 0]],
        });
        (x, y, (0..n).map(|i| i / 10).collect())
    }

    #[test]
    fn held_out_predictions_equal_refits_without_the_group() {
        let (x, y, groups) = data(60, 1);
        let s = spec(40);
        let fitted = fit(x.view(), y.view(), Some(&groups), &s).unwrap();
        let held_out = fitted.held_out.unwrap();
        for g in [0, 3, 5] {
            let keep: Vec<usize> = (0..60).filter(|&i| groups[i] != g).collect();
            let refit = fit(
                x.select(ndarray::Axis(0), &keep).view(),
                y.select(ndarray::Axis(0), &keep).view(),
                None,
                &s,
            )
            .unwrap()
            .ridge;
            for i in (0..60).filter(|&i| groups[i] == g) {
                let direct = refit.predict(x.row(i).as_slice().unwrap());
                for o in 0..2 {
                    let (a, b) = (held_out[[i, o]], direct[o]);
                    assert!(
                        (a - b).abs() < 1e-7 * (1.0 + b.abs()),
                        "row {i}: {a} vs {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn learns_a_smooth_function_and_its_intervals_cover() {
        let (x, y, groups) = data(800, 2);
        let fitted = fit(x.view(), y.view(), Some(&groups), &spec(300)).unwrap();
        let held_out = fitted.held_out.unwrap();
        let residuals: Vec<f64> = (0..800)
            .map(|i| (y[[i, 0]] - held_out[[i, 0]]).abs())
            .collect();
        let mae = residuals.iter().sum::<f64>() / 800.0;
        assert!(mae < 0.05, "held-out MAE {mae}");
        let q = conformal_half_width(&residuals, 0.9);
        let (tx, ty, _) = data(1000, 9);
        let covered = (0..1000)
            .filter(|&i| {
                (fitted.ridge.predict(tx.row(i).as_slice().unwrap())[0] - ty[[i, 0]]).abs() <= q
            })
            .count();
        assert!(
            (860..=940).contains(&covered),
            "covered {covered} of 1000 at 90 %"
        );
    }

    #[test]
    fn conformal_ranks_and_small_samples() {
        let r: Vec<f64> = (1..=9).map(f64::from).collect();
        // n = 9: rank ⌈10·0.8⌉ = 8.
        assert_eq!(conformal_half_width(&r, 0.8), 8.0);
        assert_eq!(conformal_half_width(&r, 0.95), 9.0);
        assert_eq!(conformal_half_width(&[], 0.9), f64::INFINITY);
    }

    #[test]
    fn fits_are_deterministic_and_inputs_checked() {
        let (x, y, _) = data(50, 4);
        let a = fit(x.view(), y.view(), None, &spec(20)).unwrap().ridge;
        let b = fit(x.view(), y.view(), None, &spec(20)).unwrap().ridge;
        assert_eq!(a, b);
        let mut bad = x.clone();
        bad[[3, 1]] = f64::NAN;
        assert!(fit(bad.view(), y.view(), None, &spec(20)).is_err());
        assert!(fit(x.view(), y.slice(ndarray::s![..40, ..]), None, &spec(20)).is_err());
        let zero = RidgeSpec {
            lambda: 0.0,
            ..spec(20)
        };
        assert!(fit(x.view(), y.view(), None, &zero).is_err());
    }
}
