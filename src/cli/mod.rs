//! The command line (docs/design.md §6 is the contract: extend it, never rename).

mod classify;
mod dataset;
mod error;
mod features;
mod gltf;
mod learn;
mod materials;
mod merge;
mod render;
mod report;
mod robustness;
mod serve;

pub use error::{CliError, CliResult};

use bytes::Bytes;
use clap::{Args, Parser, Subcommand};
use reflectance_core::analysis::{Placement, WhiteSpec};
use reflectance_core::model::registry;
use reflectance_core::white::Rect;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "reflectance",
    version,
    about = "Classify what a sphere is made of from one photograph"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Extract the 117 features of one image (JSON) or of a manifest (CSV).
    Features(features::FeaturesArgs),
    /// Render Ward spheres under light probes: every probe × class, with a manifest.
    Render(render::RenderArgs),
    /// Write a class file of materials over continuous Ward parameters (a seeded
    /// Latin-hypercube design) for `render --classes`.
    Materials(materials::MaterialsArgs),
    /// Join the parts of a manifest or feature table that `--shard I/N` runs wrote, in shard
    /// order, into the file of the unsharded run.
    Merge(merge::MergeArgs),
    /// Leave-one-illumination-out cross-validation.
    Cv(learn::CvArgs),
    /// Train a model and write it as a new version into a model registry.
    Train(learn::TrainArgs),
    /// Give a trained model a classifier for objects (requests with normals), fitted on
    /// spheres and objects' equivalent spheres, and write it as the model's next version.
    TrainObjects(learn::TrainObjectsArgs),
    /// Classify the images of a manifest with a trained model.
    Predict(learn::PredictArgs),
    /// Classify one photograph with a trained model (the answer of `POST /v1/classify`).
    #[command(after_help = classify::EXAMPLES)]
    Classify(classify::ClassifyArgs),
    /// Ward materials as glTF 2.0 assets (a sphere with the material): every class of a
    /// class file, or one (ρd, ρs, α).
    Gltf(gltf::GltfArgs),
    /// Datasets of your own photographs: `pack` makes the archive the server's
    /// `POST /admin/v1/datasets` takes.
    #[command(subcommand)]
    Dataset(dataset::DatasetCommand),
    /// Reproduce the structure of the paper's Tables 1 and 2 (Markdown, JSON, plots).
    Report(report::ReportArgs),
    /// Accuracy of models on renders captured as photographs, one capture factor at a time.
    Robustness(robustness::RobustnessArgs),
    /// Run the classification service (data plane, and the admin plane when a token is set).
    Serve(serve::ServeArgs),
    /// Exit 0 when a server answers GET /health/ready with 200 (for container health checks).
    Healthcheck(serve::HealthcheckArgs),
}

/// Decoding limits against decompression bombs.
#[derive(Args, Debug, Clone, Copy)]
pub struct LimitArgs {
    /// Largest accepted image width in pixels.
    #[arg(long, env = "REFLECTANCE_MAX_WIDTH", default_value_t = reflectance_core::decode::Limits::default().max_width)]
    max_width: u32,
    /// Largest accepted image height in pixels.
    #[arg(long, env = "REFLECTANCE_MAX_HEIGHT", default_value_t = reflectance_core::decode::Limits::default().max_height)]
    max_height: u32,
    /// Largest accepted number of pixels.
    #[arg(long, env = "REFLECTANCE_MAX_PIXELS", default_value_t = reflectance_core::decode::Limits::default().max_pixels)]
    max_pixels: u64,
}

impl LimitArgs {
    pub fn limits(&self) -> reflectance_core::decode::Limits {
        reflectance_core::decode::Limits {
            max_width: self.max_width,
            max_height: self.max_height,
            max_pixels: self.max_pixels,
        }
    }

    /// Decoding within these limits, each file with its own encoding (a manifest's column,
    /// else sRGB).
    pub fn decode_options(&self) -> reflectance_core::decode::DecodeOptions {
        reflectance_core::decode::DecodeOptions {
            encoding: None,
            limits: self.limits(),
            colour: false,
        }
    }
}

