//! RBF C-SVC: kernel matrix, an SMO solver in the manner of libsvm's `Solver` (Fan, Chen &
//! Lin 2005: second-order working-set selection "WSS3", τ = 1e-12, stopping tolerance
//! ε = 1e-3, shrinking with one unshrink near the end, bias averaged over the free support
//! vectors), and the one-against-all model.
//!
//! The kernel matrix of the training rows is computed once per fit and shared by every
//! one-against-all binary problem, and by the internal cross-validation of the Platt
//! calibration (which solves the same problems on subsets of the rows). Its element type
//! is a parameter ([`KernelValue`]: `f64`, or `f32` like libsvm's `Qfloat`); the pipeline
//! uses `f64` (see `benches/learn.rs` and docs/performance.md for the measurement: with the whole matrix
//! in memory, f32 saves memory bandwidth only, and the difference is within noise at these
//! sizes, while f64 makes training and prediction use identical kernel values).

use crate::learn::Inconsistent;

use ndarray::ArrayView2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Element type of a kernel matrix.
pub trait KernelValue: Copy + Send + Sync + Default + 'static {
    /// The value stored for a kernel value (rounded for `f32`).
    fn from_f64(v: f64) -> Self;
    /// The stored value as `f64`.
    fn get(self) -> f64;
}

impl KernelValue for f64 {
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn get(self) -> f64 {
        self
    }
}

impl KernelValue for f32 {
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn get(self) -> f64 {
        f64::from(self)
    }
}

/// ‖a − b‖² over the common length, summed in four interleaved partial sums (so the
/// compiler can vectorize it; the order is fixed, so results are reproducible).
#[inline]
pub fn squared_distance(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut acc = [0.0f64; 4];
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            let d = x[k] - y[k];
            acc[k] += d * d;
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in ra.iter().zip(rb) {
        let d = x - y;
        s += d * d;
    }
    s
}

/// exp(−γ‖a − b‖²).
#[inline]
pub fn rbf(a: &[f64], b: &[f64], gamma: f64) -> f64 {
    (-gamma * squared_distance(a, b)).exp()
}

/// A dense symmetric kernel matrix.
#[derive(Clone, Debug)]
pub struct Gram<T> {
    n: usize,
    values: Vec<T>,
}

impl<T: KernelValue> Gram<T> {
    /// RBF kernel matrix of the rows of `x` (computed in parallel; exactly symmetric).
    pub fn rbf(x: ArrayView2<f64>, gamma: f64) -> Self {
        let n = x.nrows();
        let x = x.as_standard_layout();
        let d = x.ncols();
        let flat = x.as_slice().unwrap_or(&[]);
        let row = |i: usize| &flat[i * d..(i + 1) * d];
        let mut values = vec![T::default(); n * n];
        values
            .par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(i, out)| {
                for (j, o) in out.iter_mut().enumerate().skip(i) {
                    *o = T::from_f64(rbf(row(i), row(j), gamma));
                }
            });
        for i in 0..n {
            for j in 0..i {
                values[i * n + j] = values[j * n + i];
            }
        }
        Gram { n, values }
    }

    /// Number of rows (the matrix is n × n).
    pub fn n(&self) -> usize {
        self.n
    }

    /// Row `i`'s kernel values.
    #[inline(always)]
    pub fn row(&self, i: usize) -> &[T] {
        &self.values[i * self.n..(i + 1) * self.n]
    }

    /// K(x_i, x_j).
    #[inline(always)]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.values[i * self.n + j].get()
    }
}

/// Parameters of the binary solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverParams {
    /// Upper bound of every α (the same for both classes).
    pub c: f64,
    /// Stopping tolerance on the maximal KKT violation m(α) − M(α).
    pub eps: f64,
    /// Replaces a non-positive curvature in the working-set selection and the update.
    pub tau: f64,
    /// Whether to shrink the active set (with one unshrink near the end, as libsvm does).
    pub shrinking: bool,
    /// Iteration limit; 0 means libsvm's max(10⁷, 100·l).
    pub max_iter: usize,
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            c: 100.0,
            eps: 1e-3,
            tau: 1e-12,
            shrinking: true,
            max_iter: 0,
        }
    }
}

