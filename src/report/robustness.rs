//! Accuracy through the camera: every test render captured by [`reflectance_render::capture`] at each
//! setting of a sweep (one factor at a time around a clean baseline, the extremes of the
//! ranges all at once, and settings drawn at random within the ranges), then classified by
//! each model exactly as the service would (`inference::classify` on the captured file,
//! with the white and circle a user would report).

use super::ReportError;
use super::plots::{colour, plot_error, render_png};
use crate::progress;
use ndarray::Array2;
use plotters::prelude::*;
use rayon::prelude::*;
use reflectance_core::analysis::{Placement, WhiteSpec};
use reflectance_core::dataset::{self, Manifest};
use reflectance_core::decode::{self, DecodeOptions};
use reflectance_core::inference::{self, Answer, Input, LoadedModel};
use reflectance_core::locate::Circle;
use reflectance_core::util::rng::Rng;
use reflectance_render::capture::{
    self, CaptureRanges, CaptureSettings, DrawSettings, Quantization,
};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

/// How a sweep point turns a render into the classifier's input.
#[derive(Clone, Copy, Debug)]
pub enum Camera {
    /// The render itself (float, nothing clips), with its exact white and circle.
    Original,
    Fixed(CaptureSettings),
    /// Settings drawn at random within the ranges, anew for every image and draw.
    Random,
}

/// One point of the sweep: a factor, its value, and its camera.
#[derive(Clone, Debug)]
pub struct Setting {
    pub factor: &'static str,
    pub value: String,
    pub camera: Camera,
}

/// The factors, in the report's order, with the axis label of their plot.
pub const FACTORS: [(&str, &str); 6] = [
    ("noise", "noise at white (% of white)"),
    ("jpeg", "JPEG quality (8-bit sRGB)"),
    (
        "exposure",
        "white's level (fraction of full scale; 8-bit sRGB)",
    ),
    ("blur", "lens blur σ (px)"),
    ("radius", "sphere radius (px)"),
    ("errors", "white and circle errors"),
];

/// Draws of random settings per image for the `random` rows.
pub const RANDOM_DRAWS: usize = 4;

/// `a + (b − a)·k/n` for each k of `ks`.
fn spaced(
    [a, b]: [f64; 2],
    n: usize,
    ks: std::ops::RangeInclusive<usize>,
) -> impl Iterator<Item = f64> {
    ks.map(move |k| a + (b - a) * k as f64 / n as f64)
}

