//! Learning speed on a synthetic 770-row table (11 classes × 10 illuminations × 7 views,
//! 117 canonically named features, like a rendered training set).
//!
//! The table is also written to `$TMPDIR/reflectance_learn_bench.csv`, so that
//! `scripts/learn_reference/time_sklearn.py` can time scikit-learn/libsvm on the same data.
//!
//! Cases: the full calibrated fit (selection + scaler + SVM + 5-fold Platt), the bare
//! one-against-all SVM training (kernel matrix + K binary SMO problems; this is what
//! `OneVsRestClassifier(SVC)` does) with f64 or f32 kernel values and shrinking on or off,
//! leave-one-illumination-out CV, and per-image prediction.

use divan::Bencher;
use ndarray::{Array2, Axis};
use reflectance_core::classify::cross_validate;
use reflectance_core::classify::svm::{Gram, KernelValue, SolverParams, train_one_vs_all};
use reflectance_core::classify::{ClassifierKind, TrainSpec, fit};
use reflectance_core::dataset::{FeatureTable, Sample};
use reflectance_core::features::{default_names, named_set};
use reflectance_core::learn::scaler::Scaler;
use reflectance_core::learn::{Dataset, FeatureSet};
use reflectance_core::util::rng::Rng;

fn main() {
    // As the binary does: see `reflectance_core::util::heap`.
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    let path = std::env::temp_dir().join("reflectance_learn_bench.csv");
    table().write(&path).expect("write bench table");
    eprintln!("bench table: {}", path.display());
    divan::main();
}

const CLASSES: usize = 11;
const GROUPS: usize = 10;
const VIEWS: usize = 7;

