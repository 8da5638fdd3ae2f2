//! Normal maps, and the equivalent sphere of an object of known shape (issue #44).
//!
//! Under distant light and a distant viewer the light leaving a surface point depends on its
//! normal, not on where the point is. So each pixel of an object whose camera-space normals
//! are known has a place on an *equivalent sphere*: the sphere point with the same normal
//! (Dror, Adelson & Willsky, *Recognition of surface reflectance properties from a single
//! image under unknown real-world illumination*, 2001). The cells of that sphere no pixel
//! reaches are missing.
//!
//! Conventions: +X right, +Y up (image up), +Z toward the camera. A PNG stores
//! n = 2v / max − 1 per channel (8 or 16 bits); (0, 0, 0) or alpha 0 is background.

use super::blocks::{Blocks, Border};
use super::footprint::Footprint;
use super::occlusion;
use crate::decode::{DecodeError, Limits, exr_file};
use crate::image::circle::Circle;
use ndarray::Array2;
use std::io::Cursor;

/// A normal may differ from unit length by this much before it is refused as not a normal
/// (8-bit quantization moves a unit normal's length by less than 0.01).
pub const UNIT_TOLERANCE: f32 = 0.1;
/// The fraction of object pixels that may fail [`UNIT_TOLERANCE`] (stray pixels of a mixed
/// edge) before the map is refused.
pub const MAX_NOT_UNIT: f64 = 0.01;
/// Neighbouring object pixels whose normals differ by more than this angle (degrees) lie
/// across a depth edge or a crease; their colours mix two surfaces, so neither is mapped.
pub const EDGE_ANGLE_DEG: f32 = 25.0;

/// Camera-space unit normals per pixel; the zero vector marks background.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    normals: Array2<[f32; 3]>,
    /// Object pixels whose normal faced away from the camera (z < 0): counted, then made
    /// background.
    back_facing: usize,
}

/// What is wrong with a normal map, in words that say what to fix.
#[derive(Debug, thiserror::Error)]
pub enum NormalsError {
    /// The bytes are not a PNG image this decoder reads.
    #[error("the normal map does not decode as a PNG image (give a PNG or an OpenEXR file): {0}")]
    NotPng(#[source] image::ImageError),
    /// The map does not decode (an EXR's error), or is larger than the limits.
    #[error("the normal map: {0}")]
    Decode(#[from] DecodeError),
    /// An EXR normal map without its three channels.
    #[error(
        "the EXR normal map has no R, G and B channels: store the normal's X, Y, Z as float R, G, B"
    )]
    NoXyz,
    /// The map's size differs from the photograph's.
    #[error(
        "the normal map is {found_w}×{found_h} but the photograph is {want_w}×{want_h}: give a map of the photograph's size"
    )]
    Size {
        /// The map's width (px).
        found_w: usize,
        /// The map's height (px).
        found_h: usize,
        /// The photograph's width (px).
        want_w: usize,
        /// The photograph's height (px).
        want_h: usize,
    },
    /// Too many pixels are not unit vectors.
    #[error(
        "{count} of {object} normals ({percent:.1} %) are not unit length within {UNIT_TOLERANCE}: \
         give camera-space unit normals stored as n = 2v/max − 1 (background (0, 0, 0) or alpha 0)"
    )]
    NotUnit {
        /// Pixels off unit length.
        count: usize,
        /// Object pixels.
        object: usize,
        /// 100 · count / object.
        percent: f64,
    },
    /// No pixel is object.
    #[error(
        "the normal map has no object pixel facing the camera (all background, masked or z < 0)"
    )]
    Empty,
    /// Every object pixel is a saddle or a hollow, or in the object's own shadow.
    #[error(
        "the object is not convex anywhere it shows (a hollow or a saddle) or hides its own sky \
         there: it shadows and lights itself, and its light is not a sphere's; photograph a \
         convex, open part of it"
    )]
    NotConvex,
}

impl NormalMap {
    /// Decode a normal map file, PNG or OpenEXR (told by their signatures), within `limits`.
    pub fn decode(bytes: &[u8], limits: &Limits) -> Result<NormalMap, NormalsError> {
        const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
        match bytes.starts_with(&EXR_MAGIC) {
            true => NormalMap::from_exr(bytes, limits),
            false => NormalMap::from_png(bytes, limits),
        }
    }

    /// Decode a PNG normal map (8 or 16 bits, RGB or RGBA), within `limits`.
    pub fn from_png(bytes: &[u8], limits: &Limits) -> Result<NormalMap, NormalsError> {
        use image::ImageDecoder;
        let decoder = image::codecs::png::PngDecoder::new(Cursor::new(bytes))
            .map_err(NormalsError::NotPng)?;
        let (w, h) = decoder.dimensions();
        limits.check(u64::from(w), u64::from(h))?;
        let rgba = image::DynamicImage::from_decoder(decoder)
            .map_err(NormalsError::NotPng)?
            .into_rgba16();
        let (w, h) = (w as usize, h as usize);
        let mut samples = Array2::from_elem((h, w), [0.0f32; 4]);
        for (cell, pixel) in samples.iter_mut().zip(rgba.pixels()) {
            let v = pixel.0.map(|c| f32::from(c) / 65535.0);
            *cell = v;
        }
        NormalMap::from_encoded(&samples)
    }

