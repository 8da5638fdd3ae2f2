//! The fitted pipeline: choose the classifier's inputs (fixed set, automatic selection or
//! PCA), standardize, classify (SVM one-against-all, k-NN, or chance), calibrate.
//!
//! [`Classifier`] serializes with serde to plain numbers and vectors (no array types), so a
//! model file can embed it; after deserializing, call [`Classifier::validate`] before use.

use super::calibration::{self, Calibration, Sigmoid, stratified_folds};
use super::grid::{self, GridSearch};
use super::knn::{ChanceModel, KnnModel};
use super::options::{CALIBRATION_FOLDS, CalibrationKind, ClassifierKind, TrainSpec};
use super::pca::Pca;
use super::prepare::{apply_transform, check_svm_params, count_classes, prepare};
use super::svm::{self, Gram, SolverParams, SvmModel};
use crate::learn::error::LearnError;
use crate::learn::matrix::Dataset;
use crate::learn::scaler::Scaler;
use crate::util::progress::{Counter, Observer, Silent};
use crate::util::rng::Rng;
use ndarray::{Array2, ArrayView2};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A fitted model of one of the [`ClassifierKind`]s (k-NN serves `nn` and `knn5`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Model {
    /// An RBF-kernel SVM.
    Svm(SvmModel),
    /// Nearest neighbours (k = 1 or 5) over the training rows.
    Knn(KnnModel),
    /// The training class frequencies.
    Chance(ChanceModel),
}

/// Output of one classification.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    /// The predicted class (index in class order).
    pub class: usize,
    /// Class probabilities (calibrated for the SVM), in class order, summing to 1.
    pub probabilities: Vec<f64>,
    /// SVM decision values; k-NN vote fractions; chance: training frequencies.
    pub decision: Vec<f64>,
}

/// A fitted classifier: the input transformation, the model and its calibration. Its parts
/// are consistent by construction (training, or a model file that passed its checks); they
/// are read through the methods below and cannot be changed from outside the core.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Classifier {
    pub(crate) classes: Vec<String>,
    /// Named `classifier` in model files.
    #[serde(rename = "classifier")]
    pub(crate) kind: ClassifierKind,
    /// The feature set as specified (`hand6`, `auto6`, …).
    pub(crate) feature_set: String,
    /// Names of the full input row's columns (the 117 features, canonical order).
    pub(crate) input_names: Vec<String>,
    /// Names of the classifier's inputs: the selected features, in selection order, or
    /// `pc1…pcN` for PCA.
    pub(crate) selected: Vec<String>,
    /// Indices into the full row of the selected features (for PCA: of the PCA inputs,
    /// i.e. every column).
    pub(crate) selected_indices: Vec<usize>,
    /// auto<N>: the Bayes error of each feature when it was selected.
    pub(crate) selection_errors: Option<Vec<f64>>,
    pub(crate) pca: Option<Pca>,
    pub(crate) scaler: Scaler,
    pub(crate) model: Model,
    pub(crate) calibration: Option<Calibration>,
    pub(crate) grid_search: Option<GridSearch>,
    pub(crate) n_train: usize,
}

/// The decision values of rows held out by the calibration folds of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct HeldOut {
    /// Per row of the fit (in the order of its `rows`): the calibration fold that held it
    /// out, or `None` for rows that train in every fold (illuminations with augmented views
    /// only, e.g. synthetic maps).
    pub fold: Vec<Option<usize>>,
    /// Per row of the fit: its decision values when it was held out (empty for `None`).
    pub decision: Vec<Vec<f64>>,
    /// Number of calibration folds.
    pub folds: usize,
    /// Whether the folds are whole illuminations (else stratified rows: fewer than two
    /// illuminations to hold out).
    pub by_illumination: bool,
}

