//! Objects other than the sphere, as camera-space normal maps (issue #44, "Training for it").
//!
//! A [`Shape`] in a [`Pose`] is scaled so that its bounding sphere is the sphere renderer's
//! unit sphere (it fits the sphere's circle, [`crate::circle`], whatever the pose) and
//! rasterized at N×N pixels with the sphere renderer's orthographic camera and pixel grid:
//! `samples²` stratified sub-pixel samples per pixel, the pixel's normal their normalized
//! mean and its coverage the fraction that hit. Analytic shapes are ray cast (exact normals
//! from the implicit function's gradient; the sphere by the renderer's own formula), meshes
//! by a z-buffer over the sub-pixel samples. Conventions of the core's normal maps
//! ([`reflectance_core::object::normals`]): +X right, +Y up (image up), +Z toward the camera;
//! background has no normal.
//!
//! [`crate::render_normals`] shades a map with the sphere's shader; [`Normals::to_png`]
//! writes it as the core reads it.

mod analytic;
mod mesh;
mod obj;
mod ply;
mod surface;

pub use analytic::{Ball, Blob};
pub use mesh::{CREASE_DEG, CornerNormals, Mesh, MeshLimits};
pub(crate) use surface::MapSurface;

use crate::{Grid, Vec3};
use reflectance_core::object::normals::NormalMap;
use reflectance_core::util::rng::Rng;
use std::path::{Path, PathBuf};

/// Why a shape could not be made or rasterized.
#[derive(Debug, thiserror::Error)]
pub enum ShapeError {
    /// A shape's parameter is out of its range.
    #[error("invalid shape: {0}")]
    Parameter(String),
    /// The image size or sub-pixel samples are out of range.
    #[error("a normal map is 1…{max} pixels a side with 1…16 sub-pixel samples per side (got {size} and {samples})", max = crate::SIZES.end())]
    Size {
        /// The requested size (px).
        size: usize,
        /// The requested samples per side.
        samples: usize,
    },
    /// A mesh file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// A mesh file is malformed.
    #[error("{format} line {line}: {message}")]
    Parse {
        /// "OBJ" or "PLY".
        format: &'static str,
        /// The line (1-based; for binary PLY the header's last line).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A mesh is larger than the limits.
    #[error("the mesh is too large: {0}")]
    TooLarge(String),
    /// A mesh has no triangle with an area.
    #[error("the mesh has no triangle with an area")]
    Empty,
    /// The file's extension names no mesh format this reads.
    #[error("{0}: a mesh is an .obj or .ply file")]
    Format(String),
    /// A `--shape` specification is not one of the shapes.
    #[error("unknown shape {0:?}: sphere, torus, superquadric, capsule, blob or mesh:PATH")]
    Unknown(String),
    /// A normal map given for rendering is not square.
    #[error("a normal map to render must be square (got {width}×{height})")]
    NotSquare {
        /// Width (px).
        width: usize,
        /// Height (px).
        height: usize,
    },
    /// The PNG encoder failed.
    #[error("encoding the normal map: {0}")]
    Encode(String),
}

/// A rotation from the shape's own frame to camera space (rows of a 3 × 3 matrix).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    rows: [[f64; 3]; 3],
}

impl Default for Pose {
    fn default() -> Self {
        Pose::identity()
    }
}

