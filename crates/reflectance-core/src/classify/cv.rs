//! Leave-one-illumination-out cross-validation: each illumination (group) in turn is held
//! out, the whole pipeline (selection or PCA, standardization, SVM, calibration) is fitted
//! on the other groups' rows, and the held-out group's un-augmented rows are predicted.
//! Augmented rows (`<probe>@<suffix>`, see [`crate::learn::matrix`]) train only, and leave the
//! training set together with their probe.
//!
//! Folds run in parallel; each fold's seed is forked from the run's seed by its group index,
//! and results are assembled in a fixed order, so the report does not depend on the number
//! of threads.

use super::options::TrainSpec;
use super::pipeline::{Classifier, fit_rows};
use super::svm::squared_distance;
use crate::learn::error::LearnError;
use crate::learn::matrix::Dataset;
use crate::util::progress::{Counter, Observer, Silent};
use crate::util::rng::Rng;
use rayon::prelude::*;
use serde::Serialize;

/// Probabilities are clipped below at this value in the log-loss.
pub const LOG_LOSS_FLOOR: f64 = 1e-15;
/// Equal-width confidence bins of the expected calibration error.
pub const ECE_BINS: usize = 10;

/// One class's leave-one-illumination-out accuracy.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClassScore {
    /// The class's name.
    pub class: String,
    /// Held-out images of the class.
    pub n: usize,
    /// Of them, classified correctly.
    pub correct: usize,
    /// `correct / n`, in [0, 1] (0 for a class without images).
    pub accuracy: f64,
}

/// The training image nearest to a misclassified one (the paper's Fig. 13).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Nearest {
    /// The training image's path, as its manifest gives it.
    pub path: String,
    /// Its class.
    pub class: String,
    /// Its illumination (light probe).
    pub illumination: String,
    /// Euclidean, in the fold's standardized classifier-input space.
    pub distance: f64,
}

/// One held-out image's classification in the cross-validation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictionRecord {
    /// The image's path, as its manifest gives it.
    pub path: String,
    /// Its illumination, the fold's held-out one.
    pub illumination: String,
    /// Its true class.
    pub truth: String,
    /// The class predicted.
    pub predicted: String,
    /// Whether `predicted` is `truth`.
    pub correct: bool,
    /// Class order.
    pub probabilities: Vec<f64>,
    /// SVM decision values (k-NN: vote fractions; chance: frequencies), class order.
    pub decision_values: Vec<f64>,
    /// For misclassified images only.
    pub nearest: Option<Nearest>,
}

/// One fold: an illumination held out.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FoldReport {
    /// The held-out illumination.
    pub illumination: String,
    /// Training rows of the fold.
    pub n_train: usize,
    /// Held-out rows of the fold.
    pub n_test: usize,
    /// Of them, classified correctly.
    pub correct: usize,
    /// `correct / n_test`, in [0, 1].
    pub accuracy: f64,
    /// The classifier's inputs in this fold (auto<N>: in selection order).
    pub selected: Vec<String>,
    /// SVM only: the C and γ used (grid search may choose them per fold).
    pub c: Option<f64>,
    /// SVM only: the γ used.
    pub gamma: Option<f64>,
}

/// Leave-one-illumination-out cross-validation: the summary and every evaluated row.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CvReport {
    /// The metrics.
    #[serde(flatten)]
    pub summary: CvSummary,
    /// Evaluated rows, in table order.
    pub predictions: Vec<PredictionRecord>,
}

/// Leave-one-illumination-out cross-validation metrics (what the service's jobs report).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CvSummary {
    /// The feature set as specified (`hand6`, `auto6`, `pca6`, a list…).
    pub features: String,
    /// The classifier (`svm`, `nn`, `knn5` or `chance`).
    pub classifier: String,
    /// The run's seed; each fold's seed is forked from it by the fold's index.
    pub seed: u64,
    /// Class names, in the order of `per_class` and `confusion`.
    pub classes: Vec<String>,
    /// Held-out images evaluated (each once).
    pub n: usize,
    /// Of them, classified correctly.
    pub correct: usize,
    /// `correct / n`, in [0, 1].
    pub accuracy: f64,
    /// Expected accuracy of guessing uniformly at random: 1 / number of classes.
    pub random_guess_accuracy: f64,
    /// Each class's held-out images and accuracy, in class order.
    pub per_class: Vec<ClassScore>,
    /// confusion[truth][predicted], class order.
    pub confusion: Vec<Vec<usize>>,
    /// Mean −ln p(true class), p clipped below at 1e-15.
    pub log_loss: f64,
    /// Expected calibration error: 10 equal-width bins of the largest probability;
    /// Σ_b (n_b / n)·|accuracy_b − mean confidence_b|, where a row counts as correct when
    /// its most probable class (first on ties) is the true class.
    pub ece: f64,
    /// One report per held-out illumination.
    pub folds: Vec<FoldReport>,
}

