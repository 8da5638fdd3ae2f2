//! Automatic sphere detection on photograph-like composites, per category of photograph:
//! rendered spheres of every kind (matte, glossy, mirror; light and dark) pasted onto table
//! tops and into real scenes (crops of the shared light probes, which are photographs);
//! small spheres in phone-sized pictures; large ones; spheres cut by the frame; crops the
//! ball fills; several balls among flat round things; and a mirror ball in front of the
//! very scene it reflects. Objects around, contact shadows, camera noise, lens blur and
//! JPEG at quality 70–95. Found means the chosen circle is within 2 % of a sphere's radius,
//! in centre and in radius.
//!
//! `REFLECTANCE_COMPOSITES=N cargo test --release --test numerics detection -- --nocapture`
//! measures on N composites (default 36, cycling through the categories) and prints the
//! rates per category; `REFLECTANCE_COMPOSITE_DUMP=DIR` writes the missed ones there.
//! `REFLECTANCE_DETECT_LONG_SIDE=N` gives detection the picture area-reduced to a long side of
//! N px (what a reduced decode hands it), the circle found scaled back (here and in
//! `real_photos`).

use ndarray::Array2;
use reflectance_core::decode::{DecodeOptions, Limits, decode};
use reflectance_core::image::blur::gaussian_blur;
use reflectance_core::image::display::linear_to_srgb;
use reflectance_core::locate::{self, Circle, GeometryError};
use reflectance_core::util::rng::Rng;
use reflectance_render::capture;
use reflectance_render::envmap::EnvMap;
use reflectance_render::ward::Ward;
use reflectance_render::{Lighting, Quality, View};
use std::path::PathBuf;

/// Detection as a reduced decode would give it the picture: area-reduced to a long side of
/// `REFLECTANCE_DETECT_LONG_SIDE` px when it is longer, the circles scaled back to its own
/// coordinates.
pub(crate) fn detect_as_received(
    luminance: ndarray::ArrayView2<f64>,
) -> (
    Result<locate::Geometry, GeometryError>,
    Vec<locate::Geometry>,
) {
    let long = std::env::var("REFLECTANCE_DETECT_LONG_SIDE")
        .ok()
        .and_then(|v| v.parse::<usize>().ok());
    let (h, w) = luminance.dim();
    let Some(scale) = long
        .filter(|&long| h.max(w) > long)
        .map(|long| long as f64 / h.max(w) as f64)
    else {
        return locate::detect_ranked(luminance);
    };
    let reduced = reflectance_core::image::resample::downsample(luminance, scale);
    let back = |g: locate::Geometry| {
        let c = g.circle().enlarged(scale);
        locate::Geometry {
            cx: c.cx,
            cy: c.cy,
            r: c.r,
            ..g
        }
    };
    let (found, ranked) = locate::detect_ranked(reduced.view());
    (found.map(back), ranked.into_iter().map(back).collect())
}

fn shared_probes() -> PathBuf {
    crate::common::shared().join("data/probes")
}

fn probe(name: &str) -> EnvMap {
    let path = shared_probes().join(name);
    EnvMap::load(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (../shared is required)", path.display()))
}

/// Spheres are rendered under these probes; a low-contrast composite puts one in front of
/// its own probe.
const SPHERE_PROBES: [&str; 2] = ["polyhaven_noon_grass.hdr", "polyhaven_studio_small_03.hdr"];
/// Scenes behind the spheres otherwise.
const SCENE_PROBES: [&str; 3] = [
    "polyhaven_courtyard.hdr",
    "polyhaven_vestibule.hdr",
    "polyhaven_dresden_square.hdr",
];

/// A rendered sphere: luminance (outside the disc filled with the rim's values, so that it
/// can be enlarged without a dark seam), its circle, white, and the probe it was lit by.
struct Sphere {
    luminance: Array2<f64>,
    circle: Circle,
    white: f64,
    probe: usize,
    mirror: bool,
}

fn spheres(probes: &[EnvMap]) -> Vec<Sphere> {
    let classes = [
        ("black", 0.1, 0.0, 0.0),
        ("white", 0.9, 0.0, 0.0),
        ("chrome", 0.0, 0.75, 0.0),
        ("shiny", 0.7, 0.25, 0.01),
        ("dark-shiny", 0.05, 0.05, 0.02),
    ];
    let size = 220;
    let mut out = Vec::new();
    for (probe, map) in probes.iter().enumerate() {
        let lighting = Lighting::new(map.clone());
        let view = View::default();
        let white = lighting.white(&view);
        for (_class, rho_d, rho_s, alpha) in classes {
            let material = Ward {
                rho_d,
                rho_s,
                alpha,
            };
            let image = reflectance_render::render(
                &lighting,
                &material,
                size,
                &view,
                &Quality::default(),
                &mut Rng::new(1),
            );
            let circle = reflectance_render::circle(size);
            let raw = Array2::from_shape_fn((size, size), |(y, x)| {
                f64::from(image.luminance[y * size + x])
            });
            // Outside (and on) the rim: the value just inside, along the same ray.
            let luminance = Array2::from_shape_fn((size, size), |(y, x)| {
                let (dx, dy) = (x as f64 - circle.cx, y as f64 - circle.cy);
                let d = dx.hypot(dy);
                if d < circle.r - 1.5 {
                    return raw[[y, x]];
                }
                let k = (circle.r - 2.0) / d.max(1e-9);
                let (sx, sy) = (circle.cx + dx * k, circle.cy + dy * k);
                raw[[sy.round() as usize, sx.round() as usize]]
            });
            out.push(Sphere {
                luminance,
                circle,
                white,
                probe,
                mirror: alpha == 0.0 && rho_s > 0.5,
            });
        }
    }
    out
}

/// What kind of photograph a composite imitates.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Category {
    /// r 60–300 px on a light, mid or dark table top, a gradient or wood grain.
    TableTop,
    /// r 60–300 px in front of a real scene, or a scene over a table.
    Scene,
    /// r 40–80 px in a picture 1500–4000 px wide (up to 12 MP).
    Small,
    /// r 400–2000 px: phone-sized pictures (up to 30 MP).
    Large,
    /// 10–45 % of the rim outside the frame.
    CutByFrame,
    /// A crop the ball fills: 90–100 % of the frame's shorter side, sometimes cut by it.
    FillsFrame,
    /// Two or three balls with flat discs and rings of similar size around them.
    Crowd,
    /// A mirror or glossy ball in front of the scene it reflects, softly focused.
    LowContrast,
    /// r 60–250 px away from the middle of a wide-angle picture (65° across, 1600–3000 px):
    /// an ellipse up to 1.2 times longer away from the centre than across.
    OffAxis,
    // The judging set's kinds (what real photographs the detector missed look like):
    /// A close-up: the ball 1.05–1.5 times the frame's shorter side across, crossing one or
    /// two edges (half to four fifths of its rim inside).
    CloseUp,
    /// A dim tinted mirror ball (a fifth to a half of chrome's reflectance) in front of the
    /// scene it reflects, at its brightness.
    Tinted,
    /// A ball of r 100–400 px photographed out of focus: blur of 1.5–4 % of r.
    SoftFocus,
    /// r 30–70 px in a picture 2000–4000 px wide, among objects and a ring of another size.
    SmallInClutter,
}

