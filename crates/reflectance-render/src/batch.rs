//! Rendering whole datasets: every probe × class entry (× augmentation views), in parallel,
//! deterministic for a seed, resumable, with `manifest.csv`
//! (`path,class,illumination,cx,cy,r,white`; illumination = probe file stem, or
//! `<stem>@<variant>` for augmented views; a class's members are named
//! `<class>+<member>` in file names, by their class in the `class` column). A shard renders one contiguous block of the
//! same images and writes its part of the manifest ([`reflectance_core::util::shard`]).

use super::envmap::{EnvMap, EnvMapError};
use super::shapes::{Normals, ShapeError, ShapeSpec};
use super::ward::Material;
use super::{Lighting, Quality, View, render_finished, render_normals_finished};
use crate::capture::{self, CaptureRanges, CaptureSettings, DrawSettings};
use rayon::prelude::*;
use reflectance_core::dataset::{SYNTHETIC_ILLUMINATION, format_f64};
use reflectance_core::decode::pfm;
use reflectance_core::material::{ClassFileError, InvalidRanges};
use reflectance_core::util::durable::write_atomic;
use reflectance_core::util::progress;
use reflectance_core::util::rng::Rng;
use reflectance_core::util::shard::Shard;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error(transparent)]
    Classes(#[from] ClassFileError),
    /// A probe that does not load (shared: each job of the probe reports the one failure).
    #[error(transparent)]
    Probe(Arc<EnvMapError>),
    #[error("no probes found in {0}")]
    NoProbes(String),
    #[error("probe {name:?} listed in {list} was not found")]
    MissingProbe { list: String, name: String },
    #[error("invalid rendering option: {0}")]
    Options(String),
    #[error("invalid rendering option: {0}")]
    Invalid(#[from] OptionsError),
    #[error(transparent)]
    Shape(#[from] ShapeError),
    #[error("cancelled")]
    Cancelled,
}

impl From<EnvMapError> for RenderError {
    fn from(e: EnvMapError) -> Self {
        RenderError::Probe(Arc::new(e))
    }
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> RenderError + '_ {
    move |source| RenderError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Probe files: every `*.hdr` of a directory (sorted), or the names listed in a text file
/// (one per line, `#` comments), resolved against the list's folder, then its parent (so
/// `probes/sets/all.txt` finds `probes/*.hdr`).
pub fn probe_list(arg: &Path) -> Result<Vec<PathBuf>, RenderError> {
    let probes = if arg.is_dir() {
        let mut found: Vec<PathBuf> = std::fs::read_dir(arg)
            .map_err(io_error(arg))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("hdr")))
            .collect();
        found.sort();
        found
    } else {
        let text = std::fs::read_to_string(arg).map_err(io_error(arg))?;
        let base = arg.parent().unwrap_or(Path::new("."));
        let mut found = Vec::new();
        for name in text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
        {
            let candidates = [base.join(name), base.join("..").join(name)];
            let path = candidates
                .into_iter()
                .find(|p| p.is_file())
                .ok_or_else(|| RenderError::MissingProbe {
                    list: arg.display().to_string(),
                    name: name.to_string(),
                })?;
            found.push(path);
        }
        found
    };
    if probes.is_empty() {
        return Err(RenderError::NoProbes(arg.display().to_string()));
    }
    Ok(probes)
}

/// Extra training views of each probe: turns about +Y and changes of viewer elevation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Augment {
    /// Number of evenly spaced azimuths (1 = only the original); each is a whole number of
    /// map columns so that a turn equals rolling the map.
    pub rotations: usize,
    /// Additional viewer elevations in degrees (the default 45° view is always rendered).
    pub elevations: Vec<f64>,
    /// Additional dynamic ranges of each probe: luminance L^k (rescaled to the same mean),
    /// k < 1 flattening and k > 1 sharpening the contrast between sources and surroundings.
    pub contrasts: Vec<f64>,
    /// Additional captures of each probe `factor` times coarser ([`EnvMap::reduced`]): the
    /// same scene with less fine detail, as the upsampled probes have.
    pub reductions: Vec<usize>,
    /// Procedural illuminations ([`super::synthetic`]) rendered besides the probes, in the
    /// original view only, labelled `synthetic@s<seed>-<index>`: one group that never
    /// holds originals, so cross-validation trains on them in every fold and never tests them.
    pub synthetic: usize,
    /// Photograph-like captures of every rendered image ([`crate::capture`]), each with its
    /// own settings drawn from `capture_ranges`: `@cap<k>` views (8-bit PNG, JPEG or 16-bit
    /// linear PNG files, with the white and circle a user would report).
    pub captures: usize,
    pub capture_ranges: CaptureRanges,
    /// The object: the sphere (the default), or a shape rasterized once
    /// ([`crate::shapes`], in [`ShapeSpec::pose`], a blob seeded by the run's seed) and
    /// shaded from its normals, each image with its `<name>.normals.png` beside it.
    pub shape: ShapeSpec,
}