struct FoldResult {
    report: FoldReport,
    rows: Vec<(usize, PredictionRecord)>,
}

fn run_fold(
    ds: &Dataset,
    group: usize,
    spec: &TrainSpec,
    seed: u64,
) -> Result<FoldResult, LearnError> {
    let all: Vec<usize> = (0..ds.n_rows()).collect();
    let (train, test) = ds.split_group(&all, group);
    let fold_seed = Rng::fork(seed, group as u64).next_u64();
    let clf: Classifier = fit_rows(ds, &train, spec, fold_seed)?;
    let row = |r: usize| ds.x.row(r).to_vec();
    let train_z: Vec<Vec<f64>> = train
        .iter()
        .map(|&r| clf.transform(&row(r)))
        .collect::<Result<_, _>>()?;
    let mut rows = Vec::with_capacity(test.len());
    let mut correct = 0;
    for &r in &test {
        let z = clf.transform(&row(r))?;
        let out = clf.classify_transformed(&z);
        let ok = out.class == ds.labels[r];
        correct += usize::from(ok);
        let nearest = if ok {
            None
        } else {
            let mut best: Option<(f64, usize)> = None;
            for (i, t) in train_z.iter().enumerate() {
                let d = squared_distance(t, &z);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, i));
                }
            }
            best.map(|(d, i)| {
                let tr = train[i];
                Nearest {
                    path: ds.paths[tr].clone(),
                    class: ds.classes[ds.labels[tr]].clone(),
                    illumination: ds.illuminations[tr].clone(),
                    distance: d.sqrt(),
                }
            })
        };
        rows.push((
            r,
            PredictionRecord {
                path: ds.paths[r].clone(),
                illumination: ds.illuminations[r].clone(),
                truth: ds.classes[ds.labels[r]].clone(),
                predicted: ds.classes[out.class].clone(),
                correct: ok,
                probabilities: out.probabilities,
                decision_values: out.decision,
                nearest,
            },
        ));
    }
    let (c, gamma) = match &clf.model {
        super::pipeline::Model::Svm(m) => (Some(m.c), Some(m.gamma)),
        _ => (None, None),
    };
    Ok(FoldResult {
        report: FoldReport {
            illumination: ds.group_names[group].clone(),
            n_train: train.len(),
            n_test: test.len(),
            correct,
            accuracy: correct as f64 / test.len().max(1) as f64,
            selected: clf.selected.clone(),
            c,
            gamma,
        },
        rows,
    })
}

/// Leave-one-illumination-out cross-validation of `spec` on `ds`.
pub fn cross_validate(ds: &Dataset, spec: &TrainSpec, seed: u64) -> Result<CvReport, LearnError> {
    cross_validate_with(ds, spec, seed, &Silent)
}