const CATEGORIES: [Category; 9] = [
    Category::TableTop,
    Category::Scene,
    Category::Small,
    Category::Large,
    Category::CutByFrame,
    Category::FillsFrame,
    Category::Crowd,
    Category::LowContrast,
    Category::OffAxis,
];

/// The judging set: kinds the detector was not tuned on, measured apart
/// ([`found_in_judging_composites`]).
const JUDGING: [Category; 4] = [
    Category::CloseUp,
    Category::Tinted,
    Category::SoftFocus,
    Category::SmallInClutter,
];

/// `lo..hi`, log-uniform.
fn log_uniform(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + rng.next_f64() * (hi.ln() - lo.ln())).exp()
}

/// A crop of a real probe around its horizon, `w × h`, with its median at `level`.
fn scene(map: &EnvMap, w: usize, h: usize, level: f64, rng: &mut Rng) -> Array2<f64> {
    let u0 = rng.next_f64();
    let (span_u, span_v) = (0.35, 0.45);
    let crop = Array2::from_shape_fn((h, w), |(y, x)| {
        let u = (u0 + span_u * x as f64 / w as f64).fract();
        let v = 0.3 + span_v * y as f64 / h as f64;
        let (mx, my) = (u * map.width as f64, v * map.height as f64);
        let (i, j) = ((my as usize).min(map.height - 1), (mx as usize) % map.width);
        map.luminance[i * map.width + j]
    });
    let median = median(crop.iter().copied().collect()).max(1e-9);
    crop.mapv(|v| v / median * level)
}

fn median(mut values: Vec<f64>) -> f64 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Table {
    Light,
    Mid,
    Dark,
    Gradient,
    Wood,
}

fn table(kind: Table, w: usize, h: usize, rng: &mut Rng) -> Array2<f64> {
    let level = match kind {
        Table::Light => 0.75,
        Table::Mid => 0.35,
        Table::Dark => 0.06,
        _ => 0.2 + 0.4 * rng.next_f64(),
    };
    // Grain about 60 px apart in an 800 px picture, as many across a larger one.
    let grain_scale = 800.0 / w.max(h) as f64;
    let (fx, fy, phase) = (
        (0.05 + 0.1 * rng.next_f64()) * grain_scale,
        0.01 * grain_scale,
        7.0 * rng.next_f64(),
    );
    Array2::from_shape_fn((h, w), |(y, x)| {
        let (u, v) = (x as f64 / w as f64, y as f64 / h as f64);
        let light_falloff = 1.0 - 0.25 * (u - 0.5).powi(2) - 0.15 * v;
        match kind {
            Table::Gradient => level * (0.3 + 1.4 * u) * light_falloff,
            Table::Wood => {
                let grain = (fx * x as f64 + 4.0 * (fy * y as f64 + phase).sin()).sin();
                level * (1.0 + 0.25 * grain) * light_falloff
            }
            _ => level * light_falloff,
        }
    })
}

/// How a lens draws a ball seen off its axis: stretched by `factor` (1 / cos of the angle
/// off the axis) along the unit direction (`ux`, `uy`) away from the picture's centre.
#[derive(Clone, Copy, Debug)]
struct Stretch {
    factor: f64,
    ux: f64,
    uy: f64,
}

const ON_AXIS: Stretch = Stretch {
    factor: 1.0,
    ux: 1.0,
    uy: 0.0,
};