    /// Decode an OpenEXR normal map: float R, G, B are the normal's X, Y, Z (the zero vector
    /// is background; an A channel of 0 too), within `limits`.
    pub fn from_exr(bytes: &[u8], limits: &Limits) -> Result<NormalMap, NormalsError> {
        let layer = exr_file::read_channels(bytes, limits)?;
        let (Some(x), Some(y), Some(z)) = (layer.get("R"), layer.get("G"), layer.get("B")) else {
            return Err(NormalsError::NoXyz);
        };
        let alpha = layer.get("A");
        let normals = Array2::from_shape_fn((layer.height, layer.width), |(row, col)| {
            let i = row * layer.width + col;
            match alpha.is_some_and(|a| a[i] == 0.0) {
                true => [0.0; 3],
                false => [x[i], y[i], z[i]],
            }
        });
        NormalMap::from_vectors(normals)
    }

    /// Normals from encoded samples v ∈ [0, 1] per channel (RGBA): n = 2v − 1; black or
    /// transparent is background.
    pub fn from_encoded(samples: &Array2<[f32; 4]>) -> Result<NormalMap, NormalsError> {
        let normals = samples.mapv(|[r, g, b, a]| {
            if a == 0.0 || (r == 0.0 && g == 0.0 && b == 0.0) {
                [0.0; 3]
            } else {
                [2.0 * r - 1.0, 2.0 * g - 1.0, 2.0 * b - 1.0]
            }
        });
        NormalMap::from_vectors(normals)
    }

    /// Normals from vectors (the zero vector: background): checked for unit length,
    /// normalized, back-facing ones counted and dropped.
    pub fn from_vectors(mut normals: Array2<[f32; 3]>) -> Result<NormalMap, NormalsError> {
        let (mut object, mut not_unit, mut back_facing) = (0usize, 0usize, 0usize);
        for n in normals.iter_mut() {
            let length = n.iter().map(|c| c * c).sum::<f32>().sqrt();
            if length == 0.0 {
                continue;
            }
            object += 1;
            if !length.is_finite() || (length - 1.0).abs() > UNIT_TOLERANCE {
                not_unit += 1;
                *n = [0.0; 3];
                continue;
            }
            *n = n.map(|c| c / length);
            if n[2] < 0.0 {
                back_facing += 1;
                *n = [0.0; 3];
            }
        }
        if not_unit as f64 > MAX_NOT_UNIT * object as f64 {
            return Err(NormalsError::NotUnit {
                count: not_unit,
                object,
                percent: 100.0 * not_unit as f64 / object as f64,
            });
        }
        if object == back_facing + not_unit {
            return Err(NormalsError::Empty);
        }
        Ok(NormalMap {
            normals,
            back_facing,
        })
    }

    /// Width (px).
    pub fn width(&self) -> usize {
        self.normals.ncols()
    }

    /// Height (px).
    pub fn height(&self) -> usize {
        self.normals.nrows()
    }

    /// Object pixels whose normal faced away from the camera, ignored.
    pub fn back_facing(&self) -> usize {
        self.back_facing
    }

    /// The unit normal at (row, column), `None` for background.
    pub fn at(&self, row: usize, col: usize) -> Option<[f32; 3]> {
        let n = *self.normals.get((row, col))?;
        (!is_background(&n)).then_some(n)
    }

    /// Whether the map fits a photograph of `width` × `height`.
    pub fn check_size(&self, width: usize, height: usize) -> Result<(), NormalsError> {
        if (self.width(), self.height()) == (width, height) {
            return Ok(());
        }
        Err(NormalsError::Size {
            found_w: self.width(),
            found_h: self.height(),
            want_w: width,
            want_h: height,
        })
    }
}

/// The equivalent sphere's image spans this many radii each side of its centre.
const MARGIN: f64 = 1.35;

/// Passes of [`fill_holes`]: pixels sparser than the sphere's cells leave gaps of a cell or
/// two between the cells they reach.
const FILL_PASSES: usize = 2;

/// A missing cell with at least this many observed cells among its eight neighbours is
/// a gap between observed cells, not outside them (a cell beside a straight edge of an
/// observed region has three).
const FILL_NEIGHBOURS: usize = 5;

/// Fill the missing cells of the disc that lie between observed ones with the mean of their
/// observed neighbours (one pass: cells filled in it do not count as neighbours).
fn fill_holes(luminance: &mut Array2<f64>, observed: &mut Array2<bool>, centre: f64, r: f64) {
    let (h, w) = observed.dim();
    let mut filled = Vec::new();
    for row in 1..h.saturating_sub(1) {
        for col in 1..w.saturating_sub(1) {
            let (dx, dy) = (col as f64 - centre, row as f64 - centre);
            if observed[(row, col)] || dx * dx + dy * dy > r * r {
                continue;
            }
            let (mut n, mut sum) = (0usize, 0.0);
            for (y, x) in (row - 1..=row + 1).flat_map(|y| (col - 1..=col + 1).map(move |x| (y, x)))
            {
                if observed[(y, x)] {
                    n += 1;
                    sum += luminance[(y, x)];
                }
            }
            if n >= FILL_NEIGHBOURS {
                filled.push((row, col, sum / n as f64));
            }
        }
    }
    for (row, col, v) in filled {
        luminance[(row, col)] = v;
        observed[(row, col)] = true;
    }
}

/// Pixels each side over which the normal field's turn is taken to judge convexity: wider
/// than a pixel, so that what is left of the normals' noise after smoothing does not decide.
const CONVEXITY_REACH: usize = 3;

/// A pixel is not convex when its normal turns against the surface's curvature along some
/// direction by more than this share of how it turns along the other.
const CONVEXITY_TOLERANCE: f64 = 0.25;