/// Folds of whole illuminations: the groups with un-augmented rows are shuffled and dealt
/// to `k` folds; the other groups' rows stay in training (`None`).
fn illumination_folds(
    groups: &[usize],
    evaluated: &[usize],
    k: usize,
    rng: &mut Rng,
) -> Vec<Option<usize>> {
    let mut order = evaluated.to_vec();
    rng.shuffle(&mut order);
    let fold_of: std::collections::HashMap<usize, usize> =
        order.iter().enumerate().map(|(i, &g)| (g, i % k)).collect();
    groups.iter().map(|g| fold_of.get(g).copied()).collect()
}

/// Decision values of rows held out by an internal cross-validation on the fit's kernel
/// matrix (the internal folds solve the same problems on subsets of its rows; the
/// selection and standardization of the enclosing fit are kept, as libsvm does).
fn held_out_decisions(
    gram: &Gram<f64>,
    labels: &[usize],
    fold: Vec<Option<usize>>,
    (k, n_classes): (usize, usize),
    params: &SolverParams,
    counter: &Counter,
) -> Vec<Vec<f64>> {
    let n = labels.len();
    let per_fold: Vec<Vec<(usize, Vec<f64>)>> = (0..k)
        .into_par_iter()
        .map(|f| {
            let _tick = counter.ticks_when_dropped();
            let train: Vec<usize> = (0..n).filter(|&i| fold[i] != Some(f)).collect();
            let test: Vec<usize> = (0..n).filter(|&i| fold[i] == Some(f)).collect();
            let train_labels: Vec<usize> = train.iter().map(|&i| labels[i]).collect();
            let sols = svm::train_one_vs_all(gram, &train, &train_labels, n_classes, params);
            test.iter()
                .map(|&t| {
                    let dec = sols
                        .iter()
                        .map(|s| match s {
                            Some(s) => s.decision_at(gram, &train, t),
                            // No row of the class in this fold's training part: libsvm's
                            // convention for a one-class problem, f = −1.
                            None => -1.0,
                        })
                        .collect();
                    (t, dec)
                })
                .collect()
        })
        .collect();
    let mut dec = vec![Vec::new(); n];
    for (t, values) in per_fold.into_iter().flatten() {
        dec[t] = values;
    }
    dec
}

/// The rows of a fit the calibration folds deal out.
struct FitRows<'a> {
    labels: &'a [usize],
    groups: &'a [usize],
    augmented: &'a [bool],
}

/// The calibration folds of a fit: softmax, folds of whole illuminations (probabilities for
/// light the model never saw), stratified rows when fewer than two illuminations can be
/// held out; Platt, `CALIBRATION_FOLDS` stratified folds (seeded). The fold of every row,
/// the number of folds, and whether they are illuminations.
fn calibration_folds(
    rows: &FitRows,
    n_classes: usize,
    kind: CalibrationKind,
    folds: usize,
    rng: &mut Rng,
) -> (Vec<Option<usize>>, usize, bool) {
    let n = rows.labels.len();
    let mut evaluated: Vec<usize> = (0..n)
        .filter(|&i| !rows.augmented[i])
        .map(|i| rows.groups[i])
        .collect();
    evaluated.sort_unstable();
    evaluated.dedup();
    if kind == CalibrationKind::Softmax && evaluated.len() >= 2 {
        let k = match folds {
            0 => evaluated.len(),
            k => k.min(evaluated.len()),
        };
        (illumination_folds(rows.groups, &evaluated, k, rng), k, true)
    } else {
        let k = CALIBRATION_FOLDS.min(n);
        let folds = stratified_folds(rows.labels, n_classes, k, rng);
        (folds.into_iter().map(Some).collect(), k, false)
    }
}

