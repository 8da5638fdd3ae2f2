//! The search over the SVM's hyper-parameter grid ([`Grid`]): an inner leave-one-illumination-out
//! cross-validation on the training rows only, which chooses (C, γ) for the fit.

use super::options::{Grid, TrainSpec};
use super::prepare::{apply_transform, check_svm_params, count_classes, prepare};
use super::svm::{self, Gram, SolverParams};
use crate::learn::error::LearnError;
use crate::learn::feature_set::FeatureSet;
use crate::learn::matrix::Dataset;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// One grid point's inner-CV score.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridPoint {
    /// SVM C of the point.
    pub c: f64,
    /// SVM γ of the point.
    pub gamma: f64,
    /// Held-out rows classified correctly.
    pub correct: usize,
    /// Held-out rows.
    pub n: usize,
}

/// The inner cross-validation's search over the [`Grid`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridSearch {
    /// Every point's score, in grid order (C major, then γ).
    pub points: Vec<GridPoint>,
    /// Index of the chosen point: the most correct, the first in grid order (C major, then
    /// γ) on ties.
    pub chosen: usize,
}

/// Inner leave-one-illumination-out CV over the grid, on the training rows only.
pub(super) fn search(
    ds: &Dataset,
    rows: &[usize],
    spec: &TrainSpec,
    grid: &Grid,
) -> Result<GridSearch, LearnError> {
    if grid.c.is_empty() || grid.gamma_multipliers.is_empty() {
        return Err(LearnError::InvalidParameter(
            "empty hyper-parameter grid".into(),
        ));
    }
    let mut groups: Vec<usize> = rows
        .iter()
        .filter(|&&r| !ds.augmented[r])
        .map(|&r| ds.groups[r])
        .collect();
    groups.sort_unstable();
    groups.dedup();
    if groups.len() < 2 {
        return Err(LearnError::InvalidParameter(format!(
            "grid search needs at least 2 training illuminations, found {}",
            groups.len()
        )));
    }
    let per_group: Vec<Vec<usize>> = groups
        .par_iter()
        .map(|&g| held_out_correct(ds, rows, g, spec, grid))
        .collect::<Result<_, _>>()?;
    let n_eval: usize = groups
        .iter()
        .map(|&g| ds.split_group(rows, g).1.len())
        .sum();
    let d_final = match &spec.features {
        FeatureSet::Auto(n) | FeatureSet::Pca(n) => *n,
        fixed => fixed.resolve(&ds.names)?.map_or(1, |v| v.len()),
    };
    let mut points = Vec::with_capacity(points(grid));
    for &c in &grid.c {
        for &m in &grid.gamma_multipliers {
            points.push(GridPoint {
                c,
                gamma: m / d_final as f64,
                correct: 0,
                n: n_eval,
            });
        }
    }
    for correct in &per_group {
        for (p, &c) in points.iter_mut().zip(correct) {
            p.correct += c;
        }
    }
    let mut chosen = 0;
    for (i, p) in points.iter().enumerate() {
        if p.correct > points[chosen].correct {
            chosen = i;
        }
    }
    Ok(GridSearch { points, chosen })
}

/// With the illumination `group` held out of `rows`: its rows classified correctly at each
/// grid point (the selection and standardization fitted on the other rows).
fn held_out_correct(
    ds: &Dataset,
    rows: &[usize],
    group: usize,
    spec: &TrainSpec,
    grid: &Grid,
) -> Result<Vec<usize>, LearnError> {
    let k = ds.n_classes();
    let (train, test) = ds.split_group(rows, group);
    let train_labels: Vec<usize> = train.iter().map(|&r| ds.labels[r]).collect();
    if test.is_empty() || count_classes(&train_labels, k) < 2 {
        return Ok(vec![0; points(grid)]);
    }
    let prep = prepare(ds, &train, &spec.features)?;
    let d = prep.z.ncols();
    let mut all = prep.z.clone();
    for &r in &test {
        let z = apply_transform(
            &prep.selected_indices,
            prep.pca.as_ref(),
            &prep.scaler,
            &ds.x.row(r).to_vec(),
        );
        all.push_row(ndarray::ArrayView1::from(&z))
            .map_err(|e| LearnError::Numerical(e.to_string()))?;
    }
    let local_train: Vec<usize> = (0..train.len()).collect();
    let mut correct = vec![0; points(grid)];
    for (gi, m) in grid.gamma_multipliers.iter().enumerate() {
        let gamma = m / d as f64;
        let gram = Gram::<f64>::rbf(all.view(), gamma);
        for (ci, &c) in grid.c.iter().enumerate() {
            check_svm_params(c, gamma)?;
            let params = SolverParams {
                c,
                ..SolverParams::default()
            };
            let sols = svm::train_one_vs_all(&gram, &local_train, &train_labels, k, &params);
            let point = ci * grid.gamma_multipliers.len() + gi;
            for (t, &r) in test.iter().enumerate() {
                let dec: Vec<f64> = sols
                    .iter()
                    .map(|s| match s {
                        Some(s) => s.decision_at(&gram, &local_train, train.len() + t),
                        None => f64::NEG_INFINITY,
                    })
                    .collect();
                if svm::argmax(&dec) == ds.labels[r] {
                    correct[point] += 1;
                }
            }
        }
    }
    Ok(correct)
}

/// Number of points of `grid` (C major, then γ).
fn points(grid: &Grid) -> usize {
    grid.c.len() * grid.gamma_multipliers.len()
}