impl Pose {
    /// No rotation.
    pub fn identity() -> Pose {
        Pose {
            rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    }

    /// Rotate by `x` degrees about +X, then `y` about +Y, then `z` about +Z (camera axes).
    pub fn from_euler_deg(x: f64, y: f64, z: f64) -> Pose {
        let (sx, cx) = x.to_radians().sin_cos();
        let (sy, cy) = y.to_radians().sin_cos();
        let (sz, cz) = z.to_radians().sin_cos();
        let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        Pose {
            rows: product(&rz, &product(&ry, &rx)),
        }
    }

    /// A uniformly distributed rotation (Shoemake's quaternion method), from `rng`.
    pub fn random(rng: &mut Rng) -> Pose {
        let (u1, u2, u3) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
        let tau = 2.0 * std::f64::consts::PI;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let q = [
            a * (tau * u2).sin(),
            a * (tau * u2).cos(),
            b * (tau * u3).sin(),
            b * (tau * u3).cos(),
        ];
        Pose::from_quaternion(q)
    }

    /// The rotation of a unit quaternion (x, y, z, w).
    fn from_quaternion([x, y, z, w]: [f64; 4]) -> Pose {
        Pose {
            rows: [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - z * w),
                    2.0 * (x * z + y * w),
                ],
                [
                    2.0 * (x * y + z * w),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - x * w),
                ],
                [
                    2.0 * (x * z - y * w),
                    2.0 * (y * z + x * w),
                    1.0 - 2.0 * (x * x + y * y),
                ],
            ],
        }
    }

    /// Shape frame → camera.
    pub(crate) fn apply(&self, p: Vec3) -> Vec3 {
        let r = &self.rows;
        Vec3::new(
            r[0][0] * p.x + r[0][1] * p.y + r[0][2] * p.z,
            r[1][0] * p.x + r[1][1] * p.y + r[1][2] * p.z,
            r[2][0] * p.x + r[2][1] * p.y + r[2][2] * p.z,
        )
    }

    /// Camera → shape frame (the transpose).
    pub(crate) fn invert(&self, p: Vec3) -> Vec3 {
        let r = &self.rows;
        Vec3::new(
            r[0][0] * p.x + r[1][0] * p.y + r[2][0] * p.z,
            r[0][1] * p.x + r[1][1] * p.y + r[2][1] * p.z,
            r[0][2] * p.x + r[1][2] * p.y + r[2][2] * p.z,
        )
    }
}

fn product(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// An object to render. Analytic shapes are given in their own frame at any scale; every
/// shape is scaled to fit the frame when rasterized.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// The unit sphere: the sphere renderer's geometry exactly (in any pose).
    Sphere,
    /// A ring torus about its +Z axis: radius `major` of the tube's centre circle, radius
    /// `minor` of the tube (0 < minor ≤ major).
    Torus {
        /// Radius of the tube's centre circle.
        major: f64,
        /// Radius of the tube.
        minor: f64,
    },
    /// A superellipsoid (|x/a|^(2/e) + |y/b|^(2/e))^(e/n) + |z/c|^(2/n) ≤ 1: `axes` = (a,
    /// b, c), `exponents` = (n, e), north-south and east-west, each in 0.1…2 (1: an
    /// ellipsoid, → 0: a box, 2: an octahedron).
    Superquadric {
        /// Semi-axes (a, b, c) > 0.
        axes: [f64; 3],
        /// (north-south n, east-west e), each in 0.1…2.
        exponents: [f64; 2],
    },
    /// A capsule along +Y: a cylinder of `radius` from −`half_length` to +`half_length`,
    /// capped by hemispheres.
    Capsule {
        /// Half the cylinder's length (≥ 0).
        half_length: f64,
        /// The radius (> 0).
        radius: f64,
    },
    /// A few metaballs.
    Blob(Blob),
    /// A triangle mesh.
    Mesh(Mesh),
}

impl Shape {
    /// The torus the command line renders: tube radius 0.4 of the ring's.
    pub fn torus() -> Shape {
        Shape::Torus {
            major: 1.0,
            minor: 0.4,
        }
    }

    /// The superquadric the command line renders: a rounded box.
    pub fn superquadric() -> Shape {
        Shape::Superquadric {
            axes: [1.0, 0.8, 0.7],
            exponents: [0.4, 0.6],
        }
    }

    /// The capsule the command line renders: half as wide as it is long.
    pub fn capsule() -> Shape {
        Shape::Capsule {
            half_length: 0.5,
            radius: 0.5,
        }
    }
}

/// Sub-pixel samples per side a rasterization may take.
pub const MAX_SAMPLES: usize = 16;