/// The sweep for `ranges`, around a clean baseline: 16-bit linear, white at half of full
/// scale, no noise or blur, exact white and circle, at `radius` (the training radius).
pub fn sweep(ranges: &CaptureRanges, radius: f64) -> Vec<Setting> {
    let base = CaptureSettings {
        background: 0.3,
        shot_share: 0.8,
        ..CaptureSettings::ideal(radius)
    };
    let srgb8 = CaptureSettings {
        quantization: Quantization::Srgb8,
        ..base
    };
    let mut out = vec![Setting {
        factor: "original",
        value: "float render".into(),
        camera: Camera::Original,
    }];
    let mut add = |factor, value: String, settings| {
        out.push(Setting {
            factor,
            value,
            camera: Camera::Fixed(settings),
        })
    };
    add("clean", "16-bit linear".into(), base);
    for noise in spaced(ranges.noise, 5, 1..=5) {
        let settings = CaptureSettings { noise, ..base };
        add("noise", format!("{:.1}", 100.0 * noise), settings);
    }
    add("jpeg", "png8".into(), srgb8);
    let [q0, q1] = ranges.jpeg_quality;
    for quality in [q0, (q0 + q1) / 2, q1] {
        let quantization = Quantization::Jpeg { quality };
        add(
            "jpeg",
            quality.to_string(),
            CaptureSettings {
                quantization,
                ..base
            },
        );
    }
    for exposure in spaced(ranges.exposure, 3, 0..=3) {
        let settings = CaptureSettings { exposure, ..srgb8 };
        add("exposure", format!("{exposure:.2}"), settings);
    }
    for blur in spaced(ranges.blur, 4, 1..=4) {
        add(
            "blur",
            format!("{blur:.2}"),
            CaptureSettings { blur, ..base },
        );
    }
    for r in radius_points(ranges.radius[0], radius) {
        add(
            "radius",
            format!("{r:.0}"),
            CaptureSettings { radius: r, ..base },
        );
    }
    let (w, c, rr) = (ranges.white_error, ranges.centre_error, ranges.radius_error);
    for (label, white_error, centre, radius_error) in [
        ("white -", -w, 0.0, 0.0),
        ("white +", w, 0.0, 0.0),
        ("circle", 0.0, c, rr),
        ("circle -", 0.0, -c, -rr),
    ] {
        let settings = CaptureSettings {
            white_error,
            centre_error: [centre, centre],
            radius_error,
            ..base
        };
        add("errors", label.into(), settings);
    }
    // Everything at its worst at once, at both ends of the radius range (no larger than
    // the renders).
    let mut ends = ranges.radius.map(|r| r.min(radius)).to_vec();
    ends.dedup();
    for r in ends {
        let settings = CaptureSettings {
            radius: r,
            exposure: ranges.exposure[1],
            noise: ranges.noise[1],
            blur: ranges.blur[1],
            quantization: Quantization::Jpeg {
                quality: ranges.jpeg_quality[0],
            },
            white_error: -ranges.white_error,
            centre_error: [ranges.centre_error, -ranges.centre_error],
            radius_error: ranges.radius_error,
            ..base
        };
        add("worst", format!("r {r:.0}"), settings);
    }
    out.push(Setting {
        factor: "random",
        value: format!("{RANDOM_DRAWS} draws per image"),
        camera: Camera::Random,
    });
    out
}

/// The radii a sweep photographs the renders at: the renders' own `radius` and its halvings
/// down to the capture range's smallest, `low`, which ends the list. Never larger than the
/// renders: an enlarged render has no detail a larger ball would show.
fn radius_points(low: f64, radius: f64) -> Vec<f64> {
    if radius < low {
        return vec![radius];
    }
    let halvings = std::iter::successors(Some(radius), |r| Some(r / 2.0))
        .take_while(|&r| r > low * (1.0 + RADIUS_GAP));
    let mut points: Vec<f64> = halvings.chain([low]).collect();
    points.reverse();
    points
}

/// Radii closer than this share are one point of the sweep.
const RADIUS_GAP: f64 = 0.05;

/// A test image: a render, its class, where its sphere is and its white.
pub struct TestImage {
    pub name: String,
    pub class: String,
    pub luminance: Array2<f64>,
    pub circle: Circle,
    pub white: f64,
}

/// The renders of a manifest (original views only; rows need a class, circle and white).
pub fn test_images(
    manifest: &Manifest,
    options: &DecodeOptions,
) -> Result<Vec<TestImage>, ReportError> {
    manifest.require_labels()?;
    manifest
        .entries
        .par_iter()
        .filter(|e| e.illumination.as_deref().is_some_and(|i| !i.contains('@')))
        .map(|e| {
            let missing = |what: &str| {
                ReportError::Input(format!(
                    "{} line {}: no {what}",
                    manifest.source.display(),
                    e.line
                ))
            };
            let image = decode::decode_file(&e.file, options).map_err(|source| {
                dataset::DatasetError::Image {
                    path: manifest.source.display().to_string(),
                    line: e.line,
                    image: e.path.clone(),
                    source: source.into(),
                }
            })?;
            Ok(TestImage {
                name: e.path.clone(),
                class: e.class.clone().unwrap_or_default(),
                luminance: image.luminance,
                circle: e.circle.ok_or_else(|| missing("circle"))?,
                white: e.white.ok_or_else(|| missing("white"))?,
            })
        })
        .collect()
}

