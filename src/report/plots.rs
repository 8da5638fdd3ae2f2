//! PNG plots with plotters: confusion matrices and the paper's Fig. 7 (pix.p10 against
//! wav.s2.v.var with the SVM's decision regions). Text needs a TrueType font: DejaVu Sans
//! from the system, or the file named by `REFLECTANCE_FONT`; without one the plots are
//! skipped with a note on stderr.

use super::ReportError;
use plotters::prelude::*;
use reflectance_core::classify::{self, ClassifierKind, CvReport, TrainSpec};
use reflectance_core::dataset::FeatureTable;
use reflectance_core::learn::{Dataset, FeatureSet};
use std::path::Path;
use std::sync::OnceLock;

const FONT_PATHS: [&str; 2] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Eleven distinguishable colours (Tableau 10 plus grey).
const PALETTE: [(u8, u8, u8); 11] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (60, 60, 60),
];

pub(super) fn colour(class: usize) -> RGBColor {
    let (r, g, b) = PALETTE[class % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Pale version of a class colour for decision regions.
pub(super) fn pale(class: usize) -> RGBColor {
    let (r, g, b) = PALETTE[class % PALETTE.len()];
    let mix = |c: u8| (f64::from(c) * 0.3 + 255.0 * 0.7) as u8;
    RGBColor(mix(r), mix(g), mix(b))
}

/// Register a font once; false when none is available.
fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        let candidates = std::env::var("REFLECTANCE_FONT")
            .into_iter()
            .chain(FONT_PATHS.iter().map(|s| s.to_string()));
        for path in candidates {
            if let Ok(bytes) = std::fs::read(&path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        eprintln!("reflectance: no TrueType font found (set REFLECTANCE_FONT): skipping plots");
        false
    })
}

pub(super) fn plot_error(e: impl std::fmt::Display) -> ReportError {
    ReportError::Plot(e.to_string())
}

/// Draw into an RGB buffer with `draw`, then write it as PNG.
pub(super) fn render_png(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), ReportError>,
) -> Result<(), ReportError> {
    if !font_ready() {
        return Ok(());
    }
    let mut buffer = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        draw(root)?;
    }
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    image::ImageEncoder::write_image(
        encoder,
        &buffer,
        width,
        height,
        image::ExtendedColorType::Rgb8,
    )
    .map_err(plot_error)?;
    reflectance_core::util::durable::write_atomic(path, &png).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Row-normalized confusion matrix with counts.
pub fn confusion(report: &CvReport, path: &Path) -> Result<(), ReportError> {
    let k = report.summary.classes.len();
    let cell = 56i32;
    let (left, top) = (150i32, 80i32);
    let size = (
        (left + cell * k as i32 + 20) as u32,
        (top + cell * k as i32 + 40) as u32,
    );
    render_png(path, size, |root| {
        root.fill(&WHITE).map_err(plot_error)?;
        let title = format!(
            "{} · {} — accuracy {:.1} %",
            report.summary.features,
            report.summary.classifier,
            100.0 * report.summary.accuracy
        );
        root.draw(&Text::new(title, (10, 10), ("sans-serif", 20)))
            .map_err(plot_error)?;
        root.draw(&Text::new(
            "rows: truth · columns: predicted",
            (10, 38),
            ("sans-serif", 14),
        ))
        .map_err(plot_error)?;
        for (t, row) in report.summary.confusion.iter().enumerate() {
            let total: usize = row.iter().sum::<usize>().max(1);
            let y = top + cell * t as i32;
            let label = format!("{}. {}", t + 1, report.summary.classes[t]);
            root.draw(&Text::new(label, (8, y + cell / 2 - 7), ("sans-serif", 13)))
                .map_err(plot_error)?;
            let header = (left + cell * t as i32 + cell / 2 - 6, top - 18);
            root.draw(&Text::new((t + 1).to_string(), header, ("sans-serif", 13)))
                .map_err(plot_error)?;
            for (p, &count) in row.iter().enumerate() {
                let x = left + cell * p as i32;
                let shade = 1.0 - count as f64 / total as f64;
                let c = RGBColor(
                    (40.0 + 215.0 * shade) as u8,
                    (90.0 + 165.0 * shade) as u8,
                    (200.0 + 55.0 * shade) as u8,
                );
                root.draw(&Rectangle::new(
                    [(x, y), (x + cell - 2, y + cell - 2)],
                    c.filled(),
                ))
                .map_err(plot_error)?;
                let ink = if shade < 0.5 { &WHITE } else { &BLACK };
                root.draw(&Text::new(
                    count.to_string(),
                    (x + cell / 2 - 8, y + cell / 2 - 8),
                    ("sans-serif", 15).into_font().color(ink),
                ))
                .map_err(plot_error)?;
            }
        }
        root.present().map_err(plot_error)
    })
}

