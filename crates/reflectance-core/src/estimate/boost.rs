//! Gradient-boosted regression trees, for estimating continuous reflectance parameters where
//! a smooth kernel regression cannot follow the inputs: least squares, one ensemble per
//! output, each tree grown level by level to a fixed depth on histograms of the inputs
//! binned at their quantiles (as LightGBM and scikit-learn's `HistGradientBoostingRegressor`
//! do), and every row's prediction with its whole group left out.
//!
//! A tree is stored complete: node k's children are 2k + 1 and 2k + 2, a node that does not
//! split sends every row left (threshold `f64::MAX`), and the 2^depth leaves follow the
//! 2^depth − 1 splits. Prediction is then `depth` comparisons per tree, with no pointers.
//! There is no sampling: a fit is a function of its data alone.

use super::regress;
use crate::learn::error::LearnError;
use crate::util::progress::{Counter, Observer, Silent};
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How to fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoostSpec {
    /// Trees per output.
    pub trees: usize,
    /// Depth of every tree (2^depth leaves).
    pub depth: usize,
    /// Shrinkage: the share of each tree's fit that is added.
    pub learning_rate: f64,
    /// The fewest rows a leaf may hold.
    pub min_leaf: usize,
    /// L2 penalty on the leaf values (in rows: a leaf of n rows moves by Σr / (n + l2)).
    pub l2: f64,
    /// Quantile bins per input (at most 256).
    pub bins: usize,
}

impl Default for BoostSpec {
    fn default() -> Self {
        BoostSpec {
            trees: 300,
            depth: 5,
            learning_rate: 0.1,
            min_leaf: 20,
            l2: 1.0,
            bins: 128,
        }
    }
}

/// One complete tree (see the module).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tree {
    /// Each split's input index, nodes in breadth-first order (2^depth − 1 of them).
    pub feature: Vec<u16>,
    /// Each split's threshold: an input above it goes right (`f64::MAX`: no split).
    pub threshold: Vec<f64>,
    /// The 2^depth leaf values, left to right.
    pub leaf: Vec<f64>,
}

impl Tree {
    fn predict(&self, x: &[f64]) -> f64 {
        let mut node = 0;
        while node < self.feature.len() {
            let right = x[self.feature[node] as usize] > self.threshold[node];
            node = 2 * node + 1 + right as usize;
        }
        self.leaf[node - self.feature.len()]
    }
}

/// A fitted ensemble per output.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Boosted {
    /// Number of inputs a row has.
    pub inputs: usize,
    /// Each output's starting value (its mean).
    pub base: Vec<f64>,
    /// Each output's trees.
    pub trees: Vec<Vec<Tree>>,
}

impl Boosted {
    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.base.len()
    }

    /// Each output's prediction for a row of `inputs` values: its base plus its trees' leaves.
    pub fn predict(&self, x: &[f64]) -> Vec<f64> {
        self.base
            .iter()
            .zip(&self.trees)
            .map(|(base, trees)| base + trees.iter().map(|t| t.predict(x)).sum::<f64>())
            .collect()
    }

    /// Whether every tree is complete, reads only the inputs and holds finite numbers.
    pub fn is_consistent(&self) -> bool {
        let tree_ok = |t: &Tree| {
            t.threshold.len() == t.feature.len()
                && t.leaf.len() == t.feature.len() + 1
                && t.feature.iter().all(|&f| (f as usize) < self.inputs)
                && t.leaf.iter().all(|v| v.is_finite())
                && t.threshold.iter().all(|v| !v.is_nan())
        };
        self.trees.len() == self.base.len()
            && self.base.iter().all(|v| v.is_finite())
            && self.trees.iter().flatten().all(tree_ok)
    }
}

/// What a fit leaves behind: the model, and each row's prediction by the fit without its
/// group (when groups were given).
pub struct Fitted {
    /// The fitted ensembles.
    pub model: Boosted,
    /// Each row's prediction by the fit without its group (rows × outputs), when groups were
    /// given.
    pub held_out: Option<Array2<f64>>,
}

fn check(x: ArrayView2<f64>, y: ArrayView2<f64>, spec: &BoostSpec) -> Result<(), LearnError> {
    let bad = |what: String| Err(LearnError::InvalidParameter(what));
    if x.ncols() > u16::MAX as usize {
        return bad(format!(
            "boosting reads at most 65535 inputs, not {}",
            x.ncols()
        ));
    }
    let rate_ok = spec.learning_rate > 0.0 && spec.learning_rate <= 1.0;
    if spec.trees == 0 || !(1..=12).contains(&spec.depth) || !rate_ok {
        return bad(format!(
            "boosting needs ≥ 1 tree, a depth of 1–12 and a learning rate in (0, 1], not {}, {} and {}",
            spec.trees, spec.depth, spec.learning_rate
        ));
    }
    if !(2..=256).contains(&spec.bins) || spec.min_leaf == 0 || spec.l2.is_nan() || spec.l2 < 0.0 {
        return bad(format!(
            "boosting needs 2–256 bins, leaves of ≥ 1 row and l2 ≥ 0, not {}, {} and {}",
            spec.bins, spec.min_leaf, spec.l2
        ));
    }
    regress::check_data(x, y)
}