/// Solution of one binary C-SVC dual, in the order of the `rows` it was given.
#[derive(Clone, Debug, PartialEq)]
pub struct BinarySolution {
    /// 0 ≤ α_i ≤ C.
    pub alpha: Vec<f64>,
    /// Labels ±1.
    pub y: Vec<i8>,
    /// Decision function f(x) = Σ y_i α_i K(x_i, x) − ρ.
    pub rho: f64,
    /// Final dual gradient G_i = (Qα)_i − 1 (all rows, after the final reconstruction).
    pub gradient: Vec<f64>,
    /// Iterations the solver took.
    pub iterations: usize,
    /// False if the iteration limit stopped the solver.
    pub converged: bool,
}

impl BinarySolution {
    /// y_i α_i of row i.
    pub fn coef(&self, i: usize) -> f64 {
        f64::from(self.y[i]) * self.alpha[i]
    }

    /// Number of support vectors (α_i > 0).
    pub fn n_sv(&self) -> usize {
        self.alpha.iter().filter(|&&a| a > 0.0).count()
    }

    /// f at training row `g` (a Gram index), for a solution over `rows` of the same Gram.
    pub fn decision_at<T: KernelValue>(&self, gram: &Gram<T>, rows: &[usize], g: usize) -> f64 {
        let kg = gram.row(g);
        let mut s = 0.0;
        for (i, &r) in rows.iter().enumerate() {
            let a = self.alpha[i];
            if a > 0.0 {
                s += f64::from(self.y[i]) * a * kg[r].get();
            }
        }
        s - self.rho
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Bound {
    Lower,
    Upper,
    Free,
}

struct Solver<'a, T> {
    gram: &'a Gram<T>,
    l: usize,
    active_size: usize,
    /// Per position (positions are permuted by shrinking, as libsvm's `swap_index`):
    gi: Vec<usize>,
    y: Vec<f64>,
    alpha: Vec<f64>,
    status: Vec<Bound>,
    g: Vec<f64>,
    g_bar: Vec<f64>,
    orig: Vec<usize>,
    qd: Vec<f64>,
    c: f64,
    eps: f64,
    tau: f64,
    unshrink: bool,
}

impl<T: KernelValue> Solver<'_, T> {
    #[inline(always)]
    fn is_upper(&self, t: usize) -> bool {
        self.status[t] == Bound::Upper
    }

    #[inline(always)]
    fn is_lower(&self, t: usize) -> bool {
        self.status[t] == Bound::Lower
    }

    fn bound_of(&self, a: f64) -> Bound {
        if a >= self.c {
            Bound::Upper
        } else if a <= 0.0 {
            Bound::Lower
        } else {
            Bound::Free
        }
    }

    fn swap(&mut self, a: usize, b: usize) {
        self.gi.swap(a, b);
        self.y.swap(a, b);
        self.alpha.swap(a, b);
        self.status.swap(a, b);
        self.g.swap(a, b);
        self.g_bar.swap(a, b);
        self.orig.swap(a, b);
        self.qd.swap(a, b);
    }