/// Accuracy of one model at one setting.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    pub factor: String,
    pub value: String,
    pub model: String,
    pub n: usize,
    pub correct: usize,
    pub accuracy: f64,
    /// Captures the model could not classify (e.g. the annulus left the image).
    pub refused: usize,
    /// `confusion[truth][predicted]` in the model's class order.
    pub confusion: Vec<Vec<usize>>,
    /// Right answers of the class nearest to the Ward-parameter estimate (models with an
    /// estimator and their classes' parameters).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nearest_correct: Option<usize>,
    /// Answers whose prediction set (at the model's default coverage) holds the truth, and
    /// the sum of those sets' sizes (models with calibrated sets).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sets: Option<SetTally>,
}

/// How a model's prediction sets did on a cell's images.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SetTally {
    pub holding_truth: usize,
    pub total_size: usize,
}

/// What a model answered for one capture (class indices), or `None` when it refused it.
#[derive(Clone, Debug, PartialEq)]
struct Verdict {
    truth: usize,
    predicted: usize,
    /// The class nearest to the Ward-parameter estimate.
    nearest: Option<usize>,
    /// The prediction set.
    set: Option<Vec<usize>>,
}

impl Cell {
    fn empty(setting: &Setting, model: &str, classes: usize) -> Cell {
        Cell {
            factor: setting.factor.into(),
            value: setting.value.clone(),
            model: model.into(),
            n: 0,
            correct: 0,
            accuracy: 0.0,
            refused: 0,
            confusion: vec![vec![0; classes]; classes],
            nearest_correct: None,
            sets: None,
        }
    }

    fn add(&mut self, verdict: Option<&Verdict>) {
        self.n += 1;
        match verdict {
            Some(v) => {
                self.correct += usize::from(v.truth == v.predicted);
                self.confusion[v.truth][v.predicted] += 1;
                if let Some(nearest) = v.nearest {
                    *self.nearest_correct.get_or_insert(0) += usize::from(v.truth == nearest);
                }
                if let Some(set) = &v.set {
                    let tally = self.sets.get_or_insert_default();
                    tally.holding_truth += usize::from(set.contains(&v.truth));
                    tally.total_size += set.len();
                }
            }
            None => self.refused += 1,
        }
        self.accuracy = self.correct as f64 / self.n as f64;
    }

    /// The share of answers whose set holds the truth and the sets' mean size.
    fn set_figures(&self) -> Option<(f64, f64)> {
        let answered = (self.n - self.refused).max(1) as f64;
        self.sets.map(|t| {
            (
                t.holding_truth as f64 / answered,
                t.total_size as f64 / answered,
            )
        })
    }
}

/// Classify every test image, captured at every setting, with every model.
pub fn evaluate(
    models: &[(String, Arc<LoadedModel>)],
    images: &[TestImage],
    settings: &[Setting],
    seed: u64,
) -> Result<Vec<Cell>, ReportError> {
    let jobs: Vec<(usize, usize, usize)> = settings
        .iter()
        .enumerate()
        .flat_map(|(s, setting)| {
            let draws = match setting.camera {
                Camera::Random => RANDOM_DRAWS,
                _ => 1,
            };
            (0..images.len()).flat_map(move |i| (0..draws).map(move |d| (s, i, d)))
        })
        .collect();
    let bar = progress::bar(jobs.len() as u64, "robustness");
    let outcomes: Vec<Result<Vec<Option<Verdict>>, ReportError>> = jobs
        .par_iter()
        .map(|&(s, i, d)| {
            let image = &images[i];
            let key = format!(
                "{}|{}|{}|{d}",
                settings[s].factor, settings[s].value, image.name
            );
            let mut rng = Rng::fork(seed, fnv(&key));
            let shot = photograph(image, settings[s].camera, &mut rng)?;
            let verdicts = models
                .iter()
                .map(|(_, model)| {
                    let input = Input::new(
                        shot.bytes.clone(),
                        WhiteSpec::Value(shot.white),
                        Placement::Circle(shot.circle),
                        shot.encoding,
                        Answer::default(),
                    );
                    let classes = model.file().classifier.classes();
                    let truth = classes.iter().position(|c| *c == image.class);
                    let classified = input
                        .ok()
                        .map(|input| inference::classify(model.clone(), input, Default::default()));
                    classified
                        .and_then(Result::ok)
                        .zip(truth)
                        .map(|(c, truth)| Verdict {
                            truth,
                            predicted: c.decision.class,
                            nearest: c.ward.as_ref().and_then(|e| model.nearest_class(e)),
                            set: c.decision.set,
                        })
                })
                .collect();
            bar.inc(1);
            Ok(verdicts)
        })
        .collect();
    bar.finish();
    let mut cells: Vec<Cell> = Vec::new();
    for (&(s, _, _), outcome) in jobs.iter().zip(outcomes) {
        for ((name, _), verdict) in models.iter().zip(outcome?) {
            let setting = &settings[s];
            let position = cells.iter().position(|c| {
                c.factor == setting.factor && c.value == setting.value && &c.model == name
            });
            let at = position.unwrap_or_else(|| {
                cells.push(Cell::empty(setting, name, classes_of(models, name)));
                cells.len() - 1
            });
            cells[at].add(verdict.as_ref());
        }
    }
    Ok(cells)
}