impl Stretch {
    /// The offset from the centre, in the unstretched disc, of the point (x, y) of the picture.
    fn in_disc(&self, c: &Circle, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - c.cx, y - c.cy);
        let along = (dx * self.ux + dy * self.uy) / self.factor;
        let across = -dx * self.uy + dy * self.ux;
        (
            along * self.ux - across * self.uy,
            along * self.uy + across * self.ux,
        )
    }
}

/// The fraction of the pixel at (x, y) inside the (stretched) circle (4 × 4 samples near the
/// rim).
fn coverage(x: usize, y: usize, c: &Circle, stretch: &Stretch) -> f64 {
    let distance = |x: f64, y: f64| {
        let (dx, dy) = stretch.in_disc(c, x, y);
        dx.hypot(dy)
    };
    let d = distance(x as f64, y as f64);
    if d <= c.r - 1.0 {
        return 1.0;
    }
    if d >= c.r + 1.0 {
        return 0.0;
    }
    let offsets = [-0.375, -0.125, 0.125, 0.375];
    let inside = offsets
        .iter()
        .flat_map(|dy| offsets.iter().map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| distance(x as f64 + **dx, y as f64 + **dy) <= c.r)
        .count();
    inside as f64 / 16.0
}

/// Blend `value(x, y)` into `image` over the pixels `c`, stretched, covers.
fn paint(
    image: &mut Array2<f64>,
    c: &Circle,
    stretch: &Stretch,
    value: impl Fn(usize, usize) -> f64,
) {
    let (h, w) = image.dim();
    let reach = c.r * stretch.factor + 2.0;
    let span = |centre: f64, n: usize| {
        let lo = (centre - reach).floor().max(0.0) as usize;
        let hi = ((centre + reach).ceil().max(0.0) as usize).min(n);
        lo..hi
    };
    for y in span(c.cy, h) {
        for x in span(c.cx, w) {
            let k = coverage(x, y, c, stretch);
            if k > 0.0 {
                let v = &mut image[[y, x]];
                *v = k * value(x, y) + (1.0 - k) * *v;
            }
        }
    }
}

/// Paste `sphere`, enlarged or reduced to `at` and stretched, in units of white.
fn paste(image: &mut Array2<f64>, sphere: &Sphere, at: &Circle, stretch: &Stretch) {
    let factor = at.r / sphere.circle.r;
    let scaled = capture::scale(sphere.luminance.view(), factor);
    let (sx0, sy0) = (
        (sphere.circle.cx + 0.5) * factor - 0.5,
        (sphere.circle.cy + 0.5) * factor - 0.5,
    );
    paint(image, at, stretch, |x, y| {
        let (dx, dy) = stretch.in_disc(at, x as f64, y as f64);
        let (sx, sy) = ((sx0 + dx).round(), (sy0 + dy).round());
        scaled
            .get([sy.max(0.0) as usize, sx.max(0.0) as usize])
            .copied()
            .unwrap_or(0.0)
            / sphere.white
    });
}

/// Objects around the spheres: boxes and elongated ellipses with sharp edges, away from them,
/// sized for the picture.
fn clutter(image: &mut Array2<f64>, avoid: &[Circle], rng: &mut Rng) {
    let (h, w) = image.dim();
    let size = w.max(h) as f64 / 800.0;
    for _ in 0..(2 + rng.below(4)) {
        let (cx, cy) = (rng.next_f64() * w as f64, rng.next_f64() * h as f64);
        // Elongated (a ≥ 1.5 b): nothing else in the picture is a circle.
        let b = (10.0 + 60.0 * rng.next_f64()) * size;
        let a = b * (1.5 + 1.5 * rng.next_f64());
        if avoid
            .iter()
            .any(|c| (cx - c.cx).hypot(cy - c.cy) < c.r + a.max(b) + 10.0)
        {
            continue;
        }
        let level = 0.05 + 1.2 * rng.next_f64();
        let ellipse = rng.below(2) == 0;
        let (y0, y1) = (
            (cy - a).max(0.0) as usize,
            ((cy + a).max(0.0) as usize).min(h),
        );
        let (x0, x1) = (
            (cx - a).max(0.0) as usize,
            ((cx + a).max(0.0) as usize).min(w),
        );
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = ((x as f64 - cx) / a, (y as f64 - cy) / b);
                let inside = if ellipse {
                    dx * dx + dy * dy <= 1.0
                } else {
                    dx.abs() <= 1.0 && dy.abs() <= 1.0
                };
                if inside {
                    image[[y, x]] = level;
                }
            }
        }
    }
}

/// A soft contact shadow under a sphere standing on a table.
fn contact_shadow(image: &mut Array2<f64>, c: &Circle) {
    let (h, w) = image.dim();
    let rows = (c.cy.max(0.0) as usize).min(h)..((c.cy + 1.6 * c.r).max(0.0) as usize).min(h);
    let cols = ((c.cx - 2.0 * c.r).max(0.0) as usize).min(w)..((c.cx + 2.0 * c.r) as usize).min(w);
    for y in rows {
        for x in cols.clone() {
            let (dx, dy) = (
                (x as f64 - c.cx) / (0.9 * c.r),
                (y as f64 - c.cy - 0.85 * c.r) / (0.25 * c.r),
            );
            image[[y, x]] *= 1.0 - 0.6 * (-(dx * dx + dy * dy)).exp();
        }
    }
}

