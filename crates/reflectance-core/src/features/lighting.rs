//! Whether one small light in the dark lit the sphere (docs/design.md §3 "Domain", the
//! lighting check).
//!
//! A sphere's shading under one distant source of light is A·max(0, n·l) + C: a clamped
//! cosine of the normal n around the light's direction l, plus what the rest of the world
//! adds (C). Any wider light is a sum of such cosines, which is flatter than any one of them,
//! so C/(A + C), the *ambient share*, is the dimmest side's share of the brightest: about
//! 0.1–0.5 in daylight and in rooms, down to 0.014 for a matte sphere in full sun under the
//! 70 probes of `../shared`, and 0 for a lamp in the dark. A fit that makes it clearly
//! negative sees shading that falls to black toward the rim faster than a cosine, which takes
//! a small source in the dark *and* pixels curved more steeply than sRGB (linear data read as
//! sRGB, a camera curve far steeper than sRGB).
//!
//! The fit: about [`SAMPLES`] pixels of the disc within 0.9 r, the light's direction searched
//! over a Fibonacci lattice of [`DIRECTIONS`] and refined in a shrinking 3 × 3 pattern, A and
//! C by least squares for each; the pixels brighter than the fit by 2.5 residual deviations
//! (the highlights) are then left out and the fit refined again from there, up to three times. `fit` is the
//! share of the kept pixels' variance the model explains: a sphere lit by a scene (a mirror,
//! texture, several lights) fits poorly, and then the share says nothing.
//!
//! The same fit tells a highlight: pixels far above the diffuse shading, which no matte
//! surface shows (`highlight`); a matte answer for such a sphere is not sure of itself
//! (`inference::decide` adds the glossy classes to its set).

use crate::image::circle::Circle;
use ndarray::ArrayView2;
use std::ops::Range;

/// Pixels the fit samples, about.
pub const SAMPLES: usize = 256;
/// Directions of the coarse search.
pub const DIRECTIONS: usize = 64;
/// The fit's explained share of the variance at least this: the shading is one light's.
pub const MIN_FIT: f64 = 0.9;
/// Below this ambient share, with a fit at least [`MIN_FIT`], the input is out of domain:
/// about half-way from 0 to the −0.27 and −0.30 of a photometric-stereo ball stored as linear
/// 8-bit data (docs/accuracy.md, "Honest answers"), and below the −0.11 of a sphere under
/// `open3d_streetlamp` (a street lamp at night) through a camera curve 1.25 times steeper
/// than sRGB.
pub const AMBIENT_LIMIT: f64 = -0.15;

/// A highlight: the mean of the [`HIGHLIGHT_PIXELS`] pixels furthest above the fit at least
/// this share of the fit's brightest (A + C). Under the 25 probes held out of training no
/// matte sphere comes above 0.28 rendered, 0.57 through the capture model (noise, JPEG); the
/// median white_shiny capture reaches 0.72, the median black_shiny one 5 (docs/accuracy.md,
/// "Honest answers").
pub const HIGHLIGHT: f64 = 0.75;
/// Pixels averaged for the highlight: a few, so that one noisy pixel does not make one.
pub const HIGHLIGHT_PIXELS: usize = 5;

/// The clamped-cosine fit of a sphere's shading (see the module).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// C / (A + C): the dimmest side's brightness as a share of the brightest's.
    pub ambient: f64,
    /// The share of the variance the fit explains, over the pixels it kept.
    pub fit: f64,
    /// How far the brightest few pixels of the disc rise above the fit, as a share of the
    /// fit's brightest: a specular highlight, which a matte surface does not show.
    pub highlight: f64,
}

impl Shading {
    /// Lit by one small source in the dark, on pixels steeper than sRGB: out of domain.
    pub fn beyond_any_light(&self) -> bool {
        self.fit >= MIN_FIT && self.ambient < AMBIENT_LIMIT
    }

    /// The sphere shows a highlight brighter than its diffuse shading: not matte.
    pub fn shows_highlight(&self) -> bool {
        self.highlight >= HIGHLIGHT
    }

    /// Why such an input is out of domain, in words.
    pub fn reason(&self) -> String {
        format!(
            "its shading falls to black toward the rim faster than any light can make it \
             (one light's cosine explains {:.0} % of it, with an ambient share of {:.2}, where \
             daylight and rooms give 0.01 or more): one small lamp in the dark, with pixels \
             that are not sRGB-encoded; the model knows natural light, not a single lamp, and \
             if the pixels are linear (raw or scientific data), say so with encoding=linear",
            100.0 * self.fit,
            self.ambient
        )
    }
}