/// A turn against the curvature of less than this many cells over the reach is no turn: a
/// flat face's normals differ by their rounding.
const CONVEXITY_FLOOR: f64 = 0.05;

/// Whether the surface at the inner pixel `i` is convex, judged by how its normal's sphere
/// position (`place`) moves with the pixel. On a convex surface it moves the way the pixel
/// does, in every direction (the Gauss map's derivative, symmetrized, is positive definite);
/// at a saddle it moves against it along one direction, in a hollow along every one. Such a
/// point sees its own surface: it is shadowed and lit by the object itself, and its light is
/// not that of the sphere point with its normal (design.md §8, "Objects of any shape").
fn convex(
    map: &[[f32; 3]],
    picture: &Picture,
    i: usize,
    place: impl Fn(&[f32; 3]) -> [f64; 2],
) -> bool {
    let (w, h) = (picture.w, picture.h);
    let (row, col) = (i / w, i % w);
    // The widest reach whose four neighbours are on the object (at 1, [`on_edge`] ensured it).
    let Some(d) = (1..=CONVEXITY_REACH).rev().find(|&d| {
        row >= d
            && col >= d
            && row + d < h
            && col + d < w
            && [i - d, i + d, i - d * w, i + d * w]
                .iter()
                .all(|&j| !is_background(&map[j]))
    }) else {
        return true;
    };
    let turn = |a: usize, b: usize| {
        let (p, q) = (place(&map[a]), place(&map[b]));
        [q[0] - p[0], q[1] - p[1]]
    };
    let (across, down) = (turn(i - d, i + d), turn(i - d * w, i + d * w));
    // The symmetric part of [across down] and its eigenvalues.
    let mean = 0.5 * (across[0] + down[1]);
    let spread = (0.5 * (across[0] - down[1])).hypot(0.5 * (across[1] + down[0]));
    let (low, high) = (mean - spread, mean + spread);
    low >= 0.0 || low.abs() <= (CONVEXITY_TOLERANCE * high.abs()).max(CONVEXITY_FLOOR)
}

/// Whether a normal is background.
fn is_background(n: &[f32; 3]) -> bool {
    *n == [0.0; 3]
}

/// Whether pixel `i` of a normal map is the object's: a normal, inside the mask if any.
fn is_object(raw: &[[f32; 3]], keep: Option<&[bool]>, i: usize) -> bool {
    !is_background(&raw[i]) && keep.is_none_or(|k| k[i])
}

/// The most a photograph and its normals are reduced by before mapping.
const MAX_REDUCTION: usize = 16;

/// Fewest pixel steps [`reduction`] reads before it reduces.
const MIN_STEPS: usize = 64;

/// The fewest pixels across the longer side a reduced photograph keeps: its shape (edges,
/// its own shadows) stays resolved when most of it is flat and its median turn is 0.
const MIN_REDUCED_SIDE: usize = 128;

/// The median of `turns` weighted by the sphere's area each covers (turn²): the turn of the
/// pixels that cover the median cell, where most pixels may sit on flat faces that cover few
/// cells. Sorts `turns`.
fn area_median(turns: &mut [f64]) -> f64 {
    turns.sort_unstable_by(f64::total_cmp);
    let half = turns.iter().map(|t| t * t).sum::<f64>() / 2.0;
    let mut covered = 0.0;
    for &t in turns.iter() {
        covered += t * t;
        if covered >= half {
            return t;
        }
    }
    0.0
}

/// How a photograph is reduced before mapping: by `blocks`×`blocks` block means, then by
/// `factor` with area weights.
struct Reduction {
    blocks: usize,
    factor: f64,
}

/// How a photograph whose normals turn slowly from pixel to pixel is reduced before
/// mapping, judged by the median turn per pixel in cells of the sphere (read on every 7th
/// row and column). Block means first, by ⌊1 / turn⌋ within 1 ..= [`MAX_REDUCTION`]: a 12 MP
/// photograph of a large object turns its normals by a tenth of a cell per pixel, and the
/// mapping then reads a hundredth of the pixels. Then area weights, by what is left of
/// turn·blocks < 1 ([`area_median`]'s turn), so that the pixels at the median cell move by
/// one cell, as a sphere's photograph is
/// brought to the working radius before its unwrap (the finest bands read the resampling:
/// a sphere given by its normals is then reduced as by its circle). Either keeps
/// [`MIN_REDUCED_SIDE`].
fn reduction(
    raw: &[[f32; 3]],
    keep: Option<&[bool]>,
    w: usize,
    h: usize,
    radius: f64,
) -> Reduction {
    let none = Reduction {
        blocks: 1,
        factor: 1.0,
    };
    let kept = |i: usize| is_object(raw, keep, i);
    let mut steps = Vec::new();
    for row in (0..h).step_by(7) {
        for col in (0..w.saturating_sub(1)).step_by(7) {
            let i = row * w + col;
            if kept(i) && kept(i + 1) {
                let (a, b) = (raw[i], raw[i + 1]);
                let d = f64::from((a[0] - b[0]).hypot(a[1] - b[1]));
                steps.push(d * radius);
            }
        }
    }
    if steps.len() < MIN_STEPS {
        return none;
    }
    let middle = steps.len() / 2;
    let (_, median, _) = steps.select_nth_unstable_by(middle, f64::total_cmp);
    let median = *median;
    let most = (w.max(h) / MIN_REDUCED_SIDE).clamp(1, MAX_REDUCTION);
    let blocks = match median > 0.0 {
        true => ((1.0 / median).floor() as usize).clamp(1, most),
        false => most,
    };
    let least = (MIN_REDUCED_SIDE as f64 / (w.max(h) / blocks) as f64).min(1.0);
    let factor = (area_median(&mut steps) * blocks as f64).clamp(least, 1.0);
    Reduction {
        blocks,
        // As a sphere within 1 % of the working radius is not resampled.
        factor: if factor * 1.01 >= 1.0 { 1.0 } else { factor },
    }
}

