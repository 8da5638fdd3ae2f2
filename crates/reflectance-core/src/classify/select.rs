//! Automatic feature selection (docs/design.md §3 "Automatic selection", the paper's §5.3).
//!
//! Repeat N times: for every remaining feature fit one Gaussian per class (class mean,
//! ddof = 1 standard deviation floored at 1e-6 × the feature's overall ddof = 1 standard
//! deviation, priors = class frequencies) and compute the exact one-dimensional Bayes error
//! of that mixture; choose the feature with the smallest error (the first in column order on
//! exact ties); regress every unchosen feature on the chosen one (pooled affine least
//! squares over all samples) and replace it by the residual. The classifier then uses the
//! original values of the chosen features, in the order of selection.
//!
//! Clarifications (the paper leaves them open; docs/design.md §3 states them):
//! * "overall std" is the ddof = 1 standard deviation of the feature's *current* values
//!   (after the residualizations so far), over all training samples.
//! * A class with a single sample has no ddof = 1 standard deviation: it gets the floor.
//! * A feature whose current values are constant, or whose residual standard deviation has
//!   fallen below 1e-9 × its original standard deviation (it is, to rounding, a linear
//!   function of the features already chosen — e.g. `ratio.v.s1_s2` once both
//!   `wav.s1.v.var` and `wav.s2.v.var` are chosen), carries no further information: its
//!   error is that of always guessing the most probable class, 1 − max prior, instead of
//!   the error of a mixture fitted to rounding noise.

use crate::learn::error::LearnError;
use crate::learn::normal;
use ndarray::ArrayView2;

/// Relative floor of the per-class standard deviations.
pub const STD_FLOOR: f64 = 1e-6;
/// Residual std / original std below which a feature counts as exhausted.
pub const EXHAUSTED: f64 = 1e-9;

/// One class's weighted Gaussian.
#[derive(Clone, Copy, Debug)]
pub struct Component {
    /// The class's frequency in the training data.
    pub prior: f64,
    /// The class's mean of the feature.
    pub mean: f64,
    /// Its ddof = 1 standard deviation, floored at [`STD_FLOOR`] × the feature's.
    pub std: f64,
}

impl Component {
    /// log(prior × density) up to the common −log√(2π).
    fn log_weight(&self, x: f64) -> f64 {
        let z = (x - self.mean) / self.std;
        self.prior.ln() - self.std.ln() - 0.5 * z * z
    }

    /// Probability mass of this (unweighted) Gaussian on (lo, hi).
    fn mass(&self, lo: f64, hi: f64) -> f64 {
        normal::interval_mass((lo - self.mean) / self.std, (hi - self.mean) / self.std)
    }
}

/// Points where the weighted densities of `a` and `b` are equal.
fn crossings(a: &Component, b: &Component, out: &mut Vec<f64>) {
    // With x = a.mean + t and d = b.mean − a.mean, log(π_a N_a) = log(π_b N_b) reads
    // q2·t² + q1·t + q0 = 0.
    let (va, vb) = (a.std * a.std, b.std * b.std);
    let d = b.mean - a.mean;
    let q2 = 0.5 / vb - 0.5 / va;
    let q1 = -d / vb;
    let q0 = 0.5 * d * d / vb + (a.prior * b.std).ln() - (b.prior * a.std).ln();
    let mut push = |t: f64| {
        let x = a.mean + t;
        if x.is_finite() {
            out.push(x);
        }
    };
    if q2 == 0.0 {
        // Equal variances: one crossing (none if the curves are parallel or identical).
        if q1 != 0.0 {
            push(-q0 / q1);
        }
        return;
    }
    let disc = q1 * q1 - 4.0 * q2 * q0;
    if disc.is_nan() || disc < 0.0 {
        return;
    }
    let root = disc.sqrt();
    // Numerically stable pair of roots.
    let q = -0.5 * (q1 + root.copysign(q1));
    if q != 0.0 {
        push(q / q2);
        push(q0 / q);
    } else {
        // q1 = 0 and disc = 0: a double root at t = 0.
        push(0.0);
    }
}