/// A file to classify and what its user reports with it.
struct Shot {
    bytes: bytes::Bytes,
    white: f64,
    circle: Circle,
    encoding: Option<reflectance_core::decode::Encoding>,
}

fn photograph(image: &TestImage, camera: Camera, rng: &mut Rng) -> Result<Shot, ReportError> {
    let settings = match camera {
        Camera::Original => {
            let (h, w) = image.luminance.dim();
            let values: Vec<f32> = image.luminance.iter().map(|&v| v as f32).collect();
            return Ok(Shot {
                bytes: reflectance_core::decode::pfm::encode_gray(w, h, &values).into(),
                white: image.white,
                circle: image.circle,
                encoding: None,
            });
        }
        Camera::Fixed(settings) => settings,
        Camera::Random => CaptureRanges::default().sample(rng),
    };
    let shot = capture::capture(
        image.luminance.view(),
        &image.circle,
        image.white,
        &settings,
        rng,
    )
    .map_err(|e| ReportError::Input(format!("{}: {e}", image.name)))?;
    Ok(Shot {
        bytes: shot.bytes.into(),
        white: shot.white,
        circle: shot.circle,
        encoding: Some(shot.quantization.encoding()),
    })
}

fn classes_of(models: &[(String, Arc<LoadedModel>)], name: &str) -> usize {
    models
        .iter()
        .find(|(n, _)| n == name)
        .map_or(0, |(_, m)| m.file().classifier.classes().len())
}

/// FNV-1a of a text: a stable stream index.
fn fnv(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    })
}

/// The cells as Markdown: the accuracy, a row per setting and a column per model; then,
/// for models with prediction sets, how often a set held the truth and its mean size.
pub fn markdown(cells: &[Cell], models: &[String]) -> String {
    let mut out = table(cells, models, accuracy_text);
    if cells.iter().any(|c| c.sets.is_some()) {
        out.push_str(
            "\nPrediction sets (the model's default coverage): holding the truth, mean size\n\n",
        );
        out.push_str(&table(cells, models, |c| {
            c.set_figures().map_or("–".into(), |(holding, size)| {
                format!("{:.1} %, {size:.2}", 100.0 * holding)
            })
        }));
    }
    out
}

