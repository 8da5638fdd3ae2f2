//! The paper's Tables 1 and 2 on our data: leave-one-illumination-out accuracy for feature
//! sets × data sets (SVM), and for classifiers × feature sets, with the paper's figures
//! beside ours; Markdown, JSON and PNG plots.
//!
//! `--data DIR` holds four rendered data sets, each a folder with `manifest.csv`:
//! `paper9_6`, `paper9_11`, `all_6`, `all_11` (probe set × class set). Features are cached
//! as `features.csv` next to each manifest.

mod plots;

use crate::dataset::{self, FeatureTable};
use crate::features::{Extractor, FeatureConfig};
use crate::image_io::DecodeOptions;
use crate::learn::{self, ClassifierKind, CvReport, Dataset, FeatureSet, TrainSpec};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{0}")]
    Data(#[from] dataset::DatasetError),
    #[error("{0}")]
    Learn(#[from] learn::LearnError),
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error(
        "data set {0} is missing: expected {0}/manifest.csv (see README, \"Reproducing the paper's tables\")"
    )]
    Missing(String),
    #[error("plot: {0}")]
    Plot(String),
}

/// The four data sets of Table 1, in column order.
pub const DATASETS: [(&str, &str); 4] = [
    ("paper9_6", "6 classes, paper9 (9 maps)"),
    ("paper9_11", "11 classes, paper9 (9 maps)"),
    ("all_6", "6 classes, all (70 maps)"),
    ("all_11", "11 classes, all (70 maps)"),
];

/// Table 1 rows after `chance`: feature sets for the SVM.
pub const TABLE1_ROWS: [&str; 6] = ["mean1", "hand2", "hand6", "auto6", "pca6", "all"];
/// Table 2: classifiers × feature sets.
pub const TABLE2_CLASSIFIERS: [&str; 3] = ["svm", "nn", "knn5"];
pub const TABLE2_SETS: [&str; 2] = ["hand6", "all"];

/// The paper's figures that we have (Table 1, hand6 SVM row), per data set.
fn paper_figure(dataset: &str, features: &str, classifier: &str) -> Option<f64> {
    if features != "hand6" || classifier != "svm" {
        return None;
    }
    match dataset {
        "paper9_6" => Some(98.1),
        "paper9_11" => Some(83.8),
        "all_6" => Some(99.7),
        "all_11" => Some(98.5),
        _ => None,
    }
}

/// One cross-validation run's summary (the per-image predictions go to the CV JSON only).
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    pub dataset: String,
    pub features: String,
    pub classifier: String,
    pub accuracy: f64,
    pub correct: usize,
    pub n: usize,
    pub log_loss: f64,
    pub ece: f64,
    pub paper: Option<f64>,
    pub per_class: Vec<learn::cv::ClassScore>,
    pub confusion: Vec<Vec<usize>>,
    pub classes: Vec<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub seed: u64,
    /// Training rows per data set (augmented views included) and evaluated rows.
    pub datasets: Vec<DatasetSummary>,
    pub chance: Vec<f64>,
    pub cells: Vec<Cell>,
}

#[derive(Clone, Debug, Serialize)]
pub struct DatasetSummary {
    pub name: String,
    pub rows: usize,
    pub evaluated: usize,
    pub illuminations: usize,
    pub classes: usize,
}

/// Features of a data set, from the cache when it is newer than the manifest.
fn features_of(dir: &Path, options: &DecodeOptions) -> Result<FeatureTable, ReportError> {
    let manifest = dir.join("manifest.csv");
    if !manifest.is_file() {
        return Err(ReportError::Missing(dir.display().to_string()));
    }
    let cache = dir.join("features.csv");
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    if modified(&cache).is_some_and(|c| modified(&manifest).is_some_and(|m| c >= m)) {
        return Ok(FeatureTable::read(&cache)?);
    }
    let extractor =
        Extractor::new(FeatureConfig::default()).map_err(|e| ReportError::Plot(e.to_string()))?;
    let manifest = dataset::read_manifest(&manifest)?;
    manifest.require_labels()?;
    let table = dataset::extract_manifest(&extractor, &manifest, options)?;
    table.write(&cache)?;
    Ok(table)
}

fn cell(dataset: &str, report: &CvReport) -> Cell {
    Cell {
        dataset: dataset.to_string(),
        features: report.features.clone(),
        classifier: report.classifier.clone(),
        accuracy: report.accuracy,
        correct: report.correct,
        n: report.n,
        log_loss: report.log_loss,
        ece: report.ece,
        paper: paper_figure(dataset, &report.features, &report.classifier),
        per_class: report.per_class.clone(),
        confusion: report.confusion.clone(),
        classes: report.classes.clone(),
    }
}