/// [`cross_validate`] reporting each completed fold to `observer`; a cancellation seen
/// before a fold starts ends the run with [`LearnError::Cancelled`] (running folds finish).
pub fn cross_validate_with(
    ds: &Dataset,
    spec: &TrainSpec,
    seed: u64,
    observer: &dyn Observer,
) -> Result<CvReport, LearnError> {
    let mut evaluated = vec![false; ds.group_names.len()];
    for r in 0..ds.n_rows() {
        if !ds.augmented[r] {
            evaluated[ds.groups[r]] = true;
        }
    }
    let groups: Vec<usize> = (0..ds.group_names.len())
        .filter(|&g| evaluated[g])
        .collect();
    if groups.len() < 2 {
        return Err(LearnError::TooFewGroups(groups.len()));
    }
    let counter = Counter::new(observer, groups.len());
    let results: Vec<FoldResult> = groups
        .par_iter()
        .map(|&g| {
            if counter.cancelled() {
                return Err(LearnError::Cancelled);
            }
            let fold = run_fold(ds, g, spec, seed);
            counter.tick();
            fold
        })
        .collect::<Result<_, _>>()?;
    let k = ds.n_classes();
    let mut folds = Vec::with_capacity(results.len());
    let mut records: Vec<(usize, PredictionRecord)> = Vec::new();
    for res in results {
        folds.push(res.report);
        records.extend(res.rows);
    }
    records.sort_by_key(|(r, _)| *r);
    let mut confusion = vec![vec![0usize; k]; k];
    let mut log_loss = 0.0;
    let mut bins = vec![(0usize, 0.0f64, 0usize); ECE_BINS];
    for (r, rec) in &records {
        let truth = ds.labels[*r];
        let predicted = ds.classes.binary_search(&rec.predicted).unwrap_or(0);
        confusion[truth][predicted] += 1;
        let p_true = rec.probabilities.get(truth).copied().unwrap_or(0.0);
        log_loss -= p_true.max(LOG_LOSS_FLOOR).ln();
        let top = super::svm::argmax(&rec.probabilities);
        let conf = rec.probabilities.get(top).copied().unwrap_or(0.0);
        let b = ((conf * ECE_BINS as f64) as usize).min(ECE_BINS - 1);
        bins[b].0 += 1;
        bins[b].1 += conf;
        bins[b].2 += usize::from(top == truth);
    }
    let n = records.len();
    let nf = n.max(1) as f64;
    let ece = bins
        .iter()
        .filter(|b| b.0 > 0)
        .map(|&(count, conf, hits)| {
            let c = count as f64;
            c / nf * (hits as f64 / c - conf / c).abs()
        })
        .sum();
    let correct: usize = (0..k).map(|c| confusion[c][c]).sum();
    let per_class = (0..k)
        .map(|c| {
            let n_c: usize = confusion[c].iter().sum();
            ClassScore {
                class: ds.classes[c].clone(),
                n: n_c,
                correct: confusion[c][c],
                accuracy: if n_c > 0 {
                    confusion[c][c] as f64 / n_c as f64
                } else {
                    0.0
                },
            }
        })
        .collect();
    let summary = CvSummary {
        features: spec.features.to_string(),
        classifier: spec.classifier.to_string(),
        seed,
        classes: ds.classes.clone(),
        n,
        correct,
        accuracy: correct as f64 / nf,
        random_guess_accuracy: 1.0 / k as f64,
        per_class,
        confusion,
        log_loss: log_loss / nf,
        ece,
        folds,
    };
    Ok(CvReport {
        summary,
        predictions: records.into_iter().map(|(_, rec)| rec).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::classify::ClassifierKind;
    use crate::dataset::FeatureTable;
    use crate::learn::feature_set::FeatureSet;
    use crate::learn::testutil::table;

    fn spec(features: &str, classifier: ClassifierKind) -> TrainSpec {
        let names: Vec<String> = (0..4).map(|j| format!("f{j}")).collect();
        TrainSpec::new(
            FeatureSet::parse_with(features, &names).unwrap(),
            classifier,
        )
    }

    fn base() -> FeatureTable {
        table(21, 3, 5, 4, 4, 1.5)
    }

    #[test]
    fn report_is_consistent() {
        let ds = Dataset::from_table(&base()).unwrap();
        let r = cross_validate(&ds, &spec("all", ClassifierKind::Svm), 5).unwrap();
        assert_eq!(r.summary.n, ds.n_rows());
        assert_eq!(r.summary.folds.len(), 5);
        assert_eq!(
            r.summary.confusion.iter().flatten().sum::<usize>(),
            r.summary.n
        );
        let correct = r.predictions.iter().filter(|p| p.correct).count();
        assert_eq!(correct, r.summary.correct);
        assert_eq!(
            r.summary.folds.iter().map(|f| f.correct).sum::<usize>(),
            r.summary.correct
        );
        assert!((r.summary.accuracy - correct as f64 / r.summary.n as f64).abs() < 1e-15);
        assert!(
            r.summary.accuracy > 0.5 && r.summary.accuracy < 1.0,
            "{}",
            r.summary.accuracy
        );
        assert_eq!(r.summary.random_guess_accuracy, 1.0 / 3.0);
        for (c, s) in r.summary.per_class.iter().enumerate() {
            assert_eq!(s.n, 20);
            assert_eq!(s.correct, r.summary.confusion[c][c]);
        }
        // Log-loss and ECE recomputed from the records.
        let ll: f64 = r
            .predictions
            .iter()
            .map(|p| {
                let t = ds.classes.iter().position(|c| *c == p.truth).unwrap();
                -p.probabilities[t].max(1e-15).ln()
            })
            .sum::<f64>()
            / r.summary.n as f64;
        assert!((ll - r.summary.log_loss).abs() < 1e-12);
        assert!(r.summary.ece >= 0.0 && r.summary.ece <= 1.0);
        for (i, p) in r.predictions.iter().enumerate() {
            assert_eq!(p.path, ds.paths[i]);
            assert_eq!(p.nearest.is_some(), !p.correct);
            if let Some(n) = &p.nearest {
                // The nearest training image comes from another illumination.
                assert_ne!(n.illumination, p.illumination);
                assert!(n.distance >= 0.0);
            }
        }
        assert!(
            r.summary
                .folds
                .iter()
                .all(|f| f.c == Some(100.0) && f.gamma == Some(0.25))
        );
        serde_json::to_string(&r).unwrap();
    }

    #[test]
    fn same_report_with_one_or_two_threads() {
        let ds = Dataset::from_table(&base()).unwrap();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| cross_validate(&ds, &spec("auto2", ClassifierKind::Svm), 9).unwrap())
        };
        assert_eq!(run(1), run(2));
    }

    #[test]
    fn nearest_neighbour_of_a_1nn_mistake_has_the_predicted_class() {
        let ds = Dataset::from_table(&base()).unwrap();
        let r = cross_validate(&ds, &spec("f0,f1", ClassifierKind::Nn), 1).unwrap();
        let wrong: Vec<_> = r.predictions.iter().filter(|p| !p.correct).collect();
        assert!(!wrong.is_empty());
        for p in wrong {
            assert_eq!(p.nearest.as_ref().unwrap().class, p.predicted);
        }
    }

    #[test]
    fn chance_baseline() {
        let ds = Dataset::from_table(&base()).unwrap();
        let r = cross_validate(&ds, &spec("all", ClassifierKind::Chance), 1).unwrap();
        // Balanced classes: always the first class, accuracy 1/3, log-loss ln 3.
        assert!(r.predictions.iter().all(|p| p.predicted == "c0"));
        assert!((r.summary.accuracy - 1.0 / 3.0).abs() < 1e-15);
        assert!((r.summary.log_loss - 3f64.ln()).abs() < 1e-12);
    }

    #[test]
    fn augmented_rows_train_only_and_leave_with_their_probe() {
        let mut t = base();
        let originals = t.samples.len();
        let extra: Vec<_> = t
            .samples
            .iter()
            .map(|s| {
                let mut a = s.clone();
                a.illumination = format!("{}@rot090", s.illumination);
                a.path = format!("rot/{}", s.path);
                a.values.iter_mut().for_each(|v| *v += 0.01);
                a
            })
            .collect();
        t.samples.extend(extra);
        let ds = Dataset::from_table(&t).unwrap();
        assert_eq!(ds.group_names.len(), 5);
        let r = cross_validate(&ds, &spec("all", ClassifierKind::Nn), 1).unwrap();
        assert_eq!(r.summary.n, originals);
        assert!(r.predictions.iter().all(|p| !p.illumination.contains('@')));
        for f in &r.summary.folds {
            // 2 × (4 other groups × 12 rows): the held-out probe's copies left with it.
            assert_eq!((f.n_train, f.n_test), (96, 12));
        }
        for p in r.predictions.iter().filter(|p| !p.correct) {
            let n = p.nearest.as_ref().unwrap();
            let probe = n.illumination.split('@').next().unwrap();
            assert_ne!(probe, p.illumination);
        }
        // Only augmented rows for a probe: it trains but is not a fold.
        let mut t2 = base();
        for s in t2.samples.iter_mut().filter(|s| s.illumination == "g4") {
            s.illumination = "g4@flip".into();
        }
        let ds2 = Dataset::from_table(&t2).unwrap();
        let r2 = cross_validate(&ds2, &spec("all", ClassifierKind::Nn), 1).unwrap();
        assert_eq!(r2.summary.folds.len(), 4);
        assert!(r2.summary.folds.iter().all(|f| f.n_train == 48));
    }

    #[test]
    fn needs_two_illuminations() {
        let mut t = base();
        t.samples
            .iter_mut()
            .for_each(|s| s.illumination = "only".into());
        let ds = Dataset::from_table(&t).unwrap();
        assert_eq!(
            cross_validate(&ds, &spec("all", ClassifierKind::Svm), 1),
            Err(LearnError::TooFewGroups(1))
        );
    }
}
