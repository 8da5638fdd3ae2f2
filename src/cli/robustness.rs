//! `reflectance robustness --manifest M --model DIR/NAME [--model …] [--out DIR]`: accuracy
//! of models on a manifest's renders captured as photographs, one capture factor at a time
//! (Markdown, JSON and a PNG plot).

use super::{CliResult, RunArgs};
use crate::report::robustness;
use clap::Args;
use reflectance_core::dataset;
use reflectance_render::capture::CaptureRanges;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct RobustnessArgs {
    /// Test renders (a manifest with class, illumination, circle and white; views with an
    /// `@` suffix are skipped).
    #[arg(long)]
    manifest: PathBuf,
    /// A model, `DIR/NAME` or `DIR/NAME/VERSION`; repeat to compare models.
    #[arg(long, required = true)]
    model: Vec<PathBuf>,
    /// Output folder for robustness.md, robustness.json and robustness.png (default: the
    /// manifest's folder).
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    run: RunArgs,
}

pub fn run(args: RobustnessArgs) -> CliResult {
    let manifest = dataset::read_manifest(&args.manifest)?;
    let options = args.run.limits.decode_options();
    let images = robustness::test_images(&manifest, &options)?;
    let mut radii: Vec<f64> = images.iter().map(|i| i.circle.r).collect();
    radii.sort_by(f64::total_cmp);
    let radius = *radii
        .get(radii.len() / 2)
        .ok_or("the manifest has no original renders")?;
    let models = robustness::load_models(&args.model)?;
    let names: Vec<String> = models.iter().map(|(n, _)| n.clone()).collect();
    let settings = robustness::sweep(&CaptureRanges::default(), radius);
    let cells = robustness::evaluate(&models, &images, &settings, args.run.seed)?;
    let out = args.out.unwrap_or_else(|| {
        args.manifest
            .parent()
            .map_or_else(|| PathBuf::from("."), PathBuf::from)
    });
    robustness::write(&cells, &names, &out)?;
    print!("{}", robustness::markdown(&cells, &names));
    eprintln!("written to {}", out.display());
    Ok(())
}