fn normal(rng: &mut Rng) -> f64 {
    let u = 1.0 - rng.next_f64();
    let v = rng.next_f64();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Class and illumination latent factors, their interaction, per-view nuisance and noise,
/// mapped to 117 columns; the ratio columns are exact differences of the log variances.
fn table() -> FeatureTable {
    let mut rng = Rng::new(770);
    let names = default_names().to_vec();
    let m = names.len();
    let mut gauss =
        |n: usize, s: f64| -> Vec<f64> { (0..n).map(|_| s * normal(&mut rng)).collect() };
    let theta: Vec<Vec<f64>> = (0..CLASSES).map(|_| gauss(4, 1.0)).collect();
    let phi: Vec<Vec<f64>> = (0..GROUPS).map(|_| gauss(3, 1.0)).collect();
    let mut w_class: Vec<Vec<f64>> = (0..m).map(|_| gauss(4, 0.9)).collect();
    let w_group: Vec<Vec<f64>> = (0..m).map(|_| gauss(3, 1.1)).collect();
    let w_inter: Vec<Vec<f64>> = (0..m).map(|_| gauss(12, 0.25)).collect();
    let w_view: Vec<Vec<f64>> = (0..m).map(|_| gauss(3, 0.5)).collect();
    let offset = gauss(m, 2.0);
    for n in named_set("hand6").unwrap_or_default() {
        if let Some(j) = names.iter().position(|x| *x == n) {
            w_class[j].iter_mut().for_each(|w| *w *= 2.5);
        }
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut samples = Vec::new();
    for (g, phi) in phi.iter().enumerate() {
        for (c, theta) in theta.iter().enumerate() {
            for v in 0..VIEWS {
                let view = gauss(3, 1.0);
                let mut values: Vec<f64> = (0..m)
                    .map(|j| {
                        let inter: f64 = (0..4)
                            .flat_map(|a| (0..3).map(move |b| (a, b)))
                            .map(|(a, b)| w_inter[j][a * 3 + b] * theta[a] * phi[b])
                            .sum();
                        let f = dot(&w_class[j], theta)
                            + dot(&w_group[j], phi)
                            + inter
                            + dot(&w_view[j], &view)
                            + 0.8 * gauss(1, 1.0)[0];
                        offset[j] + 0.5 * f
                    })
                    .collect();
                for band in ["h", "v", "d"] {
                    for k in 1..4 {
                        let col = |n: String| names.iter().position(|x| *x == n).unwrap_or(0);
                        let r = col(format!("ratio.{band}.s{k}_s{}", k + 1));
                        let a = col(format!("wav.s{k}.{band}.var"));
                        let b = col(format!("wav.s{}.{band}.var", k + 1));
                        values[r] = values[a] - values[b];
                    }
                }
                samples.push(Sample {
                    path: format!("g{g}/c{c:02}_{v}.png"),
                    class: format!("c{c:02}"),
                    illumination: format!("g{g}"),
                    values,
                });
            }
        }
    }
    FeatureTable { names, samples }
}

fn dataset() -> Dataset {
    Dataset::from_table(&table()).expect("dataset")
}

fn spec(set: &str) -> TrainSpec {
    TrainSpec::new(set.parse::<FeatureSet>().expect("set"), ClassifierKind::Svm)
}

fn single_thread<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
        .install(f)
}

/// Full calibrated fit (2 threads: OvA problems and calibration folds in parallel).
#[divan::bench(args = ["hand6", "all"], sample_count = 10)]
fn fit_calibrated(bencher: Bencher, set: &str) {
    let ds = dataset();
    let s = spec(set);
    bencher.bench(|| fit(&ds, &s, 1).expect("fit"));
}

/// The same on one thread (comparable to OneVsRest(SVC(probability=True)) fit).
#[divan::bench(args = ["hand6", "all"], sample_count = 10)]
fn fit_calibrated_1thread(bencher: Bencher, set: &str) {
    let ds = dataset();
    let s = spec(set);
    bencher.bench(|| single_thread(|| fit(&ds, &s, 1).expect("fit")));
}

fn standardized(ds: &Dataset, set: &str) -> Array2<f64> {
    let cols = set
        .parse::<FeatureSet>()
        .expect("set")
        .resolve(&ds.names)
        .expect("resolve")
        .expect("fixed");
    let x = ds.x.select(Axis(1), &cols);
    Scaler::fit(x.view()).transform(x.view())
}

fn ova<T: KernelValue>(ds: &Dataset, z: &Array2<f64>, shrinking: bool) -> usize {
    let gram = Gram::<T>::rbf(z.view(), 1.0 / z.ncols() as f64);
    let rows: Vec<usize> = (0..ds.n_rows()).collect();
    let params = SolverParams {
        shrinking,
        ..SolverParams::default()
    };
    let sols = train_one_vs_all(&gram, &rows, &ds.labels, ds.n_classes(), &params);
    sols.iter().flatten().map(|s| s.iterations).sum()
}

/// Bare one-against-all training, single thread (comparable to OneVsRest(SVC) fit).
#[divan::bench(args = ["hand6", "all"], sample_count = 20)]
fn ova_f64_shrinking(bencher: Bencher, set: &str) {
    let ds = dataset();
    let z = standardized(&ds, set);
    bencher.bench(|| single_thread(|| ova::<f64>(&ds, &z, true)));
}

#[divan::bench(args = ["hand6", "all"], sample_count = 20)]
fn ova_f32_shrinking(bencher: Bencher, set: &str) {
    let ds = dataset();
    let z = standardized(&ds, set);
    bencher.bench(|| single_thread(|| ova::<f32>(&ds, &z, true)));
}

#[divan::bench(args = ["hand6", "all"], sample_count = 20)]
fn ova_f64_no_shrinking(bencher: Bencher, set: &str) {
    let ds = dataset();
    let z = standardized(&ds, set);
    bencher.bench(|| single_thread(|| ova::<f64>(&ds, &z, false)));
}

/// The kernel matrix alone, single thread.
#[divan::bench(args = ["hand6", "all"], sample_count = 20)]
fn kernel_matrix_f64(bencher: Bencher, set: &str) {
    let ds = dataset();
    let z = standardized(&ds, set);
    bencher.bench(|| single_thread(|| Gram::<f64>::rbf(z.view(), 1.0 / z.ncols() as f64)));
}

/// Leave-one-illumination-out CV (10 folds, each a calibrated fit), 2 threads.
#[divan::bench(args = ["hand6", "all"], sample_count = 3)]
fn cv_loio(bencher: Bencher, set: &str) {
    let ds = dataset();
    let s = spec(set);
    bencher.bench(|| cross_validate(&ds, &s, 1).expect("cv"));
}

#[divan::bench(args = ["hand6", "all"], sample_count = 3)]
fn cv_loio_1thread(bencher: Bencher, set: &str) {
    let ds = dataset();
    let s = spec(set);
    bencher.bench(|| single_thread(|| cross_validate(&ds, &s, 1).expect("cv")));
}

/// One image: transform, decision values, calibrated probabilities.
#[divan::bench(args = ["hand6", "all"])]
fn predict_one(bencher: Bencher, set: &str) {
    let ds = dataset();
    let clf = fit(&ds, &spec(set), 1).expect("fit");
    let row = ds.x.row(0).to_vec();
    bencher.bench(|| clf.classify(divan::black_box(&row)).expect("classify"));
}

/// One image's Ward-parameter estimate with a shipped model's estimator (the cost a request
/// adds beyond classification when the model has one): standardize, 1 500 random Fourier
/// features, 4 outputs, intervals.
#[divan::bench(args = ["ward6", "ward11"])]
fn estimate_one(bencher: Bencher, name: &str) {
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let model = reflectance_core::model::registry::Registry::new(models)
        .load(name, 1)
        .expect("shipped model");
    let estimator = model.estimator.expect("shipped models carry an estimator");
    let row = vec![0.5; model.features.config.names().len()];
    bencher.bench(|| estimator.estimate(divan::black_box(&row)));
}

/// What the service decides of one feature row with a shipped model, beside the bare
/// classifier: the prediction set and the domain check add to it (issue 33: ≤ 0.1 ms).
/// "… without white": the classifier without white answers instead.
#[divan::bench(args = ["ward6", "ward11", "ward6 without white", "ward11 without white"])]
fn decide_one(bencher: Bencher, case: &str) {
    let name = case.split(' ').next().unwrap_or(case);
    let (model, row) = shipped_row(name);
    let context = reflectance_core::inference::Context {
        request: reflectance_core::model::Request {
            white_given: !case.ends_with("without white"),
            object: false,
        },
        radius: 100.0,
        measured: None,
        coverage: 0.95,
    };
    bencher.bench(|| reflectance_core::inference::decide(&model, divan::black_box(&row), context));
}

/// The bare classifier on the same row (what `decide_one` adds to).
#[divan::bench(args = ["ward6", "ward11"])]
fn classify_one_shipped(bencher: Bencher, name: &str) {
    let (model, row) = shipped_row(name);
    bencher.bench(|| model.classifier.classify(divan::black_box(&row)));
}

/// A shipped model and its self-test row (a real training image's features).
fn shipped_row(name: &str) -> (reflectance_core::model::ModelFile, Vec<f64>) {
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let model = reflectance_core::model::registry::Registry::new(models)
        .load(name, 1)
        .expect("shipped model");
    let row = model.self_test.features.clone();
    (model, row)
}