    /// WSS3: i maximizes −y_i G_i over I_up; j minimizes the second-order decrease
    /// −(b_ij²)/a_ij over I_low with b_ij > 0. None when m(α) − M(α) < ε.
    fn select_working_set(&self) -> Option<(usize, usize)> {
        let mut gmax = f64::NEG_INFINITY;
        let mut gmax_idx = None;
        for t in 0..self.active_size {
            let v = if self.y[t] > 0.0 {
                if self.is_upper(t) {
                    continue;
                }
                -self.g[t]
            } else {
                if self.is_lower(t) {
                    continue;
                }
                self.g[t]
            };
            if v >= gmax {
                gmax = v;
                gmax_idx = Some(t);
            }
        }
        let i = gmax_idx?;
        let ki = self.gram.row(self.gi[i]);
        let qd_i = self.qd[i];
        let mut gmax2 = f64::NEG_INFINITY;
        let mut gmin_idx = None;
        let mut obj_diff_min = f64::INFINITY;
        for j in 0..self.active_size {
            let gj = self.g[j];
            let (violation, grad_diff) = if self.y[j] > 0.0 {
                if self.is_lower(j) {
                    continue;
                }
                (gj, gmax + gj)
            } else {
                if self.is_upper(j) {
                    continue;
                }
                (-gj, gmax - gj)
            };
            if violation >= gmax2 {
                gmax2 = violation;
            }
            if grad_diff > 0.0 {
                // Q_ii + Q_jj − 2 y_i y_j Q_ij = K_ii + K_jj − 2 K_ij for either sign.
                let quad = qd_i + self.qd[j] - 2.0 * ki[self.gi[j]].get();
                let obj_diff = -(grad_diff * grad_diff) / if quad > 0.0 { quad } else { self.tau };
                if obj_diff <= obj_diff_min {
                    gmin_idx = Some(j);
                    obj_diff_min = obj_diff;
                }
            }
        }
        if gmax + gmax2 < self.eps {
            return None;
        }
        gmin_idx.map(|j| (i, j))
    }

    fn be_shrunk(&self, t: usize, gmax1: f64, gmax2: f64) -> bool {
        let pos = self.y[t] > 0.0;
        match self.status[t] {
            Bound::Upper => -self.g[t] > if pos { gmax1 } else { gmax2 },
            Bound::Lower => self.g[t] > if pos { gmax2 } else { gmax1 },
            Bound::Free => false,
        }
    }

    fn do_shrinking(&mut self) {
        // gmax1 = max −y G over I_up, gmax2 = max y G over I_low.
        let mut gmax1 = f64::NEG_INFINITY;
        let mut gmax2 = f64::NEG_INFINITY;
        for t in 0..self.active_size {
            let g = self.g[t];
            if self.y[t] > 0.0 {
                if !self.is_upper(t) {
                    gmax1 = gmax1.max(-g);
                }
                if !self.is_lower(t) {
                    gmax2 = gmax2.max(g);
                }
            } else {
                if !self.is_upper(t) {
                    gmax2 = gmax2.max(-g);
                }
                if !self.is_lower(t) {
                    gmax1 = gmax1.max(g);
                }
            }
        }
        if !self.unshrink && gmax1 + gmax2 <= self.eps * 10.0 {
            self.unshrink = true;
            self.reconstruct_gradient();
            self.active_size = self.l;
        }
        let mut t = 0;
        while t < self.active_size {
            if self.be_shrunk(t, gmax1, gmax2) {
                self.active_size -= 1;
                while self.active_size > t {
                    if !self.be_shrunk(self.active_size, gmax1, gmax2) {
                        self.swap(t, self.active_size);
                        break;
                    }
                    self.active_size -= 1;
                }
            }
            t += 1;
        }
    }

    /// Recomputes G of the inactive positions from G_bar and the free α.
    fn reconstruct_gradient(&mut self) {
        if self.active_size == self.l {
            return;
        }
        let (a, l) = (self.active_size, self.l);
        let gram = self.gram;
        for t in a..l {
            self.g[t] = self.g_bar[t] - 1.0;
        }
        for i in 0..a {
            if self.status[i] != Bound::Free {
                continue;
            }
            let ki = gram.row(self.gi[i]);
            let w = self.alpha[i] * self.y[i];
            for t in a..l {
                self.g[t] += w * self.y[t] * ki[self.gi[t]].get();
            }
        }
    }