/// Run every cross-validation of Tables 1 and 2, write `report.md`, `report.json` and the
/// plots into `out`, and return the report.
pub fn run(
    data: &Path,
    out: &Path,
    seed: u64,
    options: &DecodeOptions,
) -> Result<Report, ReportError> {
    std::fs::create_dir_all(out).map_err(|source| ReportError::Io {
        path: out.display().to_string(),
        source,
    })?;
    let mut runs: Vec<(&str, &str, &str)> = Vec::new();
    for (name, _) in DATASETS {
        for set in TABLE1_ROWS {
            runs.push((name, set, "svm"));
        }
        for classifier in TABLE2_CLASSIFIERS.iter().filter(|c| **c != "svm") {
            for set in TABLE2_SETS {
                runs.push((name, set, classifier));
            }
        }
    }
    let bar = crate::progress::bar(runs.len() as u64, "report");
    let mut tables = Vec::new();
    let mut datasets = Vec::new();
    for (name, _) in DATASETS {
        let table = features_of(&data.join(name), options)?;
        let ds = Dataset::from_table(&table)?;
        datasets.push(DatasetSummary {
            name: name.to_string(),
            rows: ds.n_rows(),
            evaluated: ds.augmented.iter().filter(|a| !**a).count(),
            illuminations: ds.group_names.len(),
            classes: ds.n_classes(),
        });
        tables.push((name, table, ds));
    }
    let mut cells = Vec::new();
    for (name, set, classifier) in runs {
        let (_, table, ds) = tables
            .iter()
            .find(|(n, _, _)| *n == name)
            .expect("loaded above");
        let spec = TrainSpec::new(
            FeatureSet::parse_with(set, &table.names)?,
            classifier.parse::<ClassifierKind>()?,
        );
        let report = learn::cross_validate(ds, &spec, seed)?;
        if set == "hand6" && classifier == "svm" {
            plots::confusion(
                &report,
                &out.join(format!("confusion_{name}_hand6_svm.png")),
            )?;
        }
        cells.push(cell(name, &report));
        bar.inc(1);
    }
    bar.finish_and_clear();
    for (name, table, ds) in tables.iter().filter(|(n, _, _)| n.ends_with("_6")) {
        plots::fig7(table, ds, seed, &out.join(format!("fig7_{name}.png")))?;
    }
    let report = Report {
        seed,
        chance: datasets.iter().map(|d| 1.0 / d.classes as f64).collect(),
        datasets,
        cells,
    };
    let json = serde_json::to_vec_pretty(&report).map_err(|e| ReportError::Plot(e.to_string()))?;
    write(&out.join("report.json"), &json)?;
    write(&out.join("report.md"), markdown(&report).as_bytes())?;
    Ok(report)
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    crate::fsutil::write_atomic(path, bytes).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn find<'a>(
    report: &'a Report,
    dataset: &str,
    features: &str,
    classifier: &str,
) -> Option<&'a Cell> {
    report
        .cells
        .iter()
        .find(|c| c.dataset == dataset && c.features == features && c.classifier == classifier)
}

fn format_cell(cell: Option<&Cell>) -> String {
    match cell {
        Some(c) => match c.paper {
            Some(p) => format!("{:.1} ({p:.1})", 100.0 * c.accuracy),
            None => format!("{:.1} (—)", 100.0 * c.accuracy),
        },
        None => "—".into(),
    }
}

/// Tables 1 and 2 as Markdown: our accuracy (%) with the paper's figure in parentheses.
pub fn markdown(report: &Report) -> String {
    let mut md =
        String::from("# Reflectance classification: the paper's Tables 1 and 2 on our data\n\n");
    let _ = writeln!(
        md,
        "Leave-one-illumination-out accuracy (%), ours with the paper's figure in parentheses \
         (— where the paper's figure is not available to us). Seed {}.\n",
        report.seed
    );
    md.push_str(
        "| data set | images | evaluated | illuminations | classes |\n|---|---|---|---|---|\n",
    );
    for d in &report.datasets {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            d.name, d.rows, d.evaluated, d.illuminations, d.classes
        );
    }
    md.push_str(
        "\n## Table 1 — SVM (RBF, C = 100, γ = 1/n), feature sets × data sets\n\n| features |",
    );
    for (_, title) in DATASETS {
        let _ = write!(md, " {title} |");
    }
    md.push_str("\n|---|---|---|---|---|\n| chance |");
    for c in &report.chance {
        let _ = write!(md, " {:.1} |", 100.0 * c);
    }
    md.push('\n');
    for set in TABLE1_ROWS {
        let _ = write!(md, "| {set} |");
        for (name, _) in DATASETS {
            let _ = write!(md, " {} |", format_cell(find(report, name, set, "svm")));
        }
        md.push('\n');
    }
    md.push_str("\n## Table 2 — classifiers × feature sets\n\n| classifier | features |");
    for (_, title) in DATASETS {
        let _ = write!(md, " {title} |");
    }
    md.push_str("\n|---|---|---|---|---|---|\n");
    for classifier in TABLE2_CLASSIFIERS {
        for set in TABLE2_SETS {
            let _ = write!(md, "| {classifier} | {set} |");
            for (name, _) in DATASETS {
                let _ = write!(
                    md,
                    " {} |",
                    format_cell(find(report, name, set, classifier))
                );
            }
            md.push('\n');
        }
    }
    md.push_str("\nLog-loss and expected calibration error of every run are in `report.json`; \
                 confusion matrices of hand6 (SVM) in `confusion_*.png`; the Fig. 7 scatter with the \
                 SVM's decision regions in `fig7_*.png`.\n");
    md
}

/// Default output folder for `report --data DIR`.
pub fn default_out(data: &Path) -> PathBuf {
    data.join("report")
}