/// Camera-space normals and coverage of an N×N image.
#[derive(Clone, Debug, PartialEq)]
pub struct Normals {
    size: usize,
    /// Unit normals, row-major; [0, 0, 0] where no sample hit.
    normals: Vec<[f32; 3]>,
    /// Fraction of each pixel's samples that hit the object.
    coverage: Vec<f32>,
}

impl Normals {
    /// Size (px a side).
    pub fn size(&self) -> usize {
        self.size
    }

    /// The unit normal of pixel (row, col), `None` for background.
    pub fn at(&self, row: usize, col: usize) -> Option<[f32; 3]> {
        let i = self.index(row, col)?;
        let n = self.normals[i];
        (n != [0.0; 3]).then_some(n)
    }

    /// The index of pixel (row, col), if it is in the image.
    fn index(&self, row: usize, col: usize) -> Option<usize> {
        let i = row.checked_mul(self.size)?.checked_add(col)?;
        (col < self.size && i < self.normals.len()).then_some(i)
    }

    /// The covered fraction of pixel (row, col) (0 outside the image).
    pub fn coverage(&self, row: usize, col: usize) -> f32 {
        let i = self.index(row, col);
        i.and_then(|i| self.coverage.get(i).copied()).unwrap_or(0.0)
    }

    /// A map of your own: `size`² camera-space normals, row-major ([0, 0, 0] for
    /// background; others unit within 0.01, then normalized, and z ≥ 0) and the covered
    /// fraction of each pixel (in [0, 1]; 0 exactly where the normal is background).
    pub fn new(
        size: usize,
        mut normals: Vec<[f32; 3]>,
        coverage: Vec<f32>,
    ) -> Result<Normals, ShapeError> {
        let cells = size.checked_mul(size);
        if cells != Some(normals.len()) || cells != Some(coverage.len()) {
            return Err(ShapeError::Parameter(format!(
                "{} normals and {} coverages for {size}² pixels",
                normals.len(),
                coverage.len()
            )));
        }
        for (n, &c) in normals.iter_mut().zip(&coverage) {
            let background = *n == [0.0; 3];
            let length = n.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt();
            let unit = (length - 1.0).abs() <= 0.01 && n[2] >= 0.0;
            if !(0.0..=1.0).contains(&c) || background != (c == 0.0) || !(background || unit) {
                return Err(ShapeError::Parameter(format!(
                    "normal {n:?} with coverage {c}: give unit normals facing the camera \
                     where coverage is in (0, 1], and [0, 0, 0] where it is 0"
                )));
            }
            if !background {
                *n = n.map(|v| (f64::from(v) / length) as f32);
            }
        }
        Ok(Normals {
            size,
            normals,
            coverage,
        })
    }

    /// A square map of the core (a normal map read from a file): coverage 1 on the object.
    pub fn from_map(map: &NormalMap) -> Result<Normals, ShapeError> {
        let (width, height) = (map.width(), map.height());
        if width != height {
            return Err(ShapeError::NotSquare { width, height });
        }
        let cells = (0..height).flat_map(|r| (0..width).map(move |c| map.at(r, c)));
        let normals: Vec<[f32; 3]> = cells.map(|n| n.unwrap_or([0.0; 3])).collect();
        let coverage = normals.iter().map(|n| f32::from(*n != [0.0; 3])).collect();
        Ok(Normals {
            size: width,
            normals,
            coverage,
        })
    }