/// Fit `y` (n × outputs) on `x` (n × inputs); with `groups` (one id per row), also every
/// row's prediction with its whole group left out (one fit per group, in parallel).
pub fn fit(
    x: ArrayView2<f64>,
    y: ArrayView2<f64>,
    groups: Option<&[usize]>,
    spec: &BoostSpec,
) -> Result<Fitted, LearnError> {
    fit_observed(x, y, groups, spec, &Silent)
}

/// [`fit`], reporting each fit (the groups' and the whole one) to `observer`, and stopping
/// when it cancels.
pub fn fit_observed(
    x: ArrayView2<f64>,
    y: ArrayView2<f64>,
    groups: Option<&[usize]>,
    spec: &BoostSpec,
    observer: &dyn Observer,
) -> Result<Fitted, LearnError> {
    check(x, y, spec)?;
    let mut ids = groups.map(<[usize]>::to_vec).unwrap_or_default();
    ids.sort_unstable();
    ids.dedup();
    let counter = Counter::new(observer, ids.len() + 1);
    let all: Vec<usize> = (0..x.nrows()).collect();
    let model = fit_rows(x, y, &all, spec);
    counter.tick();
    let held_out = match groups {
        Some(g) => Some(held_out_predictions(x, y, g, &ids, spec, &counter)?),
        None => None,
    };
    Ok(Fitted { model, held_out })
}

fn held_out_predictions(
    x: ArrayView2<f64>,
    y: ArrayView2<f64>,
    groups: &[usize],
    ids: &[usize],
    spec: &BoostSpec,
    counter: &Counter,
) -> Result<Array2<f64>, LearnError> {
    let per_group: Vec<Vec<(usize, Vec<f64>)>> = ids
        .par_iter()
        .map(|&g| {
            if counter.cancelled() {
                return Err(LearnError::Cancelled);
            }
            let (held, kept): (Vec<usize>, Vec<usize>) =
                (0..groups.len()).partition(|&i| groups[i] == g);
            // A group that is every row leaves nothing to fit: its rows keep the targets' mean.
            let model = fit_rows(x, y, &kept, spec);
            counter.tick();
            Ok(held
                .into_iter()
                .map(|i| (i, model.predict(&x.row(i).to_vec())))
                .collect())
        })
        .collect::<Result<_, _>>()?;
    let mut predictions = Array2::zeros((groups.len(), y.ncols()));
    for (i, values) in per_group.into_iter().flatten() {
        for (o, v) in values.into_iter().enumerate() {
            predictions[[i, o]] = v;
        }
    }
    Ok(predictions)
}

/// The inputs of `rows` as bin indices (column-major), and each input's cut points: bin b
/// holds the values ≤ cuts[b] and above cuts[b − 1].
struct Binned {
    bins: Vec<u8>,
    cuts: Vec<Vec<f64>>,
    rows: usize,
}

impl Binned {
    fn new(x: ArrayView2<f64>, rows: &[usize], bins: usize) -> Binned {
        let cuts: Vec<Vec<f64>> = (0..x.ncols())
            .map(|f| quantile_cuts(rows.iter().map(|&i| x[[i, f]]).collect(), bins))
            .collect();
        let mut binned = Vec::with_capacity(rows.len() * x.ncols());
        for (f, c) in cuts.iter().enumerate() {
            binned.extend(
                rows.iter()
                    .map(|&i| c.partition_point(|&v| v < x[[i, f]]) as u8),
            );
        }
        Binned {
            bins: binned,
            cuts,
            rows: rows.len(),
        }
    }

    fn column(&self, f: usize) -> &[u8] {
        &self.bins[f * self.rows..(f + 1) * self.rows]
    }
}

/// At most `bins − 1` distinct cut points at the values' quantiles, each the midpoint between
/// two neighbouring distinct values so that a split sits between observations.
fn quantile_cuts(mut values: Vec<f64>, bins: usize) -> Vec<f64> {
    values.sort_by(f64::total_cmp);
    values.dedup();
    if values.len() <= bins {
        return values.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    }
    let mut cuts: Vec<f64> = (1..bins)
        .map(|k| {
            let i = k * (values.len() - 1) / bins;
            0.5 * (values[i] + values[i + 1])
        })
        .collect();
    cuts.dedup();
    cuts
}