/// The calibration of a fit and the held-out decision values it was fitted on: one
/// softmax temperature, or one Platt sigmoid per class.
fn calibrate(
    gram: &Gram<f64>,
    rows: &FitRows,
    n_classes: usize,
    params: &SolverParams,
    spec: &TrainSpec,
    rng: &mut Rng,
    observer: &dyn Observer,
) -> (Calibration, HeldOut) {
    let labels = rows.labels;
    let n = labels.len();
    let kind = spec.calibration;
    let (fold, k, by_illumination) =
        calibration_folds(rows, n_classes, kind, spec.calibration_folds, rng);
    // Its folds, then the calibration's fit.
    let counter = Counter::new(observer, k + 1);
    let decision = held_out_decisions(gram, labels, fold.clone(), (k, n_classes), params, &counter);
    let calibration = match kind {
        CalibrationKind::Softmax => {
            let rows: Vec<usize> = (0..n).filter(|&i| fold[i].is_some()).collect();
            let dec: Vec<Vec<f64>> = rows.iter().map(|&i| decision[i].clone()).collect();
            let truth: Vec<usize> = rows.iter().map(|&i| labels[i]).collect();
            Calibration::Softmax {
                temperature: calibration::fit_temperature(&dec, &truth),
            }
        }
        CalibrationKind::Platt => Calibration::Platt {
            sigmoids: (0..n_classes)
                .map(|class| {
                    let values: Vec<f64> = decision.iter().map(|d| d[class]).collect();
                    let positive: Vec<bool> = labels.iter().map(|&l| l == class).collect();
                    Sigmoid::fit(&values, &positive)
                })
                .collect(),
        },
    };
    counter.tick();
    let held_out = HeldOut {
        fold,
        decision,
        folds: k,
        by_illumination,
    };
    (calibration, held_out)
}

/// Fits the pipeline on every row of `ds`.
pub fn fit(ds: &Dataset, spec: &TrainSpec, seed: u64) -> Result<Classifier, LearnError> {
    let rows: Vec<usize> = (0..ds.n_rows()).collect();
    fit_rows(ds, &rows, spec, seed)
}

/// Fits the pipeline on the rows `rows` of `ds` (selection, PCA, standardization, SVM and
/// calibration all see these rows only).
pub fn fit_rows(
    ds: &Dataset,
    rows: &[usize],
    spec: &TrainSpec,
    seed: u64,
) -> Result<Classifier, LearnError> {
    Ok(fit_rows_held_out(ds, rows, spec, seed)?.0)
}

/// [`fit_rows`], and for an SVM the decision values its calibration held out.
pub fn fit_rows_held_out(
    ds: &Dataset,
    rows: &[usize],
    spec: &TrainSpec,
    seed: u64,
) -> Result<(Classifier, Option<HeldOut>), LearnError> {
    fit_rows_observed(ds, rows, spec, seed, &Silent)
}

