//! The paper's Tables 1 and 2 on our data: leave-one-illumination-out accuracy for feature
//! sets × data sets (SVM), and for classifiers × feature sets, with the paper's figures
//! beside ours; Markdown, JSON and PNG plots.
//!
//! `--data DIR` holds four rendered data sets, each a folder with `manifest.csv`:
//! `paper9_6`, `paper9_11`, `all_6`, `all_11` (probe set × class set). Features (with the
//! log-domain and radial ones) are cached as `features.csv` next to each manifest.
//!
//! With a fifth, `materials` (materials of a continuous design rendered like the others, with
//! the class file they were rendered from as `materials/materials.json`), the report also
//! cross-validates the Ward-parameter estimate and writes `estimate.md`, `estimate.json` and
//! `estimate.png`.
//!
//! Three protocols: the paper's (original renders only, the 117 features) for every cell of
//! Tables 1 and 2, and ours for hand6, hand6+log and hand6+log+radial: `augmented`
//! (training views of the probes, when the data sets have them) and `synthetic` (those views
//! and the procedural illuminations, when the data sets have them).

pub mod estimate;
mod plots;
pub(crate) mod robustness;

use reflectance_core::classify::{self, ClassifierKind, CvReport, TrainSpec};
use reflectance_core::dataset::{self, FeatureTable};
use reflectance_core::decode::DecodeOptions;
use reflectance_core::estimate::{self as ward, EstimateReport};
use reflectance_core::features::{Extractor, Families, FeatureConfig, Preprocessing};
use reflectance_core::learn::{self, Dataset, FeatureSet};
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
        "data set {0} is missing: expected {0}/manifest.csv (see docs/accuracy.md, \"Reproducing the paper's tables\")"
    )]
    Missing(String),
    #[error("plot: {0}")]
    Plot(String),
    #[error("{0}")]
    Input(String),
}

/// The four data sets of Table 1, in column order.
pub const DATASETS: [(&str, &str); 4] = [
    ("paper9_6", "6 classes, paper9"),
    ("paper9_11", "11 classes, paper9"),
    ("all_6", "6 classes, all"),
    ("all_11", "11 classes, all"),
];

/// The optional data set of the Ward-parameter estimate, and its class file within.
pub const MATERIALS: (&str, &str) = ("materials", "materials.json");

/// Table 1 rows after `chance`: feature sets for the SVM.
pub const TABLE1_ROWS: [&str; 6] = ["mean1", "hand2", "hand6", "auto6", "pca6", "all"];
/// Our protocols, these feature sets (SVM).
pub const AUGMENTED_ROWS: [&str; 3] = ["hand6", "hand6+log", "hand6+log+radial"];
/// Protocols in the order of a data set's table variants.
const PROTOCOLS: [&str; 3] = ["paper", "augmented", "synthetic"];
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
    /// `paper` (original renders, 117 features), `augmented` (training views added) or
    /// `synthetic` (training views and synthetic illuminations added).
    pub protocol: String,
    pub features: String,
    pub classifier: String,
    pub accuracy: f64,
    pub correct: usize,
    pub n: usize,
    pub log_loss: f64,
    pub ece: f64,
    pub paper: Option<f64>,
    pub per_class: Vec<classify::cv::ClassScore>,
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
    /// The Ward-parameter estimate cross-validated on `materials`, when the data have it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate: Option<EstimateReport>,
}

#[derive(Clone, Debug, Serialize)]
pub struct DatasetSummary {
    pub name: String,
    pub rows: usize,
    /// Rows of synthetic illuminations (training only), included in `rows`.
    pub synthetic_rows: usize,
    pub evaluated: usize,
    pub illuminations: usize,
    pub classes: usize,
}

/// Features of a data set, from the cache when it is newer than the manifest and has every
/// column (an older version's cache may lack extensions).
fn features_of(dir: &Path, options: &DecodeOptions) -> Result<FeatureTable, ReportError> {
    let manifest = dir.join("manifest.csv");
    if !manifest.is_file() {
        return Err(ReportError::Missing(dir.display().to_string()));
    }
    let config = FeatureConfig::extended(Families::ALL, Preprocessing::default());
    let cache = dir.join("features.csv");
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    if modified(&cache).is_some_and(|c| modified(&manifest).is_some_and(|m| c >= m)) {
        let cached = FeatureTable::read(&cache)?;
        if cached.names == config.names() {
            return Ok(cached);
        }
    }
    let extractor = Extractor::new(config).map_err(|e| ReportError::Plot(e.to_string()))?;
    let manifest = dataset::read_manifest(&manifest)?;
    manifest.require_labels()?;
    let table = crate::progress::observed("features", |bar| {
        dataset::extract_manifest_with(&extractor, &manifest, options, bar)
    })?;
    table.write(&cache)?;
    Ok(table)
}

