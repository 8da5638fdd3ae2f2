//! The steps every fit shares (the pipeline's, and the grid search's inner folds): the
//! input transformation fitted on training rows (selection or PCA, then standardization),
//! and the checks of a fit's classes and SVM parameters.

use super::pca::Pca;
use super::select;
use crate::learn::error::LearnError;
use crate::learn::feature_set::FeatureSet;
use crate::learn::matrix::Dataset;
use crate::learn::scaler::Scaler;
use ndarray::{Array2, Axis};

/// The input transformation fitted on training rows.
pub(super) struct Prepared {
    pub(super) selected: Vec<String>,
    pub(super) selected_indices: Vec<usize>,
    pub(super) selection_errors: Option<Vec<f64>>,
    pub(super) pca: Option<Pca>,
    pub(super) scaler: Scaler,
    /// Standardized classifier inputs of the training rows (in the order given).
    pub(super) z: Array2<f64>,
}

pub(super) fn prepare(
    ds: &Dataset,
    rows: &[usize],
    features: &FeatureSet,
) -> Result<Prepared, LearnError> {
    let x = ds.x.select(Axis(0), rows);
    let labels: Vec<usize> = rows.iter().map(|&r| ds.labels[r]).collect();
    let mut selection_errors = None;
    let mut pca = None;
    let (selected, selected_indices, inputs) = match features.resolve(&ds.names)? {
        Some(idx) => {
            let names = idx.iter().map(|&i| ds.names[i].clone()).collect();
            let inputs = x.select(Axis(1), &idx);
            (names, idx, inputs)
        }
        None => match features {
            FeatureSet::Auto(n) => {
                let sel = select::select(x.view(), &labels, ds.n_classes(), *n)?;
                let idx = sel.columns.clone();
                selection_errors = Some(sel.errors);
                let names = idx.iter().map(|&i| ds.names[i].clone()).collect();
                let inputs = x.select(Axis(1), &idx);
                (names, idx, inputs)
            }
            FeatureSet::Pca(n) => {
                let p = Pca::fit(x.view(), *n)?;
                let mut inputs = Array2::zeros((rows.len(), *n));
                for (i, row) in x.rows().into_iter().enumerate() {
                    let scores = p.transform_row(&row.to_vec());
                    inputs
                        .row_mut(i)
                        .assign(&ndarray::ArrayView1::from(&scores));
                }
                pca = Some(p);
                let names = (1..=*n).map(|k| format!("pc{k}")).collect();
                (names, (0..ds.names.len()).collect(), inputs)
            }
            _ => {
                return Err(LearnError::InvalidParameter(format!(
                    "feature set {features} did not resolve"
                )));
            }
        },
    };
    if selected_indices.is_empty() {
        return Err(LearnError::InvalidParameter("empty feature set".into()));
    }
    let scaler = Scaler::fit(inputs.view());
    let z = scaler.transform(inputs.view());
    Ok(Prepared {
        selected,
        selected_indices,
        selection_errors,
        pca,
        scaler,
        z,
    })
}

/// Standardized classifier inputs of a full row (no checks: rows come from the dataset).
pub(super) fn apply_transform(
    selected_indices: &[usize],
    pca: Option<&Pca>,
    scaler: &Scaler,
    row: &[f64],
) -> Vec<f64> {
    let picked: Vec<f64> = selected_indices.iter().map(|&i| row[i]).collect();
    let mut v = match pca {
        Some(p) => p.transform_row(&picked),
        None => picked,
    };
    scaler.apply(&mut v);
    v
}

/// An SVM's C and γ: finite and positive.
pub(super) fn check_svm_params(c: f64, gamma: f64) -> Result<(), LearnError> {
    if !(c.is_finite() && c > 0.0) {
        return Err(LearnError::InvalidParameter(format!(
            "C must be > 0, not {c}"
        )));
    }
    if !(gamma.is_finite() && gamma > 0.0) {
        return Err(LearnError::InvalidParameter(format!(
            "gamma must be > 0, not {gamma}"
        )));
    }
    Ok(())
}

/// How many of `n_classes` classes occur among `labels`.
pub(super) fn count_classes(labels: &[usize], n_classes: usize) -> usize {
    let mut seen = vec![false; n_classes];
    for &l in labels {
        seen[l] = true;
    }
    seen.iter().filter(|&&s| s).count()
}
