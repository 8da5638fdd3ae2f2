//! `reflectance cv`, `train` and `predict`.

use super::{CliError, CliResult, LimitArgs};
use crate::progress;
use crate::report::estimate::Protocol;
use clap::Args;
use reflectance_core::classify::{ClassifierOptions, CvReport};
use reflectance_core::dataset::{self, FeatureTable, Manifest};
use reflectance_core::estimate;
use reflectance_core::features::families::DOMAIN;
use reflectance_core::features::{CaptureMeasurements, Extractor, FeatureConfig, FeatureOptions};
use reflectance_core::inference;
use reflectance_core::learn::{Dataset, FeatureSet};
use reflectance_core::material::load_classes;
use reflectance_core::model::Request;
use reflectance_core::model::publish::{Activate, Current};
use reflectance_core::model::registry::{self, Registry};
use reflectance_core::model::train::{self, TrainOptions};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Where the labelled data come from.
#[derive(Args, Debug)]
#[group(required = true, multiple = false)]
pub struct DataArgs {
    /// Dataset manifest (features are extracted first); give it more than once to learn
    /// from the rows of several (spheres and objects of other shapes, say), each row's path
    /// then prefixed with its manifest's folder.
    #[arg(long)]
    manifest: Vec<PathBuf>,
    /// Feature table written by `reflectance features --out`.
    #[arg(long)]
    table: Option<PathBuf>,
}

impl DataArgs {
    /// The feature table and a label for provenance; manifests are extracted with `config`.
    fn load(&self, limits: &LimitArgs, config: FeatureConfig) -> CliResult<(FeatureTable, String)> {
        self.load_with_manifest(limits, config)
            .map(|(table, label, _)| (table, label))
    }

    /// [`DataArgs::load`], and the manifest when the data came as one.
    fn load_with_manifest(
        &self,
        limits: &LimitArgs,
        config: FeatureConfig,
    ) -> CliResult<(FeatureTable, String, Option<Manifest>)> {
        if let Some(table) = &self.table {
            let t = FeatureTable::read(table)?;
            return Ok((t, table.display().to_string(), None));
        }
        if self.manifest.is_empty() {
            return Err("give --manifest or --table".into());
        }
        let manifests = self.manifest.iter().map(|p| dataset::read_manifest(p));
        let manifest = Manifest::concat(manifests.collect::<Result<_, _>>()?);
        manifest.require_labels()?;
        let extractor = Extractor::new(config)?;
        let options = limits.decode_options();
        let table = progress::observed("features", |bar| {
            dataset::extract_manifest_with(&extractor, &manifest, &options, bar)
        })?;
        let label = manifest.source.display().to_string();
        Ok((table, label, Some(manifest)))
    }
}

#[derive(Args, Debug)]
pub struct CvArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    options: ClassifierOptions,
    /// With --manifest: extensions of the extracted features (implied by sets that name
    /// them, such as hand6+log), and the preprocessing.
    #[command(flatten)]
    extraction: FeatureOptions,
    /// Print the full report as JSON.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    estimate: EstimateArgs,
    #[command(flatten)]
    limits: LimitArgs,
}

/// Estimating the Ward parameters instead of naming a class.
#[derive(Args, Debug)]
pub struct EstimateArgs {
    /// Estimate (ρd, ρs, α) with 90 % intervals instead of classifying, by the regression
    /// --regressor chooses (gradient-boosted trees by default); the classes must be
    /// materials of --ward-classes.
    #[arg(long, requires = "ward_classes")]
    estimate: bool,
    /// The class file whose Ward parameters are the targets (e.g. from `materials`).
    #[arg(long, requires = "estimate")]
    ward_classes: Option<PathBuf>,
    /// With --estimate: also write estimate.md (errors overall, for the originals and the
    /// augmented views, and per illumination), estimate.json (every held-out estimate) and
    /// estimate.png (estimated against true, with intervals) into this folder.
    #[arg(long, requires = "estimate")]
    out: Option<PathBuf>,
    #[command(flatten)]
    ridge: estimate::EstimatorOptions,
}