/// A picture in units of white, where its spheres are (and how stretched), and the lens
/// blur to apply.
struct Staged {
    scene: Array2<f64>,
    spheres: Vec<(Circle, Stretch)>,
    blur: f64,
}

/// A background of `w × h`: a table top or a scene (over a table below `horizon`).
fn background(
    w: usize,
    h: usize,
    horizon: Option<f64>,
    maps: &[EnvMap],
    rng: &mut Rng,
) -> Array2<f64> {
    let map = &maps[rng.below(maps.len() as u64) as usize];
    match horizon {
        None => {
            let kinds = [
                Table::Light,
                Table::Mid,
                Table::Dark,
                Table::Gradient,
                Table::Wood,
            ];
            table(kinds[rng.below(kinds.len() as u64) as usize], w, h, rng)
        }
        Some(horizon) => {
            let mut top = scene(map, w, h, 0.3, rng);
            if horizon < h as f64 {
                let bottom = table(Table::Wood, w, h, rng);
                let from = horizon.max(0.0) as usize;
                top.slice_mut(ndarray::s![from.., ..])
                    .assign(&bottom.slice(ndarray::s![from.., ..]));
            }
            top
        }
    }
}

/// A single sphere of radius `r` somewhere in a `w × h` picture, at least `margin` inside.
fn placed(w: usize, h: usize, r: f64, margin: f64, rng: &mut Rng) -> Circle {
    let free = |n: usize| (n as f64 - 2.0 * (margin + r)).max(0.0);
    Circle {
        cx: margin + r + rng.next_f64() * free(w),
        cy: margin + r + rng.next_f64() * free(h),
        r,
    }
}

/// One sphere on a table top or in a scene: the classic composite.
fn single(
    sphere: &Sphere,
    (w, h): (usize, usize),
    (at, stretch): (Circle, Stretch),
    in_scene: bool,
    maps: &[EnvMap],
    rng: &mut Rng,
) -> Staged {
    let horizon = (in_scene && rng.below(2) == 0)
        .then_some(at.cy + 0.3 * at.r)
        .or(in_scene.then_some(f64::INFINITY));
    let mut scene = background(w, h, horizon, maps, rng);
    clutter(&mut scene, &[at], rng);
    if horizon != Some(f64::INFINITY) {
        contact_shadow(&mut scene, &at);
    }
    paste(&mut scene, sphere, &at, &stretch);
    Staged {
        scene,
        spheres: vec![(at, stretch)],
        blur: 0.1 + 0.9 * rng.next_f64(),
    }
}

fn stage(
    category: Category,
    spheres: &[Sphere],
    sphere_maps: &[EnvMap],
    maps: &[EnvMap],
    rng: &mut Rng,
) -> Staged {
    let sphere = &spheres[rng.below(spheres.len() as u64) as usize];
    match category {
        Category::TableTop | Category::Scene => {
            let r = log_uniform(rng, 60.0, 300.0);
            let margin = 0.25 * r + 4.0;
            let w = (2.0 * (r + margin) + rng.next_f64() * 500.0).ceil() as usize;
            let h = (2.0 * (r + margin) + rng.next_f64() * 300.0).ceil() as usize;
            let at = placed(w, h, r, margin, rng);
            single(
                sphere,
                (w, h),
                (at, ON_AXIS),
                category == Category::Scene,
                maps,
                rng,
            )
        }
        Category::Small => {
            let r = log_uniform(rng, 40.0, 80.0);
            let w = (1500.0 + 2500.0 * rng.next_f64()) as usize;
            let h = w * 3 / 4;
            let at = placed(w, h, r, 0.25 * r + 4.0, rng);
            single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng)
        }
        Category::Large => {
            let r = log_uniform(rng, 400.0, 2000.0);
            let w = ((2.3 + 0.9 * rng.next_f64()) * r) as usize;
            let h = ((w * 3 / 4) as f64).max(2.3 * r) as usize;
            let at = placed(w, h, r, 0.1 * r, rng);
            single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng)
        }
        Category::CutByFrame => {
            let r = log_uniform(rng, 60.0, 300.0);
            let w = (2.0 * r + 200.0 + rng.next_f64() * 500.0).ceil() as usize;
            let h = (2.0 * r + 200.0 + rng.next_f64() * 300.0).ceil() as usize;
            // Beyond one or two edges by 0.1–0.45 r: up to ~30 % of the rim unseen.
            let past = |rng: &mut Rng| r - (0.1 + 0.35 * rng.next_f64()) * r;
            let mut at = placed(w, h, r, 4.0, rng);
            match rng.below(4) {
                0 => at.cx = past(rng) - 0.5,
                1 => at.cy = h as f64 - 0.5 - past(rng),
                2 => {
                    at.cx = w as f64 - 0.5 - past(rng);
                    at.cy = past(rng) - 0.5;
                }
                _ => at.cy = past(rng) - 0.5,
            }
            single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng)
        }
        Category::FillsFrame => {
            let r = log_uniform(rng, 100.0, 1000.0);
            let h = (2.0 * r / (0.9 + 0.12 * rng.next_f64())).round() as usize;
            let w = (h as f64 * (1.0 + 0.4 * rng.next_f64())).round() as usize;
            let at = Circle {
                cx: 0.5 * (w as f64 - 1.0) + 0.05 * r * (rng.next_f64() - 0.5),
                cy: 0.5 * (h as f64 - 1.0) + 0.05 * r * (rng.next_f64() - 0.5),
                r,
            };
            single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng)
        }
        Category::Crowd => crowd(spheres, maps, rng),
        Category::OffAxis => {
            let w = (1600.0 + 1400.0 * rng.next_f64()) as usize;
            let h = w * 3 / 4;
            let focal = 0.5 * w as f64 / (32.5f64).to_radians().tan();
            let r = log_uniform(rng, 60.0, 250.0);
            let at = placed(w, h, r * 1.25, 4.0, rng);
            let at = Circle { r, ..at };
            let (dx, dy) = (at.cx - 0.5 * w as f64, at.cy - 0.5 * h as f64);
            let off = dx.hypot(dy).max(1e-9);
            let stretch = Stretch {
                factor: 1.0 / (off / focal).atan().cos(),
                ux: dx / off,
                uy: dy / off,
            };
            single(sphere, (w, h), (at, stretch), rng.below(2) == 0, maps, rng)
        }
        Category::LowContrast => in_own_scene(spheres, sphere_maps, 1.0, rng),
        Category::Tinted => {
            let tint = 0.2 + 0.3 * rng.next_f64();
            in_own_scene(spheres, sphere_maps, tint, rng)
        }
        Category::CloseUp => close_up(sphere, maps, rng),
        Category::SoftFocus => {
            let r = log_uniform(rng, 100.0, 400.0);
            let margin = 0.25 * r + 4.0;
            let w = (2.0 * (r + margin) + rng.next_f64() * 600.0).ceil() as usize;
            let h = (2.0 * (r + margin) + rng.next_f64() * 400.0).ceil() as usize;
            let at = placed(w, h, r, margin, rng);
            let mut staged = single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng);
            staged.blur = (0.015 + 0.025 * rng.next_f64()) * r;
            staged
        }
        Category::SmallInClutter => small_in_clutter(sphere, maps, rng),
    }
}