fn cell(dataset: &str, protocol: &str, report: &CvReport) -> Cell {
    Cell {
        dataset: dataset.to_string(),
        protocol: protocol.to_string(),
        features: report.summary.features.clone(),
        classifier: report.summary.classifier.clone(),
        accuracy: report.summary.accuracy,
        correct: report.summary.correct,
        n: report.summary.n,
        log_loss: report.summary.log_loss,
        ece: report.summary.ece,
        paper: paper_figure(
            dataset,
            &report.summary.features,
            &report.summary.classifier,
        )
        .filter(|_| protocol == "paper"),
        per_class: report.summary.per_class.clone(),
        confusion: report.summary.confusion.clone(),
        classes: report.summary.classes.clone(),
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
    // (data set, protocol, feature set, classifier)
    let mut runs: Vec<(&str, &str, &str, &str)> = Vec::new();
    for (name, _) in DATASETS {
        for set in TABLE1_ROWS {
            runs.push((name, "paper", set, "svm"));
        }
        for classifier in TABLE2_CLASSIFIERS.iter().filter(|c| **c != "svm") {
            for set in TABLE2_SETS {
                runs.push((name, "paper", set, classifier));
            }
        }
    }
    let base_names = FeatureConfig::default().names();
    let mut tables = Vec::new();
    let mut datasets = Vec::new();
    for (name, _) in DATASETS {
        let full = features_of(&data.join(name), options)?;
        let paper = full
            .originals()
            .with_columns(&base_names)
            .map_err(|e| ReportError::Plot(e.to_string()))?;
        let views = full.without_synthetic();
        let synthetic_rows = full.samples.len() - views.samples.len();
        let paper_ds = Dataset::from_table(&paper)?;
        datasets.push(DatasetSummary {
            name: name.to_string(),
            rows: full.samples.len(),
            synthetic_rows,
            evaluated: paper_ds.n_rows(),
            illuminations: paper_ds.group_names.len(),
            classes: paper_ds.n_classes(),
        });
        let ours = if synthetic_rows > 0 {
            &PROTOCOLS[1..]
        } else {
            &PROTOCOLS[1..2]
        };
        runs.extend(
            ours.iter()
                .flat_map(|p| AUGMENTED_ROWS.map(|set| (name, *p, set, "svm"))),
        );
        let views_ds = Dataset::from_table(&views)?;
        let full_ds = Dataset::from_table(&full)?;
        tables.push((
            name,
            [(paper, paper_ds), (views, views_ds), (full, full_ds)],
        ));
    }
    let bar = crate::progress::bar(runs.len() as u64, "report");
    let mut cells = Vec::new();
    for (name, protocol, set, classifier) in runs {
        let (_, variants) = tables
            .iter()
            .find(|(n, _)| *n == name)
            .expect("loaded above");
        let variant = PROTOCOLS.iter().position(|p| *p == protocol).unwrap_or(0);
        let (table, ds) = &variants[variant];
        let spec = TrainSpec::new(
            FeatureSet::parse_with(set, &table.names)?,
            classifier.parse::<ClassifierKind>()?,
        );
        let report = classify::cross_validate(ds, &spec, seed)?;
        let plotted =
            classifier == "svm" && ((set, protocol) == ("hand6", "paper") || set == "hand6+log");
        if plotted {
            let file = format!("confusion_{name}_{}_{protocol}.png", set.replace('+', "_"));
            plots::confusion(&report, &out.join(file))?;
        }
        cells.push(cell(name, protocol, &report));
        bar.inc(1);
    }
    bar.finish();
    for (name, variants) in tables.iter().filter(|(n, _)| n.ends_with("_6")) {
        let (table, ds) = &variants[0];
        plots::fig7(table, ds, seed, &out.join(format!("fig7_{name}.png")))?;
    }
    let report = Report {
        seed,
        chance: datasets.iter().map(|d| 1.0 / d.classes as f64).collect(),
        datasets,
        cells,
        estimate: estimate_of(data, out, options)?,
    };
    let json = serde_json::to_vec_pretty(&report).map_err(|e| ReportError::Plot(e.to_string()))?;
    write(&out.join("report.json"), &json)?;
    write(&out.join("report.md"), markdown(&report).as_bytes())?;
    Ok(report)
}

/// The Ward-parameter estimate on `data/materials`, cross-validated over its illuminations as
/// the shipped estimators are fitted (their features and boosted trees), written into `out`
/// (`estimate.md`, `.json`, `.png`); `None` without that data set.
fn estimate_of(
    data: &Path,
    out: &Path,
    options: &DecodeOptions,
) -> Result<Option<EstimateReport>, ReportError> {
    let (name, classes) = MATERIALS;
    let dir = data.join(name);
    if !dir.join("manifest.csv").is_file() {
        return Ok(None);
    }
    let materials = reflectance_core::material::load_classes(&dir.join(classes)).map_err(|e| {
        ReportError::Input(format!(
            "{}: {e} (the materials' class file, as rendered, belongs beside the manifest)",
            dir.display()
        ))
    })?;
    let table = features_of(&dir, options)?.without_synthetic();
    let ds = Dataset::from_table(&table)?;
    let features = FeatureSet::parse_with(ward::SHIPPED_FEATURES, &ds.names)?;
    let spec = ward::RegressionSpec::Boost(Default::default());
    let fit = ward::fit(&ds, name, &materials, &features, &spec)?;
    let title = format!("{} on {name}", ward::SHIPPED_FEATURES);
    let protocol = estimate::Protocol::CrossValidated;
    estimate::write(out, &title, protocol, &fit.report, &fit.details)?;
    Ok(Some(fit.report))
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    reflectance_core::util::durable::write_atomic(path, bytes).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn find<'a>(
    report: &'a Report,
    dataset: &str,
    protocol: &str,
    features: &str,
    classifier: &str,
) -> Option<&'a Cell> {
    report.cells.iter().find(|c| {
        c.dataset == dataset
            && c.protocol == protocol
            && c.features == features
            && c.classifier == classifier
    })
}

