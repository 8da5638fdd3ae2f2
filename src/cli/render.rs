//! `reflectance render --probes DIR|LIST --classes C.json --out DIR [--size N] [--seed S]
//! [--shape SHAPE] [--shard I/N]`.

use super::CliResult;
use clap::Args;
use reflectance_core::util::shard::Shard;
use reflectance_render::Quality;
use reflectance_render::batch::{self, Augment, BatchSpec};
use reflectance_render::shapes::ShapeSpec;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A folder of lat-long Radiance .hdr probes, or a text file listing probe files.
    #[arg(long)]
    probes: PathBuf,
    /// Class file: {"classes": [{"name", "rho_d", "rho_s", "alpha"}, …]}.
    #[arg(long)]
    classes: PathBuf,
    /// Output folder (created; images already complete there are kept).
    #[arg(long)]
    out: PathBuf,
    /// Image size in pixels (the sphere's radius is size/2.2).
    #[arg(long, default_value_t = 256)]
    size: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Augmentation: render each probe turned to this many evenly spaced azimuths.
    #[arg(long, default_value_t = 1)]
    rotations: usize,
    /// Augmentation: extra viewer elevations in degrees (comma-separated), besides 45.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    elevations: Vec<f64>,
    /// Augmentation: extra dynamic ranges of each probe (comma-separated exponents k of
    /// luminance^k, e.g. 0.7,1.4).
    #[arg(long, value_delimiter = ',')]
    contrasts: Vec<f64>,
    /// Augmentation: extra captures of each probe this many times coarser (comma-separated
    /// factors, e.g. 2 for 256 × 128 from 512 × 256), averaged and interpolated back.
    #[arg(long, value_delimiter = ',')]
    reductions: Vec<usize>,
    /// Augmentation: also render this many procedural illuminations (dead-leaves maps with
    /// compact sources; labelled `synthetic@…`, used for training only).
    #[arg(long, default_value_t = 0)]
    synthetic: usize,
    /// Augmentation: this many photograph-like captures of every image (`@cap<k>`, used
    /// for training only): radius, exposure and clipping, shot and read noise, lens blur,
    /// 8-bit sRGB, JPEG or 16-bit linear files, and the white and circle errors a user
    /// makes, each drawn anew within the capture ranges.
    #[arg(long, default_value_t = 0)]
    captures: usize,
    /// Sub-pixel samples per side.
    #[arg(long, default_value_t = Quality::default().pixel_samples)]
    pixel_samples: usize,
    /// Sub-pixel samples per side for glossy lobes.
    #[arg(long, default_value_t = Quality::default().lobe_pixel_samples)]
    lobe_pixel_samples: usize,
    /// Lattice points of the lobe quadrature (for α ≤ 0.02; more for broader lobes).
    #[arg(long, default_value_t = Quality::default().lobe_points)]
    lobe_points: usize,
    /// Render only shard I of N (zero-based, e.g. an indexed job's completion index): the
    /// I-th of N contiguous blocks of the images, byte-identical to the whole run's, with
    /// the parts manifest.shard-I-of-N.csv (and captures.shard-….csv) instead of
    /// manifest.csv; `reflectance merge` joins the parts.
    #[arg(long, value_name = "I/N")]
    shard: Option<Shard>,
    /// The object: sphere, torus, superquadric, capsule, blob (seeded by --seed) or
    /// mesh:PATH (.obj or .ply), fitted to the sphere's circle and shaded from its normals;
    /// a shape's camera-space normals are written beside each image as <name>.normals.png.
    #[arg(long, default_value = "sphere", value_name = "SHAPE")]
    shape: ShapeSpec,
}

pub fn run(args: RenderArgs) -> CliResult {
    let spec = BatchSpec {
        probes: batch::probe_list(&args.probes)?,
        classes: reflectance_core::material::load_classes(&args.classes)?,
        out: args.out,
        size: args.size,
        seed: args.seed,
        quality: Quality {
            pixel_samples: args.pixel_samples,
            lobe_pixel_samples: args.lobe_pixel_samples,
            lobe_points: args.lobe_points,
        },
        augment: Augment {
            rotations: args.rotations,
            elevations: args.elevations,
            contrasts: args.contrasts,
            reductions: args.reductions,
            synthetic: args.synthetic,
            captures: args.captures,
            capture_ranges: Default::default(),
            shape: args.shape,
        },
        shard: args.shard,
    };
    let start = std::time::Instant::now();
    let summary =
        crate::progress::observed("render", |bar| batch::render_dataset_with(&spec, bar))?;
    eprintln!(
        "rendered {} of {} images ({} already complete) in {:.1} s",
        summary.rendered,
        summary.images,
        summary.skipped,
        start.elapsed().as_secs_f64()
    );
    println!("{}", summary.manifest.display());
    Ok(())
}