    fn calculate_rho(&self) -> f64 {
        let mut ub = f64::INFINITY;
        let mut lb = f64::NEG_INFINITY;
        let mut sum_free = 0.0;
        let mut n_free = 0usize;
        for t in 0..self.active_size {
            let yg = self.y[t] * self.g[t];
            match (self.status[t], self.y[t] > 0.0) {
                (Bound::Lower, true) | (Bound::Upper, false) => ub = ub.min(yg),
                (Bound::Lower, false) | (Bound::Upper, true) => lb = lb.max(yg),
                (Bound::Free, _) => {
                    n_free += 1;
                    sum_free += yg;
                }
            }
        }
        if n_free > 0 {
            sum_free / n_free as f64
        } else {
            (ub + lb) / 2.0
        }
    }

    fn update_pair(&mut self, i: usize, j: usize) {
        let c = self.c;
        let gram = self.gram;
        let ki = gram.row(self.gi[i]);
        let kj = gram.row(self.gi[j]);
        let kij = ki[self.gi[j]].get();
        let (yi, yj) = (self.y[i], self.y[j]);
        let (old_i, old_j) = (self.alpha[i], self.alpha[j]);
        let mut quad = self.qd[i] + self.qd[j] - 2.0 * kij;
        if quad <= 0.0 {
            quad = self.tau;
        }
        let (mut ai, mut aj) = (old_i, old_j);
        if yi != yj {
            let delta = (-self.g[i] - self.g[j]) / quad;
            let diff = ai - aj;
            ai += delta;
            aj += delta;
            if diff > 0.0 {
                if aj < 0.0 {
                    aj = 0.0;
                    ai = diff;
                }
            } else if ai < 0.0 {
                ai = 0.0;
                aj = -diff;
            }
            if diff > 0.0 {
                // diff > C_i − C_j = 0
                if ai > c {
                    ai = c;
                    aj = c - diff;
                }
            } else if aj > c {
                aj = c;
                ai = c + diff;
            }
        } else {
            let delta = (self.g[i] - self.g[j]) / quad;
            let sum = ai + aj;
            ai -= delta;
            aj += delta;
            clip_to_box(&mut ai, &mut aj, sum, c);
            clip_to_box(&mut aj, &mut ai, sum, c);
        }
        self.alpha[i] = ai;
        self.alpha[j] = aj;
        // G_t += Q_ti Δα_i + Q_tj Δα_j, with Q_ti = y_t y_i K_ti.
        let wi = yi * (ai - old_i);
        let wj = yj * (aj - old_j);
        for t in 0..self.active_size {
            let gt = self.gi[t];
            self.g[t] += self.y[t] * (wi * ki[gt].get() + wj * kj[gt].get());
        }
        for (p, old, k) in [(i, old_i, ki), (j, old_j, kj)] {
            let was_upper = old >= c;
            let status = self.bound_of(self.alpha[p]);
            self.status[p] = status;
            let is_upper = status == Bound::Upper;
            if was_upper != is_upper {
                let w = (if is_upper { c } else { -c }) * self.y[p];
                for t in 0..self.l {
                    self.g_bar[t] += w * self.y[t] * k[self.gi[t]].get();
                }
            }
        }
    }
}