/// [`fit_rows_held_out`], reporting an SVM's calibration folds and calibration fit to
/// `observer` as they finish (the units of the current stage).
pub fn fit_rows_observed(
    ds: &Dataset,
    rows: &[usize],
    spec: &TrainSpec,
    seed: u64,
    observer: &dyn Observer,
) -> Result<(Classifier, Option<HeldOut>), LearnError> {
    if rows.is_empty() {
        return Err(LearnError::NoRows);
    }
    if let Some(&r) = rows.iter().find(|&&r| r >= ds.n_rows()) {
        return Err(LearnError::InvalidParameter(format!(
            "row {r} outside the dataset ({} rows)",
            ds.n_rows()
        )));
    }
    let k = ds.n_classes();
    let labels: Vec<usize> = rows.iter().map(|&r| ds.labels[r]).collect();
    let present = count_classes(&labels, k);
    if present < 2 {
        return Err(LearnError::TooFewTrainingClasses(present));
    }
    let prep = prepare(ds, rows, &spec.features)?;
    let d = prep.z.ncols();
    let mut rng = Rng::new(seed);
    let mut grid_result = None;
    let mut calibration = None;
    let mut held_out = None;
    let model = match spec.classifier {
        ClassifierKind::Svm => {
            let (c, gamma) = match &spec.grid {
                Some(grid) => {
                    let gs = grid::search(ds, rows, spec, grid)?;
                    let p = &gs.points[gs.chosen];
                    let cg = (p.c, p.gamma);
                    grid_result = Some(gs);
                    cg
                }
                None => (spec.c, spec.gamma.unwrap_or(1.0 / d as f64)),
            };
            check_svm_params(c, gamma)?;
            let params = SolverParams {
                c,
                ..SolverParams::default()
            };
            let gram = Gram::<f64>::rbf(prep.z.view(), gamma);
            let local: Vec<usize> = (0..rows.len()).collect();
            let sols = svm::train_one_vs_all(&gram, &local, &labels, k, &params);
            let groups: Vec<usize> = rows.iter().map(|&r| ds.groups[r]).collect();
            let augmented: Vec<bool> = rows.iter().map(|&r| ds.augmented[r]).collect();
            let fit_rows = FitRows {
                labels: &labels,
                groups: &groups,
                augmented: &augmented,
            };
            let (fitted, values) =
                calibrate(&gram, &fit_rows, k, &params, spec, &mut rng, observer);
            calibration = Some(fitted);
            held_out = Some(values);
            Model::Svm(SvmModel::from_solutions(
                prep.z.view(),
                &local,
                &sols,
                gamma,
                c,
            ))
        }
        ClassifierKind::Nn | ClassifierKind::Knn5 => Model::Knn(KnnModel {
            k: if spec.classifier == ClassifierKind::Nn {
                1
            } else {
                5
            },
            n_classes: k,
            train: prep.z.rows().into_iter().map(|r| r.to_vec()).collect(),
            labels: labels.clone(),
        }),
        ClassifierKind::Chance => Model::Chance(ChanceModel::fit(&labels, k)),
    };
    let classifier = Classifier {
        classes: ds.classes.clone(),
        kind: spec.classifier,
        feature_set: spec.features.to_string(),
        input_names: ds.names.clone(),
        selected: prep.selected,
        selected_indices: prep.selected_indices,
        selection_errors: prep.selection_errors,
        pca: prep.pca,
        scaler: prep.scaler,
        model,
        calibration,
        grid_search: grid_result,
        n_train: rows.len(),
    };
    Ok((classifier, held_out))
}

impl Classifier {
    /// The class names, in the order of every output.
    pub fn classes(&self) -> &[String] {
        &self.classes
    }

    /// Which classifier it is.
    pub fn kind(&self) -> ClassifierKind {
        self.kind
    }

    /// The fitted model (an SVM's C and γ, …).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Whether its probabilities are calibrated.
    pub fn is_calibrated(&self) -> bool {
        self.calibration.is_some()
    }

    /// Number of classes.
    pub fn n_classes(&self) -> usize {
        self.classes.len()
    }

    /// Length of the full input row.
    pub fn n_inputs(&self) -> usize {
        self.input_names.len()
    }

    /// Dimension of the classifier's (standardized) input space.
    pub fn dim(&self) -> usize {
        self.scaler.dim()
    }