/// One sampled pixel: its normal and luminance.
struct Sample {
    n: [f64; 3],
    l: f64,
}

/// The fit of the sphere `c` in `image` (`None`: too few pixels, or no light explains
/// anything, as on a flat disc).
pub fn shading(image: ArrayView2<f64>, c: &Circle) -> Option<Shading> {
    let samples = sample(image, c);
    if samples.len() < SAMPLES / 4 {
        return None;
    }
    let mut kept: Vec<&Sample> = samples.iter().collect();
    let mut best = refine(&kept, coarse(&kept)?, 0.2);
    for _ in 0..3 {
        let deviation = best.mse.sqrt();
        let next: Vec<&Sample> = samples
            .iter()
            .filter(|s| s.l - best.predict(s) < 2.5 * deviation)
            .collect();
        if next.len() == kept.len() || next.len() < SAMPLES / 4 {
            break;
        }
        kept = next;
        best = refine(&kept, fit_along(&kept, best.dir)?, 0.05);
    }
    let mean = kept.iter().map(|s| s.l).sum::<f64>() / kept.len() as f64;
    let variance = kept.iter().map(|s| (s.l - mean).powi(2)).sum::<f64>() / kept.len() as f64;
    if variance <= 0.0 {
        return None;
    }
    Some(Shading {
        ambient: best.c / (best.a + best.c),
        fit: 1.0 - best.mse / variance,
        highlight: highlight(image, c, &best),
    })
}

/// The mean of the [`HIGHLIGHT_PIXELS`] largest rises above `fit` over the disc within 0.9 r,
/// as a share of the fit's brightest. Every pixel is read (a highlight can be smaller than
/// the samples' spacing), but the fit is evaluated at the brightest pixel of each 2 × 2
/// block only: a highlight's pixels are its block's brightest, and the fit barely changes
/// within a block.
fn highlight(image: ArrayView2<f64>, c: &Circle, fit: &Fit) -> f64 {
    let mut top = [f64::NEG_INFINITY; HIGHLIGHT_PIXELS];
    let width = image.ncols();
    let (rows, cols) = disc_bounds(image, c);
    let standard = image.as_standard_layout();
    let Some(pixels) = standard.as_slice() else {
        return 0.0;
    };
    // The fit's cosine along a row is concave (a plane plus a half-circle's height), so its
    // least over the row's part of the disc is at one of the ends: the fit there bounds it.
    let least_cosine = |row: usize| {
        let y = (c.cy - row as f64) / c.r;
        let half = (0.81 - y * y).max(0.0).sqrt();
        let z = (1.0 - y * y - half * half).max(0.0).sqrt();
        let end = |x: f64| cosine(&[x, y, z], &fit.dir);
        end(-half).min(end(half))
    };
    for row in rows.clone().step_by(2) {
        // (With the light behind the sphere's rim, the cosine is convex: only C bounds it.)
        let least = match fit.dir[2] >= 0.0 {
            true => least_cosine(row).min(least_cosine(row + 1)),
            false => 0.0,
        };
        let floor = fit.c + fit.a * least;
        for col in cols.clone().step_by(2) {
            let block = (row..(row + 2).min(rows.end), col..(col + 2).min(cols.end));
            let (value, r, k) = brightest(pixels, width, block);
            if value - floor <= top[0] {
                continue;
            }
            let (x, y) = ((k as f64 - c.cx) / c.r, (c.cy - r as f64) / c.r);
            let rho2 = x * x + y * y;
            if rho2 >= 0.81 {
                continue;
            }
            let rise = value - fit.a * cosine(&[x, y, (1.0 - rho2).sqrt()], &fit.dir) - fit.c;
            if rise > top[0] {
                top[0] = rise;
                top.sort_unstable_by(f64::total_cmp);
            }
        }
    }
    let mean = top.iter().sum::<f64>() / HIGHLIGHT_PIXELS as f64;
    (mean / (fit.a + fit.c)).max(0.0)
}

/// The brightest pixel of a block of rows and columns of the row-major `pixels`: its value,
/// row and column.
fn brightest(
    pixels: &[f64],
    width: usize,
    (rows, cols): (Range<usize>, Range<usize>),
) -> (f64, usize, usize) {
    let mut best = (f64::NEG_INFINITY, rows.start, cols.start);
    for r in rows {
        for (k, &value) in pixels[r * width + cols.start..r * width + cols.end]
            .iter()
            .enumerate()
        {
            if value > best.0 {
                best = (value, r, cols.start + k);
            }
        }
    }
    best
}