/// Solves the C-SVC dual for the Gram rows `rows` with labels `y` (±1, same length as
/// `rows`), starting at α = 0.
/// A problem whose labels are all equal has α = 0 and f ≡ that label (libsvm's convention
/// for a one-class training fold).
pub fn solve<T: KernelValue>(
    gram: &Gram<T>,
    rows: &[usize],
    y: &[i8],
    params: &SolverParams,
) -> BinarySolution {
    let l = rows.len();
    let all_same = y.iter().all(|&v| v == y[0]);
    if l == 0 || all_same {
        return BinarySolution {
            alpha: vec![0.0; l],
            y: y.to_vec(),
            rho: -f64::from(y.first().copied().unwrap_or(1)),
            gradient: vec![-1.0; l],
            iterations: 0,
            converged: true,
        };
    }
    let mut s = Solver {
        gram,
        l,
        active_size: l,
        gi: rows.to_vec(),
        y: y.iter().map(|&v| if v > 0 { 1.0 } else { -1.0 }).collect(),
        alpha: vec![0.0; l],
        status: vec![Bound::Lower; l],
        g: vec![-1.0; l],
        g_bar: vec![0.0; l],
        orig: (0..l).collect(),
        qd: rows.iter().map(|&r| gram.get(r, r)).collect(),
        c: params.c,
        eps: params.eps,
        tau: params.tau,
        unshrink: false,
    };
    let max_iter = if params.max_iter > 0 {
        params.max_iter
    } else {
        10_000_000usize.max(l.saturating_mul(100))
    };
    let mut counter = l.min(1000) + 1;
    let mut iter = 0;
    let mut converged = false;
    while iter < max_iter {
        counter -= 1;
        if counter == 0 {
            counter = l.min(1000);
            if params.shrinking {
                s.do_shrinking();
            }
        }
        let (i, j) = match s.select_working_set() {
            Some(ij) => ij,
            None => {
                s.reconstruct_gradient();
                s.active_size = l;
                match s.select_working_set() {
                    Some(ij) => {
                        counter = 1;
                        ij
                    }
                    None => {
                        converged = true;
                        break;
                    }
                }
            }
        };
        iter += 1;
        s.update_pair(i, j);
    }
    if !converged && s.active_size < l {
        s.reconstruct_gradient();
        s.active_size = l;
    }
    let rho = s.calculate_rho();
    let mut alpha = vec![0.0; l];
    let mut gradient = vec![0.0; l];
    for p in 0..l {
        alpha[s.orig[p]] = s.alpha[p];
        gradient[s.orig[p]] = s.g[p];
    }
    BinarySolution {
        alpha,
        y: y.to_vec(),
        rho,
        gradient,
        iterations: iter,
        converged,
    }
}

/// One binary problem per class (class k = +1, the rest −1) over the Gram rows `rows`
/// whose classes are `labels`, solved in parallel. `None` for a class without rows.
pub fn train_one_vs_all<T: KernelValue>(
    gram: &Gram<T>,
    rows: &[usize],
    labels: &[usize],
    n_classes: usize,
    params: &SolverParams,
) -> Vec<Option<BinarySolution>> {
    (0..n_classes)
        .into_par_iter()
        .map(|k| {
            if !labels.contains(&k) {
                return None;
            }
            let y: Vec<i8> = labels
                .iter()
                .map(|&l| if l == k { 1 } else { -1 })
                .collect();
            Some(solve(gram, rows, &y, params))
        })
        .collect()
}

/// The fitted one-against-all SVM: the union of the support vectors stored once, with one
/// coefficient row per class.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SvmModel {
    /// Always "rbf": K(a, b) = exp(−γ‖a − b‖²).
    pub kernel: String,
    /// RBF γ (> 0).
    pub gamma: f64,
    /// The C it was trained with (> 0).
    pub c: f64,
    /// Support vectors (standardized feature space), each a row.
    pub support_vectors: Vec<Vec<f64>>,
    /// coef[k][s] = y_s α_s of support vector s in class k's problem (0 if not its SV).
    pub coef: Vec<Vec<f64>>,
    /// Bias of each class's decision function f_k(x) = Σ_s coef[k][s] K(sv_s, x) − ρ_k.
    pub rho: Vec<f64>,
    /// False for a class that had no training rows: f_k = −∞, never predicted.
    pub trained: Vec<bool>,
}