    /// Checks that the parts fit together (after deserializing a model file).
    pub fn validate(&self) -> Result<(), LearnError> {
        let bad = |m: String| Err(LearnError::InvalidModel(m));
        let k = self.n_classes();
        if k < 2 {
            return bad(format!("{k} classes"));
        }
        if let Some(&i) = self
            .selected_indices
            .iter()
            .find(|&&i| i >= self.n_inputs())
        {
            return bad(format!("selected index {i} ≥ {} inputs", self.n_inputs()));
        }
        let picked = self.selected_indices.len();
        let dim = match &self.pca {
            Some(p) => {
                p.check().map_err(|e| LearnError::InvalidModel(e.0))?;
                if p.input_dim() != picked {
                    return bad("PCA input dimension disagrees".into());
                }
                p.output_dim()
            }
            None => picked,
        };
        if self.scaler.mean.len() != dim || self.scaler.std.len() != dim || dim == 0 {
            return bad("scaler dimension disagrees".into());
        }
        if self.selected.len() != dim {
            return bad("selected names disagree with the input dimension".into());
        }
        if self.scaler.std.iter().any(|&s| !(s.is_finite() && s > 0.0)) {
            return bad("scaler std must be positive".into());
        }
        match &self.model {
            Model::Svm(m) => {
                m.check(dim).map_err(|e| LearnError::InvalidModel(e.0))?;
                if m.n_classes() != k {
                    return bad("SVM class count disagrees".into());
                }
                if let Some(c) = &self.calibration {
                    if c.classes().is_some_and(|n| n != k) {
                        return bad("calibration class count disagrees".into());
                    }
                    if !c.is_valid() {
                        return bad("calibration has non-finite values".into());
                    }
                }
            }
            Model::Knn(m) => {
                m.check(dim).map_err(|e| LearnError::InvalidModel(e.0))?;
                if m.n_classes != k {
                    return bad("k-NN class count disagrees".into());
                }
            }
            Model::Chance(m) => {
                if m.frequencies.len() != k {
                    return bad("chance class count disagrees".into());
                }
            }
        }
        Ok(())
    }

    /// The standardized classifier inputs of a full feature row.
    pub fn transform(&self, row: &[f64]) -> Result<Vec<f64>, LearnError> {
        if row.len() != self.n_inputs() {
            return Err(LearnError::RowLength {
                expected: self.n_inputs(),
                got: row.len(),
            });
        }
        for &i in &self.selected_indices {
            let Some(&v) = row.get(i) else {
                return Err(LearnError::InvalidModel(format!(
                    "selected index {i} outside the input row"
                )));
            };
            if !v.is_finite() {
                return Err(LearnError::NonFiniteInput {
                    name: self.input_names[i].clone(),
                    value: v,
                });
            }
        }
        Ok(apply_transform(
            &self.selected_indices,
            self.pca.as_ref(),
            &self.scaler,
            row,
        ))
    }

    /// Classifies standardized inputs.
    pub fn classify_transformed(&self, z: &[f64]) -> Output {
        match &self.model {
            Model::Svm(m) => {
                let decision = m.decision_values(z);
                let probabilities = match &self.calibration {
                    Some(c) => c.probabilities(&decision),
                    None => {
                        let top = svm::argmax(&decision);
                        (0..decision.len())
                            .map(|k| if k == top { 1.0 } else { 0.0 })
                            .collect()
                    }
                };
                // One rule: the label is the most probable class (first on ties). With the
                // softmax calibration that is the largest decision value.
                let class = svm::argmax(&probabilities);
                Output {
                    class,
                    probabilities,
                    decision,
                }
            }
            Model::Knn(m) => {
                let vote = m.vote(z);
                Output {
                    class: vote.class,
                    probabilities: vote.fractions.clone(),
                    decision: vote.fractions,
                }
            }
            Model::Chance(m) => Output {
                class: m.class(),
                probabilities: m.frequencies.clone(),
                decision: m.frequencies.clone(),
            },
        }
    }

    /// Class, probabilities and decision values of a full feature row.
    pub fn classify(&self, row: &[f64]) -> Result<Output, LearnError> {
        Ok(self.classify_transformed(&self.transform(row)?))
    }

    /// Class probabilities in class order (calibrated for the SVM).
    pub fn predict_proba(&self, row: &[f64]) -> Result<Vec<f64>, LearnError> {
        Ok(self.classify(row)?.probabilities)
    }

    /// The predicted class index: the most probable class (first on ties; for the SVM with
    /// the softmax calibration the largest decision value), or the k-NN vote, or the most
    /// frequent training class.
    pub fn predict(&self, row: &[f64]) -> Result<usize, LearnError> {
        Ok(self.classify(row)?.class)
    }

