//! `reflectance features IMAGE …` (JSON) and `reflectance features --manifest M --out F
//! [--shard I/N]` (CSV).

use super::{CliError, CliResult, LimitArgs, SphereArgs};
use clap::Args;
use reflectance_core::analysis;
use reflectance_core::dataset::{self, Manifest};
use reflectance_core::decode::{self, DecodeOptions, Encoding};
use reflectance_core::features::Extractor;
use reflectance_core::util::shard::Shard;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct FeaturesArgs {
    /// Image of the sphere (PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM, OpenEXR).
    #[arg(required_unless_present = "manifest", conflicts_with = "manifest")]
    image: Option<PathBuf>,
    #[command(flatten)]
    sphere: SphereArgs,
    /// How integer samples are linearized: srgb, linear or gamma:<g>.
    #[arg(long)]
    encoding: Option<String>,
    /// Dataset manifest (path,class,illumination[,cx,cy,r,white,encoding,normals,mask]).
    #[arg(long, requires = "out")]
    manifest: Option<PathBuf>,
    /// Output CSV for --manifest.
    #[arg(long, requires = "manifest")]
    out: Option<PathBuf>,
    /// With --manifest: only the rows of shard I of N (zero-based; the I-th of N contiguous
    /// blocks), written beside --out as F.shard-I-of-N.csv (its path is printed);
    /// `reflectance merge` joins the parts into the table of the whole manifest.
    #[arg(long, value_name = "I/N", requires = "manifest")]
    shard: Option<Shard>,
    #[command(flatten)]
    extensions: reflectance_core::features::FeatureOptions,
    #[command(flatten)]
    limits: LimitArgs,
}

#[derive(Serialize)]
struct Output<'a> {
    names: Vec<String>,
    values: &'a [f64],
    geometry: &'a reflectance_core::locate::Geometry,
    white: &'a reflectance_core::white::White,
    warnings: &'a [String],
}

pub fn run(args: FeaturesArgs) -> CliResult {
    let extractor = Extractor::new(args.extensions.config("")?)?;
    let encoding = args
        .encoding
        .as_deref()
        .map(str::parse::<Encoding>)
        .transpose()?;
    let options = DecodeOptions {
        encoding,
        limits: args.limits.limits(),
        colour: false,
    };
    match (&args.manifest, &args.out) {
        (Some(manifest), Some(out)) => table(manifest, out, args.shard, &extractor, &options),
        _ => single(&args, &extractor, &options),
    }
}

/// The feature table of a manifest, or of a shard's block of its rows (written beside `out`,
/// its path printed).
fn table(
    manifest: &Path,
    out: &Path,
    shard: Option<Shard>,
    extractor: &Extractor,
    options: &DecodeOptions,
) -> CliResult {
    let manifest: Manifest = dataset::read_manifest(manifest)?;
    let manifest = match shard {
        Some(shard) => manifest.shard(shard),
        None => manifest,
    };
    let table = crate::progress::observed("features", |bar| {
        dataset::extract_manifest_with(extractor, &manifest, options, bar)
    })?;
    let Some(shard) = shard else {
        return Ok(table.write(out)?);
    };
    let part = shard.part_path(out);
    table.write(&part)?;
    println!("{}", part.display());
    Ok(())
}

fn single(args: &FeaturesArgs, extractor: &Extractor, options: &DecodeOptions) -> CliResult {
    let path = args.image.as_ref().ok_or("give an IMAGE or --manifest")?;
    let decode = |p: &PathBuf, options: &DecodeOptions| {
        decode::decode_file(p, options).map_err(|e| CliError::at(p.display(), e))
    };
    let image = decode(path, options)?;
    let (placement, white) = args.sphere.placement_and_white()?;
    let placement = placement
        .decode(options)
        .map_err(|e| CliError::at(path.display(), e))?;
    let card = args.sphere.white_image.as_ref().unwrap_or(path);
    let white = white
        .decode(options)
        .map_err(|e| CliError::at(card.display(), e))?;
    let result = analysis::analyze(extractor, &image, &placement, &white)
        .map_err(|e| CliError::Invalid(super::analysis_error(&e)))?;
    let output = Output {
        names: extractor.config().names(),
        values: &result.values,
        geometry: &result.geometry,
        white: &result.white,
        warnings: &result.warnings,
    };
    let json = serde_json::to_string_pretty(&output)?;
    println!("{json}");
    Ok(())
}
