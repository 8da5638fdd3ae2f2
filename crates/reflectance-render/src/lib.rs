//! Training data: spheres of Ward reflectance rendered under real light probes
//! (paper §4.2, §6.1; docs/design.md §3 "Rendering").
//!
//! Orthographic camera, unit sphere at the origin, viewer direction
//! `v = (0, sin e, cos e)` (e = 45° by default), image up = +Y orthogonalized against v,
//! image right = +X, frame half-width 1.1 radii: the sphere's circle in an N×N image is
//! `cx = cy = (N−1)/2`, `r = N/2.2`. Each pixel averages stratified sub-pixel samples
//! (background 0); shiny classes add stratified samples of the Ward lobe per sub-pixel.
//! A class entry's [`Finish`] adds a Fresnel term to the specular part (and weights the
//! diffuse part by what the coat lets through) and a printed disc ([`render_finished`]).
//!
//! Other objects (issue #44) are rasterized to camera-space normal maps ([`shapes`]) and
//! shaded through the same path by [`render_normals`].

pub mod batch;
pub mod capture;
pub mod envmap;
pub(crate) mod fastmath;
pub(crate) mod highlights;
pub(crate) mod irradiance;
pub mod pbr;
pub mod preview;
pub mod shapes;
pub(crate) mod synthetic;
pub mod ward;

// The core's modules under the names the renderer has always used.
/// The design of continuous materials (it lives with the materials, in the core).
pub use reflectance_core::material::design;

use envmap::EnvMap;
use highlights::{BrightSources, SourcePoint, points_per_side};
use irradiance::Irradiance;
use reflectance_core::locate::Circle;
pub use reflectance_core::material::Finish;
use reflectance_core::material::{Disc, Specular};
use reflectance_core::util::rng::Rng;
use std::f64::consts::PI;
use std::ops::{Add, Mul, Sub};
use ward::{Frame, LocalHalf, Ward, WardBrdf, lobe_sample, local_half};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vec3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl Vec3 {
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3 { x, y, z }
    }
    #[inline]
    pub fn dot(self, o: Vec3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    pub fn normalized(self) -> Vec3 {
        self * (1.0 / self.dot(self).sqrt())
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, k: f64) -> Vec3 {
        Vec3::new(self.x * k, self.y * k, self.z * k)
    }
}

/// Frame half-width in sphere radii.
pub const HALF_WIDTH: f64 = 1.1;

/// Where the viewer is, and how the environment is turned (for augmentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Elevation of the viewer above the horizontal, degrees (docs/design.md §3 "Rendering": 45).
    pub elevation_deg: f64,
    /// Rotation of the environment about +Y, degrees: rendering a map with azimuth
    /// 360·k/W equals rendering the map with its columns rolled right by k.
    pub azimuth_deg: f64,
}

impl Default for View {
    fn default() -> Self {
        View {
            elevation_deg: 45.0,
            azimuth_deg: 0.0,
        }
    }
}

/// Sampling density.
///
/// * `pixel_samples²` stratified, jittered sub-pixel samples per pixel for coverage, the
///   diffuse term and mirror reflections;
/// * glossy lobes: `lobe_pixel_samples²` sub-pixel samples, each integrating the Ward lobe
///   over the map (without its bright sources) with the same lattice quadrature for every
///   pixel (`lobe_points` points for α ≤ 0.02, proportionally more for broader lobes), so
///   the result is a smooth function of the normal (no pixel-to-pixel noise, which would
///   land in the finest-scale features);
/// * pixels whose reflection footprint holds a bright source: a dense grid of sub-pixel
///   samples for the exact bright-source sum (and, for mirrors, for the whole pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    pub pixel_samples: usize,
    pub lobe_pixel_samples: usize,
    pub lobe_points: usize,
}

impl Default for Quality {
    fn default() -> Self {
        Quality {
            pixel_samples: 4,
            lobe_pixel_samples: 3,
            lobe_points: 13,
        }
    }
}

/// One rendered sphere.
#[derive(Clone, Debug)]
pub struct Rendering {
    pub size: usize,
    /// Linear luminance, row-major, background 0.
    pub luminance: Vec<f32>,
    /// Fraction of each pixel covered by the sphere.
    pub coverage: Vec<f32>,
    pub circle: Circle,
}