    /// Decision values of a full feature row: an SVM's one-against-all decision values, k-NN's vote
    /// fractions, chance's training frequencies.
    pub fn decision_values(&self, row: &[f64]) -> Result<Vec<f64>, LearnError> {
        Ok(self.classify(row)?.decision)
    }

    /// [`Classifier::classify`] of every row of `x` (in parallel, results in row order).
    pub fn classify_batch(&self, x: ArrayView2<f64>) -> Result<Vec<Output>, LearnError> {
        (0..x.nrows())
            .into_par_iter()
            .map(|i| self.classify(&x.row(i).to_vec()))
            .collect()
    }

    /// [`Classifier::predict_proba`] of every row of `x` (rows × classes).
    pub fn predict_proba_batch(&self, x: ArrayView2<f64>) -> Result<Array2<f64>, LearnError> {
        let out = self.classify_batch(x)?;
        Ok(to_matrix(
            out.iter().map(|o| &o.probabilities),
            self.n_classes(),
        ))
    }

    /// [`Classifier::decision_values`] of every row of `x`, one row each.
    pub fn decision_values_batch(&self, x: ArrayView2<f64>) -> Result<Array2<f64>, LearnError> {
        let out = self.classify_batch(x)?;
        Ok(to_matrix(out.iter().map(|o| &o.decision), self.n_classes()))
    }

    /// [`Classifier::predict`] of every row of `x`.
    pub fn predict_batch(&self, x: ArrayView2<f64>) -> Result<Vec<usize>, LearnError> {
        Ok(self.classify_batch(x)?.iter().map(|o| o.class).collect())
    }
}