/// Printed after an estimator is fitted.
fn estimate_summary(report: &estimate::EstimateReport, protocol: Protocol) -> String {
    let pct = |x: f64| format!("{:.1} %", 100.0 * x);
    let (w, e) = (&report.half_widths, &report.errors);
    format!(
        "{} {} illuminations, {} images ({} augmented views)\n\
         total reflectance  MAE {:.4}\n\
         rho_d              MAE {:.4}   90 % interval ± {:.4}, covers {}\n\
         rho_s              MAE {:.4}   90 % interval ± {:.4}, covers {}\n\
         mirror or not      {} right\n\
         log10 alpha        MAE {}   90 % interval ± {:.4}, covers {}\n",
        protocol.over(),
        report.illuminations,
        e.n,
        report.augmented,
        e.mae_total,
        e.mae_rho_d,
        w.rho_d,
        pct(e.coverage_rho_d),
        e.mae_rho_s,
        w.rho_s,
        pct(e.coverage_rho_s),
        pct(e.mirror_accuracy),
        e.mae_log10_alpha
            .map_or("n/a (no glossy sphere)".into(), |v| format!("{v:.4}")),
        w.log10_alpha,
        pct(e.coverage_alpha)
    )
}

/// Leave-one-illumination-out errors of the Ward-parameter estimate.
fn cv_estimate(args: &CvArgs, table: &FeatureTable, label: &str) -> CliResult {
    let path = args
        .estimate
        .ward_classes
        .as_ref()
        .ok_or("--estimate needs --ward-classes")?;
    let materials = load_classes(path)?;
    let features = args.options.spec(&table.names)?.features;
    let ds = Dataset::from_table(table)?;
    let spec = (args.estimate.ridge).regression_spec(
        &features,
        &ds.names,
        args.options.gamma,
        args.options.seed,
    )?;
    let fit = progress::observed("estimate", |bar| {
        estimate::fit_observed(&ds, "", &materials, &features, &spec, bar)
    })?;
    let report = fit.report;
    if let Some(out) = &args.estimate.out {
        let title = format!("{} on {label}", args.options.features);
        crate::report::estimate::write(
            out,
            &title,
            Protocol::CrossValidated,
            &report,
            &fit.details,
        )?;
        eprintln!("written to {}", out.display());
    }
    match args.json {
        true => println!("{}", serde_json::to_string_pretty(&report)?),
        false => print!("{}", estimate_summary(&report, Protocol::CrossValidated)),
    }
    Ok(())
}