fn fit_rows(x: ArrayView2<f64>, y: ArrayView2<f64>, rows: &[usize], spec: &BoostSpec) -> Boosted {
    let binned = Binned::new(x, rows, spec.bins);
    let (base, trees) = (0..y.ncols())
        .map(|o| {
            let target: Vec<f64> = rows.iter().map(|&i| y[[i, o]]).collect();
            boost_output(&binned, &target, spec)
        })
        .unzip();
    Boosted {
        inputs: x.ncols(),
        base,
        trees,
    }
}

fn boost_output(binned: &Binned, target: &[f64], spec: &BoostSpec) -> (f64, Vec<Tree>) {
    let n = target.len();
    let base = match n {
        0 => 0.0,
        _ => target.iter().sum::<f64>() / n as f64,
    };
    let mut prediction = vec![base; n];
    let mut trees = Vec::with_capacity(spec.trees);
    let mut residual = vec![0.0; n];
    let mut leaf_of = vec![0usize; n];
    for _ in 0..spec.trees {
        for i in 0..n {
            residual[i] = target[i] - prediction[i];
        }
        let tree = grow(binned, &residual, &mut leaf_of, spec);
        for i in 0..n {
            prediction[i] += tree.leaf[leaf_of[i]];
        }
        trees.push(tree);
    }
    (base, trees)
}

/// The best split of one node: (gain, input, last bin of the left side).
type Split = (f64, usize, usize);

/// One tree on the residuals; `leaf_of` receives each row's leaf.
fn grow(binned: &Binned, residual: &[f64], leaf_of: &mut [usize], spec: &BoostSpec) -> Tree {
    let splits = (1usize << spec.depth) - 1;
    let mut feature = vec![0u16; splits];
    let mut threshold = vec![f64::MAX; splits];
    // node[i]: the node of row i on the current level, numbered within the level.
    let mut node = vec![0usize; residual.len()];
    for level in 0..spec.depth {
        let width = 1usize << level;
        let best = best_splits(binned, residual, &node, width, spec);
        let first = width - 1;
        for (k, split) in best.iter().enumerate() {
            if let Some((_, f, bin)) = split {
                feature[first + k] = *f as u16;
                threshold[first + k] = binned.cuts[*f][*bin];
            }
        }
        for (i, n) in node.iter_mut().enumerate() {
            let right = match best[*n] {
                Some((_, f, bin)) => binned.column(f)[i] as usize > bin,
                None => false,
            };
            *n = 2 * *n + right as usize;
        }
    }
    let leaves = splits + 1;
    let (mut sum, mut count) = (vec![0.0; leaves], vec![0usize; leaves]);
    for (i, &n) in node.iter().enumerate() {
        sum[n] += residual[i];
        count[n] += 1;
    }
    let leaf = (0..leaves)
        .map(|k| spec.learning_rate * sum[k] / (count[k] as f64 + spec.l2).max(f64::MIN_POSITIVE))
        .collect();
    leaf_of.copy_from_slice(&node);
    Tree {
        feature,
        threshold,
        leaf,
    }
}