/// The exact Bayes error of a one-dimensional Gaussian mixture: 1 − ∫ max_k π_k N_k(x) dx,
/// computed as Σ over the intervals between crossing points of the masses of the classes
/// that lose there (so small errors keep their relative precision). Components with zero
/// prior are ignored.
pub fn bayes_error(components: &[Component]) -> f64 {
    let comps: Vec<&Component> = components.iter().filter(|c| c.prior > 0.0).collect();
    if comps.len() < 2 {
        return 0.0;
    }
    let mut points = Vec::new();
    for (i, a) in comps.iter().enumerate() {
        for b in &comps[i + 1..] {
            crossings(a, b, &mut points);
        }
    }
    points.sort_by(f64::total_cmp);
    points.dedup();
    let mut edges = Vec::with_capacity(points.len() + 2);
    edges.push(f64::NEG_INFINITY);
    edges.extend(points);
    edges.push(f64::INFINITY);
    let mut error = 0.0;
    for w in edges.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
            continue;
        }
        // Any point inside the interval decides its winner (no crossing lies inside).
        let probe = match (lo.is_finite(), hi.is_finite()) {
            (true, true) => lo + 0.5 * (hi - lo),
            (false, true) => hi - (1.0 + hi.abs()),
            (true, false) => lo + (1.0 + lo.abs()),
            (false, false) => comps.iter().map(|c| c.mean).sum::<f64>() / comps.len() as f64,
        };
        let mut winner = 0;
        let mut best = f64::NEG_INFINITY;
        for (k, c) in comps.iter().enumerate() {
            let v = c.log_weight(probe);
            if v > best {
                best = v;
                winner = k;
            }
        }
        for (k, c) in comps.iter().enumerate() {
            if k != winner {
                error += c.prior * c.mass(lo, hi);
            }
        }
    }
    error.clamp(0.0, 1.0)
}

fn mean_std(values: impl Iterator<Item = f64> + Clone) -> (f64, f64, usize) {
    let n = values.clone().count();
    if n == 0 {
        return (0.0, 0.0, 0);
    }
    let mean = values.clone().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, f64::NAN, n);
    }
    let ss = values.map(|v| (v - mean) * (v - mean)).sum::<f64>();
    (mean, (ss / (n - 1) as f64).sqrt(), n)
}

/// The per-class Gaussians of one feature (None: constant, no information).
fn class_components(
    values: &[f64],
    labels: &[usize],
    priors: &[f64],
    counts: &[usize],
) -> Option<Vec<Component>> {
    let (_, overall, _) = mean_std(values.iter().copied());
    if overall.is_nan() || overall <= 0.0 {
        return None;
    }
    let floor = STD_FLOOR * overall;
    let mut comps = Vec::with_capacity(priors.len());
    for (k, &prior) in priors.iter().enumerate() {
        if counts[k] == 0 {
            comps.push(Component {
                prior: 0.0,
                mean: 0.0,
                std: 1.0,
            });
            continue;
        }
        let class_values = values
            .iter()
            .zip(labels)
            .filter(move |&(_, &l)| l == k)
            .map(|(&v, _)| v);
        let (mean, std, _) = mean_std(class_values);
        let std = if std.is_nan() { floor } else { std.max(floor) };
        comps.push(Component { prior, mean, std });
    }
    Some(comps)
}

/// The result of [`select`]: chosen columns (into the candidate matrix) in order of
/// selection, with the Bayes error each had when chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The chosen columns, in order of selection.
    pub columns: Vec<usize>,
    /// The Bayes error of each when chosen.
    pub errors: Vec<f64>,
}