/// Pixels each side of a normal that its smoothing averages.
const SMOOTH_REACH: usize = 2;

/// Neighbours whose normals are within this angle of a pixel's are averaged with it: the
/// same surface, noisy; beyond it, across a crease.
const SMOOTH_CONE_DEG: f32 = 60.0;

/// The normals of a `w`×`h` row-major map, each averaged with those of the same surface
/// around it (within [`SMOOTH_REACH`] pixels and [`SMOOTH_CONE_DEG`]) and renormalized.
/// Measured normals scatter pixel by pixel (a depth camera's, a network's; 8-bit files round
/// them), and a normal off by 5° lands 10 cells away on a sphere of radius 116: the smooth
/// normal field of the surface places its pixels, as the geometry does for a sphere.
fn smoothed(map: &[[f32; 3]], w: usize, h: usize) -> Vec<[f32; 3]> {
    let cos_cone = SMOOTH_CONE_DEG.to_radians().cos();
    let mut out = map.to_vec();
    for row in 0..h {
        let rows = row.saturating_sub(SMOOTH_REACH)..(row + SMOOTH_REACH + 1).min(h);
        for col in 0..w {
            let n = map[row * w + col];
            if is_background(&n) {
                continue;
            }
            let cols = col.saturating_sub(SMOOTH_REACH)..(col + SMOOTH_REACH + 1).min(w);
            let mut sum = [0.0f32; 3];
            for m in rows
                .clone()
                .flat_map(|r| map[r * w + cols.start..r * w + cols.end].iter())
            {
                if !is_background(m) && n[0] * m[0] + n[1] * m[1] + n[2] * m[2] >= cos_cone {
                    sum = [sum[0] + m[0], sum[1] + m[1], sum[2] + m[2]];
                }
            }
            let length = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
            if length > 0.0 {
                out[row * w + col] = sum.map(|c| c / length);
            }
        }
    }
    out
}

/// Whether the inner pixel `i` of a `w`-wide row-major map lies across a depth edge or
/// crease from a neighbour, or beside background (a silhouette pixel mixes the object with
/// what is behind it).
fn on_edge(map: &[[f32; 3]], w: usize, i: usize, cos_edge: f32) -> bool {
    let n = map[i];
    [map[i - 1], map[i + 1], map[i - w], map[i + w]]
        .iter()
        .any(|m| is_background(m) || n[0] * m[0] + n[1] * m[1] + n[2] * m[2] < cos_edge)
}

/// An object's photograph seen as a sphere: luminance at the sphere position of each
/// object pixel's normal, averaged per cell, and which cells some pixel reached.
#[derive(Clone, Debug)]
pub struct EquivalentSphere {
    /// The sphere's luminance (0 where not observed); the image is square.
    pub luminance: Array2<f64>,
    /// Cells some object pixel reached.
    pub observed: Array2<bool>,
    /// The sphere in `luminance`'s pixels.
    pub circle: Circle,
    /// The fraction of the sphere's disc observed, in [0, 1].
    pub fraction: f64,
    /// How far the given normals of the mapped pixels stray from their smoothed field: the
    /// RMS angle, in degrees (about 0 for exact geometry).
    pub scatter_deg: f64,
    /// The share of the object's pixels (away from edges) left out because the surface there
    /// is not convex ([`convex`]), in [0, 1].
    pub not_convex_fraction: f64,
    /// The share of the object's pixels (away from edges) left out because, convex, they are
    /// in the object's own shadow: the object hides more than a tenth of their sky
    /// ([`occlusion`]), in [0, 1].
    pub shadowed_fraction: f64,
    /// Every mapped pixel's footprint on the sphere (in `luminance`'s pixels) and its
    /// luminance: what the unwrap resamples once, as it does a sphere's photograph.
    pub footprints: Vec<(Footprint, f64)>,
}

impl EquivalentSphere {
    /// The luminance with the disc's missing cells set to the mean of its observed ones
    /// (outside the disc: 0, a sphere on black).
    pub fn filled(&self) -> Array2<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for (&v, _) in self
            .luminance
            .iter()
            .zip(&self.observed)
            .filter(|(_, o)| **o)
        {
            sum += v;
            n += 1;
        }
        let mean = sum / n.max(1) as f64;
        let Circle { cx, cy, r } = self.circle;
        let mut filled = self.luminance.clone();
        for ((row, col), v) in filled.indexed_iter_mut() {
            let (dx, dy) = (col as f64 - cx, row as f64 - cy);
            if !self.observed[(row, col)] && dx * dx + dy * dy <= r * r {
                *v = mean;
            }
        }
        filled
    }
}