/// Image sizes a rendering may have: from the least whose sphere (r = N / 2.2) features can
/// be extracted from (r ≥ 32 px) to a sane maximum.
pub const SIZES: std::ops::RangeInclusive<usize> = 71..=4096;

/// An image size outside [`SIZES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "size {0} must be between {min} (a sphere of radius {radius} px, the least that features \
     can be extracted from) and {max}",
    min = SIZES.start(),
    radius = reflectance_core::locate::MIN_RADIUS,
    max = SIZES.end()
)]
pub struct SizeError(pub usize);

/// Whether `size` is in [`SIZES`].
pub fn check_size(size: usize) -> Result<(), SizeError> {
    match SIZES.contains(&size) {
        true => Ok(()),
        false => Err(SizeError(size)),
    }
}

/// The sphere's circle in an N×N rendering.
pub fn circle(size: usize) -> Circle {
    let c = (size as f64 - 1.0) / 2.0;
    Circle {
        cx: c,
        cy: c,
        r: size as f64 / (2.0 * HALF_WIDTH),
    }
}

/// An environment map with everything precomputed per probe: irradiance and the bright
/// sources for specular reflection.
pub struct Lighting {
    pub map: EnvMap,
    pub irradiance: Irradiance,
    pub bright: BrightSources,
}

impl Lighting {
    pub fn new(map: EnvMap) -> Lighting {
        Lighting {
            irradiance: Irradiance::new(&map),
            bright: BrightSources::new(&map),
            map,
        }
    }

    pub fn white(&self, view: &View) -> f64 {
        white(&self.map, view)
    }
}

/// The white reference: radiance of an ideal white Lambertian patch facing the viewer,
/// E(v)/π, by direct summation over the map.
pub fn white(map: &EnvMap, view: &View) -> f64 {
    let camera = Camera::new(view);
    map.irradiance_exact(camera.to_map(camera.v)) / PI
}

/// The camera basis and the world → map rotation.
struct Camera {
    v: Vec3,
    up: Vec3,
    right: Vec3,
    /// cos and sin of the azimuth rotation applied to world directions before map lookups.
    rotation: (f64, f64),
}

impl Camera {
    fn new(view: &View) -> Camera {
        let e = view.elevation_deg.to_radians();
        let v = Vec3::new(0.0, e.sin(), e.cos());
        let y = Vec3::new(0.0, 1.0, 0.0);
        let up = (y - v * v.dot(y)).normalized();
        let a = view.azimuth_deg.to_radians();
        Camera {
            v,
            up,
            right: Vec3::new(1.0, 0.0, 0.0),
            rotation: (a.cos(), a.sin()),
        }
    }

    /// The world direction of a camera-space one (+X right, +Y image up, +Z toward the viewer).
    #[inline]
    fn world(&self, n: Vec3) -> Vec3 {
        self.right * n.x + self.up * n.y + self.v * n.z
    }

    /// Rotate a world direction about +Y so that its map azimuth φ = atan2(x, −z) decreases
    /// by the view's azimuth (the environment turns by +azimuth).
    #[inline]
    fn to_map(&self, d: Vec3) -> Vec3 {
        let (c, s) = self.rotation;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }
}

/// Sub-pixel samples per side for pixels whose reflection footprint holds a bright source.
const DENSE_SIDE: usize = 8;
/// ... and for lobes broader than [`BROAD_LOBE`] in pixels the object covers: over a pixel
/// (about 1/r rad of normal) their highlight changes by a small fraction of itself.
const BROAD_DENSE_SIDE: usize = 2;
/// Above every α the paper's classes and the continuous materials use (≤ 0.2), so that
/// their renders keep their bits; rubber, matte paint and a ping-pong ball's coat (0.3–0.5)
/// took ten times a glossy class's time with the dense grid.
const BROAD_LOBE: f64 = 0.2;
/// Lobe reach: beyond tan δ = 4.55 α the lobe is below 1e-9 of its peak, negligible even for
/// the sun against the sky.
const LOBE_REACH: f64 = 4.55;

/// Render one sphere of `material` under `lighting`, N×N pixels, deterministic for `rng`.
pub fn render(
    lighting: &Lighting,
    material: &Ward,
    size: usize,
    view: &View,
    quality: &Quality,
    rng: &mut Rng,
) -> Rendering {
    let plain = Finish::default();
    render_finished(lighting, material, &plain, size, view, quality, rng)
}