/// A Markdown table of `text` of each cell: a row per setting, a column per model.
fn table(cells: &[Cell], models: &[String], text: impl Fn(&Cell) -> String) -> String {
    let mut out = String::from("| factor | setting |");
    for m in models {
        let _ = write!(out, " {m} |");
    }
    out.push_str("\n|---|---|");
    out.push_str(&"---|".repeat(models.len()));
    out.push('\n');
    let mut rows: Vec<(&str, &str)> = Vec::new();
    for c in cells {
        if !rows.contains(&(c.factor.as_str(), c.value.as_str())) {
            rows.push((&c.factor, &c.value));
        }
    }
    for (factor, value) in rows {
        let _ = write!(out, "| {factor} | {value} |");
        for m in models {
            let cell = cells
                .iter()
                .find(|c| c.factor == factor && c.value == value && &c.model == m);
            let _ = write!(out, " {} |", cell.map_or("–".into(), &text));
        }
        out.push('\n');
    }
    out
}

/// A cell's accuracy, the estimate's nearest class's and what was refused.
fn accuracy_text(c: &Cell) -> String {
    let mut out = format!("{:.1} % ({}/{})", 100.0 * c.accuracy, c.correct, c.n);
    if let Some(right) = c.nearest_correct {
        let share = 100.0 * right as f64 / c.n.max(1) as f64;
        let _ = write!(out, "; estimate's nearest class {share:.1} %");
    }
    if c.refused > 0 {
        let _ = write!(out, ", {} refused", c.refused);
    }
    out
}

/// Load the models named `DIR/NAME[/VERSION]`, labelled by their path.
pub fn load_models(
    paths: &[std::path::PathBuf],
) -> Result<Vec<(String, Arc<LoadedModel>)>, ReportError> {
    paths
        .iter()
        .map(|path| {
            let fail = |e: String| ReportError::Input(format!("{}: {e}", path.display()));
            let file = reflectance_core::model::registry::load_path(path)
                .map_err(|e| fail(e.to_string()))?;
            let model = LoadedModel::new(file).map_err(|e| fail(e.to_string()))?;
            Ok((path.display().to_string(), Arc::new(model)))
        })
        .collect()
}

/// Write `robustness.md`, `robustness.json` and `robustness.png` into `out`.
pub fn write(cells: &[Cell], models: &[String], out: &Path) -> Result<(), ReportError> {
    std::fs::create_dir_all(out).map_err(|source| ReportError::Io {
        path: out.display().to_string(),
        source,
    })?;
    let save = |name: &str, bytes: &[u8]| {
        let path = out.join(name);
        reflectance_core::util::durable::write_atomic(&path, bytes).map_err(|source| {
            ReportError::Io {
                path: path.display().to_string(),
                source,
            }
        })
    };
    save("robustness.md", markdown(cells, models).as_bytes())?;
    let json = serde_json::to_vec_pretty(cells).map_err(|e| ReportError::Input(e.to_string()))?;
    save("robustness.json", &json)?;
    plot(cells, models, &out.join("robustness.png"))
}