/// Selects `n` columns of `x` (rows = training samples) for the classes `labels`
/// (`0..n_classes`).
pub fn select(
    x: ArrayView2<f64>,
    labels: &[usize],
    n_classes: usize,
    n: usize,
) -> Result<Selection, LearnError> {
    let (rows, cols) = x.dim();
    if labels.len() != rows {
        return Err(LearnError::InvalidParameter(format!(
            "{} labels for {rows} rows",
            labels.len()
        )));
    }
    if n == 0 || n > cols {
        return Err(LearnError::InvalidParameter(format!(
            "cannot select {n} of {cols} features"
        )));
    }
    if rows < 2 {
        return Err(LearnError::InvalidParameter(
            "feature selection needs at least 2 training rows".into(),
        ));
    }
    let mut counts = vec![0usize; n_classes];
    for &l in labels {
        match counts.get_mut(l) {
            Some(c) => *c += 1,
            None => {
                return Err(LearnError::InvalidParameter(format!(
                    "label {l} out of range for {n_classes} classes"
                )));
            }
        }
    }
    let priors: Vec<f64> = counts.iter().map(|&c| c as f64 / rows as f64).collect();
    let guess_error = 1.0 - priors.iter().copied().fold(0.0, f64::max);
    // Column-major working copy: current (residualized) values of every feature.
    let mut current: Vec<Vec<f64>> = x.columns().into_iter().map(|c| c.to_vec()).collect();
    let original_std: Vec<f64> = current
        .iter()
        .map(|c| mean_std(c.iter().copied()).1)
        .collect();
    let mut remaining: Vec<usize> = (0..cols).collect();
    let mut selection = Selection {
        columns: Vec::with_capacity(n),
        errors: Vec::with_capacity(n),
    };
    for _ in 0..n {
        let mut best: Option<(usize, f64)> = None;
        for (pos, &j) in remaining.iter().enumerate() {
            let values = &current[j];
            let (_, std_now, _) = mean_std(values.iter().copied());
            let exhausted = std_now.is_nan() || std_now <= EXHAUSTED * original_std[j];
            let error = if exhausted {
                guess_error
            } else {
                match class_components(values, labels, &priors, &counts) {
                    Some(comps) => bayes_error(&comps),
                    None => guess_error,
                }
            };
            if best.is_none_or(|(_, e)| error < e) {
                best = Some((pos, error));
            }
        }
        let Some((pos, error)) = best else { break };
        let chosen = remaining.remove(pos);
        selection.columns.push(chosen);
        selection.errors.push(error);
        // Residualize the others on the chosen feature's current values.
        let c = std::mem::take(&mut current[chosen]);
        let n_rows = rows as f64;
        let c_mean = c.iter().sum::<f64>() / n_rows;
        let c_ss: f64 = c.iter().map(|v| (v - c_mean) * (v - c_mean)).sum();
        for &j in &remaining {
            let f = &mut current[j];
            let f_mean = f.iter().sum::<f64>() / n_rows;
            let slope = if c_ss > 0.0 {
                c.iter()
                    .zip(f.iter())
                    .map(|(cv, fv)| (cv - c_mean) * (fv - f_mean))
                    .sum::<f64>()
                    / c_ss
            } else {
                0.0
            };
            for (fv, cv) in f.iter_mut().zip(&c) {
                *fv = (*fv - f_mean) - slope * (cv - c_mean);
            }
        }
        current[chosen] = c;
    }
    Ok(selection)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn comp(prior: f64, mean: f64, std: f64) -> Component {
        Component { prior, mean, std }
    }

    #[test]
    fn equal_variance_pair_matches_closed_form() {
        for (dmu, sigma) in [
            (1.0, 1.0),
            (2.5, 0.7),
            (10.0, 1.0),
            (0.01, 3.0),
            (40.0, 2.0),
        ] {
            let err = bayes_error(&[comp(0.5, 0.0, sigma), comp(0.5, dmu, sigma)]);
            let want = normal::cdf(-dmu / (2.0 * sigma));
            assert!(
                ((err - want) / want).abs() < 1e-13,
                "Δμ={dmu} σ={sigma}: {err:e} vs {want:e}"
            );
        }
    }

    #[test]
    fn unequal_priors_and_variances() {
        // Equal variances, priors 0.8/0.2: threshold shifts by σ² ln(π0/π1)/Δμ.
        let (s, d) = (1.0, 2.0);
        let t = d / 2.0 + s * s * (0.8f64 / 0.2).ln() / d;
        let want = 0.8 * normal::sf(t / s) + 0.2 * normal::cdf((t - d) / s);
        let got = bayes_error(&[comp(0.8, 0.0, s), comp(0.2, d, s)]);
        assert!((got - want).abs() < 1e-15, "{got} {want}");
        // Same mean, different variances: two crossings at ±x*.
        let (s0, s1) = (1.0f64, 2.0f64);
        let x = (2.0 * (s1 / s0).ln() / (1.0 / (s0 * s0) - 1.0 / (s1 * s1))).sqrt();
        let want = 0.5 * 2.0 * normal::sf(x / s0) + 0.5 * (1.0 - 2.0 * normal::sf(x / s1));
        let got = bayes_error(&[comp(0.5, 0.0, s0), comp(0.5, 0.0, s1)]);
        assert!((got - want).abs() < 1e-15, "{got} {want}");
        // Identical components: half the mass is misclassified.
        let got = bayes_error(&[comp(0.5, 1.0, 2.0), comp(0.5, 1.0, 2.0)]);
        assert!((got - 0.5).abs() < 1e-15);
        // Three well separated classes: error is tiny but positive and accurate.
        let got = bayes_error(&[
            comp(1.0 / 3.0, 0.0, 1.0),
            comp(1.0 / 3.0, 20.0, 1.0),
            comp(1.0 / 3.0, 40.0, 1.0),
        ]);
        let want = 4.0 / 3.0 * normal::sf(10.0);
        assert!(((got - want) / want).abs() < 1e-12, "{got:e} {want:e}");
    }

    /// A brute-force check of the interval logic: Riemann sum of 1 − max density.
    #[test]
    fn matches_numerical_integration() {
        let comps = [
            comp(0.2, -1.0, 0.5),
            comp(0.5, 0.3, 1.7),
            comp(0.3, 2.0, 0.8),
        ];
        let (lo, hi, steps) = (-15.0, 15.0, 600_000);
        let h = (hi - lo) / steps as f64;
        let mut correct = 0.0;
        for i in 0..steps {
            let x = lo + (i as f64 + 0.5) * h;
            let best = comps
                .iter()
                .map(|c| {
                    let z = (x - c.mean) / c.std;
                    c.prior * (-0.5 * z * z).exp() / (c.std * (2.0 * std::f64::consts::PI).sqrt())
                })
                .fold(0.0, f64::max);
            correct += best * h;
        }
        let got = bayes_error(&comps);
        assert!(
            (got - (1.0 - correct)).abs() < 1e-9,
            "{got} vs {}",
            1.0 - correct
        );
    }

    #[test]
    fn selects_informative_then_residualizes() {
        // Three classes. f1 separates class 0 from the rest; f2 = 2·f1 + 1 (redundant);
        // f3 = 5·f1 + a class-1-vs-2 signal uncorrelated with f1, visible only once f1's
        // contribution is regressed out; f0 weakly informative, its signal explained by f1
        // and f3 together.
        let mut rng = crate::util::rng::Rng::new(5);
        let n = 300;
        let mut x = Array2::zeros((n, 4));
        let mut labels = Vec::new();
        for i in 0..n {
            let k = i % 3;
            labels.push(k);
            let mut noise = || rng.next_f64() - 0.5;
            let is = |c: usize| if k == c { 1.0 } else { 0.0 };
            let f1 = 3.0 * is(0) + noise();
            x[[i, 0]] = 0.3 * k as f64 + noise();
            x[[i, 1]] = f1;
            x[[i, 2]] = 2.0 * f1 + 1.0;
            x[[i, 3]] = 5.0 * f1 + 0.3 * (is(1) - is(2)) + 0.05 * noise();
        }
        let sel = select(x.view(), &labels, 3, 3).unwrap();
        assert_eq!(sel.columns, [1, 3, 0], "{sel:?}");
        assert!(sel.errors[0] < 0.35 && sel.errors[1] < 0.05, "{sel:?}");
        // Ties go to the first column: two identical columns.
        let mut y = Array2::zeros((n, 2));
        for i in 0..n {
            y[[i, 0]] = x[[i, 0]];
            y[[i, 1]] = x[[i, 0]];
        }
        assert_eq!(select(y.view(), &labels, 3, 1).unwrap().columns, [0]);
        assert!(select(y.view(), &labels, 3, 3).is_err());
    }
}