/// [`render`] of a material with a [`Finish`]: its Fresnel term on the mirror (at n·v),
/// the lobe (at v·h per sample) and the bright sources (at v·h), the diffuse part weighted
/// by 1 − the coat's reflectance at n·v, and its printed disc, centred at a direction drawn
/// from `rng` ([`Disc::draw_centre`]) before any pixel. The plain finish renders exactly
/// as [`render`] (the same bytes: `rng` is not drawn from for it).
pub fn render_finished(
    lighting: &Lighting,
    material: &Ward,
    finish: &Finish,
    size: usize,
    view: &View,
    quality: &Quality,
    rng: &mut Rng,
) -> Rendering {
    let surface = SphereSurface {
        scale: Grid::new(size).scale,
    };
    let appearance = (material, finish);
    shade_image(lighting, appearance, view, quality, size, &surface, rng)
}

/// Render an object from its camera-space normals ([`shapes::Normals`]) under `lighting`:
/// each pixel shaded from its normal by the sphere's shader (the normals are interpolated
/// between pixel centres within a pixel, never across a crease), weighted by the pixel's
/// coverage. Deterministic for `rng`; the circle is the frame's ([`circle`]).
pub fn render_normals(
    lighting: &Lighting,
    material: &Ward,
    view: &View,
    normals: &shapes::Normals,
    quality: &Quality,
    rng: &mut Rng,
) -> Rendering {
    let plain = Finish::default();
    render_normals_finished(lighting, material, &plain, view, normals, quality, rng)
}

/// [`render_normals`] of a material with a [`Finish`], as [`render_finished`] (a disc
/// lies on the object where its normals point within the disc's radius of its centre).
pub fn render_normals_finished(
    lighting: &Lighting,
    material: &Ward,
    finish: &Finish,
    view: &View,
    normals: &shapes::Normals,
    quality: &Quality,
    rng: &mut Rng,
) -> Rendering {
    let surface = shapes::MapSurface::new(normals);
    let appearance = (material, finish);
    let size = normals.size();
    shade_image(lighting, appearance, view, quality, size, &surface, rng)
}

/// Shade every pixel `surface` covers: the one shading path of spheres and shapes.
fn shade_image(
    lighting: &Lighting,
    appearance: (&Ward, &Finish),
    view: &View,
    quality: &Quality,
    size: usize,
    surface: &impl Surface,
    rng: &mut Rng,
) -> Rendering {
    let shader = Shader::new(lighting, appearance, view, quality, size, surface, rng);
    let mut luminance = vec![0.0f32; size * size];
    let mut coverage = vec![0.0f32; size * size];
    let mut near = Vec::new();
    for row in 0..size {
        for col in 0..size {
            let pixel = shader.grid.pixel(row, col);
            if !surface.covers(&pixel) {
                continue;
            }
            shader.bright_near(&pixel, &mut near);
            let (value, covered) = shader.shade_pixel(&pixel, &near, rng);
            let weight = surface.weight(&pixel);
            luminance[row * size + col] = (value * weight) as f32;
            coverage[row * size + col] = (covered * weight) as f32;
        }
    }
    Rendering {
        size,
        luminance,
        coverage,
        circle: circle(size),
    }
}

/// A pixel's square in the image plane (sphere radii, +X right, +Y up): its row and column,
/// lower-left corner and centre.
pub(crate) struct Pixel {
    pub(crate) row: usize,
    pub(crate) col: usize,
    pub(crate) corner: (f64, f64),
    pub(crate) centre: (f64, f64),
}

/// The pixel grid of an N×N image of the frame (half-width [`HALF_WIDTH`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grid {
    /// A pixel's side in sphere radii.
    pub(crate) scale: f64,
    half: f64,
}

impl Grid {
    pub(crate) fn new(size: usize) -> Grid {
        Grid {
            scale: 2.0 * HALF_WIDTH / size as f64,
            half: size as f64 / 2.0,
        }
    }

    pub(crate) fn pixel(&self, row: usize, col: usize) -> Pixel {
        let x0 = (col as f64 - self.half) * self.scale;
        let y0 = (self.half - row as f64 - 1.0) * self.scale;
        Pixel {
            row,
            col,
            corner: (x0, y0),
            centre: (x0 + 0.5 * self.scale, y0 + 0.5 * self.scale),
        }
    }
}

