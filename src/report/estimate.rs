//! The Ward-parameter estimate's leave-one-illumination-out report: the estimates against the
//! true values as scatter plots with their intervals, the coverage, and the errors of every
//! illumination (`estimate.md`, `estimate.json`, `estimate.png`).

use super::ReportError;
use super::plots::{plot_error, render_png};
use plotters::prelude::*;
use reflectance_core::estimate::{
    Errors, EstimateDetails, EstimateReport, HeldOut, Interval, MIRROR_LOG_ALPHA,
};
use reflectance_core::learn::matrix::parse_illumination;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// At most this many rows get an interval bar in the plots (every row gets a point).
const BARS: usize = 400;

#[derive(Serialize)]
struct Written<'a> {
    report: &'a EstimateReport,
    details: &'a EstimateDetails,
}

/// How the held-out estimates were made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    /// Leave-one-illumination-out: each illumination's intervals sized by the others' errors.
    CrossValidated,
    /// A fitted estimator on illuminations it never saw, with its own intervals.
    Unseen,
}

impl Protocol {
    /// How a summary line names the illuminations: "… over N illuminations".
    pub fn over(self) -> &'static str {
        match self {
            Protocol::CrossValidated => "leave-one-illumination-out over",
            Protocol::Unseen => "over",
        }
    }
}

/// Write `estimate.md`, `estimate.json` and `estimate.png` into `out` (created).
pub fn write(
    out: &Path,
    title: &str,
    protocol: Protocol,
    report: &EstimateReport,
    details: &EstimateDetails,
) -> Result<(), ReportError> {
    let io = |source| ReportError::Io {
        path: out.display().to_string(),
        source,
    };
    std::fs::create_dir_all(out).map_err(io)?;
    let json = serde_json::to_vec_pretty(&Written { report, details }).map_err(plot_error)?;
    let file = |name: &str, bytes: &[u8]| {
        let path = out.join(name);
        reflectance_core::util::durable::write_atomic(&path, bytes).map_err(|source| {
            ReportError::Io {
                path: path.display().to_string(),
                source,
            }
        })
    };
    file("estimate.json", &json)?;
    file(
        "estimate.md",
        markdown(title, protocol, report, details).as_bytes(),
    )?;
    scatter(title, details, &out.join("estimate.png"))
}

/// One line of the summary: a measure of some rows, as text.
type Measure = fn(&Errors) -> String;

fn pct(x: f64) -> String {
    format!("{:.1} %", 100.0 * x)
}

fn coverage(e: &Errors) -> String {
    format!(
        "{:.1} / {:.1} / {:.1} %",
        100.0 * e.coverage_rho_d,
        100.0 * e.coverage_rho_s,
        100.0 * e.coverage_alpha
    )
}

fn alpha_error(e: &Errors) -> String {
    e.mae_log10_alpha.map_or("–".into(), |v| format!("{v:.3}"))
}

/// The report as Markdown: a summary (all rows, originals, augmented views) and a table of
/// the illuminations, worst total reflectance first.
pub fn markdown(
    title: &str,
    protocol: Protocol,
    report: &EstimateReport,
    details: &EstimateDetails,
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "## Estimating the Ward parameters: {title}\n");
    let (how, widths) = match protocol {
        Protocol::CrossValidated => (
            "Leave-one-illumination-out over",
            "each illumination's are sized by the other illuminations' errors",
        ),
        Protocol::Unseen => (
            "A fitted estimator on",
            "the estimator's own, sized on its training illuminations",
        ),
    };
    let _ = writeln!(
        md,
        "{how} {} illuminations: {} images, {} of them augmented views (evaluated \
         too). 90 % intervals: ρd ± {:.3}, ρs ± {:.3}, log10 α ± {:.3}; {widths}.\n",
        details.illuminations.len(),
        report.errors.n,
        report.augmented,
        report.half_widths.rho_d,
        report.half_widths.rho_s,
        report.half_widths.log10_alpha,
    );
    let columns: Vec<(&str, &Errors)> = [
        ("originals", &details.originals),
        ("augmented views", &details.augmented),
    ]
    .into_iter()
    .filter_map(|(name, e)| e.as_ref().map(|e| (name, e)))
    .collect();
    let all = &report.errors;
    let mut header = String::from("| | all");
    for (name, _) in &columns {
        let _ = write!(header, " | {name}");
    }
    let _ = writeln!(md, "{header} |\n|---|---{}|", "|---".repeat(columns.len()));
    let rows: [(&str, Measure); 7] = [
        ("images", |e| e.n.to_string()),
        ("total reflectance ρd + ρs, MAE", |e| {
            format!("{:.3}", e.mae_total)
        }),
        ("ρd, MAE", |e| format!("{:.3}", e.mae_rho_d)),
        ("ρs, MAE", |e| format!("{:.3}", e.mae_rho_s)),
        ("mirror or not, right", |e| pct(e.mirror_accuracy)),
        ("log10 α of the glossy ones, MAE", alpha_error),
        ("90 % intervals cover (ρd / ρs / α)", coverage),
    ];
    for (label, value) in rows {
        let mut line = format!("| {label} | {}", value(all));
        for (_, e) in &columns {
            let _ = write!(line, " | {}", value(e));
        }
        let _ = writeln!(md, "{line} |");
    }
    let _ = writeln!(
        md,
        "\n### Per illumination (worst total reflectance first)\n\n\
         | illumination | images | total MAE | ρd MAE | ρs MAE | mirror right | log10 α MAE | cover ρd / ρs / α |\n\
         |---|---|---|---|---|---|---|---|"
    );
    let mut illuminations: Vec<_> = details.illuminations.iter().collect();
    illuminations.sort_by(|a, b| b.errors.mae_total.total_cmp(&a.errors.mae_total));
    for g in illuminations {
        let e = &g.errors;
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {:.3} | {:.3} | {} | {} | {} |",
            g.illumination,
            e.n,
            e.mae_total,
            e.mae_rho_d,
            e.mae_rho_s,
            pct(e.mirror_accuracy),
            alpha_error(e),
            coverage(e)
        );
    }
    md
}