fn to_matrix<'a>(rows: impl ExactSizeIterator<Item = &'a Vec<f64>>, k: usize) -> Array2<f64> {
    let mut m = Array2::zeros((rows.len(), k));
    for (i, r) in rows.enumerate() {
        for (j, &v) in r.iter().enumerate().take(k) {
            m[[i, j]] = v;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::FeatureSet;
    use crate::learn::testutil::table;

    fn dataset(noise: f64) -> Dataset {
        Dataset::from_table(&table(3, 3, 4, 6, 5, noise)).unwrap()
    }

    fn spec(features: &str, classifier: ClassifierKind) -> TrainSpec {
        let names: Vec<String> = (0..5).map(|j| format!("f{j}")).collect();
        TrainSpec::new(
            FeatureSet::parse_with(features, &names).unwrap(),
            classifier,
        )
    }

    #[test]
    fn svm_pipeline_predicts_and_calibrates() {
        let ds = dataset(0.6);
        let clf = fit(&ds, &spec("all", ClassifierKind::Svm), 1).unwrap();
        clf.validate().unwrap();
        let Model::Svm(m) = &clf.model else {
            panic!("not an SVM")
        };
        assert_eq!((m.c, m.gamma), (100.0, 0.2));
        let mut correct = 0;
        for i in 0..ds.n_rows() {
            let row = ds.x.row(i).to_vec();
            let out = clf.classify(&row).unwrap();
            assert_eq!(out.class, svm::argmax(&out.decision));
            assert!((out.probabilities.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(out.probabilities.iter().all(|&p| (0.0..=1.0).contains(&p)));
            assert_eq!(clf.predict(&row).unwrap(), out.class);
            assert_eq!(clf.predict_proba(&row).unwrap(), out.probabilities);
            correct += usize::from(out.class == ds.labels[i]);
        }
        assert!(correct >= ds.n_rows() * 9 / 10, "{correct}");
        // Batch = one by one.
        let batch = clf.predict_proba_batch(ds.x.view()).unwrap();
        let dec = clf.decision_values_batch(ds.x.view()).unwrap();
        let classes = clf.predict_batch(ds.x.view()).unwrap();
        for (i, &class) in classes.iter().enumerate() {
            let out = clf.classify(&ds.x.row(i).to_vec()).unwrap();
            assert_eq!(batch.row(i).to_vec(), out.probabilities);
            assert_eq!(dec.row(i).to_vec(), out.decision);
            assert_eq!(class, out.class);
        }
    }

    #[test]
    fn serde_round_trip_is_exact_and_validated() {
        let ds = dataset(0.8);
        for s in [
            spec("auto3", ClassifierKind::Svm),
            spec("pca2", ClassifierKind::Svm),
            spec("f1,f3", ClassifierKind::Knn5),
            spec("all", ClassifierKind::Chance),
        ] {
            let clf = fit(&ds, &s, 3).unwrap();
            let json = serde_json::to_string(&clf).unwrap();
            let back: Classifier = serde_json::from_str(&json).unwrap();
            back.validate().unwrap();
            assert_eq!(back, clf);
            for i in 0..ds.n_rows() {
                let row = ds.x.row(i).to_vec();
                assert_eq!(back.classify(&row).unwrap(), clf.classify(&row).unwrap());
            }
        }
        let clf = fit(&ds, &spec("all", ClassifierKind::Svm), 3).unwrap();
        let mut bad = clf.clone();
        bad.selected_indices[0] = 99;
        assert!(matches!(bad.validate(), Err(LearnError::InvalidModel(_))));
        let mut bad = clf.clone();
        if let Model::Svm(m) = &mut bad.model {
            m.support_vectors[0].pop();
        }
        assert!(bad.validate().is_err());
        let mut bad = clf.clone();
        bad.scaler.std[0] = 0.0;
        assert!(bad.validate().is_err());
        assert_eq!(
            clf.predict(&[1.0, 2.0]),
            Err(LearnError::RowLength {
                expected: 5,
                got: 2
            })
        );
        assert!(matches!(
            clf.predict(&[0.0, f64::NAN, 0.0, 0.0, 0.0]),
            Err(LearnError::NonFiniteInput { .. })
        ));
    }

    #[test]
    fn deterministic_for_a_seed() {
        let ds = dataset(1.0);
        let s = spec("auto2", ClassifierKind::Svm);
        let a = fit(&ds, &s, 11).unwrap();
        let b = fit(&ds, &s, 11).unwrap();
        assert_eq!(a, b);
        let c = fit(&ds, &s, 12).unwrap();
        // Only the calibration folds depend on the seed (with 4 illuminations, each is a
        // fold of its own whatever the seed; Platt's stratified folds move).
        assert_eq!(a.model, c.model);
        assert_eq!(a.calibration, c.calibration);
        let platt = TrainSpec {
            calibration: CalibrationKind::Platt,
            ..s.clone()
        };
        let (a, c) = (fit(&ds, &platt, 11).unwrap(), fit(&ds, &platt, 12).unwrap());
        assert_eq!(a.model, c.model);
        assert_ne!(a.calibration, c.calibration);
    }

    #[test]
    fn selection_pca_and_baselines() {
        let ds = dataset(0.8);
        let auto = fit(&ds, &spec("auto2", ClassifierKind::Nn), 1).unwrap();
        assert_eq!(auto.selected.len(), 2);
        assert_eq!(auto.selection_errors.as_ref().map(Vec::len), Some(2));
        for (name, &i) in auto.selected.iter().zip(&auto.selected_indices) {
            assert_eq!(&ds.names[i], name);
        }
        let pca = fit(&ds, &spec("pca3", ClassifierKind::Svm), 1).unwrap();
        assert_eq!(pca.selected, ["pc1", "pc2", "pc3"]);
        assert_eq!(pca.selected_indices, [0, 1, 2, 3, 4]);
        let Model::Svm(m) = &pca.model else { panic!() };
        assert!((m.gamma - 1.0 / 3.0).abs() < 1e-15);
        // 1-NN reproduces its training labels (distinct points).
        let nn = fit(&ds, &spec("all", ClassifierKind::Nn), 1).unwrap();
        for i in 0..ds.n_rows() {
            let out = nn.classify(&ds.x.row(i).to_vec()).unwrap();
            assert_eq!(out.class, ds.labels[i]);
            assert_eq!(out.probabilities[out.class], 1.0);
        }
        let chance = fit(&ds, &spec("all", ClassifierKind::Chance), 1).unwrap();
        let out = chance.classify(&ds.x.row(0).to_vec()).unwrap();
        assert_eq!(out.class, 0);
        assert_eq!(out.probabilities, [1.0 / 3.0; 3]);
    }

    #[test]
    fn grid_search_is_inner_and_deterministic() {
        let ds = dataset(1.2);
        let mut s = spec("all", ClassifierKind::Svm);
        s.grid = Some(crate::classify::Grid {
            c: vec![0.1, 10.0],
            gamma_multipliers: vec![0.5, 2.0],
        });
        let train: Vec<usize> = (0..ds.n_rows()).filter(|&r| ds.groups[r] != 0).collect();
        let a = fit_rows(&ds, &train, &s, 1).unwrap();
        let b = fit_rows(&ds, &train, &s, 1).unwrap();
        assert_eq!(a, b);
        let gs = a.grid_search.as_ref().unwrap();
        assert_eq!(gs.points.len(), 4);
        // Inner CV on the 3 training groups only: 3 × 18 evaluated rows.
        assert!(gs.points.iter().all(|p| p.n == 54));
        let best = gs.points.iter().map(|p| p.correct).max().unwrap();
        assert_eq!(gs.points[gs.chosen].correct, best);
        assert!(gs.points.iter().take(gs.chosen).all(|p| p.correct < best));
        let Model::Svm(m) = &a.model else { panic!() };
        assert_eq!(
            (m.c, m.gamma),
            (gs.points[gs.chosen].c, gs.points[gs.chosen].gamma)
        );
    }

    #[test]
    fn rejects_degenerate_training_sets() {
        let ds = dataset(0.5);
        let one_class: Vec<usize> = (0..ds.n_rows()).filter(|&r| ds.labels[r] == 1).collect();
        assert_eq!(
            fit_rows(&ds, &one_class, &spec("all", ClassifierKind::Svm), 1),
            Err(LearnError::TooFewTrainingClasses(1))
        );
        assert_eq!(
            fit_rows(&ds, &[], &spec("all", ClassifierKind::Svm), 1),
            Err(LearnError::NoRows)
        );
        let mut s = spec("all", ClassifierKind::Svm);
        s.c = -1.0;
        assert!(matches!(
            fit(&ds, &s, 1),
            Err(LearnError::InvalidParameter(_))
        ));
        assert!(fit(&ds, &spec("auto9", ClassifierKind::Svm), 1).is_err());
        assert!("svm2".parse::<ClassifierKind>().is_err());
        assert_eq!("knn5".parse::<ClassifierKind>(), Ok(ClassifierKind::Knn5));
    }

    #[test]
    fn absent_class_is_never_predicted() {
        let ds = dataset(0.5);
        let rows: Vec<usize> = (0..ds.n_rows()).filter(|&r| ds.labels[r] != 2).collect();
        let clf = fit_rows(&ds, &rows, &spec("all", ClassifierKind::Svm), 1).unwrap();
        clf.validate().unwrap();
        for i in 0..ds.n_rows() {
            let out = clf.classify(&ds.x.row(i).to_vec()).unwrap();
            assert_ne!(out.class, 2);
            assert_eq!(out.probabilities[2], 0.0);
            assert_eq!(out.decision[2], f64::NEG_INFINITY);
        }
        let json = serde_json::to_string(&clf).unwrap();
        let back: Classifier = serde_json::from_str(&json).unwrap();
        assert_eq!(back, clf);
    }
}