/// One view of a probe: the illumination label suffix and the camera.
#[derive(Clone, Debug)]
struct Variant {
    suffix: String,
    view: View,
    /// Index into the probe's lightings ([`Augment::lighting`]).
    lighting: usize,
}

/// A number as a short label: `40`, `0.8`.
fn label(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format_f64(v)
    }
}

fn variants(augment: &Augment, map_width: usize) -> Vec<Variant> {
    let mut out = vec![Variant {
        suffix: String::new(),
        view: View::default(),
        lighting: 0,
    }];
    let turns = augment.rotations.max(1);
    for t in 1..turns {
        let columns = t * map_width / turns;
        let degrees = 360.0 * columns as f64 / map_width as f64;
        out.push(Variant {
            suffix: format!("@rot{:03}", degrees.round() as i64),
            view: View {
                azimuth_deg: degrees,
                ..View::default()
            },
            lighting: 0,
        });
    }
    for &e in &augment.elevations {
        out.push(Variant {
            suffix: format!("@el{}", label(e)),
            view: View {
                elevation_deg: e,
                ..View::default()
            },
            lighting: 0,
        });
    }
    let contrasts = augment.contrasts.iter().map(|&c| format!("@c{}", label(c)));
    let reductions = augment.reductions.iter().map(|f| format!("@lr{f}"));
    for (k, suffix) in contrasts.chain(reductions).enumerate() {
        out.push(Variant {
            suffix,
            view: View::default(),
            lighting: k + 1,
        });
    }
    out
}

impl Augment {
    /// Lightings of a probe: the map as it is, then one per contrast, then one per reduction.
    fn lightings(&self) -> usize {
        1 + self.contrasts.len() + self.reductions.len()
    }

    /// How many views [`variants`] makes of a probe, whatever its map's width.
    fn views(&self) -> usize {
        self.rotations.max(1) + self.elevations.len() + self.lightings() - 1
    }

    /// Lighting `k` of a probe whose map is `map`.
    fn lighting(&self, map: &EnvMap, k: usize) -> EnvMap {
        let contrasts = self.contrasts.len();
        match k {
            0 => map.clone(),
            k if k <= contrasts => map.with_contrast(self.contrasts[k - 1]),
            k => map.reduced(self.reductions[k - 1 - contrasts]),
        }
    }
}