/// A mirror ball, its reflectance times `tint`, in front of the scene it reflects at the
/// brightness of its reflection, softly focused.
fn in_own_scene(spheres: &[Sphere], sphere_maps: &[EnvMap], tint: f64, rng: &mut Rng) -> Staged {
    let own: Vec<&Sphere> = spheres.iter().filter(|s| s.mirror).collect();
    let sphere = own[rng.below(own.len() as u64) as usize];
    let r = log_uniform(rng, 60.0, 300.0);
    let w = (2.0 * r + 100.0 + rng.next_f64() * 500.0).ceil() as usize;
    let h = (2.0 * r + 100.0 + rng.next_f64() * 300.0).ceil() as usize;
    let at = placed(w, h, r, 0.2 * r, rng);
    let inside = tint * median(sphere.luminance.iter().copied().collect()) / sphere.white;
    let mut scene = scene(&sphere_maps[sphere.probe], w, h, inside, rng);
    let tinted = Sphere {
        luminance: sphere.luminance.mapv(|v| v * tint),
        ..*sphere
    };
    paste(&mut scene, &tinted, &at, &ON_AXIS);
    Staged {
        scene,
        spheres: vec![(at, ON_AXIS)],
        blur: 0.5 + 2.0 * rng.next_f64(),
    }
}

/// A ball held up close: wider than the frame's shorter side, crossing one or two edges
/// with half to four fifths of its rim inside.
fn close_up(sphere: &Sphere, maps: &[EnvMap], rng: &mut Rng) -> Staged {
    let h = (600.0 + 1400.0 * rng.next_f64()) as usize;
    let w = (h as f64 * (1.0 + 0.5 * rng.next_f64())) as usize;
    let draw = |rng: &mut Rng| Circle {
        cx: w as f64 * rng.next_f64(),
        cy: h as f64 * rng.next_f64(),
        r: (0.525 + 0.225 * rng.next_f64()) * h as f64,
    };
    let mut at = draw(rng);
    while !(0.5..=0.8).contains(&locate::visible_rim(&at, w, h)) {
        at = draw(rng);
    }
    single(sphere, (w, h), (at, ON_AXIS), rng.below(2) == 0, maps, rng)
}

/// A small ball in a furnished room: a scene, objects around (boxes, elongated shapes) and a
/// ring (a plate, a clock) of another size.
fn small_in_clutter(sphere: &Sphere, maps: &[EnvMap], rng: &mut Rng) -> Staged {
    let w = (2000.0 + 2000.0 * rng.next_f64()) as usize;
    let h = w * 3 / 4;
    let r = log_uniform(rng, 30.0, 70.0);
    let at = placed(w, h, r, 0.25 * r + 4.0, rng);
    let mut staged = single(sphere, (w, h), (at, ON_AXIS), true, maps, rng);
    for _ in 0..3 {
        clutter(&mut staged.scene, &[at], rng);
    }
    for _ in 0..100 {
        let ring = placed(w, h, r * (2.0 + 2.0 * rng.next_f64()), 4.0, rng);
        if (ring.cx - at.cx).hypot(ring.cy - at.cy) > ring.r + at.r + 0.5 * r {
            let inner = Circle {
                r: ring.r * (0.75 + 0.15 * rng.next_f64()),
                ..ring
            };
            let inside = staged.scene.clone();
            let level = 0.05 + 1.0 * rng.next_f64();
            paint(&mut staged.scene, &ring, &ON_AXIS, |_, _| level);
            paint(&mut staged.scene, &inner, &ON_AXIS, |x, y| inside[[y, x]]);
            break;
        }
    }
    staged
}