    /// The map as a 16-bit RGB PNG the core reads ([`NormalMap::from_png`]): v = (n + 1) / 2
    /// of 65535 per channel, background (0, 0, 0).
    pub fn to_png(&self) -> Result<Vec<u8>, ShapeError> {
        let mut bytes = Vec::with_capacity(self.normals.len() * 6);
        for n in &self.normals {
            let encoded = match *n == [0.0; 3] {
                true => [0u16; 3],
                false => n.map(|c| ((f64::from(c) + 1.0) * 0.5 * 65535.0).round() as u16),
            };
            for c in encoded {
                // The encoder takes 16-bit samples in native byte order.
                bytes.extend_from_slice(&c.to_ne_bytes());
            }
        }
        let mut png = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut png);
        let side = u32::try_from(self.size).map_err(|e| ShapeError::Encode(e.to_string()))?;
        image::ImageEncoder::write_image(
            encoder,
            &bytes,
            side,
            side,
            image::ExtendedColorType::Rgb16,
        )
        .map_err(|e| ShapeError::Encode(e.to_string()))?;
        Ok(png)
    }
}

/// What a shape's ray caster or rasterizer reports for one image.
pub(crate) trait Raster {
    /// The camera-space normal seen at image-plane point (x, y) (sphere radii), if any.
    fn normal_at(&self, x: f64, y: f64) -> Option<Vec3>;
}

/// Rasterize `shape` in `pose` at `size`² pixels with `samples`² stratified sub-pixel
/// samples per pixel (the same for a fixed input: no randomness).
pub fn rasterize(
    shape: &Shape,
    pose: &Pose,
    size: usize,
    samples: usize,
) -> Result<Normals, ShapeError> {
    if !(1..=*crate::SIZES.end()).contains(&size) || !(1..=MAX_SAMPLES).contains(&samples) {
        return Err(ShapeError::Size { size, samples });
    }
    match shape {
        Shape::Mesh(mesh) => Ok(mesh::rasterize(mesh, pose, size, samples)),
        analytic => {
            let caster = analytic::Caster::new(analytic, pose)?;
            Ok(cast(&caster, size, samples))
        }
    }
}

/// Sample `raster` over the pixel grid of an N×N image, rows in parallel (each pixel on
/// its own: the same result on any number of threads).
fn cast(raster: &(impl Raster + Sync), size: usize, samples: usize) -> Normals {
    use rayon::prelude::*;
    let grid = Grid::new(size);
    let step = grid.scale / samples as f64;
    let pixel = |row: usize, col: usize| {
        let pixel = grid.pixel(row, col);
        let hits = (0..samples * samples).filter_map(|index| {
            let x = pixel.corner.0 + ((index % samples) as f64 + 0.5) * step;
            let y = pixel.corner.1 + ((index / samples) as f64 + 0.5) * step;
            raster.normal_at(x, y)
        });
        let (n, count) = mean_normal(hits);
        (n, (count as f64 / (samples * samples) as f64) as f32)
    };
    let cells: Vec<([f32; 3], f32)> = (0..size)
        .into_par_iter()
        .flat_map_iter(|row| (0..size).map(move |col| pixel(row, col)))
        .collect();
    let (normals, coverage) = cells.into_iter().unzip();
    Normals {
        size,
        normals,
        coverage,
    }
}

/// The normalized mean of `normals` (f64 sums) and how many there were; [0, 0, 0] for none.
pub(crate) fn mean_normal(normals: impl Iterator<Item = Vec3>) -> ([f32; 3], usize) {
    let (mut sum, mut count) = (Vec3::new(0.0, 0.0, 0.0), 0usize);
    for n in normals {
        sum = sum + n;
        count += 1;
    }
    let length = sum.dot(sum).sqrt();
    if count == 0 || length == 0.0 || !length.is_finite() {
        return ([0.0; 3], 0);
    }
    let n = sum * (1.0 / length);
    ([n.x as f32, n.y as f32, n.z as f32], count)
}

/// A normal facing the camera: z < 0 (a grazing sample, an interpolated normal past a
/// silhouette) clamped to 0; None if nothing is left.
pub(crate) fn facing(n: Vec3) -> Option<Vec3> {
    let n = Vec3::new(n.x, n.y, n.z.max(0.0));
    let length = n.dot(n).sqrt();
    (length > 1e-12 && length.is_finite()).then(|| n * (1.0 / length))
}