/// What the shader sees of the object: camera-space normals at image-plane points.
pub(crate) trait Surface {
    /// Whether `pixel` may hold some of the object.
    fn covers(&self, pixel: &Pixel) -> bool;
    /// The camera-space normal at (x, y) of `pixel`, or None where the object is not.
    fn normal(&self, pixel: &Pixel, x: f64, y: f64) -> Option<Vec3>;
    /// A camera-space normal for the reflection footprint at (x, y) of `pixel`, also just
    /// outside the object (pulled onto it).
    fn footprint_normal(&self, pixel: &Pixel, x: f64, y: f64) -> Vec3;
    /// The factor of the pixel's shaded value and coverage (a normal map's coverage).
    fn weight(&self, pixel: &Pixel) -> f64;
}

/// The camera-space normal of the unit sphere at image-plane point (x, y), or None outside.
#[inline]
pub(crate) fn sphere_normal(x: f64, y: f64) -> Option<Vec3> {
    let r2 = x * x + y * y;
    (r2 < 1.0).then(|| Vec3::new(x, y, (1.0 - r2).sqrt()))
}

/// The unit sphere at the origin, exactly.
struct SphereSurface {
    scale: f64,
}

impl Surface for SphereSurface {
    fn covers(&self, pixel: &Pixel) -> bool {
        pixel.centre.0.hypot(pixel.centre.1) <= 1.0 + self.scale
    }

    fn normal(&self, _: &Pixel, x: f64, y: f64) -> Option<Vec3> {
        sphere_normal(x, y)
    }

    fn footprint_normal(&self, _: &Pixel, x: f64, y: f64) -> Vec3 {
        let r = x.hypot(y);
        let k = if r > 0.999 { 0.999 / r } else { 1.0 };
        sphere_normal(x * k, y * k).unwrap_or(Vec3::new(0.0, 0.0, 1.0))
    }

    fn weight(&self, _: &Pixel) -> f64 {
        1.0
    }
}

/// A printed disc placed on the object: its centre (world), cos of its radius, its albedo.
struct PlacedDisc {
    centre: Vec3,
    cos_radius: f64,
    albedo: f64,
}

/// Everything fixed for one image.
struct Shader<'a, S> {
    lighting: &'a Lighting,
    surface: &'a S,
    material: &'a Ward,
    /// The specular reflectance by angle (Ward's constant ρs for the plain finish).
    specular: Specular,
    disc: Option<PlacedDisc>,
    camera: Camera,
    /// Sub-pixel samples per side.
    k: usize,
    /// Sub-pixel samples per side for the glossy lobe (0 unless the material has one).
    lobe_k: usize,
    /// The lobe quadrature: half vectors of a lattice of (u1, u2), the same for every pixel.
    lattice: Vec<LocalHalf>,
    grid: Grid,
    /// Points of every bright source at the spacing this material's lobe needs.
    points: Vec<Vec<SourcePoint>>,
}