/// The seed of a long run's random streams and the decoding limits (`report`,
/// `robustness`).
#[derive(Args, Debug)]
pub struct RunArgs {
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub limits: LimitArgs,
}

/// Where the sphere is in one image and how bright white is there (`features IMAGE`,
/// `classify`).
#[derive(Args, Debug, Clone)]
pub struct SphereArgs {
    /// Sphere centre x (column; pixel centres are integers); give --cx, --cy and --r
    /// together, or none of them (then the image's alpha channel, else automatic detection).
    #[arg(long, requires_all = ["cy", "r"], allow_negative_numbers = true)]
    pub cx: Option<f64>,
    /// Sphere centre y in pixels (row, downwards).
    #[arg(long, requires_all = ["cx", "r"], allow_negative_numbers = true)]
    pub cy: Option<f64>,
    /// Sphere radius in pixels (≥ 32).
    #[arg(long, requires_all = ["cx", "cy"], allow_negative_numbers = true)]
    pub r: Option<f64>,
    /// A mask image of the sphere (same size: alpha, or luminance ≥ 0.5); a circle is
    /// fitted to its edge. With --normals, the object's pixels.
    #[arg(long, conflicts_with_all = ["cx", "cy", "r"])]
    pub mask: Option<std::path::PathBuf>,
    /// An object of any shape instead of a sphere: its camera-space unit normals per pixel,
    /// the image's size (+X right, +Y up, +Z toward the camera), as PNG (n = 2v/max − 1;
    /// background black or transparent) or OpenEXR (float R, G, B = X, Y, Z); --mask then
    /// gives the object's pixels.
    #[arg(long, conflicts_with_all = ["cx", "cy", "r"])]
    pub normals: Option<std::path::PathBuf>,
    /// Linear luminance of an ideal white surface facing the viewer at the sphere: for 8- and
    /// 16-bit images a fraction of full scale (a white card at 80 % of full scale: 0.8).
    #[arg(long, allow_negative_numbers = true, conflicts_with = "card")]
    pub white: Option<f64>,
    /// A crop of a white card photographed with the sphere: its median luminance is the
    /// white reference.
    #[arg(long, group = "card")]
    pub white_image: Option<std::path::PathBuf>,
    /// A white card inside the image itself: the rectangle X,Y,W,H in pixels (left, top,
    /// width, height) whose median luminance is the white reference.
    #[arg(long, group = "card", allow_hyphen_values = true)]
    pub white_rect: Option<Rect>,
    /// Reflectance of the white card in (0, 1] (white = card median / reflectance).
    #[arg(long, requires = "card", default_value_t = 1.0)]
    pub white_reflectance: f64,
}

impl SphereArgs {
    /// Where the sphere is and how bright white is, as the flags give them: the mask's,
    /// the normals' and the card's files read, the rules checked ([`Placement::new`],
    /// [`WhiteSpec::new`]).
    pub fn placement_and_white(&self) -> CliResult<(Placement<Bytes, Bytes>, WhiteSpec<Bytes>)> {
        let file =
            |path: &Option<PathBuf>, what| path.as_deref().map(|p| read(p, what)).transpose();
        let card = self.white_image.is_some() || self.white_rect.is_some();
        let white = WhiteSpec::new(
            self.white,
            file(&self.white_image, "white image")?,
            self.white_rect,
            // The flag has a default; it is the card's only when there is a card.
            card.then_some(self.white_reflectance),
        )?;
        let placement = Placement::new(self.cx, self.cy, self.r, file(&self.mask, "mask")?)?
            .with_normals(file(&self.normals, "normals")?)?;
        Ok((placement, white))
    }
}

/// The model `reflectance classify` uses when none is named: the server's default.
pub const DEFAULT_MODEL: &str = "ward6";