/// "ours (paper)" for a cell, with the paper's figure `paper` when given.
fn format_cell(cell: Option<&Cell>, paper: Option<f64>) -> String {
    match (cell, paper) {
        (Some(c), Some(p)) => format!("{:.1} ({p:.1})", 100.0 * c.accuracy),
        (Some(c), None) => format!("{:.1} (—)", 100.0 * c.accuracy),
        (None, _) => "—".into(),
    }
}

/// A table's header: one column per data set, with the number of light probes it holds.
fn header(md: &mut String, first: &str, report: &Report) {
    md.push_str(first);
    for (name, title) in DATASETS {
        let maps = report.datasets.iter().find(|d| d.name == name);
        match maps {
            Some(d) => {
                let _ = write!(md, " {title} ({} maps) |", d.illuminations);
            }
            None => {
                let _ = write!(md, " {title} |");
            }
        }
    }
    md.push('\n');
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
        "| data set | images (with views) | of synthetic illuminations | evaluated | illuminations | classes |\n\
         |---|---|---|---|---|---|\n",
    );
    for d in &report.datasets {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            d.name, d.rows, d.synthetic_rows, d.evaluated, d.illuminations, d.classes
        );
    }
    md.push_str("\n## Table 1 — SVM (RBF, C = 100, γ = 1/n), feature sets × data sets\n\n");
    header(&mut md, "| features |", report);
    md.push_str("|---|---|---|---|---|\n| chance |");
    for c in &report.chance {
        let _ = write!(md, " {:.1} |", 100.0 * c);
    }
    md.push('\n');
    for set in TABLE1_ROWS {
        let _ = write!(md, "| {set} |");
        for (name, _) in DATASETS {
            let cell = find(report, name, "paper", set, "svm");
            let _ = write!(md, " {} |", format_cell(cell, cell.and_then(|c| c.paper)));
        }
        md.push('\n');
    }
    for (protocol, label) in [
        ("augmented", "augmented training views"),
        ("synthetic", "views + synthetic illuminations"),
    ] {
        if !report.cells.iter().any(|c| c.protocol == protocol) {
            continue;
        }
        for set in AUGMENTED_ROWS {
            let _ = write!(md, "| **{set}, {label}** |");
            for (name, _) in DATASETS {
                let cell = find(report, name, protocol, set, "svm");
                let _ = write!(
                    md,
                    " {} |",
                    format_cell(cell, paper_figure(name, "hand6", "svm"))
                );
            }
            md.push('\n');
        }
    }
    md.push_str(
        "\nThe rows above the bold ones follow the paper's protocol: the original renders only and \
         the 117 features. The bold rows train on every rendered view of the other illuminations \
         (turns about the vertical axis and other viewer elevations; the held-out illumination's \
         views are excluded) and are evaluated on the same original renders; the synthetic rows \
         also train on procedural illuminations (`render --synthetic`), in every fold. hand6+log \
         adds the log-domain pixel statistics and subband variances, hand6+log+radial also how \
         the log-domain pixel mean and variance and the subband variances change from ring to \
         ring of the annulus (three rings). Beside them: the paper's hand6 figure.\n",
    );
    md.push_str("\n## Table 2 — classifiers × feature sets (paper protocol)\n\n");
    header(&mut md, "| classifier | features |", report);
    md.push_str("|---|---|---|---|---|---|\n");
    for classifier in TABLE2_CLASSIFIERS {
        for set in TABLE2_SETS {
            let _ = write!(md, "| {classifier} | {set} |");
            for (name, _) in DATASETS {
                let cell = find(report, name, "paper", set, classifier);
                let _ = write!(md, " {} |", format_cell(cell, cell.and_then(|c| c.paper)));
            }
            md.push('\n');
        }
    }
    md.push_str(
        "\nLog-loss and expected calibration error of every run are in `report.json`; confusion \
         matrices of hand6 (paper protocol) and hand6+log (augmented) SVMs in `confusion_*.png`; \
         the Fig. 7 scatter with the SVM's decision regions in `fig7_*.png`.\n",
    );
    estimate_section(&mut md, report.estimate.as_ref());
    md
}