/// Two or three balls and two to four flat discs and rings of similar size, apart.
fn crowd(spheres: &[Sphere], maps: &[EnvMap], rng: &mut Rng) -> Staged {
    let (w, h) = (
        (900.0 + 700.0 * rng.next_f64()) as usize,
        (700.0 + 400.0 * rng.next_f64()) as usize,
    );
    let mut scene = background(
        w,
        h,
        (rng.below(2) == 0).then_some(f64::INFINITY),
        maps,
        rng,
    );
    let mut placed_circles: Vec<Circle> = Vec::new();
    let (balls, flats) = (2 + rng.below(2) as usize, 2 + rng.below(3) as usize);
    let mut tries = 0;
    while placed_circles.len() < balls + flats && tries < 200 {
        tries += 1;
        let r = log_uniform(rng, 60.0, 160.0);
        let at = placed(w, h, r, 0.2 * r + 4.0, rng);
        if placed_circles
            .iter()
            .any(|c| (c.cx - at.cx).hypot(c.cy - at.cy) < c.r + at.r + 20.0)
        {
            continue;
        }
        placed_circles.push(at);
    }
    let (ball_circles, flat_circles) = placed_circles.split_at(balls.min(placed_circles.len()));
    for at in flat_circles {
        let level = 0.05 + 1.0 * rng.next_f64();
        if rng.below(2) == 0 {
            paint(&mut scene, at, &ON_AXIS, |_, _| level);
        } else {
            // A ring (a plate's rim, a clock's bezel) around the background.
            let inner = Circle {
                r: at.r * (0.75 + 0.15 * rng.next_f64()),
                ..*at
            };
            let inside = scene.clone();
            paint(&mut scene, at, &ON_AXIS, |_, _| level);
            paint(&mut scene, &inner, &ON_AXIS, |x, y| inside[[y, x]]);
        }
    }
    for at in ball_circles {
        let sphere = &spheres[rng.below(spheres.len() as u64) as usize];
        paste(&mut scene, sphere, at, &ON_AXIS);
    }
    Staged {
        scene,
        spheres: ball_circles.iter().map(|c| (*c, ON_AXIS)).collect(),
        blur: 0.1 + 0.9 * rng.next_f64(),
    }
}

/// The camera: exposure, lens blur, noise, clipping, 8-bit sRGB JPEG at quality 70–95.
fn photograph(staged: &Staged, rng: &mut Rng) -> (Vec<u8>, u8) {
    let (h, w) = staged.scene.dim();
    let exposure = 0.3 + 0.4 * rng.next_f64();
    let blurred = gaussian_blur(staged.scene.view(), staged.blur);
    let noise = 0.02 * rng.next_f64();
    let quality = 70 + rng.below(26) as u8;
    let mut rgb = Vec::with_capacity(w * h * 3);
    for &v in blurred.iter() {
        let x = v * exposure;
        let u1 = 1.0 - rng.next_f64();
        let gauss = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * rng.next_f64()).cos();
        let x = (x + noise * exposure * (x / exposure).max(0.0).sqrt() * gauss).clamp(0.0, 1.0);
        let code = (255.0 * linear_to_srgb(x)).round() as u8;
        rgb.extend([code, code, code]);
    }
    let mut jpeg = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, quality),
        &rgb,
        w as u32,
        h as u32,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    (jpeg, quality)
}

/// Within 2 % of the sphere's radius, in centre and in radius (of a stretched one: between
/// its shortest and longest radius).
fn matches(found: &locate::Geometry, (truth, stretch): &(Circle, Stretch)) -> bool {
    (found.cx - truth.cx).hypot(found.cy - truth.cy) <= 0.02 * truth.r
        && found.r >= 0.98 * truth.r
        && found.r <= 1.02 * truth.r * stretch.factor
}

/// Found within 2 % of r per kind of `kinds`, on `count` composites cycling through them
/// (seeded by `seed`), printed as a table with the misses; the counts per kind and the misses.
fn measure(kinds: &[Category], seed: u64, count: usize) -> (Vec<(usize, usize)>, Vec<String>) {
    let sphere_maps: Vec<EnvMap> = SPHERE_PROBES.iter().map(|n| probe(n)).collect();
    let maps: Vec<EnvMap> = SCENE_PROBES.iter().map(|n| probe(n)).collect();
    let spheres = spheres(&sphere_maps);
    let options = DecodeOptions {
        encoding: None,
        colour: false,
        limits: Limits {
            max_pixels: 60_000_000,
            ..Limits::default()
        },
    };
    let mut per_kind = vec![(0usize, 0usize); kinds.len()];
    let mut misses = Vec::new();
    for i in 0..count {
        let index = i % kinds.len();
        let category = kinds[index];
        let mut rng = Rng::fork(seed, i as u64);
        let staged = stage(category, &spheres, &sphere_maps, &maps, &mut rng);
        let (jpeg, quality) = photograph(&staged, &mut rng);
        drop(staged.scene);
        let image = decode(&jpeg, &options).unwrap();
        let found = detect_as_received(image.luminance.view()).0;
        let good = found
            .as_ref()
            .is_ok_and(|g| staged.spheres.iter().any(|truth| matches(g, truth)));
        per_kind[index].1 += 1;
        if good {
            per_kind[index].0 += 1;
        } else {
            let (h, w) = image.luminance.dim();
            misses.push(format!(
                "#{i} {category:?} {w}×{h} q{quality} truth {:?}: {found:?}",
                staged.spheres
            ));
            if let Some(dir) = std::env::var_os("REFLECTANCE_COMPOSITE_DUMP") {
                let _ = std::fs::write(PathBuf::from(dir).join(format!("miss{i}.jpg")), &jpeg);
            }
        }
    }
    let total: usize = per_kind.iter().map(|k| k.0).sum();
    eprintln!("| category | found within 2 % of r |\n|---|---|");
    for (category, (ok, n)) in kinds.iter().zip(&per_kind) {
        eprintln!("| {category:?} | {ok} / {n} |");
    }
    eprintln!("found {total}/{count}");
    for miss in &misses {
        eprintln!("miss {miss}");
    }
    (per_kind, misses)
}