/// A shape as the command line names it: `sphere`, `torus`, `superquadric`, `capsule`,
/// `blob` or `mesh:PATH` (.obj or .ply).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum ShapeSpec {
    /// The sphere (today's renderer).
    #[default]
    Sphere,
    /// [`Shape::torus`].
    Torus,
    /// [`Shape::superquadric`].
    Superquadric,
    /// [`Shape::capsule`].
    Capsule,
    /// [`Blob::seeded`] with four balls.
    Blob,
    /// A mesh file.
    Mesh(PathBuf),
}

impl std::str::FromStr for ShapeSpec {
    type Err = ShapeError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text {
            "sphere" => ShapeSpec::Sphere,
            "torus" => ShapeSpec::Torus,
            "superquadric" => ShapeSpec::Superquadric,
            "capsule" => ShapeSpec::Capsule,
            "blob" => ShapeSpec::Blob,
            other => match other.strip_prefix("mesh:") {
                Some(path) if !path.is_empty() => ShapeSpec::Mesh(PathBuf::from(path)),
                _ => return Err(ShapeError::Unknown(other.to_string())),
            },
        })
    }
}

/// Balls of the command line's blob.
const BLOB_BALLS: usize = 4;

impl ShapeSpec {
    /// The shape (a blob seeded by `seed`, a mesh read within the default limits).
    pub fn shape(&self, seed: u64) -> Result<Shape, ShapeError> {
        Ok(match self {
            ShapeSpec::Sphere => Shape::Sphere,
            ShapeSpec::Torus => Shape::torus(),
            ShapeSpec::Superquadric => Shape::superquadric(),
            ShapeSpec::Capsule => Shape::capsule(),
            ShapeSpec::Blob => Shape::Blob(Blob::seeded(seed, BLOB_BALLS)),
            ShapeSpec::Mesh(path) => Shape::Mesh(load_mesh(path, &MeshLimits::default())?),
        })
    }

    /// The pose the command line renders every shape in: its top (+Y) tipped 30° toward the
    /// viewer (about +X), then turned 20° about the vertical (+Y), so that a torus shows
    /// its hole, a capsule its cap and a box three faces.
    pub fn pose(&self) -> Pose {
        Pose::from_euler_deg(30.0, 20.0, 0.0)
    }
}

/// A mesh from an `.obj` or `.ply` file (by extension), within `limits`.
pub fn load_mesh(path: &Path, limits: &MeshLimits) -> Result<Mesh, ShapeError> {
    let io = |source| ShapeError::Io {
        path: path.display().to_string(),
        source,
    };
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let parse: fn(&[u8], &MeshLimits) -> Result<Mesh, ShapeError> = match extension.as_deref() {
        Some("obj") => obj::parse,
        Some("ply") => ply::parse,
        _ => return Err(ShapeError::Format(path.display().to_string())),
    };
    check_bytes(std::fs::metadata(path).map_err(io)?.len(), limits)?;
    let bytes = std::fs::read(path).map_err(io)?;
    parse(&bytes, limits)
}

/// Whether a file of `length` bytes is within `limits`.
fn check_bytes(length: u64, limits: &MeshLimits) -> Result<(), ShapeError> {
    match length > limits.bytes {
        true => Err(ShapeError::TooLarge(format!(
            "{length} bytes, more than {}",
            limits.bytes
        ))),
        false => Ok(()),
    }
}

/// Parse an OBJ mesh from its bytes, within `limits`.
pub fn parse_obj(bytes: &[u8], limits: &MeshLimits) -> Result<Mesh, ShapeError> {
    check_bytes(bytes.len() as u64, limits)?;
    obj::parse(bytes, limits)
}

/// Parse a PLY mesh (ASCII, binary little- or big-endian) from its bytes, within `limits`.
pub fn parse_ply(bytes: &[u8], limits: &MeshLimits) -> Result<Mesh, ShapeError> {
    check_bytes(bytes.len() as u64, limits)?;
    ply::parse(bytes, limits)
}

#[cfg(test)]
mod tests;