/// What to render.
#[derive(Clone, Debug)]
pub struct BatchSpec {
    pub probes: Vec<PathBuf>,
    pub classes: Vec<Material>,
    pub out: PathBuf,
    pub size: usize,
    pub seed: u64,
    pub quality: Quality,
    pub augment: Augment,
    /// Render only this shard's block of the images, and write its parts of `manifest.csv`
    /// and `captures.csv` ([`Shard::part_path`]) instead of the whole files.
    pub shard: Option<Shard>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BatchSummary {
    pub images: usize,
    pub rendered: usize,
    pub skipped: usize,
    pub manifest: PathBuf,
}

/// Where a probe's map comes from.
enum Source {
    File(PathBuf),
    Synthetic { seed: u64, index: u64 },
}

struct Probe {
    source: Source,
    stem: String,
    map: OnceLock<Result<EnvMap, Arc<EnvMapError>>>,
    /// One lighting per dynamic range (see [`Variant::lighting`]).
    lightings: Vec<OnceLock<Lighting>>,
}

impl Probe {
    /// The map, loaded once.
    fn map(&self) -> Result<&EnvMap, RenderError> {
        let loaded = self.map.get_or_init(|| match &self.source {
            Source::File(path) => EnvMap::load(path).map_err(Arc::new),
            Source::Synthetic { seed, index } => Ok(super::synthetic::map(*seed, *index)),
        });
        loaded
            .as_ref()
            .map_err(|e| RenderError::Probe(Arc::clone(e)))
    }
}

struct Job {
    probe: usize,
    variant: Variant,
    class: usize,
    name: String,
}

/// FNV-1a: a stable per-image seed from its name.
fn stable_hash(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
    })
}

/// The index of a synthetic illumination has four digits.
const MAX_SYNTHETIC: usize = 9999;
/// Captures per image.
pub const MAX_CAPTURES: usize = 64;