impl SvmModel {
    /// Collects the model from one-against-all solutions over `rows` of the training
    /// matrix `z` (standardized features).
    pub fn from_solutions(
        z: ArrayView2<f64>,
        rows: &[usize],
        solutions: &[Option<BinarySolution>],
        gamma: f64,
        c: f64,
    ) -> SvmModel {
        let is_sv: Vec<bool> = (0..rows.len())
            .map(|i| solutions.iter().flatten().any(|s| s.alpha[i] > 0.0))
            .collect();
        let sv_pos: Vec<usize> = (0..rows.len()).filter(|&i| is_sv[i]).collect();
        SvmModel {
            kernel: "rbf".into(),
            gamma,
            c,
            support_vectors: sv_pos.iter().map(|&i| z.row(rows[i]).to_vec()).collect(),
            coef: solutions
                .iter()
                .map(|s| match s {
                    Some(s) => sv_pos.iter().map(|&i| s.coef(i)).collect(),
                    None => vec![0.0; sv_pos.len()],
                })
                .collect(),
            rho: solutions
                .iter()
                .map(|s| s.as_ref().map_or(0.0, |s| s.rho))
                .collect(),
            trained: solutions.iter().map(Option::is_some).collect(),
        }
    }

    /// Number of classes (one decision function each).
    pub fn n_classes(&self) -> usize {
        self.rho.len()
    }

    /// Number of distinct support vectors over every class's problem.
    pub fn n_support_vectors(&self) -> usize {
        self.support_vectors.len()
    }

    /// Decision value of every class for one standardized row.
    pub fn decision_values(&self, z: &[f64]) -> Vec<f64> {
        let kernel: Vec<f64> = self
            .support_vectors
            .iter()
            .map(|sv| rbf(sv, z, self.gamma))
            .collect();
        self.coef
            .iter()
            .zip(&self.rho)
            .zip(&self.trained)
            .map(|((coef, rho), &trained)| {
                if trained {
                    coef.iter().zip(&kernel).map(|(a, k)| a * k).sum::<f64>() - rho
                } else {
                    f64::NEG_INFINITY
                }
            })
            .collect()
    }