/// The paper's Fig. 7: each image at (pix.p10, wav.s2.v.var), coloured by class, over the
/// decision regions of an SVM trained on those two features.
pub fn fig7(table: &FeatureTable, ds: &Dataset, seed: u64, path: &Path) -> Result<(), ReportError> {
    let spec = TrainSpec::new(FeatureSet::Named("hand2"), ClassifierKind::Svm);
    let model = classify::fit(ds, &spec, seed)?;
    let column = |name: &str| {
        table
            .names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| ReportError::Plot(format!("no column {name}")))
    };
    let (cx, cy) = (column("pix.p10")?, column("wav.s2.v.var")?);
    let points: Vec<(f64, f64, usize)> = (0..ds.n_rows())
        .filter(|&r| !ds.augmented[r])
        .map(|r| (ds.x[[r, cx]], ds.x[[r, cy]], ds.labels[r]))
        .collect();
    let range = |f: fn(&(f64, f64, usize)) -> f64| {
        let (lo, hi) = points
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let pad = 0.05 * (hi - lo).max(1e-9);
        (lo - pad, hi + pad)
    };
    let ((x0, x1), (y0, y1)) = (range(|p| p.0), range(|p| p.1));
    let steps = 160;
    let mut row = ds.x.row(0).to_vec();
    let mut regions = Vec::with_capacity(steps * steps);
    for i in 0..steps {
        for j in 0..steps {
            let x = x0 + (x1 - x0) * (i as f64 + 0.5) / steps as f64;
            let y = y0 + (y1 - y0) * (j as f64 + 0.5) / steps as f64;
            row[cx] = x;
            row[cy] = y;
            regions.push((x, y, model.predict(&row)?));
        }
    }
    let (dx, dy) = ((x1 - x0) / steps as f64, (y1 - y0) / steps as f64);
    render_png(path, (900, 700), |root| {
        root.fill(&WHITE).map_err(plot_error)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Fig. 7: pix.p10 vs wav.s2.v.var, SVM decision regions",
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_error)?;
        chart
            .draw_series(regions.iter().map(|&(x, y, c)| {
                Rectangle::new(
                    [(x - dx / 2.0, y - dy / 2.0), (x + dx / 2.0, y + dy / 2.0)],
                    pale(c).filled(),
                )
            }))
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("pix.p10 (10th percentile of the normalized image)")
            .y_desc("wav.s2.v.var (log10)")
            .draw()
            .map_err(plot_error)?;
        for (k, name) in ds.classes.iter().enumerate() {
            chart
                .draw_series(
                    points
                        .iter()
                        .filter(|p| p.2 == k)
                        .map(|&(x, y, _)| Circle::new((x, y), 4, colour(k).filled())),
                )
                .map_err(plot_error)?
                .label(name.clone())
                .legend(move |(x, y)| Circle::new((x, y), 5, colour(k).filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_error)?;
        root.present().map_err(plot_error)
    })
}