/// Where a `--model` argument points. A path (`DIR/NAME`, `DIR/NAME/VERSION`, or a folder
/// here) is taken as given; a bare name (`ward6`) is looked for in the registries a user has
/// at hand: `$REFLECTANCE_MODELS`, `./models`, and `models` beside the binary or in the
/// repository it was built in (`target/release/../../models`).
fn model_path(arg: &Path) -> CliResult<PathBuf> {
    let name = arg.to_str().unwrap_or_default();
    if arg.components().count() != 1 || arg.is_dir() || !registry::valid_name(name) {
        return Ok(arg.to_path_buf());
    }
    let mut registries: Vec<PathBuf> = std::env::var_os("REFLECTANCE_MODELS")
        .map(PathBuf::from)
        .into_iter()
        .chain([PathBuf::from("models")])
        .collect();
    if let Some(bin) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        registries.push(bin.join("models"));
        registries.push(bin.join("../../models"));
    }
    if let Some(found) = registries.iter().map(|r| r.join(name)).find(|p| p.is_dir()) {
        return Ok(found);
    }
    let looked: Vec<String> = registries.iter().map(|r| r.display().to_string()).collect();
    Err(CliError::Invalid(format!(
        "no model {name:?} in {} (give its folder: --model DIR/{name}, or set REFLECTANCE_MODELS)",
        looked.join(", ")
    )))
}

/// The model a command line names ([`model_path`]), loaded and verified.
fn load_model_file(arg: &Path) -> CliResult<reflectance_core::model::ModelFile> {
    Ok(registry::load_path(&model_path(arg)?)?)
}

/// A file the command reads whole; `what` names it in the error.
fn read(path: &Path, what: &str) -> CliResult<Bytes> {
    std::fs::read(path)
        .map(Bytes::from)
        .map_err(|e| CliError::Invalid(format!("{what} {}: {e}", path.display())))
}

/// An analysis failure in the command line's words: a sphere detection cannot find asks for
/// the flags that place it.
fn analysis_error(e: &reflectance_core::analysis::AnalysisError) -> String {
    use reflectance_core::analysis::AnalysisError;
    use reflectance_core::locate::GeometryError;
    match e {
        AnalysisError::Geometry(GeometryError::DetectionFailed { .. }) => {
            format!("{e}; give --cx, --cy and --r, or --mask")
        }
        other => other.to_string(),
    }
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    if !matches!(cli.command, Command::Serve(_) | Command::Healthcheck(_)) {
        crate::progress::show_on_stderr();
        // A command piped into `head` ends quietly when the reader goes, as Unix tools do,
        // instead of panicking on the write. (The server keeps SIGPIPE ignored: a client
        // that hangs up is an error to handle, not a reason to stop.)
        // SAFETY: restoring a signal's default disposition before any thread is started.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    let result = match cli.command {
        Command::Features(args) => features::run(args),
        Command::Render(args) => render::run(args),
        Command::Merge(args) => merge::run(args),
        Command::Materials(args) => materials::run(args),
        Command::Cv(args) => learn::cv(args),
        Command::Train(args) => learn::train(args),
        Command::TrainObjects(args) => learn::train_objects(args),
        Command::Predict(args) => learn::predict(args),
        Command::Classify(args) => classify::run(args),
        Command::Dataset(command) => dataset::run(command),
        Command::Gltf(args) => gltf::run(args),
        Command::Report(args) => report::run(args),
        Command::Robustness(args) => robustness::run(args),
        Command::Serve(args) => serve::run(args),
        Command::Healthcheck(args) => serve::healthcheck(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("reflectance: {message}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    #[test]
    fn the_help_of_cv_and_train_names_every_feature_set() {
        let mut cli = Cli::command();
        for command in ["cv", "train"] {
            let help = cli
                .find_subcommand_mut(command)
                .expect("a subcommand")
                .render_long_help()
                .to_string();
            for set in reflectance_core::features::NAMED_SETS {
                assert!(help.contains(set), "`{command} --help` does not name {set}");
            }
        }
    }
}