/// log10 α on the plot's axis: a mirror (α = 0) at [`MIRROR_LOG_ALPHA`].
fn log_alpha(alpha: f64) -> f64 {
    if alpha > 0.0 {
        alpha.log10()
    } else {
        MIRROR_LOG_ALPHA
    }
}

/// One panel: its title, axis range, and (truth, estimate) of a row.
struct Panel {
    title: &'static str,
    range: (f64, f64),
    of: fn(&HeldOut) -> (f64, Interval),
}

const PANELS: [Panel; 3] = [
    Panel {
        title: "ρd",
        range: (0.0, 1.0),
        of: |r| (r.truth.rho_d, r.estimate.rho_d),
    },
    Panel {
        title: "ρs",
        range: (0.0, 1.0),
        of: |r| (r.truth.rho_s, r.estimate.rho_s),
    },
    Panel {
        title: "log10 α (mirrors at −2.6)",
        range: (-2.7, -0.6),
        of: |r| {
            let a = r.estimate.alpha;
            let interval = Interval {
                value: log_alpha(a.value),
                low: log_alpha(a.low),
                high: log_alpha(a.high),
            };
            (log_alpha(r.truth.alpha), interval)
        },
    },
];

/// Estimated against true, one panel per parameter: a point per row (originals blue,
/// augmented views orange), the 90 % interval of every n-th, and the diagonal.
fn scatter(title: &str, details: &EstimateDetails, path: &Path) -> Result<(), ReportError> {
    let stride = details.rows.len().div_ceil(BARS).max(1);
    let augmented = |r: &HeldOut| parse_illumination(&r.illumination).1;
    render_png(path, (1500, 540), |root| {
        root.fill(&WHITE).map_err(plot_error)?;
        let root = root
            .titled(
                &format!("Estimated against true, held-out illuminations: {title}"),
                ("sans-serif", 20),
            )
            .map_err(plot_error)?;
        for (panel, area) in PANELS.iter().zip(root.split_evenly((1, 3))) {
            let (lo, hi) = panel.range;
            let mut chart = ChartBuilder::on(&area)
                .caption(panel.title, ("sans-serif", 18))
                .margin(14)
                .x_label_area_size(40)
                .y_label_area_size(48)
                .build_cartesian_2d(lo..hi, lo..hi)
                .map_err(plot_error)?;
            chart
                .configure_mesh()
                .light_line_style(WHITE)
                .x_desc("true")
                .y_desc("estimated")
                .draw()
                .map_err(plot_error)?;
            let bars = details.rows.iter().step_by(stride).map(|r| {
                let (truth, e) = (panel.of)(r);
                PathElement::new(
                    vec![(truth, e.low.max(lo)), (truth, e.high.min(hi))],
                    RGBColor(120, 120, 120).mix(0.35),
                )
            });
            chart.draw_series(bars).map_err(plot_error)?;
            let points = details.rows.iter().map(|r| {
                let (truth, e) = (panel.of)(r);
                let colour = match augmented(r) {
                    true => RGBColor(255, 127, 14).mix(0.35),
                    false => RGBColor(31, 119, 180).mix(0.6),
                };
                Circle::new((truth, e.value.clamp(lo, hi)), 2, colour.filled())
            });
            chart.draw_series(points).map_err(plot_error)?;
            chart
                .draw_series(LineSeries::new([(lo, lo), (hi, hi)], BLACK.stroke_width(1)))
                .map_err(plot_error)?;
        }
        root.present().map_err(plot_error)
    })
}