/// Rendering options out of range: the one check of the command line's `render` and the
/// service's render jobs ([`check_options`]).
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum OptionsError {
    #[error(transparent)]
    Size(#[from] super::SizeError),
    #[error("pixel and lobe sub-pixel samples per side must be 1…16, lobe points 1…1024")]
    Quality,
    #[error(transparent)]
    CaptureRanges(#[from] InvalidRanges),
    #[error("rotations must be at most 360")]
    Rotations,
    #[error("give elevations within 5°…85°")]
    Elevations,
    #[error("give contrasts within 0.1…4")]
    Contrasts,
    #[error("give reductions within 2…16")]
    Reductions,
    #[error("synthetic illuminations must be at most {MAX_SYNTHETIC}")]
    Synthetic,
    #[error("captures must be at most {MAX_CAPTURES}")]
    Captures,
}

/// Check a rendering's options before any work: the image size ([`super::check_size`]),
/// the quality and the augmentation.
pub fn check_options(
    size: usize,
    quality: &Quality,
    augment: &Augment,
) -> Result<(), OptionsError> {
    super::check_size(size)?;
    let q = quality;
    if !(1..=16).contains(&q.pixel_samples)
        || !(1..=16).contains(&q.lobe_pixel_samples)
        || !(1..=1024).contains(&q.lobe_points)
    {
        return Err(OptionsError::Quality);
    }
    let a = augment;
    a.capture_ranges.validate()?;
    let refused = [
        (a.rotations > 360, OptionsError::Rotations),
        (
            a.elevations.iter().any(|e| !(5.0..=85.0).contains(e)),
            OptionsError::Elevations,
        ),
        (
            a.contrasts.iter().any(|c| !(0.1..=4.0).contains(c)),
            OptionsError::Contrasts,
        ),
        (
            a.reductions.iter().any(|f| !(2..=16).contains(f)),
            OptionsError::Reductions,
        ),
        (a.synthetic > MAX_SYNTHETIC, OptionsError::Synthetic),
        (a.captures > MAX_CAPTURES, OptionsError::Captures),
    ];
    match refused.into_iter().find(|(bad, _)| *bad) {
        Some((_, e)) => Err(e),
        None => Ok(()),
    }
}

/// Render every probe × variant × class into `spec.out`; images already complete are
/// skipped (resume). Writes `manifest.csv` (or the shard's part of it) last, atomically.
pub fn render_dataset(spec: &BatchSpec) -> Result<BatchSummary, RenderError> {
    render_dataset_with(spec, &progress::Silent)
}

/// The probe files, then the synthetic maps.
fn probes_of(spec: &BatchSpec) -> Vec<Probe> {
    let probe = |source: Source, stem: String| Probe {
        source,
        stem,
        map: OnceLock::new(),
        lightings: (0..spec.augment.lightings())
            .map(|_| OnceLock::new())
            .collect(),
    };
    let files = spec.probes.iter().map(|path| {
        let stem = path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        probe(Source::File(path.clone()), stem)
    });
    let seed = spec.seed;
    let synthetic = (0..spec.augment.synthetic as u64).map(|index| {
        let stem = format!("{SYNTHETIC_ILLUMINATION}@s{seed}-{index:04}");
        probe(Source::Synthetic { seed, index }, stem)
    });
    files.chain(synthetic).collect()
}

/// [`render_dataset`] reporting each finished image to `observer`; a cancellation seen
/// before an image starts ends the run with [`RenderError::Cancelled`] (the images already
/// written stay, so a later run resumes; no manifest is written).
pub fn render_dataset_with(
    spec: &BatchSpec,
    observer: &dyn progress::Observer,
) -> Result<BatchSummary, RenderError> {
    check_options(spec.size, &spec.quality, &spec.augment)?;
    std::fs::create_dir_all(&spec.out).map_err(io_error(&spec.out))?;
    let probes = probes_of(spec);
    let jobs = jobs_of(spec, &probes)?;
    let object = Object::new(spec)?;
    let expected_len =
        pfm::encode_gray(spec.size, spec.size, &vec![0.0; spec.size * spec.size]).len() as u64;
    let complete = |job: &Job| {
        let pfm_path = spec.out.join(format!("{}.pfm", job.name));
        std::fs::metadata(&pfm_path).is_ok_and(|m| m.len() == expected_len)
            && spec.out.join(format!("{}.mask.png", job.name)).is_file()
            && (object.is_none() || spec.out.join(normals_file(&job.name)).is_file())
    };
    let counter = progress::Counter::new(observer, jobs.len());
    let outcomes: Vec<Result<bool, RenderError>> = jobs
        .par_iter()
        .map(|job| {
            if counter.cancelled() {
                return Err(RenderError::Cancelled);
            }
            let result = render_job(
                spec,
                &probes[job.probe],
                job,
                (object.as_ref(), complete(job)),
            );
            counter.tick();
            result
        })
        .collect();
    let mut rendered = 0;
    for outcome in outcomes {
        rendered += usize::from(outcome?);
    }
    let manifest = write_manifest(spec, &probes, &jobs)?;
    Ok(BatchSummary {
        images: jobs.len(),
        rendered,
        skipped: jobs.len() - rendered,
        manifest,
    })
}

/// The jobs in manifest order (probe, view, class), only those of the spec's shard. The
/// numbering of the whole list needs only how many views each probe has, so the maps of
/// probes with no job in the shard are never loaded.
fn jobs_of(spec: &BatchSpec, probes: &[Probe]) -> Result<Vec<Job>, RenderError> {
    let views = |probe: &Probe| match probe.source {
        Source::File(_) => spec.augment.views(),
        Source::Synthetic { .. } => 1,
    };
    let per_probe = |probe: &Probe| views(probe) * spec.classes.len();
    let total = probes.iter().map(per_probe).sum();
    let block = spec.shard.map_or(0..total, |shard| shard.block(total));
    let mut jobs = Vec::with_capacity(block.len());
    let mut first = 0;
    for (pi, probe) in probes.iter().enumerate() {
        let own = first..first + per_probe(probe);
        first = own.end;
        if own.end <= block.start || own.start >= block.end {
            continue;
        }
        let variants = match probe.source {
            Source::File(_) => variants(&spec.augment, probe.map()?.width),
            Source::Synthetic { .. } => variants(&Augment::default(), 0),
        };
        debug_assert_eq!(variants.len(), views(probe));
        let all = variants.iter().flat_map(|variant| {
            let classes = spec.classes.iter().enumerate();
            classes.map(move |(ci, class)| (variant, ci, class))
        });
        for (k, (variant, ci, class)) in all.enumerate() {
            if block.contains(&(own.start + k)) {
                jobs.push(Job {
                    probe: pi,
                    variant: variant.clone(),
                    class: ci,
                    name: format!("{}{}__{}", probe.stem, variant.suffix, class.label()),
                });
            }
        }
    }
    Ok(jobs)
}

/// Where a whole-run file of the data set goes, or this shard's part of it.
fn output_path(spec: &BatchSpec, file: &str) -> PathBuf {
    let path = spec.out.join(file);
    match spec.shard {
        Some(shard) => shard.part_path(&path),
        None => path,
    }
}

/// Render one image unless it is `complete`, then write whichever of its captures are
/// missing; whether the image was rendered.
fn render_job(
    spec: &BatchSpec,
    probe: &Probe,
    job: &Job,
    (object, complete): (Option<&Object>, bool),
) -> Result<bool, RenderError> {
    let captures: Vec<CaptureView> = (1..=spec.augment.captures)
        .map(|k| CaptureView::new(spec, probe, job, k))
        .filter(|c| !spec.out.join(&c.file).is_file())
        .collect();
    let rendering = if complete {
        None
    } else {
        reflectance_core::util::durable::test_pause("render-image");
        let map = probe.map()?;
        let k = job.variant.lighting;
        let lighting =
            probe.lightings[k].get_or_init(|| Lighting::new(spec.augment.lighting(map, k)));
        let mut rng = Rng::fork(spec.seed, stable_hash(&job.name));
        let class = &spec.classes[job.class];
        let (material, finish, view) = (&class.ward, &class.finish, &job.variant.view);
        let quality = &spec.quality;
        let image = match object {
            None => render_finished(
                lighting, material, finish, spec.size, view, quality, &mut rng,
            ),
            Some(object) => {
                let path = spec.out.join(normals_file(&job.name));
                write_atomic(&path, &object.png).map_err(io_error(&path))?;
                let normals = &object.normals;
                render_normals_finished(
                    lighting, material, finish, view, normals, quality, &mut rng,
                )
            }
        };
        write_image(&spec.out, &job.name, &image)?;
        Some(image)
    };
    if captures.is_empty() {
        return Ok(!complete);
    }
    let luminance = match &rendering {
        Some(image) => plane(spec.size, &image.luminance),
        None => {
            let path = spec.out.join(format!("{}.pfm", job.name));
            reflectance_core::decode::decode_file(&path, &Default::default())
                .map_err(|e| RenderError::Options(format!("{}: {e}", path.display())))?
                .luminance
        }
    };
    // An object is photographed with its geometry kept, over its own coverage.
    let coverage = match (object, &rendering) {
        (None, _) => None,
        (Some(_), Some(image)) => Some(plane(spec.size, &image.coverage)),
        (Some(_), None) => Some(read_coverage(spec, &job.name)?),
    };
    let white = super::white(probe.map()?, &job.variant.view);
    let circle = super::circle(spec.size);
    for view in captures {
        let mut rng = view.rng.clone();
        let shot = match &coverage {
            None => capture::capture(luminance.view(), &circle, white, &view.settings, &mut rng),
            Some(coverage) => capture::capture_object(
                luminance.view(),
                coverage.view(),
                &circle,
                white,
                &view.settings,
                &mut rng,
            ),
        }
        .map_err(|e| RenderError::Options(e.to_string()))?;
        let path = spec.out.join(&view.file);
        write_atomic(&path, &shot.bytes).map_err(io_error(&path))?;
    }
    Ok(!complete)
}

/// A square render's row-major samples as a plane.
fn plane(size: usize, samples: &[f32]) -> ndarray::Array2<f64> {
    ndarray::Array2::from_shape_fn((size, size), |(y, x)| f64::from(samples[y * size + x]))
}

/// The coverage an image's `<name>.mask.png` holds (8-bit), as [`write_image`] wrote it.
fn read_coverage(spec: &BatchSpec, name: &str) -> Result<ndarray::Array2<f64>, RenderError> {
    let path = spec.out.join(format!("{name}.mask.png"));
    let options = reflectance_core::decode::DecodeOptions {
        encoding: Some(reflectance_core::decode::Encoding::Linear),
        ..Default::default()
    };
    let mask = reflectance_core::decode::decode_file(&path, &options)
        .map_err(|e| RenderError::Options(format!("{}: {e}", path.display())))?;
    Ok(mask.luminance)
}

/// A shape's normals for every image of a run, and their PNG.
struct Object {
    normals: Normals,
    png: Vec<u8>,
}

impl Object {
    /// The run's shape rasterized, or None for the sphere.
    fn new(spec: &BatchSpec) -> Result<Option<Object>, RenderError> {
        let kind = &spec.augment.shape;
        if *kind == ShapeSpec::Sphere {
            return Ok(None);
        }
        let shape = kind.shape(spec.seed)?;
        let normals =
            super::shapes::rasterize(&shape, &kind.pose(), spec.size, spec.quality.pixel_samples)?;
        let png = normals.to_png()?;
        Ok(Some(Object { normals, png }))
    }
}

/// The normal map written beside image `name`.
fn normals_file(name: &str) -> String {
    format!("{name}.normals.png")
}

/// A capture of one rendered image: `<probe><view>@cap<k>__<class>.<png|jpg>`, its
/// settings drawn from the ranges by a stream of its own name.
struct CaptureView {
    illumination: String,
    file: String,
    settings: CaptureSettings,
    /// The stream after the settings were drawn: the capture's noise continues it.
    rng: Rng,
}

impl CaptureView {
    fn new(spec: &BatchSpec, probe: &Probe, job: &Job, k: usize) -> CaptureView {
        let illumination = format!(
            "{}{}{}{k}",
            probe.stem,
            job.variant.suffix,
            capture::VIEW_TAG
        );
        let stem = format!("{illumination}__{}", spec.classes[job.class].label());
        let mut rng = Rng::fork(spec.seed, stable_hash(&stem));
        let mut settings = spec.augment.capture_ranges.sample(&mut rng);
        if spec.augment.shape != ShapeSpec::Sphere {
            // An object keeps its geometry ([`capture::capture_object`]).
            settings.radius = super::circle(spec.size).r;
            settings.centre_error = [0.0; 2];
            settings.radius_error = 0.0;
        }
        CaptureView {
            file: format!("{stem}.{}", settings.quantization.extension()),
            illumination,
            settings,
            rng,
        }
    }
}

/// Luminance as PFM and coverage as an 8-bit PNG mask, each written atomically (the PFM
/// last, so its presence means the image is complete).
fn write_image(out: &Path, name: &str, image: &super::Rendering) -> Result<(), RenderError> {
    let mask_path = out.join(format!("{name}.mask.png"));
    let mask: Vec<u8> = image
        .coverage
        .iter()
        .map(|c| (c * 255.0).round() as u8)
        .collect();
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    let size = image.size as u32;
    image::ImageEncoder::write_image(encoder, &mask, size, size, image::ExtendedColorType::L8)
        .map_err(|e| RenderError::Options(format!("encoding {name} mask: {e}")))?;
    write_atomic(&mask_path, &png).map_err(io_error(&mask_path))?;
    let pfm_path = out.join(format!("{name}.pfm"));
    write_atomic(
        &pfm_path,
        &pfm::encode_gray(image.size, image.size, &image.luminance),
    )
    .map_err(io_error(&pfm_path))
}

fn write_manifest(
    spec: &BatchSpec,
    probes: &[Probe],
    jobs: &[Job],
) -> Result<PathBuf, RenderError> {
    let circle = super::circle(spec.size);
    let with_captures = spec.augment.captures > 0;
    let object = spec.augment.shape != ShapeSpec::Sphere;
    let mut text = String::from("path,class,illumination,cx,cy,r,white");
    text.push_str(if with_captures { ",encoding" } else { "" });
    text.push_str(if object { ",normals\n" } else { "\n" });
    let mut settings = String::from(CAPTURE_COLUMNS);
    let mut white_cache: std::collections::HashMap<String, f64> = Default::default();
    for job in jobs {
        let illumination = format!("{}{}", probes[job.probe].stem, job.variant.suffix);
        let white = match white_cache.get(&illumination) {
            Some(&w) => w,
            None => {
                let w = super::white(probes[job.probe].map()?, &job.variant.view);
                white_cache.insert(illumination.clone(), w);
                w
            }
        };
        let class = &spec.classes[job.class].name;
        // An object is placed by its normal map, not by the sphere's circle.
        let normals = object.then(|| normals_file(&job.name));
        let row = |path: &str, illumination: &str, c: &super::Circle, white: f64| {
            let circle = match &normals {
                None => [c.cx, c.cy, c.r].map(format_f64).join(","),
                Some(_) => ",,".into(),
            };
            let white = format_f64(white);
            format!("{path},{class},{illumination},{circle},{white}")
        };
        let end = match &normals {
            Some(normals) => format!(",{normals}\n"),
            None => "\n".into(),
        };
        let image = format!("{}.pfm", job.name);
        text.push_str(&row(&image, &illumination, &circle, white));
        text.push_str(if with_captures { "," } else { "" });
        text.push_str(&end);
        for k in 1..=spec.augment.captures {
            let view = CaptureView::new(spec, &probes[job.probe], job, k);
            let (reported, white) = capture::reported(&circle, &view.settings);
            let encoding = view.settings.quantization.encoding();
            text.push_str(&row(&view.file, &view.illumination, &reported, white));
            text.push_str(&format!(",{encoding}{end}"));
            settings.push_str(&capture_row(&view.file, &view.settings));
        }
    }
    if with_captures {
        let path = output_path(spec, "captures.csv");
        write_atomic(&path, settings.as_bytes()).map_err(io_error(&path))?;
    }
    let path = output_path(spec, "manifest.csv");
    write_atomic(&path, text.as_bytes()).map_err(io_error(&path))?;
    Ok(path)
}

/// Header of `captures.csv`: each capture's settings.
const CAPTURE_COLUMNS: &str = "path,radius,exposure,noise,shot_share,blur,format,background,\
                               white_error,centre_error_x,centre_error_y,radius_error\n";

fn capture_row(path: &str, s: &CaptureSettings) -> String {
    let numbers = |values: &[f64]| values.iter().map(|&v| format_f64(v)).collect::<Vec<_>>();
    let head = numbers(&[s.radius, s.exposure, s.noise, s.shot_share, s.blur]);
    let tail = numbers(&[
        s.background,
        s.white_error,
        s.centre_error[0],
        s.centre_error[1],
        s.radius_error,
    ]);
    format!(
        "{path},{},{},{}\n",
        head.join(","),
        s.quantization,
        tail.join(",")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_option_out_of_range_is_refused_in_its_own_words() {
        let quality = Quality::default();
        let check = |size, augment: Augment| check_options(size, &quality, &augment);
        assert_eq!(check(256, Augment::default()), Ok(()));
        let cases = [
            (check(8, Augment::default()), "size 8 must be between 71"),
            (
                check(
                    256,
                    Augment {
                        captures: MAX_CAPTURES + 1,
                        ..Augment::default()
                    },
                ),
                "captures must be at most 64",
            ),
            (
                check(
                    256,
                    Augment {
                        reductions: vec![1],
                        ..Augment::default()
                    },
                ),
                "give reductions within 2…16",
            ),
            (
                check(
                    256,
                    Augment {
                        rotations: 361,
                        ..Augment::default()
                    },
                ),
                "rotations must be at most 360",
            ),
        ];
        for (refused, words) in cases {
            let message = refused.unwrap_err().to_string();
            assert!(message.starts_with(words), "{message}");
        }
    }

    #[test]
    fn the_view_count_does_not_need_the_map() {
        let augment = Augment {
            rotations: 3,
            elevations: vec![30.0, 60.0],
            contrasts: vec![0.7],
            reductions: vec![2, 4],
            ..Augment::default()
        };
        for width in [1, 64, 1000] {
            assert_eq!(variants(&augment, width).len(), augment.views());
        }
        assert_eq!(variants(&Augment::default(), 64).len(), 1);
    }
}