/// Each kind at least `of_20(kind)` of 20 found, applied to this run's count (rounded down
/// to whole composites).
fn assert_floors(
    kinds: &[Category],
    per_kind: &[(usize, usize)],
    misses: &[String],
    of_20: impl Fn(Category) -> usize,
) {
    for (&category, &(ok, n)) in kinds.iter().zip(per_kind) {
        let of_20 = of_20(category);
        let floor = (of_20 * n) / 20;
        assert!(
            ok >= floor,
            "{category:?}: {ok} of {n} found, docs/accuracy.md reports {of_20} of 20: {misses:#?}"
        );
    }
}

/// `REFLECTANCE_COMPOSITES`, else `default`.
fn composite_count(default: usize) -> usize {
    std::env::var("REFLECTANCE_COMPOSITES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
fn spheres_are_found_in_photograph_like_composites() {
    let count = composite_count(36);
    let (per_kind, misses) = measure(&CATEGORIES, 2026, count);
    // The rates docs/accuracy.md reports on 180 composites (20 of each kind), applied to
    // this run's count: 90 % in all, and each kind at least its own rate (the suite's run of
    // 4 per kind found 34 of 36).
    let total: usize = per_kind.iter().map(|k| k.0).sum();
    assert!(
        total as f64 >= 0.9 * count as f64,
        "{total} of {count}: {misses:#?}"
    );
    assert_floors(&CATEGORIES, &per_kind, &misses, |category| match category {
        Category::TableTop | Category::Large | Category::FillsFrame => 20,
        Category::Scene | Category::CutByFrame | Category::Crowd => 18,
        Category::Small => 16,
        Category::LowContrast => 15,
        _ => 17,
    });
}

/// The judging set (issue 67): composites of the kinds real photographs were missed on, kept
/// apart from the tuning set above so that a change is judged on what it was not tuned on.
/// `REFLECTANCE_COMPOSITES=80 cargo test --release --test numerics found_in_judging_composites
/// -- --nocapture` measures docs/accuracy.md's table.
#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
fn found_in_judging_composites() {
    let (per_kind, misses) = measure(&JUDGING, 2027, composite_count(16));
    // docs/accuracy.md's rates on 80 (20 of each kind), less one.
    assert_floors(&JUDGING, &per_kind, &misses, |category| match category {
        Category::CloseUp => 18,
        Category::SoftFocus => 17,
        Category::Tinted => 11,
        _ => 13,
    });
}

#[test]
fn refusals_say_why() {
    // Texture and nothing round: a refusal that says why.
    let mut rng = Rng::new(5);
    let noise = Array2::from_shape_fn((300, 400), |_| rng.next_f64());
    let flat = Array2::from_elem((300, 400), 0.4);
    let square = Array2::from_shape_fn((300, 400), |(y, x)| {
        if (60..240).contains(&y) && (100..280).contains(&x) {
            0.9
        } else {
            0.1
        }
    });
    for image in [noise, flat, square] {
        match locate::detect(image.view()) {
            Err(e @ GeometryError::DetectionFailed { .. }) => {
                // Why, in words; what to give instead is each surface's to say (the service
                // its fields: tests/server; the command line its flags: tests/cli).
                let message = e.to_string();
                assert!(
                    message.starts_with("could not find the sphere automatically: ")
                        && message.len() > 45,
                    "{message}"
                );
            }
            other => panic!("{other:?}"),
        }
    }
}

/// scikit-image's sample data: `REFLECTANCE_SKIMAGE_DATA`, else where `python3` finds it.
fn skimage_data() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("REFLECTANCE_SKIMAGE_DATA") {
        return Some(PathBuf::from(dir));
    }
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import os, skimage.data; print(os.path.dirname(skimage.data.__file__))",
        ])
        .output()
        .ok()?;
    let dir = String::from_utf8(out.stdout).ok()?;
    out.status.success().then(|| PathBuf::from(dir.trim()))
}

/// The most sample photographs of scikit-image (26 PNG and JPEG files, none of them a ball:
/// a camera man, coins, a colour wheel, a retina, …) in which a circle may be chosen
/// (docs/accuracy.md).
const SKIMAGE_CHOSEN_CEILING: usize = 7;