/// The estimate's headline errors (the rest is in `estimate.md`), or how to get them.
fn estimate_section(md: &mut String, estimate: Option<&EstimateReport>) {
    let (name, classes) = MATERIALS;
    md.push_str("\n## Beyond the paper — the Ward parameters themselves\n\n");
    let Some(r) = estimate else {
        let _ = writeln!(
            md,
            "Not measured: add a data set `{name}` (materials of `reflectance materials` rendered \
             like the others, with their class file as `{name}/{classes}`) for the \
             leave-one-illumination-out errors of the Ward-parameter estimate."
        );
        return;
    };
    let e = &r.errors;
    let pct = |x: f64| format!("{:.1} %", 100.0 * x);
    let _ = writeln!(
        md,
        "{} on `{name}`, leave-one-illumination-out over {} illuminations ({} images, {} of them \
         augmented views, evaluated too):\n\n\
         | total reflectance MAE | ρd MAE | ρs MAE | mirror or not | log10 α MAE (glossy) | 90 % intervals cover ρd / ρs / α |\n\
         |---|---|---|---|---|---|\n\
         | {:.3} | {:.3} | {:.3} | {} | {} | {} / {} / {} |\n\n\
         Per illumination, originals against views, and estimated against true: `estimate.md`, \
         `estimate.json`, `estimate.png`.",
        ward::SHIPPED_FEATURES,
        r.illuminations,
        e.n,
        r.augmented,
        e.mae_total,
        e.mae_rho_d,
        e.mae_rho_s,
        pct(e.mirror_accuracy),
        e.mae_log10_alpha.map_or("—".into(), |v| format!("{v:.3}")),
        pct(e.coverage_rho_d),
        pct(e.coverage_rho_s),
        pct(e.coverage_alpha),
    );
}

/// Default output folder for `report --data DIR`.
pub fn default_out(data: &Path) -> PathBuf {
    data.join("report")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_materials_the_report_says_how_to_measure_the_estimate() {
        let mut md = String::new();
        estimate_section(&mut md, None);
        assert!(md.contains("Not measured") && md.contains("`materials/materials.json`"));
    }
}