/// The rows and columns of `image` that hold the disc within 0.9 r of `c`.
fn disc_bounds(image: ArrayView2<f64>, c: &Circle) -> (Range<usize>, Range<usize>) {
    let (height, width) = image.dim();
    let span = |centre: f64, limit: usize| {
        let low = (centre - 0.9 * c.r).floor().max(0.0) as usize;
        low.min(limit)..((centre + 0.9 * c.r).ceil().max(0.0) as usize + 1).min(limit)
    };
    (span(c.cy, height), span(c.cx, width))
}

/// The first multiple of `stride` at or after `start`, through the end of `range`.
fn aligned(range: Range<usize>, stride: usize) -> impl Iterator<Item = usize> {
    (range.start.div_ceil(stride) * stride..range.end).step_by(stride)
}

/// The disc within 0.9 r on a grid of about [`SAMPLES`] pixels (pixel centres are integers;
/// the grid's rows and columns are the multiples of its stride).
fn sample(image: ArrayView2<f64>, c: &Circle) -> Vec<Sample> {
    let reach = 0.9 * c.r;
    let area = std::f64::consts::PI * reach * reach;
    let stride = ((area / SAMPLES as f64).sqrt().floor() as usize).max(1);
    let (rows, cols) = disc_bounds(image, c);
    let mut out = Vec::with_capacity(2 * SAMPLES);
    for row in aligned(rows, stride) {
        let y = (c.cy - row as f64) / c.r;
        if y.abs() >= 0.9 {
            continue;
        }
        for col in aligned(cols.clone(), stride) {
            let x = (col as f64 - c.cx) / c.r;
            let rho2 = x * x + y * y;
            if rho2 < 0.81 {
                let l = image[(row, col)];
                out.push(Sample {
                    n: [x, y, (1.0 - rho2).sqrt()],
                    l,
                });
            }
        }
    }
    out
}

/// A light's direction with its least-squares A, C and mean squared residual.
#[derive(Clone, Copy)]
struct Fit {
    dir: [f64; 3],
    a: f64,
    c: f64,
    mse: f64,
}

impl Fit {
    fn predict(&self, s: &Sample) -> f64 {
        self.a * cosine(&s.n, &self.dir) + self.c
    }
}

fn cosine(n: &[f64; 3], l: &[f64; 3]) -> f64 {
    (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0)
}

/// The least-squares fit for the direction `dir` (`None` unless it explains with A > 0).
fn fit_along(samples: &[&Sample], dir: [f64; 3]) -> Option<Fit> {
    let n = samples.len() as f64;
    let (mut s, mut ss, mut l, mut sl, mut ll) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for sample in samples {
        let x = cosine(&sample.n, &dir);
        s += x;
        ss += x * x;
        l += sample.l;
        sl += x * sample.l;
        ll += sample.l * sample.l;
    }
    let var = ss / n - (s / n).powi(2);
    let cov = sl / n - (s / n) * (l / n);
    if var <= 1e-12 || cov <= 0.0 {
        return None;
    }
    let a = cov / var;
    let c = l / n - a * s / n;
    let mse = (ll / n - (l / n).powi(2) - a * cov).max(0.0);
    Some(Fit { dir, a, c, mse })
}

/// The better of two fits (a missing one loses).
fn better(best: Option<Fit>, candidate: Option<Fit>) -> Option<Fit> {
    match (best, candidate) {
        (Some(b), Some(c)) if c.mse < b.mse => Some(c),
        (None, c) => c,
        (b, _) => b,
    }
}

/// The best direction of the Fibonacci lattice.
fn coarse(samples: &[&Sample]) -> Option<Fit> {
    lattice()
        .into_iter()
        .fold(None, |best, dir| better(best, fit_along(samples, dir)))
}

/// `start` refined in a 3 × 3 pattern around the best so far, from `step` (radians) halving
/// down to 0.025.
fn refine(samples: &[&Sample], start: Fit, mut step: f64) -> Fit {
    let mut best = start;
    while step >= 0.025 {
        let centre = best.dir;
        let (t1, t2) = tangents(centre);
        for i in [-1.0, 0.0, 1.0] {
            for j in [-1.0, 0.0, 1.0] {
                let d: [f64; 3] =
                    std::array::from_fn(|k| centre[k] + step * (i * t1[k] + j * t2[k]));
                if let Some(fit) = better(Some(best), fit_along(samples, normalized(d))) {
                    best = fit;
                }
            }
        }
        step /= 2.0;
    }
    best
}