/// The photograph as the mapping reads it when [`reduction`] reduces it (`None`: as it is).
fn reduced(
    raw: &[[f32; 3]],
    values: &[f64],
    keep: Option<&[bool]>,
    (w, h): (usize, usize),
    radius: f64,
) -> Option<Blocks> {
    let Reduction { blocks, factor } = reduction(raw, keep, w, h, radius);
    let object = |i: usize| is_object(raw, keep, i);
    match (blocks > 1, factor < 1.0) {
        (false, false) => None,
        (true, false) => Some(Blocks::of(
            raw,
            Some(values),
            object,
            (w, h),
            blocks,
            Border::Drop,
        )),
        (false, true) => Some(Blocks::by_area(raw, values, object, (w, h), factor)),
        (true, true) => {
            let b = Blocks::of(raw, Some(values), object, (w, h), blocks, Border::Drop);
            let object = |i: usize| b.object[i];
            Some(Blocks::by_area(
                &b.normals,
                &b.values,
                object,
                (b.w, b.h),
                factor,
            ))
        }
    }
}

/// The equivalent sphere of radius `radius` (px) of a photograph's `luminance` and its
/// normals, over the pixels `mask` keeps (all object pixels when `None`). Pixels across
/// depth edges, creases and silhouettes are left out ([`EDGE_ANGLE_DEG`]).
pub fn equivalent_sphere(
    luminance: &Array2<f64>,
    normals: &NormalMap,
    mask: Option<&Array2<bool>>,
    radius: f64,
) -> Result<EquivalentSphere, NormalsError> {
    let (h, w) = luminance.dim();
    normals.check_size(w, h)?;
    if let Some(m) = mask
        && m.dim() != (h, w)
    {
        return Err(NormalsError::Size {
            found_w: m.ncols(),
            found_h: m.nrows(),
            want_w: w,
            want_h: h,
        });
    }
    // A margin of a third of the radius around the disc, for the outline's rays.
    let side = 2 * (MARGIN * radius).ceil() as usize + 3;
    let centre = (side - 1) as f64 / 2.0;
    let raw = normals.normals.as_standard_layout();
    let raw = raw.as_slice().unwrap_or_default();
    let luminance = luminance.as_standard_layout();
    let values = luminance.as_slice().unwrap_or_default();
    let keep = mask.map(|m| m.as_standard_layout());
    let keep = keep.as_ref().and_then(|m| m.as_slice());
    let small = reduced(raw, values, keep, (w, h), radius);
    let picture = match &small {
        Some(small) => Picture {
            raw: &small.normals,
            values: &small.values,
            keep: None,
            w: small.w,
            h: small.h,
        },
        None => Picture {
            raw,
            values,
            keep,
            w,
            h,
        },
    };
    let splat = Splat::of(&picture, side, radius);
    let mut observed = splat.weight.mapv(|w| w > 0.0);
    let mut luminance = ndarray::Zip::from(&splat.sum)
        .and(&splat.weight)
        .map_collect(|&s, &w| if w > 0.0 { s / w } else { 0.0 });
    for _ in 0..FILL_PASSES {
        fill_holes(&mut luminance, &mut observed, centre, radius);
    }
    let (mut disc, mut seen) = (0usize, 0usize);
    for ((row, col), &o) in observed.indexed_iter() {
        let (dx, dy) = (col as f64 - centre, row as f64 - centre);
        if dx * dx + dy * dy <= radius * radius {
            disc += 1;
            seen += usize::from(o);
        }
    }
    if seen == 0 {
        return Err(if splat.not_convex + splat.shadowed > 0 {
            NormalsError::NotConvex
        } else {
            NormalsError::Empty
        });
    }
    Ok(EquivalentSphere {
        luminance,
        observed,
        circle: Circle {
            cx: centre,
            cy: centre,
            r: radius,
        },
        fraction: seen as f64 / disc.max(1) as f64,
        not_convex_fraction: splat.not_convex as f64 / splat.judged().max(1) as f64,
        shadowed_fraction: splat.shadowed as f64 / splat.judged().max(1) as f64,
        scatter_deg: (splat.scatter / splat.judged().max(1) as f64)
            .sqrt()
            .to_degrees(),
        footprints: splat.footprints,
    })
}

/// A photograph's luminance and normals, row-major, and the pixels kept (all object pixels
/// when `None`).
struct Picture<'a> {
    raw: &'a [[f32; 3]],
    values: &'a [f64],
    keep: Option<&'a [bool]>,
    w: usize,
    h: usize,
}

/// The pixels of a picture spread over the equivalent sphere's grid.
struct Splat {
    /// Σ weight · luminance per cell.
    sum: Array2<f64>,
    /// Σ weight per cell.
    weight: Array2<f64>,
    /// Σ squared angles (rad²) between the given and the smoothed normals of mapped pixels.
    scatter: f64,
    /// The mapped pixels' footprints and luminances.
    footprints: Vec<(Footprint, f64)>,
    /// Pixels left out as saddles or hollows.
    not_convex: usize,
    /// Convex pixels left out in the object's own shadow.
    shadowed: usize,
}