    pub(crate) fn check(&self, dim: usize) -> Result<(), Inconsistent> {
        let k = self.rho.len();
        let n_sv = self.support_vectors.len();
        if self.kernel != "rbf" {
            return Err(Inconsistent(format!(
                "unsupported kernel {:?}",
                self.kernel
            )));
        }
        if !(self.gamma.is_finite() && self.gamma > 0.0) {
            return Err(Inconsistent(format!(
                "gamma {} is not positive",
                self.gamma
            )));
        }
        if self.coef.len() != k || self.trained.len() != k {
            return Err(Inconsistent("SVM class counts disagree".into()));
        }
        if self.coef.iter().any(|c| c.len() != n_sv)
            || self.support_vectors.iter().any(|s| s.len() != dim)
        {
            return Err(Inconsistent(
                "SVM support vector dimensions disagree".into(),
            ));
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !finite(&self.rho)
            || !self.coef.iter().all(|c| finite(c))
            || !self.support_vectors.iter().all(|s| finite(s))
        {
            return Err(Inconsistent("SVM has non-finite values".into()));
        }
        Ok(())
    }
}

/// The index of the largest value, the first on ties (NaN never wins).
pub fn argmax(values: &[f64]) -> usize {
    let mut best = 0;
    for (k, &v) in values.iter().enumerate() {
        if v > values[best] || values[best].is_nan() && !v.is_nan() {
            best = k;
        }
    }
    best
}

/// libsvm's clipping of a pair whose sum is fixed (equal labels): bring `first` under C (when
/// the sum allows) or `second` up to 0, moving the rest to the other. Called once for each
/// order of the pair.
fn clip_to_box(first: &mut f64, second: &mut f64, sum: f64, c: f64) {
    if sum > c {
        if *first > c {
            *first = c;
            *second = sum - c;
        }
    } else if *second < 0.0 {
        *second = 0.0;
        *first = sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::rng::Rng;
    use ndarray::{Array2, array};

    fn all_rows(n: usize) -> Vec<usize> {
        (0..n).collect()
    }

    /// KKT conditions of the C-SVC dual at tolerance `tol`, from the solution's own
    /// decision values: α = 0 ⇒ y f ≥ 1 − tol; 0 < α < C ⇒ |y f − 1| ≤ tol; α = C ⇒
    /// y f ≤ 1 + tol; and Σ y α = 0, 0 ≤ α ≤ C.
    fn assert_kkt<T: KernelValue>(gram: &Gram<T>, sol: &BinarySolution, c: f64, tol: f64) {
        let rows = all_rows(gram.n());
        let mut balance = 0.0;
        for i in 0..rows.len() {
            let a = sol.alpha[i];
            assert!((0.0..=c).contains(&a), "α_{i} = {a}");
            let yf = f64::from(sol.y[i]) * sol.decision_at(gram, &rows, i);
            if a == 0.0 {
                assert!(yf >= 1.0 - tol, "α=0 but y f = {yf} at {i}");
            } else if a == c {
                assert!(yf <= 1.0 + tol, "α=C but y f = {yf} at {i}");
            } else {
                assert!((yf - 1.0).abs() <= tol, "free but y f = {yf} at {i}");
            }
            balance += sol.coef(i);
        }
        assert!(balance.abs() < 1e-9 * c, "Σ y α = {balance}");
    }

    fn blobs(seed: u64, n: usize, sep: f64) -> (Array2<f64>, Vec<usize>) {
        let mut rng = Rng::new(seed);
        let mut x = Array2::zeros((n, 2));
        let mut labels = Vec::new();
        for i in 0..n {
            let k = i % 3;
            labels.push(k);
            let angle = k as f64 * 2.1;
            x[[i, 0]] = sep * angle.cos() + rng.next_f64() * 2.0 - 1.0;
            x[[i, 1]] = sep * angle.sin() + rng.next_f64() * 2.0 - 1.0;
        }
        (x, labels)
    }

    #[test]
    fn two_points_closed_form() {
        let x = array![[0.0], [1.0]];
        let gamma = 0.7;
        let gram = Gram::<f64>::rbf(x.view(), gamma);
        let sol = solve(&gram, &[0, 1], &[1, -1], &SolverParams::default());
        let k = (-gamma).exp();
        let a = 1.0 / (1.0 - k);
        assert!((sol.alpha[0] - a).abs() < 1e-12 && (sol.alpha[1] - a).abs() < 1e-12);
        assert!(sol.rho.abs() < 1e-12);
        assert!((sol.decision_at(&gram, &[0, 1], 0) - 1.0).abs() < 1e-12);
        assert!((sol.decision_at(&gram, &[0, 1], 1) + 1.0).abs() < 1e-12);
        // With C below the unconstrained optimum both α sit at the bound, and with no
        // free SV ρ is the midpoint of the feasible interval (0 by symmetry).
        let params = SolverParams {
            c: 0.5,
            ..SolverParams::default()
        };
        let sol = solve(&gram, &[0, 1], &[1, -1], &params);
        assert_eq!(sol.alpha, [0.5, 0.5]);
        assert!(sol.rho.abs() < 1e-12);
    }

    #[test]
    fn separable_problem_is_separated_and_kkt_holds() {
        let (x, labels) = blobs(1, 90, 4.0);
        let gram = Gram::<f64>::rbf(x.view(), 0.5);
        let y: Vec<i8> = labels
            .iter()
            .map(|&l| if l == 0 { 1 } else { -1 })
            .collect();
        let rows = all_rows(90);
        let sol = solve(&gram, &rows, &y, &SolverParams::default());
        assert!(sol.converged);
        for (i, &yi) in y.iter().enumerate() {
            assert!(f64::from(yi) * sol.decision_at(&gram, &rows, i) > 0.0);
        }
        assert_kkt(&gram, &sol, 100.0, 2e-3);
        // Few support vectors on well-separated blobs.
        assert!(sol.n_sv() < 30, "{}", sol.n_sv());
    }

    #[test]
    fn overlapping_problem_kkt_with_and_without_shrinking() {
        let (x, labels) = blobs(2, 300, 1.0);
        for c in [1.0, 100.0] {
            let gram = Gram::<f64>::rbf(x.view(), 2.0);
            let y: Vec<i8> = labels
                .iter()
                .map(|&l| if l == 1 { 1 } else { -1 })
                .collect();
            let rows = all_rows(300);
            let mut params = SolverParams {
                c,
                ..SolverParams::default()
            };
            let a = solve(&gram, &rows, &y, &params);
            assert!(a.iterations > 50);
            assert_kkt(&gram, &a, c, 2e-3);
            params.shrinking = false;
            let b = solve(&gram, &rows, &y, &params);
            assert_kkt(&gram, &b, c, 2e-3);
            // Both stop within ε of the same optimum: decision values agree closely.
            for i in 0..300 {
                let (fa, fb) = (
                    a.decision_at(&gram, &rows, i),
                    b.decision_at(&gram, &rows, i),
                );
                assert!((fa - fb).abs() < 5e-3, "c={c} row {i}: {fa} vs {fb}");
            }
            // Tighter tolerance: tighter KKT.
            params.eps = 1e-6;
            let t = solve(&gram, &rows, &y, &params);
            assert_kkt(&gram, &t, c, 2e-6);
        }
    }

    #[test]
    fn subsets_and_f32_kernel() {
        let (x, labels) = blobs(3, 120, 2.0);
        let g64 = Gram::<f64>::rbf(x.view(), 1.0);
        let g32 = Gram::<f32>::rbf(x.view(), 1.0);
        // A subset of the big Gram equals the Gram of the subset.
        let rows: Vec<usize> = (0..120).filter(|i| i % 4 != 0).collect();
        let sub = x.select(ndarray::Axis(0), &rows);
        let gsub = Gram::<f64>::rbf(sub.view(), 1.0);
        let ys: Vec<i8> = rows
            .iter()
            .map(|&r| if labels[r] == 2 { 1 } else { -1 })
            .collect();
        let p = SolverParams::default();
        let a = solve(&g64, &rows, &ys, &p);
        let b = solve(&gsub, &all_rows(rows.len()), &ys, &p);
        assert_eq!(a, b);
        let c = solve(&g32, &rows, &ys, &p);
        for (i, &r) in rows.iter().enumerate() {
            let fa = a.decision_at(&g64, &rows, r);
            let fc = c.decision_at(&g64, &rows, r);
            assert!((fa - fc).abs() < 1e-2, "{i}: {fa} vs {fc}");
        }
    }

    #[test]
    fn one_vs_all_model_predicts_training_blobs() {
        let (x, labels) = blobs(4, 150, 4.0);
        let gram = Gram::<f64>::rbf(x.view(), 0.5);
        let rows = all_rows(150);
        let sols = train_one_vs_all(&gram, &rows, &labels, 4, &SolverParams::default());
        assert!(sols[3].is_none());
        let model = SvmModel::from_solutions(x.view(), &rows, &sols, 0.5, 100.0);
        model.check(2).unwrap();
        assert_eq!(model.trained, [true, true, true, false]);
        for i in 0..150 {
            let z = x.row(i).to_vec();
            let dec = model.decision_values(&z);
            assert_eq!(dec[3], f64::NEG_INFINITY);
            assert_eq!(argmax(&dec), labels[i]);
            // Model decision values equal the solver's (same kernel values in f64).
            let f = sols[labels[i]]
                .as_ref()
                .unwrap()
                .decision_at(&gram, &rows, i);
            assert!((dec[labels[i]] - f).abs() < 1e-12);
        }
        // Each stored vector is a support vector of at least one class.
        for s in 0..model.n_support_vectors() {
            assert!(model.coef.iter().any(|c| c[s] != 0.0));
        }
    }

    #[test]
    fn argmax_ties_first() {
        assert_eq!(argmax(&[1.0, 3.0, 3.0]), 1);
        assert_eq!(argmax(&[f64::NAN, 0.0]), 1);
        assert_eq!(argmax(&[f64::NEG_INFINITY, -5.0]), 1);
    }
}