pub fn cv(args: CvArgs) -> CliResult {
    let config = args.extraction.config(&args.options.features)?;
    let (table, label) = args.data.load(&args.limits, config)?;
    if args.estimate.estimate {
        return cv_estimate(&args, &table, &label);
    }
    let spec = args.options.spec(&table.names)?;
    let ds = Dataset::from_table(&table)?;
    let report = progress::observed("cv", |bar| {
        reflectance_core::classify::cross_validate_with(&ds, &spec, args.options.seed, bar)
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", human_report(&report, ds.group_names.len()));
    }
    Ok(())
}

/// The report as a terminal table.
pub fn human_report(r: &CvReport, illuminations: usize) -> String {
    let mut out = String::new();
    let pct = |x: f64| format!("{:.1} %", 100.0 * x);
    let _ = writeln!(
        out,
        "leave-one-illumination-out: {} · {} — {} images, {} illuminations, {} classes",
        r.summary.features,
        r.summary.classifier,
        r.summary.n,
        illuminations,
        r.summary.classes.len()
    );
    let _ = writeln!(
        out,
        "accuracy {} ({}/{})   chance {}   log-loss {:.3}   ECE {:.3}\n",
        pct(r.summary.accuracy),
        r.summary.correct,
        r.summary.n,
        pct(r.summary.random_guess_accuracy),
        r.summary.log_loss,
        r.summary.ece
    );
    let width = r
        .summary
        .classes
        .iter()
        .map(String::len)
        .max()
        .unwrap_or(5)
        .max(5);
    let _ = writeln!(out, "{:width$}  accuracy", "class");
    for c in &r.summary.per_class {
        let _ = writeln!(
            out,
            "{:width$}  {:>7} ({}/{})",
            c.class,
            pct(c.accuracy),
            c.correct,
            c.n
        );
    }
    let _ = writeln!(
        out,
        "\nconfusion (rows = truth, columns = predicted, same order):"
    );
    for (name, row) in r.summary.classes.iter().zip(&r.summary.confusion) {
        let cells: Vec<String> = row.iter().map(|n| format!("{n:>4}")).collect();
        let _ = writeln!(out, "{name:width$}  {}", cells.join(""));
    }
    let wrong: Vec<_> = r.predictions.iter().filter(|p| !p.correct).collect();
    if !wrong.is_empty() {
        let _ = writeln!(out, "\nmisclassified (with the nearest training image):");
        for p in wrong {
            let nearest = p.nearest.as_ref().map_or(String::new(), |n| {
                format!(
                    "; nearest {} ({}, {}, d = {:.2})",
                    n.path, n.class, n.illumination, n.distance
                )
            });
            let _ = writeln!(
                out,
                "  {} [{}]: {} → {}{}",
                p.path, p.illumination, p.truth, p.predicted, nearest
            );
        }
    }
    out
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    #[command(flatten)]
    data: DataArgs,
    #[command(flatten)]
    options: ClassifierOptions,
    /// With --manifest: extensions of the extracted features (implied by sets that name
    /// them, such as hand6+log), and the preprocessing the model records.
    #[command(flatten)]
    extraction: FeatureOptions,
    /// Model registry folder.
    #[arg(long)]
    models: PathBuf,
    /// Model name (a-z, 0-9, '_', '-').
    #[arg(long)]
    name: String,
    /// Class file with the classes' Ward parameters (recorded in the model).
    #[arg(long)]
    classes: Option<PathBuf>,
    /// Skip the cross-validation report stored with the model.
    #[arg(long)]
    no_cv: bool,
    /// Whether the new version becomes the active one: never, always, or if-better (its
    /// cross-validated accuracy beats the active version's, or there is none). The version
    /// active before is pinned in the registry's ACTIVE file either way, as the service's
    /// train jobs do (whose default is never).
    #[arg(long, value_enum, default_value_t = Activate::IfBetter)]
    activate: Activate,
    /// Fit the classifier without white on the classes' reference materials only: leave out
    /// the images of their members (`CLASS+MEMBER` in a rendered file's name), which without
    /// white a classifier cannot tell from other classes (a black lacquer from chrome).
    #[arg(long)]
    no_white_references_only: bool,
    /// Take the Ward-parameter estimator and the classifier for objects of this model
    /// (DIR/NAME, DIR/NAME/VERSION or a name, as `classify --model`) instead of fitting
    /// them: the features are extracted with its families too, and its preprocessing and
    /// classes must be the new model's. A retrained classifier keeps what reads the
    /// features alike.
    #[arg(long, conflicts_with = "estimator_table")]
    carry_from: Option<PathBuf>,
    #[command(flatten)]
    estimator: EstimatorArgs,
    #[command(flatten)]
    limits: LimitArgs,
}

/// A Ward-parameter estimator fitted next to the classifier.
#[derive(Args, Debug)]
pub struct EstimatorArgs {
    /// Also fit a Ward-parameter estimator on this feature table (extracted with the model's
    /// flags, e.g. of materials from `materials`), reading the classifier's feature set.
    #[arg(long, requires = "estimator_classes")]
    estimator_table: Option<PathBuf>,
    /// The class file of the estimator table's materials (their Ward parameters).
    #[arg(long, requires = "estimator_table")]
    estimator_classes: Option<PathBuf>,
    /// The estimator's features (a named set or a list of names; default: --features). The
    /// extraction computes the families they name, e.g. the centre for hand6+log+cap+ctr.
    #[arg(long, requires = "estimator_table")]
    estimator_features: Option<String>,
    #[command(flatten)]
    ridge: estimate::EstimatorOptions,
}

impl EstimatorArgs {
    /// `config` with the families the estimator's features name.
    fn config(&self, config: FeatureConfig) -> FeatureConfig {
        match &self.estimator_features {
            Some(features) => config.with_families_of(features),
            None => config,
        }
    }

    /// What the estimator is fitted on, when asked for (γ: --ridge-gamma, else `gamma`),
    /// for a model of the columns `names`.
    fn data(
        &self,
        gamma: Option<f64>,
        names: &[String],
    ) -> CliResult<Option<train::EstimatorData>> {
        let (Some(table), Some(classes)) = (&self.estimator_table, &self.estimator_classes) else {
            return Ok(None);
        };
        let features = self
            .estimator_features
            .as_deref()
            .map(|spec| FeatureSet::parse_with(spec, names))
            .transpose()?;
        Ok(Some(train::EstimatorData {
            table: FeatureTable::read(table)?,
            label: table.display().to_string(),
            materials: load_classes(classes)?,
            features,
            regression: self.ridge,
            gamma,
        }))
    }
}

pub fn train(args: TrainArgs) -> CliResult {
    registry::check_name(&args.name)?;
    let classes = args.classes.as_deref().map(load_classes).transpose()?;
    let carried = args
        .carry_from
        .as_deref()
        .map(super::load_model_file)
        .transpose()?;
    // A model's domain check reads how well each circle follows a sphere's outline; what
    // is carried reads the families of the model it comes from.
    let mut config = (args.estimator)
        .config(args.extraction.config(&args.options.features)?)
        .with(&DOMAIN);
    if let Some(from) = &carried {
        config.families = config.families.union(from.features.config.families);
        train::check_carry(&config, from)?;
    }
    let (table, label, manifest) = args.data.load_with_manifest(&args.limits, config)?;
    let options = TrainOptions {
        name: args.name.clone(),
        spec: args.options.spec(&table.names)?,
        seed: args.options.seed,
        cross_validate: !args.no_cv,
        classes,
        preprocessing: args.extraction.preprocessing,
        images: manifest,
        decode: args.limits.decode_options(),
        estimator: args.estimator.data(args.options.gamma, &table.names)?,
        no_white_references_only: args.no_white_references_only,
    };
    let mut trained = progress::observed("train", |bar| {
        train::train_with(&table, &label, &options, bar)
    })?;
    if let Some(from) = &carried {
        train::carry_heads(&mut trained.model, from)?;
    }
    if let Some(report) = &trained.estimate {
        eprint!(
            "estimator: {}",
            estimate_summary(report, Protocol::CrossValidated)
        );
    }
    publish(&mut trained, &args.models, args.activate)
}

/// Publish a trained model as the next version of its name in the registry `models`,
/// activated by `activate`; print its folder.
fn publish(
    trained: &mut train::Trained,
    models: &std::path::Path,
    activate: Activate,
) -> CliResult {
    let registry = Registry::new(models);
    let name = trained.model.name.clone();
    let current = Current::in_registry(&registry, &name);
    let published = trained.publish_by(&registry, current, activate)?;
    if let Some(e) = &published.pin_failed {
        eprintln!("warning: could not pin the version active before: {e}");
    }
    let activated = published.decision.activates();
    if activated {
        registry.set_active(&name, published.version)?;
    }
    eprintln!(
        "version {} {} ({})",
        published.version,
        if activated {
            "activated"
        } else {
            "published, not activated"
        },
        published.decision
    );
    let dir = published.dir;
    if let Some(r) = &trained.report {
        eprintln!(
            "cross-validated accuracy {:.1} % ({}/{})",
            100.0 * r.summary.accuracy,
            r.summary.correct,
            r.summary.n
        );
    }
    println!("{}", dir.display());
    Ok(())
}

#[derive(Args, Debug)]
pub struct TrainObjectsArgs {
    /// The model to extend: DIR/NAME (the active version), DIR/NAME/VERSION, or a name (as
    /// `classify --model`).
    #[arg(long)]
    model: PathBuf,
    /// Spheres and objects (manifests with a `normals` column), extracted with the model's
    /// configuration; or a table extracted so.
    #[command(flatten)]
    data: DataArgs,
    /// Model registry folder the new version is written to (as the next version of the
    /// model's name there).
    #[arg(long)]
    models: PathBuf,
    /// Folds of illuminations whose held-out decision values calibrate the classifier for
    /// objects (0: every illumination held out in turn).
    #[arg(long, default_value_t = reflectance_core::classify::CALIBRATION_FOLDS)]
    calibration_folds: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Whether the new version becomes the active one: never, always or if-better (which,
    /// without a cross-validated accuracy, activates it only where no version is active).
    /// Spheres are answered by it exactly as by the model it extends.
    #[arg(long, value_enum, default_value_t = Activate::Always)]
    activate: Activate,
    #[command(flatten)]
    limits: LimitArgs,
}

pub fn train_objects(args: TrainObjectsArgs) -> CliResult {
    let base = super::load_model_file(&args.model)?;
    let (table, label) = args.data.load(&args.limits, base.features.config)?;
    let mut trained = progress::observed("train", |bar| {
        train::add_objects(
            &base,
            &table,
            &label,
            (args.calibration_folds, args.seed),
            bar,
        )
    })?;
    publish(&mut trained, &args.models, args.activate)
}

#[derive(Args, Debug)]
pub struct PredictArgs {
    /// DIR/NAME (the active version), DIR/NAME/VERSION, or a name (as `classify --model`).
    #[arg(long)]
    model: PathBuf,
    #[arg(long)]
    manifest: PathBuf,
    /// Output CSV: path,label,p_<class>…,set (its classes, space-separated),in_domain,
    /// domain_score,domain_failed (the checks that failed: typicality, outline, brightness,
    /// envelope) (and, when the model has an estimator, rho_d,rho_d_low,rho_d_high,
    /// rho_s,…,alpha_high). Rows without white are classified as the service classifies a
    /// request without one.
    #[arg(long)]
    out: PathBuf,
    /// The class file of the manifest's materials: also measure the model's Ward-parameter
    /// estimate against their true parameters (printed; see --estimate-report).
    #[arg(long)]
    ward_classes: Option<PathBuf>,
    /// With --ward-classes: write estimate.md, estimate.json and estimate.png here.
    #[arg(long, requires = "ward_classes")]
    estimate_report: Option<PathBuf>,
    /// The prediction sets' coverage, from 0.5 to 0.999 (default 0.95).
    #[arg(long)]
    coverage: Option<f64>,
    #[command(flatten)]
    limits: LimitArgs,
}

pub fn predict(args: PredictArgs) -> CliResult {
    let model = super::load_model_file(&args.model)?;
    let (name, version) = (model.name.clone(), model.version);
    let extractor = Extractor::new(model.features.config)?;
    let manifest = dataset::read_manifest(&args.manifest)?;
    let options = args.limits.decode_options();
    // Measured as the service measures a request: the lighting check reads the shading.
    let (table, shading) = progress::observed("features", |bar| {
        dataset::extract_manifest_measured(&extractor, &manifest, &options, bar, true)
    })?;
    let classes = model.classifier.classes();
    let estimator = model.estimator.as_ref();
    let mut csv = String::from("path,label");
    for c in classes {
        let _ = write!(csv, ",p_{c}");
    }
    csv.push_str(",set,in_domain,domain_score,domain_failed");
    if estimator.is_some() {
        for p in ["rho_d", "rho_s", "alpha"] {
            let _ = write!(csv, ",{p},{p}_low,{p}_high");
        }
    }
    csv.push('\n');
    let coverage = args
        .coverage
        .map(reflectance_core::classify::conformal::check_coverage)
        .transpose()?
        .unwrap_or(reflectance_core::classify::conformal::DEFAULT_COVERAGE);
    let layout = model.features.config.layout();
    let mut tally = Tally::default();
    let rows = table.samples.iter().zip(&manifest.entries).zip(shading);
    for ((sample, entry), measurements) in rows {
        // As the service would: no white is no white, not white = 1.
        let measured =
            CaptureMeasurements::of_row(&layout, &sample.values).map(|m| CaptureMeasurements {
                shading: measurements.and_then(|m| m.shading),
                ..m
            });
        let context = inference::Context {
            request: Request {
                white_given: entry.white.is_some(),
                object: entry.normals.is_some(),
            },
            radius: entry.circle.map_or(f64::NAN, |c| c.r),
            measured: measured.as_ref(),
            coverage,
        };
        let decision = inference::decide(&model, &sample.values, context)?;
        let label = &classes[decision.class];
        let _ = write!(csv, "{},{}", csv_field(&sample.path), csv_field(label));
        for p in &decision.probabilities {
            let _ = write!(csv, ",{}", dataset::format_f64(*p));
        }
        let set: Vec<&str> = decision
            .set
            .iter()
            .flatten()
            .map(|&k| classes[k].as_str())
            .collect();
        let score = decision.verdict.as_ref().map(|v| v.score);
        let mut failed: Vec<String> = decision
            .verdict
            .iter()
            .flat_map(|v| v.failed())
            .map(|k| inference::wire_name(&k))
            .collect();
        if decision.beyond_any_light() {
            failed.push("lighting".into());
        }
        if !decision.envelope.is_empty() {
            failed.push("envelope".into());
        }
        let _ = write!(
            csv,
            ",{},{},{},{}",
            csv_field(&set.join(" ")),
            decision.in_domain(),
            score.map_or(String::new(), dataset::format_f64),
            failed.join(" ")
        );
        if let Some(e) = inference::estimate(&model, &decision, &sample.values) {
            for i in [e.rho_d, e.rho_s, e.alpha] {
                for v in [i.value, i.low, i.high] {
                    let _ = write!(csv, ",{}", dataset::format_f64(v));
                }
            }
        }
        csv.push('\n');
        // Only rows of the model's classes count (a manifest of other materials may be
        // here for the estimate alone).
        let truth = entry.class.as_ref().filter(|c| classes.contains(c));
        tally.add(
            truth.map(|t| t == label),
            truth.map(|t| set.contains(&t.as_str())),
            &decision,
        );
    }
    reflectance_core::util::durable::write_atomic(&args.out, csv.as_bytes())
        .map_err(|e| CliError::at(args.out.display(), e))?;
    print!("{}", tally.summary(&name, version, coverage));
    match (&args.ward_classes, estimator) {
        (Some(path), Some(estimator)) => evaluate_estimator(&args, path, estimator, &table),
        (Some(_), None) => Err(CliError::Invalid(format!(
            "{name} version {version} has no Ward-parameter estimator"
        ))),
        (None, _) => Ok(()),
    }
}

/// What `predict` counts.
#[derive(Default)]
struct Tally {
    rows: usize,
    labelled: usize,
    correct: usize,
    /// Labelled rows with a prediction set, those whose set held the truth, and their sizes.
    with_sets: usize,
    covered: usize,
    set_sizes: usize,
    in_domain: usize,
}

impl Tally {
    /// One row: whether its label was right and its set held the truth (`None`: no class
    /// of the model's), and its decision.
    fn add(&mut self, right: Option<bool>, covered: Option<bool>, decision: &inference::Decision) {
        self.rows += 1;
        self.in_domain += usize::from(decision.in_domain());
        if let Some(right) = right {
            self.labelled += 1;
            self.correct += usize::from(right);
        }
        if let (Some(covered), Some(set)) = (covered, &decision.set) {
            self.with_sets += 1;
            self.covered += usize::from(covered);
            self.set_sizes += set.len();
        }
    }

    /// Accuracy, the sets' coverage and size, and the in-domain fraction, one line each.
    fn summary(&self, name: &str, version: u32, coverage: f64) -> String {
        // "96.0 % (24/25)"
        let share =
            |a: usize, b: usize| format!("{:.1} % ({a}/{b})", 100.0 * a as f64 / b.max(1) as f64);
        let mut out = String::new();
        if self.labelled > 0 {
            let accuracy = share(self.correct, self.labelled);
            let _ = writeln!(out, "accuracy {accuracy} with {name} version {version}");
        }
        if self.with_sets > 0 {
            let _ = writeln!(
                out,
                "prediction sets ({} %): hold the truth in {}, {:.3} classes on average",
                super::classify::percent(coverage),
                share(self.covered, self.with_sets),
                self.set_sizes as f64 / self.with_sets as f64
            );
        }
        let _ = writeln!(out, "in domain: {}", share(self.in_domain, self.rows));
        out
    }
}

/// The estimator's errors on a labelled table of materials of the class file `path`.
fn evaluate_estimator(
    args: &PredictArgs,
    path: &std::path::Path,
    estimator: &estimate::WardRegressor,
    table: &FeatureTable,
) -> CliResult {
    let materials = load_classes(path)?;
    let ds = Dataset::from_table(table)?;
    let (report, details) = estimator.evaluate(&ds, &materials)?;
    print!("estimate: {}", estimate_summary(&report, Protocol::Unseen));
    if let Some(out) = &args.estimate_report {
        let title = format!("{} on {}", args.model.display(), args.manifest.display());
        crate::report::estimate::write(out, &title, Protocol::Unseen, &report, &details)?;
        eprintln!("written to {}", out.display());
    }
    Ok(())
}

/// Quote a CSV field when it needs it.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}