impl Splat {
    /// Every kept pixel away from edges spread by its [`Footprint`] over a `side`² grid of a
    /// sphere of `radius` cells, placed by its smoothed normal.
    fn of(picture: &Picture, side: usize, radius: f64) -> Splat {
        let Picture {
            raw,
            values,
            keep,
            w,
            h,
        } = *picture;
        let centre = (side - 1) as f64 / 2.0;
        let cos_edge = EDGE_ANGLE_DEG.to_radians().cos();
        let map = &smoothed(raw, w, h);
        let object: Vec<bool> = map.iter().map(|n| !is_background(n)).collect();
        let in_shadow = occlusion::in_own_shadow(map, &object, w, h);
        let (mut sum, mut weight) = (vec![0.0; side * side], vec![0.0; side * side]);
        let (mut scatter, mut not_convex, mut shadowed) = (0.0f64, 0, 0);
        let mut footprints = Vec::new();
        let place = |n: &[f32; 3]| {
            [
                centre + radius * f64::from(n[0]),
                centre - radius * f64::from(n[1]),
            ]
        };
        // The border rows and columns are edges; each inner pixel is read with its neighbours.
        for row in 1..h.saturating_sub(1) {
            for col in 1..w.saturating_sub(1) {
                let i = row * w + col;
                let n = &map[i];
                if is_background(n) || keep.is_some_and(|k| !k[i]) || on_edge(map, w, i, cos_edge) {
                    continue;
                }
                let cos = raw[i].iter().zip(n).map(|(a, b)| a * b).sum::<f32>();
                scatter += f64::from(cos.clamp(-1.0, 1.0).acos()).powi(2);
                if !convex(map, picture, i, place) {
                    not_convex += 1;
                    continue;
                }
                if in_shadow[i] {
                    shadowed += 1;
                    continue;
                }
                // Half the step to each neighbour: the pixel's footprint on the sphere.
                let half = |a: usize, b: usize| {
                    let (p, q) = (place(&map[a]), place(&map[b]));
                    [(q[0] - p[0]) / 4.0, (q[1] - p[1]) / 4.0]
                };
                let footprint = Footprint {
                    at: place(n),
                    across: half(i - 1, i + 1),
                    down: half(i - w, i + w),
                };
                footprint.cover(side, |cell, wt| {
                    sum[cell] += wt * values[i];
                    weight[cell] += wt;
                });
                footprints.push((footprint, values[i]));
            }
        }
        let grid = |v: Vec<f64>| Array2::from_shape_vec((side, side), v).unwrap_or_default();
        Splat {
            sum: grid(sum),
            weight: grid(weight),
            scatter,
            footprints,
            not_convex,
            shadowed,
        }
    }