/// [`DIRECTIONS`] directions spread evenly over the sphere (a Fibonacci lattice).
fn lattice() -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (1.0 + 5f64.sqrt());
    (0..DIRECTIONS)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / DIRECTIONS as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * (i as f64 + 0.5);
            [r * phi.cos(), r * phi.sin(), z]
        })
        .collect()
}

fn normalized(d: [f64; 3]) -> [f64; 3] {
    let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|v| v / norm)
}

/// Two unit vectors perpendicular to `l` and to each other.
fn tangents(l: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let other = if l[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t1 = normalized(cross(l, other));
    (t1, cross(l, t1))
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    const C: Circle = Circle {
        cx: 80.0,
        cy: 80.0,
        r: 70.0,
    };

    /// A sphere shaded by `shade(n)`, on a black background.
    fn sphere(shade: impl Fn([f64; 3]) -> f64) -> Array2<f64> {
        Array2::from_shape_fn((161, 161), |(row, col)| {
            let (x, y) = ((col as f64 - C.cx) / C.r, (C.cy - row as f64) / C.r);
            let rho2 = x * x + y * y;
            if rho2 < 1.0 {
                shade([x, y, (1.0 - rho2).sqrt()])
            } else {
                0.0
            }
        })
    }

    fn lamp() -> [f64; 3] {
        normalized([0.3, 0.4, 0.8])
    }

    #[test]
    fn a_lamp_in_the_dark_has_no_ambient_and_a_lamp_with_fill_light_has_its_share() {
        let dark = shading(sphere(|n| cosine(&n, &lamp())).view(), &C).unwrap();
        assert!(dark.fit > 0.999 && dark.ambient.abs() < 0.01, "{dark:?}");
        assert!(!dark.beyond_any_light());
        // A quarter of the lamp's brightness everywhere: C / (A + C) = 0.25 / 1.25.
        let fill = shading(sphere(|n| cosine(&n, &lamp()) + 0.25).view(), &C).unwrap();
        assert!((fill.ambient - 0.2).abs() < 0.01, "{fill:?}");
        // A sharp highlight on top is left out of the fit.
        let highlight = |n: [f64; 3]| {
            let h = normalized([lamp()[0], lamp()[1], lamp()[2] + 1.0]);
            cosine(&n, &lamp()) + 0.25 + 5.0 * cosine(&n, &h).powi(400)
        };
        let glossy = shading(sphere(highlight).view(), &C).unwrap();
        assert!((glossy.ambient - 0.2).abs() < 0.02, "{glossy:?}");
        assert!(
            glossy.shows_highlight() && !fill.shows_highlight(),
            "{glossy:?} {fill:?}"
        );
    }

    #[test]
    fn a_sky_never_falls_below_zero_and_linear_data_read_as_srgb_does() {
        // A hemisphere of sky above: the shading is (1 + n·up) / 2, never a single cosine.
        let sky = shading(sphere(|n| (1.0 + n[1]) / 2.0).view(), &C).unwrap();
        assert!(sky.ambient > 0.1 && !sky.beyond_any_light(), "{sky:?}");
        // A lamp's shading stored as linear 8-bit values and decoded as sRGB.
        let srgb_decoded = |v: f64| {
            let v = (v * 255.0).round() / 255.0;
            if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        };
        let front = normalized([0.1, -0.2, 1.0]);
        let misread = shading(sphere(|n| srgb_decoded(cosine(&n, &front))).view(), &C).unwrap();
        assert!(misread.beyond_any_light(), "{misread:?}");
        assert!(misread.reason().contains("encoding=linear"));
    }

    #[test]
    fn a_scene_in_a_mirror_fits_no_light_and_a_flat_disc_gives_nothing() {
        let scene = |n: [f64; 3]| 0.5 + 0.4 * (23.0 * n[0]).sin() * (17.0 * n[1]).cos();
        let mirror = shading(sphere(scene).view(), &C).unwrap();
        assert!(
            mirror.fit < MIN_FIT && !mirror.beyond_any_light(),
            "{mirror:?}"
        );
        assert_eq!(shading(sphere(|_| 0.5).view(), &C), None);
        // Too small a disc to sample.
        let tiny = Circle { r: 5.0, ..C };
        assert_eq!(shading(sphere(|_| 0.5).view(), &tiny), None);
    }
}