impl<'a, S: Surface> Shader<'a, S> {
    fn new(
        lighting: &'a Lighting,
        (material, finish): (&'a Ward, &Finish),
        view: &View,
        quality: &Quality,
        size: usize,
        surface: &'a S,
        rng: &mut Rng,
    ) -> Self {
        let camera = Camera::new(view);
        let disc = finish.disc.map(|disc: Disc| {
            let [x, y, z] = Disc::draw_centre(rng);
            PlacedDisc {
                centre: camera.world(Vec3::new(x, y, z)),
                cos_radius: disc.cos_radius(),
                albedo: disc.albedo,
            }
        });
        let k = quality.pixel_samples.max(1);
        let glossy = material.rho_s > 0.0 && material.alpha > 0.0;
        let per_side = points_per_side(lighting.map.height, material.alpha);
        let points = if glossy {
            (0..lighting.bright.texels.len())
                .map(|i| {
                    lighting
                        .bright
                        .points(lighting.map.width, lighting.map.height, i, per_side)
                })
                .collect()
        } else {
            Vec::new()
        };
        Shader {
            lighting,
            surface,
            material,
            specular: Specular::new(material.rho_s, finish.fresnel),
            disc,
            camera,
            k,
            lobe_k: if glossy {
                quality.lobe_pixel_samples.max(1)
            } else {
                0
            },
            lattice: golden_lattice(lobe_points(quality.lobe_points, material.alpha))
                .into_iter()
                .map(|(u1, u2)| local_half(material.alpha, u1, u2))
                .collect(),
            grid: Grid::new(size),
            points,
        }
    }

    /// Mirror direction (map coordinates) at (x, y) of `pixel`, with points outside the
    /// object pulled onto it.
    fn reflection(&self, pixel: &Pixel, x: f64, y: f64) -> Vec3 {
        let n = self
            .camera
            .world(self.surface.footprint_normal(pixel, x, y));
        let v = self.camera.v;
        self.camera.to_map(n * (2.0 * n.dot(v)) - v)
    }

    /// Bright sources whose light can reach the viewer through this pixel.
    fn bright_near(&self, pixel: &Pixel, out: &mut Vec<usize>) {
        out.clear();
        if self.material.rho_s <= 0.0 || self.lighting.bright.texels.is_empty() {
            return;
        }
        let centre = self.reflection(pixel, pixel.centre.0, pixel.centre.1);
        let ((x0, y0), scale) = (pixel.corner, self.grid.scale);
        let footprint = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .map(|&(a, b)| {
                centre
                    .dot(self.reflection(pixel, x0 + a * scale, y0 + b * scale))
                    .clamp(-1.0, 1.0)
                    .acos()
            })
            .fold(0.0, f64::max);
        // Tilting the half vector by δ turns the reflected direction by at most 2δ.
        let lobe = 2.0 * (LOBE_REACH * self.material.alpha).atan();
        self.lighting.bright.near(
            centre,
            footprint + lobe + self.lighting.bright.texel_radius,
            out,
        );
    }

    /// (mean radiance, coverage) of one pixel.
    fn shade_pixel(&self, pixel: &Pixel, near: &[usize], rng: &mut Rng) -> (f64, f64) {
        let mirror = self.material.alpha == 0.0;
        if mirror && !near.is_empty() {
            // A bright source reflected in a mirror: many sub-pixel samples for the whole pixel.
            return self.integrate(pixel, self.k * DENSE_SIDE, rng, |s, n| s.radiance(n));
        }
        let (mut value, covered) = self.integrate(pixel, self.k, rng, |s, n| s.radiance(n));
        if self.lobe_k > 0 {
            value += self
                .integrate(pixel, self.lobe_k, rng, |s, n| s.glossy(n))
                .0;
        }
        if !near.is_empty() && !mirror {
            // A broad lobe's highlight changes little across a pixel the object covers.
            let side = match self.material.alpha > BROAD_LOBE && self.covers(pixel) {
                true => BROAD_DENSE_SIDE,
                false => DENSE_SIDE,
            };
            value += self
                .integrate(pixel, side, rng, |s, n| s.bright_specular(n, near))
                .0;
        }
        (value, covered)
    }

    /// Whether the object covers the whole pixel (its four corners).
    fn covers(&self, pixel: &Pixel) -> bool {
        let ((x0, y0), scale) = (pixel.corner, self.grid.scale);
        [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .all(|&(a, b)| {
                self.surface
                    .normal(pixel, x0 + a * scale, y0 + b * scale)
                    .is_some()
            })
    }

    /// The diffuse albedo at world normal `n`: the disc's on it, else ρd.
    #[inline]
    fn albedo(&self, n: Vec3) -> f64 {
        match &self.disc {
            Some(disc) if n.dot(disc.centre) >= disc.cos_radius => disc.albedo,
            _ => self.material.rho_d,
        }
    }

    /// Diffuse light from the irradiance (under a Fresnel coat, what the coat lets through
    /// at the view angle), plus for mirrors the reflection of the whole map.
    fn radiance(&self, n: Vec3) -> f64 {
        let (m, camera) = (self.material, &self.camera);
        let v = camera.v;
        let mut radiance = 0.0;
        let albedo = self.albedo(n);
        if albedo > 0.0 {
            // The plain coat's weight is exactly 1.
            let through = self.specular.diffuse_weight(n.dot(v));
            radiance += albedo / PI * self.lighting.irradiance.at(camera.to_map(n)) * through;
        }
        if m.rho_s > 0.0 && m.alpha == 0.0 {
            let mirror = n * (2.0 * n.dot(v)) - v;
            radiance +=
                self.specular.at(n.dot(v)) * self.lighting.map.lookup(camera.to_map(mirror));
        }
        radiance
    }

    /// The glossy lobe over the map without its bright sources, by the lattice quadrature
    /// in a tangent frame that turns continuously with the normal.
    fn glossy(&self, n: Vec3) -> f64 {
        let camera = &self.camera;
        let frame = Frame::continuous(n, camera.right);
        let mut total = 0.0;
        for h in &self.lattice {
            if let Some(s) = lobe_sample(&frame, camera.v, &self.specular, h) {
                total += s.weight * self.lighting.bright.dim.lookup(camera.to_map(s.wi));
            }
        }
        total / self.lattice.len() as f64
    }

    /// Specular light from the bright sources `near`, summed over their points.
    fn bright_specular(&self, n: Vec3, near: &[usize]) -> f64 {
        let n_map = self.camera.to_map(n);
        let v_map = self.camera.to_map(self.camera.v);
        let mut total = 0.0;
        let m = self.material;
        let limit = (LOBE_REACH * m.alpha).powi(2);
        let constant = self.specular.is_constant();
        for &index in near {
            for p in &self.points[index] {
                if let Some(mut f) = m.specular_brdf_within(n_map, v_map, p.direction, limit) {
                    if !constant {
                        // The coat's reflectance at v·h in place of Ward's ρs (> 0 here).
                        let h = p.direction + v_map;
                        f *= self.specular.at(v_map.dot(h) / h.dot(h).sqrt()) / m.rho_s;
                    }
                    total += f * n_map.dot(p.direction) * p.power;
                }
            }
        }
        total
    }

    /// Mean over a stratified, jittered side×side grid of sub-pixel samples of `f(normal)`
    /// (0 outside the object), and the covered fraction.
    fn integrate(
        &self,
        pixel: &Pixel,
        side: usize,
        rng: &mut Rng,
        f: impl Fn(&Self, Vec3) -> f64,
    ) -> (f64, f64) {
        let (mut sum, mut inside) = (0.0, 0usize);
        let step = self.grid.scale / side as f64;
        for index in 0..side * side {
            let x = pixel.corner.0 + ((index % side) as f64 + rng.next_f64()) * step;
            let y = pixel.corner.1 + ((index / side) as f64 + rng.next_f64()) * step;
            if let Some(n) = self.surface.normal(pixel, x, y) {
                inside += 1;
                sum += f(self, self.camera.world(n));
            }
        }
        let count = (side * side) as f64;
        (sum / count, inside as f64 / count)
    }
}
/// Lattice points for a lobe of width α: `base` up to α = 0.02 (the paper's classes; the
/// quadrature then over-estimates the lobe integral by ≤ 0.3 % for view angles within the
/// sampled annulus), proportionally more for broader lobes, at most 144.
fn lobe_points(base: usize, alpha: f64) -> usize {
    let scaled = (base.max(1) as f64 * (alpha / 0.02).max(1.0)).ceil() as usize;
    scaled.min(144.max(base))
}

/// `count` points of [0,1)² from the golden-ratio (Fibonacci) lattice: u1 = (i + ½)/count,
/// u2 = frac(i/φ + ½).
fn golden_lattice(count: usize) -> Vec<(f64, f64)> {
    let inverse_phi = 0.618_033_988_749_894_8;
    (0..count)
        .map(|i| {
            (
                (i as f64 + 0.5) / count as f64,
                (i as f64 * inverse_phi + 0.5).fract(),
            )
        })
        .collect()
}

/// Helpers for tests that use the shared light probes when they are present.
#[cfg(test)]
pub(crate) mod testing {
    use super::envmap::EnvMap;
    use std::path::PathBuf;

    pub fn probes_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/probes")
    }

    /// A probe from ../shared/data/probes (tests that call this are ignored without them,
    /// see build.rs).
    pub fn shared_probe(name: &str) -> EnvMap {
        let path = probes_dir().join(name);
        EnvMap::load(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (these tests need ../shared beside the repository)",
                path.display()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_size_is_the_least_extractable_sphere() {
        let least = *SIZES.start();
        assert!(circle(least).r >= reflectance_core::locate::MIN_RADIUS);
        assert!(circle(least - 1).r < reflectance_core::locate::MIN_RADIUS);
        assert!(check_size(least - 1).is_err() && check_size(least).is_ok());
    }
}