    /// Pixels judged: mapped or left out as not convex or in shadow.
    fn judged(&self) -> usize {
        self.footprints.len() + self.not_convex + self.shadowed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camera-space normal of a sphere of radius `r` centred at (c, c) at a pixel, if
    /// the pixel is on it.
    fn sphere_normal(row: usize, col: usize, c: f64, r: f64) -> Option<[f32; 3]> {
        let (x, y) = ((col as f64 - c) / r, (c - row as f64) / r);
        let z2 = 1.0 - x * x - y * y;
        (z2 > 0.0).then(|| [x as f32, y as f32, z2.sqrt() as f32])
    }

    fn sphere(side: usize, r: f64) -> (Array2<f64>, NormalMap) {
        let c = (side - 1) as f64 / 2.0;
        let normals = Array2::from_shape_fn((side, side), |(row, col)| {
            sphere_normal(row, col, c, r).unwrap_or([0.0; 3])
        });
        // Shading that depends on the normal only: a light from the upper left.
        let luminance =
            normals.mapv(|n| f64::from((0.3 * n[0] + 0.5 * n[1] + 0.8 * n[2]).max(0.0)));
        (luminance, NormalMap::from_vectors(normals).unwrap())
    }

    #[test]
    fn a_sphere_is_its_own_equivalent_sphere() {
        let (luminance, normals) = sphere(121, 50.0);
        let eq = equivalent_sphere(&luminance, &normals, None, 50.0).unwrap();
        assert!(eq.fraction > 0.93, "{}", eq.fraction);
        let c = eq.circle.cx;
        let mut worst = 0.0f64;
        for ((row, col), &v) in eq.luminance.indexed_iter() {
            let Some(n) = sphere_normal(row, col, c, 50.0) else {
                continue;
            };
            if eq.observed[(row, col)] && n[2] > 0.3 {
                let want = f64::from((0.3 * n[0] + 0.5 * n[1] + 0.8 * n[2]).max(0.0));
                worst = worst.max((v - want).abs());
            }
        }
        assert!(worst < 0.02, "{worst}");
    }

    /// A `side`² height field z(x, y) (x right, y up, in units of the half side) seen from
    /// above: its normals, and a luminance of 1.
    fn surface(side: usize, z: impl Fn(f64, f64) -> (f64, f64)) -> (Array2<f64>, NormalMap) {
        let half = (side - 1) as f64 / 2.0;
        let normals = Array2::from_shape_fn((side, side), |(row, col)| {
            let (x, y) = ((col as f64 - half) / half, (half - row as f64) / half);
            // z's slopes (∂z/∂x, ∂z/∂y); the normal is (−∂z/∂x, −∂z/∂y, 1), normalized.
            let (zx, zy) = z(x, y);
            let length = (zx * zx + zy * zy + 1.0).sqrt();
            [
                (-zx / length) as f32,
                (-zy / length) as f32,
                (1.0 / length) as f32,
            ]
        });
        let normals = NormalMap::from_vectors(normals).unwrap();
        (Array2::from_elem((side, side), 1.0), normals)
    }

    #[test]
    fn saddles_and_hollows_are_left_out_and_domes_kept() {
        let dome = surface(81, |x, y| (-0.8 * x, -0.8 * y));
        let eq = equivalent_sphere(&dome.0, &dome.1, None, 50.0).unwrap();
        assert!(eq.not_convex_fraction < 0.01, "{}", eq.not_convex_fraction);
        assert_eq!(eq.shadowed_fraction, 0.0);
        // A cylinder (curved across, straight along): convex, though not strictly.
        let cylinder = surface(81, |x, _| (-0.8 * x, 0.0));
        let eq = equivalent_sphere(&cylinder.0, &cylinder.1, None, 50.0).unwrap();
        assert!(eq.not_convex_fraction < 0.01, "{}", eq.not_convex_fraction);
        let saddle = surface(81, |x, y| (0.8 * x, -0.8 * y));
        let e = equivalent_sphere(&saddle.0, &saddle.1, None, 50.0).unwrap_err();
        assert!(matches!(e, NormalsError::NotConvex), "{e}");
        let bowl = surface(81, |x, y| (0.8 * x, 0.8 * y));
        let e = equivalent_sphere(&bowl.0, &bowl.1, None, 50.0).unwrap_err();
        assert!(e.to_string().contains("not convex"), "{e}");
        // A dome with a dimple: the dimple's pixels (and only about those) are left out.
        let dimple = |x: f64, y: f64| {
            let g = 0.9 * (-(x * x + y * y) / 0.08).exp();
            (
                -0.8 * x + 2.0 * x / 0.08 * g * 0.15,
                -0.8 * y + 2.0 * y / 0.08 * g * 0.15,
            )
        };
        let dimpled = surface(81, dimple);
        let eq = equivalent_sphere(&dimpled.0, &dimpled.1, None, 50.0).unwrap();
        assert!(
            (0.02..0.3).contains(&eq.not_convex_fraction),
            "{}",
            eq.not_convex_fraction
        );
    }

    #[test]
    fn a_table_in_a_balls_shadow_is_left_out() {
        // A ball of radius 0.4 (half sides) on a table, seen from above.
        let ball_on_table = |x: f64, y: f64| {
            let z2 = 0.16 - x * x - y * y;
            match z2 > 0.0 {
                true => (-x / z2.sqrt(), -y / z2.sqrt()),
                false => (0.0, 0.0),
            }
        };
        let (luminance, normals) = surface(121, ball_on_table);
        let eq = equivalent_sphere(&luminance, &normals, None, 50.0).unwrap();
        // The ring of table where the ball hides more than a tenth of the sky (out to about
        // 1.3 radii, design.md §8), against the table and the ball: about a tenth.
        assert!(
            (0.04..0.2).contains(&eq.shadowed_fraction),
            "{}",
            eq.shadowed_fraction
        );
        // The table's middle is what the ball's top sees: both kept.
        assert!(eq.observed[(eq.circle.cy as usize, eq.circle.cx as usize)]);
    }

    #[test]
    fn a_half_seen_object_observes_half_the_sphere() {
        let (luminance, normals) = sphere(121, 50.0);
        let left = Array2::from_shape_fn((121, 121), |(_, col)| col < 60);
        let eq = equivalent_sphere(&luminance, &normals, Some(&left), 50.0).unwrap();
        assert!((eq.fraction - 0.47).abs() < 0.04, "{}", eq.fraction);
        assert!(eq.observed[(60, 30)] && !eq.observed[(60, 90)]);
    }

    #[test]
    fn normals_map_by_direction_not_position() {
        // A flat face turned toward the upper right: every pixel lands on one point, spread
        // bilinearly over the cells around it.
        let n = [0.5f32, 0.5, 0.5f32.sqrt()];
        let normals = Array2::from_elem((40, 40), n);
        let luminance = Array2::from_elem((40, 40), 0.7);
        let normals = NormalMap::from_vectors(normals).unwrap();
        let eq = equivalent_sphere(&luminance, &normals, None, 50.0).unwrap();
        let cells: Vec<((usize, usize), f64)> = eq
            .luminance
            .indexed_iter()
            .filter(|(at, _)| eq.observed[*at])
            .map(|(at, &v)| (at, v))
            .collect();
        assert!((1..=4).contains(&cells.len()), "{cells:?}");
        let c = eq.circle.cx;
        for ((row, col), v) in cells {
            assert!((col as f64 - (c + 25.0)).abs() <= 1.0, "{col}");
            assert!((row as f64 - (c - 25.0)).abs() <= 1.0, "{row}");
            assert!((v - 0.7).abs() < 1e-12, "{v}");
        }
        assert!(eq.fraction < 0.001);
    }

    #[test]
    fn depth_edges_are_not_mapped() {
        // Two faces meeting at a crease: the columns on either side of it stay out.
        let normals = Array2::from_shape_fn((20, 20), |(_, col)| {
            if col < 10 {
                [-0.6f32, 0.0, 0.8]
            } else {
                [0.6, 0.0, 0.8]
            }
        });
        let luminance = Array2::from_shape_fn((20, 20), |(_, col)| col as f64);
        let normals = NormalMap::from_vectors(normals).unwrap();
        let eq = equivalent_sphere(&luminance, &normals, None, 50.0).unwrap();
        let c = eq.circle.cx;
        let left = eq.luminance[(c as usize, (c - 30.0).round() as usize)];
        let right = eq.luminance[(c as usize, (c + 30.0).round() as usize)];
        // Columns 1–8 (not 0, at the map's border, nor 9, at the crease) and 11–18.
        assert!((left - 4.5).abs() < 1e-9, "{left}");
        assert!((right - 14.5).abs() < 1e-9, "{right}");
    }

    #[test]
    fn bad_maps_are_refused_with_what_to_fix() {
        let (luminance, normals) = sphere(61, 25.0);
        let small = Array2::<f64>::zeros((60, 61));
        let e = equivalent_sphere(&small, &normals, None, 25.0).unwrap_err();
        assert!(
            e.to_string().contains("61×61 but the photograph is 61×60"),
            "{e}"
        );
        // Vectors of length 0.5: not normals.
        let half = Array2::from_elem((8, 8), [0.0f32, 0.0, 0.5]);
        let e = NormalMap::from_vectors(half).unwrap_err();
        assert!(
            matches!(
                e,
                NormalsError::NotUnit {
                    count: 64,
                    object: 64,
                    ..
                }
            ),
            "{e}"
        );
        // Back-facing normals are counted and ignored.
        let mut vectors = Array2::from_elem((8, 8), [0.0f32, 0.0, 1.0]);
        vectors[(0, 0)] = [0.0, 0.0, -1.0];
        let map = NormalMap::from_vectors(vectors).unwrap();
        assert_eq!(map.back_facing(), 1);
        assert_eq!(map.at(0, 0), None);
        let away = Array2::from_elem((4, 4), [0.0f32, 0.0, -1.0]);
        assert!(matches!(
            NormalMap::from_vectors(away),
            Err(NormalsError::Empty)
        ));
        let _ = luminance;
    }

    #[test]
    fn png_normal_maps_round_trip_at_8_and_16_bits() {
        let (_, normals) = sphere(41, 18.0);
        for sixteen in [false, true] {
            let max = if sixteen { 65535.0 } else { 255.0 };
            let encode = |c: f32| ((c + 1.0) / 2.0 * max).round();
            let mut bytes = Vec::new();
            let (w, h) = (41u32, 41u32);
            let samples: Vec<f32> = (0..41)
                .flat_map(|row| (0..41).map(move |col| (row, col)))
                .flat_map(|(row, col)| match normals.at(row, col) {
                    Some(n) => [encode(n[0]), encode(n[1]), encode(n[2])],
                    None => [0.0; 3],
                })
                .collect();
            let encoder = image::codecs::png::PngEncoder::new(&mut bytes);
            use image::ImageEncoder;
            if sixteen {
                let words: Vec<u8> = samples
                    .iter()
                    .flat_map(|&v| (v as u16).to_ne_bytes())
                    .collect();
                encoder
                    .write_image(&words, w, h, image::ExtendedColorType::Rgb16)
                    .unwrap();
            } else {
                let b: Vec<u8> = samples.iter().map(|&v| v as u8).collect();
                encoder
                    .write_image(&b, w, h, image::ExtendedColorType::Rgb8)
                    .unwrap();
            }
            let decoded = NormalMap::from_png(&bytes, &Limits::default()).unwrap();
            let mut worst = 0.0f32;
            for row in 0..41 {
                for col in 0..41 {
                    match (normals.at(row, col), decoded.at(row, col)) {
                        (Some(a), Some(b)) => {
                            let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
                            worst = worst.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
                        }
                        (None, None) => {}
                        other => panic!("({row}, {col}): {other:?}"),
                    }
                }
            }
            // f32 acos resolves about 0.03° near 0; 8 bits quantize to about 0.3°.
            let bound = if sixteen { 0.05 } else { 0.6 };
            assert!(worst < bound, "{sixteen}: {worst}°");
        }
        let e = NormalMap::from_png(b"not a png", &Limits::default()).unwrap_err();
        assert!(matches!(e, NormalsError::NotPng(_)));
    }

    /// An OpenEXR file of the normals of `map` (X, Y, Z as float R, G, B; zero background).
    fn exr_of(map: &NormalMap) -> Vec<u8> {
        use exr::prelude::*;
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let n = map.at(p.y(), p.x()).unwrap_or([0.0; 3]);
            (n[0], n[1], n[2])
        });
        let image = Image::from_channels((map.width(), map.height()), channels);
        let mut out = Cursor::new(Vec::new());
        image.write().to_buffered(&mut out).unwrap();
        out.into_inner()
    }

    #[test]
    fn exr_normal_maps_round_trip_and_say_what_is_wrong() {
        let (_, normals) = sphere(37, 16.0);
        let bytes = exr_of(&normals);
        let decoded = NormalMap::from_exr(&bytes, &Limits::default()).unwrap();
        assert_eq!((decoded.width(), decoded.height()), (37, 37));
        for row in 0..37 {
            for col in 0..37 {
                match (normals.at(row, col), decoded.at(row, col)) {
                    (Some(a), Some(b)) => {
                        assert!(
                            a.iter().zip(b).all(|(p, q)| (p - q).abs() < 1e-6),
                            "{a:?} {b:?}"
                        )
                    }
                    (None, None) => {}
                    other => panic!("({row}, {col}): {other:?}"),
                }
            }
        }
        let small = Limits {
            max_width: 36,
            ..Limits::default()
        };
        let e = NormalMap::from_exr(&bytes, &small).unwrap_err();
        assert!(
            matches!(e, NormalsError::Decode(DecodeError::TooLarge { .. })),
            "{e}"
        );
        let e = NormalMap::from_exr(&bytes[..bytes.len() / 2], &Limits::default()).unwrap_err();
        assert!(matches!(e, NormalsError::Decode(_)), "{e}");
        let grey = {
            use exr::prelude::*;
            let channels = SpecificChannels::build()
                .with_channel("Y")
                .with_pixel_fn(|_: Vec2<usize>| (0.5f32,));
            let mut out = Cursor::new(Vec::new());
            Image::from_channels((8, 8), channels)
                .write()
                .to_buffered(&mut out)
                .unwrap();
            out.into_inner()
        };
        let e = NormalMap::from_exr(&grey, &Limits::default()).unwrap_err();
        assert!(matches!(e, NormalsError::NoXyz), "{e}");
        assert!(e.to_string().contains("X, Y, Z as float R, G, B"), "{e}");
    }
}