/// For each of the level's `width` nodes, its best split, if any leaves ≥ `min_leaf` rows on
/// both sides and gains.
fn best_splits(
    binned: &Binned,
    residual: &[f64],
    node: &[usize],
    width: usize,
    spec: &BoostSpec,
) -> Vec<Option<Split>> {
    let (mut total, mut count) = (vec![0.0; width], vec![0usize; width]);
    for (i, &n) in node.iter().enumerate() {
        total[n] += residual[i];
        count[n] += 1;
    }
    let score = |g: f64, c: usize| g * g / (c as f64 + spec.l2).max(f64::MIN_POSITIVE);
    let per_input: Vec<Vec<Option<Split>>> = (0..binned.cuts.len())
        .into_par_iter()
        .map(|f| {
            let bins = binned.cuts[f].len() + 1;
            let (mut g, mut c) = (vec![0.0; width * bins], vec![0usize; width * bins]);
            for (i, &b) in binned.column(f).iter().enumerate() {
                let k = node[i] * bins + b as usize;
                g[k] += residual[i];
                c[k] += 1;
            }
            (0..width)
                .map(|n| {
                    let parent = score(total[n], count[n]);
                    let (mut gl, mut cl, mut best) = (0.0, 0usize, None::<Split>);
                    for b in 0..bins - 1 {
                        gl += g[n * bins + b];
                        cl += c[n * bins + b];
                        let cr = count[n] - cl;
                        if cl < spec.min_leaf || cr < spec.min_leaf {
                            continue;
                        }
                        let gain = score(gl, cl) + score(total[n] - gl, cr) - parent;
                        if gain > best.map_or(1e-12, |s| s.0) {
                            best = Some((gain, f, b));
                        }
                    }
                    best
                })
                .collect()
        })
        .collect();
    (0..width)
        .map(|n| {
            per_input
                .iter()
                .filter_map(|splits| splits[n])
                .fold(None, |best: Option<Split>, s| match best {
                    Some(b) if b.0 >= s.0 => Some(b),
                    _ => Some(s),
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn spec() -> BoostSpec {
        BoostSpec {
            trees: 60,
            depth: 3,
            learning_rate: 0.3,
            min_leaf: 2,
            l2: 0.0,
            bins: 64,
        }
    }

    #[test]
    fn a_step_is_learned_exactly_at_its_threshold() {
        // y = 1 where x0 > 0.5, else 0; x1 is noise the trees must ignore.
        let x = Array2::from_shape_fn((40, 2), |(i, j)| match j {
            0 => i as f64 / 39.0,
            _ => ((i * 7) % 5) as f64,
        });
        let y = Array2::from_shape_fn((40, 1), |(i, _)| f64::from(x[[i, 0]] > 0.5));
        let fitted = fit(x.view(), y.view(), None, &spec()).unwrap();
        let first = &fitted.model.trees[0][0];
        assert_eq!(first.feature[0], 0);
        assert!((0.5..0.53).contains(&first.threshold[0]), "{first:?}");
        for i in 0..40 {
            let p = fitted.model.predict(&x.row(i).to_vec())[0];
            assert!((p - y[[i, 0]]).abs() < 1e-6, "row {i}: {p}");
        }
    }

    #[test]
    fn a_smooth_function_of_two_inputs_is_fitted_closely_and_outputs_are_independent() {
        let x = Array2::from_shape_fn((400, 2), |(i, j)| match j {
            0 => (i % 20) as f64 / 19.0,
            _ => (i / 20) as f64 / 19.0,
        });
        let y = Array2::from_shape_fn((400, 2), |(i, o)| match o {
            0 => x[[i, 0]] + 2.0 * x[[i, 1]],
            _ => -3.0,
        });
        let s = BoostSpec {
            trees: 200,
            depth: 4,
            ..spec()
        };
        let fitted = fit(x.view(), y.view(), None, &s).unwrap();
        let mut worst = 0.0f64;
        for i in 0..400 {
            let p = fitted.model.predict(&x.row(i).to_vec());
            worst = worst.max((p[0] - y[[i, 0]]).abs());
            assert!((p[1] + 3.0).abs() < 1e-12, "{p:?}");
        }
        assert!(worst < 0.05, "{worst}");
        assert!(fitted.model.is_consistent());
    }

    #[test]
    fn held_out_predictions_come_from_fits_without_the_group() {
        // Two groups whose targets differ by a constant the inputs do not show: each group's
        // held-out prediction is the other group's level, never its own.
        let x = Array2::from_shape_fn((60, 1), |(i, _)| (i % 30) as f64);
        let y = Array2::from_shape_fn((60, 1), |(i, _)| if i < 30 { 0.0 } else { 10.0 });
        let groups: Vec<usize> = (0..60).map(|i| i / 30).collect();
        let fitted = fit(x.view(), y.view(), Some(&groups), &spec()).unwrap();
        let held = fitted.held_out.unwrap();
        for i in 0..60 {
            let other = if i < 30 { 10.0 } else { 0.0 };
            assert!(
                (held[[i, 0]] - other).abs() < 1e-9,
                "row {i}: {}",
                held[[i, 0]]
            );
        }
    }

    #[test]
    fn the_same_data_give_the_same_model_and_bad_specs_are_refused() {
        let x = Array2::from_shape_fn((50, 3), |(i, j)| ((i * (j + 3)) % 11) as f64);
        let y = Array2::from_shape_fn((50, 1), |(i, _)| (i % 7) as f64);
        let a = fit(x.view(), y.view(), None, &spec()).unwrap().model;
        let b = fit(x.view(), y.view(), None, &spec()).unwrap().model;
        assert_eq!(a, b);
        for bad in [
            BoostSpec { trees: 0, ..spec() },
            BoostSpec { depth: 0, ..spec() },
            BoostSpec {
                learning_rate: 0.0,
                ..spec()
            },
            BoostSpec { bins: 1, ..spec() },
        ] {
            assert!(fit(x.view(), y.view(), None, &bad).is_err(), "{bad:?}");
        }
        let mut nan = x.clone();
        nan[[3, 1]] = f64::NAN;
        assert!(fit(nan.view(), y.view(), None, &spec()).is_err());
    }
}