#[test]
#[ignore = "needs scikit-image's sample data (python3 -m pip install scikit-image, or REFLECTANCE_SKIMAGE_DATA)"]
fn few_circles_are_chosen_in_scikit_image_samples() {
    let dir = skimage_data().expect("scikit-image's sample data");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("scikit-image's data directory")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e, "png" | "jpg"))
        })
        .collect();
    paths.sort();
    let options = DecodeOptions {
        encoding: None,
        colour: false,
        limits: Limits::default(),
    };
    let mut chosen = Vec::new();
    for path in &paths {
        let Ok(image) = reflectance_core::decode::decode_file(path, &options) else {
            continue;
        };
        if let Ok(g) = locate::detect(image.luminance.view()) {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            chosen.push(format!(
                "{name} ({:.0}, {:.0}, r {:.0}) at {:.2}",
                g.cx,
                g.cy,
                g.r,
                g.confidence.unwrap_or(1.0)
            ));
        }
    }
    eprintln!("a circle chosen in {} of {}:", chosen.len(), paths.len());
    for c in &chosen {
        eprintln!("  {c}");
    }
    assert!(
        chosen.len() <= SKIMAGE_CHOSEN_CEILING,
        "a circle chosen in {} of {} of scikit-image's sample photographs: {chosen:#?}",
        chosen.len(),
        paths.len()
    );
}

/// A shaded ball painted over `image` whose rim fades into the background (no edge) along
/// `hidden` of its circumference, in six evenly spaced arcs: a mirror ball whose rim
/// vanishes against what it reflects.
fn partial_rim_ball(image: &mut Array2<f64>, ball: &Circle, hidden: f64) {
    for ((y, x), v) in image.indexed_iter_mut() {
        let (dx, dy) = ((x as f64 - ball.cx) / ball.r, (y as f64 - ball.cy) / ball.r);
        let d2 = dx * dx + dy * dy;
        if d2 > 1.0 {
            continue;
        }
        let shade = 0.55 + 0.3 * (0.5 * (-dx - dy) + 0.7 * (1.0 - d2).sqrt()).max(0.0);
        let turn = (dy.atan2(dx) / std::f64::consts::TAU + 1.0).fract();
        let in_arc = (turn * 6.0).fract() < hidden;
        *v = if in_arc {
            let t = ((1.0 - d2.sqrt()) / 0.3).clamp(0.0, 1.0);
            let smooth = t * t * (3.0 - 2.0 * t);
            *v + (shade - *v) * smooth
        } else {
            shade
        };
    }
}

/// A `w`×`h` picture, background 0.4, of `balls` whose rims fade into it along `hidden` of
/// their circumference.
fn faint_balls((w, h): (usize, usize), balls: &[Circle], hidden: f64) -> Array2<f64> {
    let mut image = Array2::from_elem((h, w), 0.4);
    for ball in balls {
        partial_rim_ball(&mut image, ball, hidden);
    }
    image
}

fn near(g: &locate::Geometry, c: &Circle) -> bool {
    (g.cx - c.cx).hypot(g.cy - c.cy) <= 0.02 * c.r && (g.r - c.r).abs() <= 0.02 * c.r
}

/// The refusal of `detect_ranked`'s answer, and the alternatives it offers.
fn refusal(image: &Array2<f64>) -> (String, Vec<locate::Geometry>) {
    match locate::detect_ranked(image.view()) {
        (Err(e @ GeometryError::DetectionFailed { .. }), offered) => (e.to_string(), offered),
        (other, _) => panic!("not refused: {other:?}"),
    }
}

#[test]
fn a_ball_with_a_faint_rim_is_taken_only_alone_and_clear_enough() {
    // Every refusal path of automatic location beyond texture and nothing round (above),
    // each beside the answer it would become if its rule were loosened. The rules themselves,
    // on both sides of each line: `locate::detect`'s unit tests.
    let ball = Circle {
        cx: 160.0,
        cy: 150.0,
        r: 90.0,
    };
    // Its rim clear along 44 % of it: under the line for any circle (0.5), over the lone
    // ball's (0.4), and nothing else round: taken.
    let alone = faint_balls((320, 300), &[ball], 0.55);
    let g = locate::detect(alone.view()).unwrap();
    assert!(near(&g, &ball), "{g:?}");
    let confidence = g.confidence.unwrap();
    assert!((0.4..0.5).contains(&confidence), "{confidence}");

    // A little fainter (39 %): refused, saying how clear its rim is, and offered.
    let (why, offered) = refusal(&faint_balls((320, 300), &[ball], 0.6));
    assert!(why.contains("only 39 %"), "{why}");
    assert!(offered.iter().any(|g| near(g, &ball)), "{offered:?}");

    // Two such balls: neither stands alone, so neither is taken; both are offered.
    let twin = Circle { cx: 480.0, ..ball };
    let (why, offered) = refusal(&faint_balls((640, 300), &[ball, twin], 0.55));
    assert!(why.contains("radius 90"), "{why}");
    for b in [&ball, &twin] {
        assert!(offered.iter().any(|g| near(g, b)), "{b:?}: {offered:?}");
    }

    // A small one (r 40) as faint: its rim (or the circle just inside it) is too short for
    // over 40 % to count as much.
    let small = Circle { r: 40.0, ..ball };
    let (why, _) = refusal(&faint_balls((320, 300), &[small], 0.55));
    let percent: f64 = why
        .split("only ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|p| p.parse().ok())
        .unwrap_or(0.0);
    assert!(why.contains("centre 160, 150") && percent >= 40.0, "{why}");
}