/// Accuracy against each capture factor ([`FACTORS`]), a panel per
/// factor and a line per model.
fn plot(cells: &[Cell], models: &[String], path: &Path) -> Result<(), ReportError> {
    let lowest = cells.iter().map(|c| c.accuracy).fold(1.0f64, f64::min);
    let floor = ((lowest * 100.0 / 10.0).floor() * 10.0).clamp(0.0, 90.0);
    render_png(path, (1200, 760), |root| {
        root.fill(&WHITE).map_err(plot_error)?;
        let (title, body) = root.split_vertically(40);
        title
            .draw(&Text::new(
                "Accuracy through the capture model (one factor at a time)",
                (10, 10),
                ("sans-serif", 20),
            ))
            .map_err(plot_error)?;
        let panels = body.split_evenly((2, 3));
        for ((factor, axis), panel) in FACTORS.iter().zip(panels.iter()) {
            let values: Vec<&str> = cells
                .iter()
                .filter(|c| c.factor == *factor && c.model == models[0])
                .map(|c| c.value.as_str())
                .collect();
            let n = values.len().max(1);
            let mut chart = ChartBuilder::on(panel)
                .caption(*factor, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(45)
                .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), floor..100.5f64)
                .map_err(plot_error)?;
            let label = |x: &f64| {
                let k = x.round();
                if (x - k).abs() < 1e-6 && k >= 0.0 {
                    values
                        .get(k as usize)
                        .map_or(String::new(), |v| v.to_string())
                } else {
                    String::new()
                }
            };
            chart
                .configure_mesh()
                .x_labels(n)
                .x_label_formatter(&label)
                .x_desc(*axis)
                .y_desc("accuracy (%)")
                .draw()
                .map_err(plot_error)?;
            for (m, model) in models.iter().enumerate() {
                let points: Vec<(f64, f64)> = values
                    .iter()
                    .enumerate()
                    .filter_map(|(k, v)| {
                        cells
                            .iter()
                            .find(|c| c.factor == *factor && c.value == *v && &c.model == model)
                            .map(|c| (k as f64, 100.0 * c.accuracy))
                    })
                    .collect();
                chart
                    .draw_series(LineSeries::new(points.clone(), colour(m).stroke_width(2)))
                    .map_err(plot_error)?
                    .label(model.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour(m).stroke_width(2))
                    });
                chart
                    .draw_series(
                        points
                            .iter()
                            .map(|&p| plotters::element::Circle::new(p, 3, colour(m).filled())),
                    )
                    .map_err(plot_error)?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(plot_error)?;
        }
        root.present().map_err(plot_error)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn radius_values(radius: f64) -> Vec<String> {
        sweep(&CaptureRanges::default(), radius)
            .into_iter()
            .filter(|s| s.factor == "radius")
            .map(|s| s.value)
            .collect()
    }

    #[test]
    fn the_worst_rows_take_the_range_s_ends_but_never_enlarge_the_renders() {
        let worst = |radius| -> Vec<String> {
            sweep(&CaptureRanges::default(), radius)
                .into_iter()
                .filter(|s| s.factor == "worst")
                .map(|s| s.value)
                .collect()
        };
        assert_eq!(worst(465.5), ["r 60", "r 400"]);
        assert_eq!(worst(116.36), ["r 60", "r 116"]);
        assert_eq!(worst(36.4), ["r 36"]);
    }

    #[test]
    fn the_radius_rows_halve_the_renders_radius_down_to_the_smallest_and_never_enlarge_them() {
        assert_eq!(radius_values(465.5), ["60", "116", "233", "466"]);
        assert_eq!(radius_values(116.36), ["60", "116"]);
        // Within a twentieth of the smallest: one point.
        assert_eq!(radius_values(124.0), ["60", "124"]);
        assert_eq!(radius_values(62.0), ["60"]);
        assert_eq!(radius_values(36.4), ["36"]);
    }

    #[test]
    fn a_cell_counts_answers_refusals_and_the_sets_that_hold_the_truth() {
        let setting = Setting {
            factor: "noise",
            value: "1.0".into(),
            camera: Camera::Original,
        };
        let mut cell = Cell::empty(&setting, "m", 3);
        let verdict = |truth, predicted, set: &[usize]| Verdict {
            truth,
            predicted,
            nearest: None,
            set: Some(set.to_vec()),
        };
        cell.add(Some(&verdict(0, 0, &[0])));
        cell.add(Some(&verdict(1, 2, &[2, 1])));
        cell.add(Some(&verdict(2, 1, &[1])));
        cell.add(None);
        assert_eq!((cell.n, cell.correct, cell.refused), (4, 1, 1));
        assert_eq!(cell.confusion[1][2] + cell.confusion[2][1], 2);
        assert_eq!(cell.accuracy, 0.25);
        // Of the three answered, two sets held the truth; four classes in all.
        let (holding, size) = cell.set_figures().unwrap();
        assert!((holding - 2.0 / 3.0).abs() < 1e-12 && (size - 4.0 / 3.0).abs() < 1e-12);
        let text = markdown(std::slice::from_ref(&cell), &["m".into()]);
        assert!(
            text.contains("| noise | 1.0 | 25.0 % (1/4), 1 refused |"),
            "{text}"
        );
        assert!(text.contains("| noise | 1.0 | 66.7 %, 1.33 |"), "{text}");
    }
}
