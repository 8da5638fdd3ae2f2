//! What the camera added, measured on the sphere itself: sensor noise, clipping and lens blur
//! (the capture family, `cap.*`, docs/design.md §8).
//!
//! **Noise.** Over the annulus the features read (0.2 r to 0.9 r), each 2 × 2 block gives a
//! mean m and a diagonal difference d = (a − b − c + e)/2. White noise of standard deviation
//! σ gives d the same σ, while a smooth reflection gives d ≈ 0 (a second mixed derivative),
//! so the median of |d| over many blocks measures the noise and shrugs off the few blocks on
//! sharp reflections (Donoho's MAD estimate, σ = 1.4826·median|d|). Camera noise grows
//! with the signal (shot noise: σ² ∝ m, plus read noise: a constant), so blocks are split
//! into eight bins of mean and σ² = a·m + b is fitted to the bins; the noise at white is
//! √(a + b) (values are in units of white). Blocks touching a clipped pixel are left out.
//!
//! **Clipping.** The fraction of the annulus's pixels at full scale (integer formats only:
//! floating-point images do not clip).
//!
//! **Lens blur.** A blurred mirror looks like a glossy sphere, and the annulus alone cannot
//! tell them apart; the silhouette can: the sphere's rim is a step, so how wide its edge is
//! tells how much the camera blurred. Along 180 rays across the rim, the width at half
//! height of the luminance slope (taken over one pixel), on the rays with the clearest
//! edges, gives σ = √(FWHM²/8 ln 2 − baseline): the baseline is what a sharp capture
//! shows (pixel area and the one-pixel slope).

use super::{Family, Kind, OfSphere, Seen};
use crate::features::layout::Layout;
use crate::features::lighting::{self, Shading};
use crate::features::observed::kept;
use crate::image::circle::Circle;
use crate::locate::detect::{RIM_STEP, RimSlopes, rim_slopes};
use crate::object::normals::EquivalentSphere;
use ndarray::ArrayView2;
use std::ops::Range;

/// Prefix of the capture measurements' names.
pub const CAPTURE_PREFIX: &str = "cap.";
/// The capture measurements: log10 of the noise at white (a fraction of white, floored at
/// 1e-4), the clipped fraction of the annulus, and log10 of the lens blur at the rim as a
/// fraction of the radius (floored at 1e-4): the blur a gloss would have to match, since a
/// lobe's blur grows with the sphere and the lens's does not.
pub const CAPTURE_NAMES: [&str; 3] = ["cap.noise", "cap.clipped", "cap.blur"];
/// Floor of the noise at white and of the rim blur before their log10 (and their value when
/// they cannot be told).
const NOISE_FLOOR: f64 = 1e-4;

/// The capture family, after the blocks.
pub const CAPTURE: Family = Family {
    option: "capture_features",
    help: "Also compute the capture measurements (`cap.noise`: the noise at white estimated on\n\
           the sphere, `cap.clipped`: its clipped fraction, `cap.blur`: the blur of its rim).",
    key: "capture",
    recorded_when_off: false,
    prefix: CAPTURE_PREFIX,
    addition: None,
    kind: Kind::OfSphere(&Capture),
};

struct Capture;

impl OfSphere for Capture {
    fn names(&self) -> &'static [&'static str] {
        &CAPTURE_NAMES
    }

    fn extract(&self, sphere: &Seen<'_>, wanted: &dyn Fn(usize) -> bool) -> Vec<f64> {
        match sphere.equivalent {
            None => of_photograph(sphere, wanted),
            Some(object) => of_object(sphere, object),
        }
    }
}

/// A photographed sphere's measurements; the rim's blur, the dearest, only when wanted.
fn of_photograph(sphere: &Seen<'_>, wanted: &dyn Fn(usize) -> bool) -> Vec<f64> {
    let mut capture = vec![f64::NAN; CAPTURE_NAMES.len()];
    if wanted(0) || wanted(1) {
        let m = measurements(sphere);
        capture[0] = m.noise.unwrap_or(0.0).max(NOISE_FLOOR).log10();
        capture[1] = m.clipped;
    }
    if wanted(2) {
        let (image, circle) = match sphere.blur_as_seen {
            true => sphere.seen(),
            false => (sphere.given.view(), &sphere.circle),
        };
        let sigma = rim_blur(image, circle).unwrap_or(0.0) / circle.r;
        capture[2] = sigma.max(NOISE_FLOOR).log10();
    }
    capture
}

/// An object's equivalent sphere's measurements, as far as they can be told: the noise of its
/// observed cells, which is what its fine bands carry; the clipped share of the annulus's
/// observed cells; the rim blur at its floor, since the sphere has no rim.
fn of_object(sphere: &Seen<'_>, object: &EquivalentSphere) -> Vec<f64> {
    let white = sphere.white;
    let ceiling = sphere
        .full_scale
        .map_or(f64::INFINITY, |f| CLIPPED * f / white);
    let kept = kept(&sphere.annulus, sphere.observed.as_ref().map(|o| &o.mask));
    let clipped = kept.iter().filter(|&&v| v >= ceiling).count();
    let c = &object.circle;
    let seen = |row: usize, col: usize| object.observed[(row, col)];
    let noise = noise_at_white_where(object.luminance.view(), c, white, f64::INFINITY, seen);
    let floor = NOISE_FLOOR.log10();
    let noise = noise.map_or(floor, |n| n.max(NOISE_FLOOR).log10());
    vec![noise, clipped as f64 / kept.len().max(1) as f64, floor]
}

/// What the capture measurements found on one sphere, and how it is lit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureMeasurements {
    /// Noise at white as a fraction of white (`None`: no block of the annulus to read it).
    pub noise: Option<f64>,
    /// Fraction of the annulus's pixels at full scale (0 for floating-point images).
    pub clipped: f64,
    /// How the sphere is lit: one light's clamped-cosine fit of its shading (`None`: from a
    /// feature row, or nothing to fit).
    pub shading: Option<Shading>,
}

impl CaptureMeasurements {
    /// The measurements as a feature row of `layout` holds them (`cap.noise`, `cap.clipped`),
    /// when it has the capture family: the noise back from its floored log10 (`None` at the
    /// floor).
    pub fn of_row(layout: &Layout, row: &[f64]) -> Option<CaptureMeasurements> {
        let capture = layout.family(&CAPTURE);
        let (noise, clipped) = (row.get(capture.start)?, row.get(capture.start + 1)?);
        Some(CaptureMeasurements {
            noise: (*noise > NOISE_FLOOR.log10()).then(|| 10f64.powf(*noise)),
            clipped: *clipped,
            shading: None,
        })
    }
}

/// A photographed sphere's measurements, measured once: the noise at white and the shading
/// as the features see the sphere (at the working radius), the clipped fraction of the image
/// as given.
pub(crate) fn measurements(sphere: &Seen<'_>) -> CaptureMeasurements {
    *sphere.capture.get_or_init(|| {
        let (seen, circle) = sphere.seen();
        let full_scale = sphere.full_scale;
        CaptureMeasurements {
            noise: noise_at_white(
                seen,
                circle,
                sphere.white,
                full_scale.unwrap_or(f64::INFINITY),
            ),
            clipped: full_scale.map_or(0.0, |f| {
                clipped_fraction(sphere.given.view(), &sphere.circle, f)
            }),
            shading: lighting::shading(seen, circle),
        }
    })
}

/// The annulus measured, as fractions of the radius (the features' default annulus).
const INNER: f64 = 0.2;
const OUTER: f64 = 0.9;
/// Bins of block means for the signal-dependent fit.
const BINS: usize = 8;
/// Fewer blocks than this give no estimate.
const MIN_BLOCKS: usize = 64;
/// Samples at or above this fraction of full scale count as clipped.
pub(crate) const CLIPPED: f64 = 0.999;

/// Pixel (x, y) lies in the annulus: beyond its hole and within its outer edge. Squared
/// distances decide all but the points within a hair of an edge, which `hypot` decides as it
/// always has (the measurements, and so the models trained on them, do not depend on the
/// shortcut).
fn inside(c: &Circle, x: f64, y: f64) -> bool {
    let (dx, dy) = (x - c.cx, y - c.cy);
    beyond_inner(c, dx, dy) && within_outer(c, dx, dy)
}

const HAIR: f64 = 1e-9;

fn beyond_inner(c: &Circle, dx: f64, dy: f64) -> bool {
    let (d2, inner2) = (dx * dx + dy * dy, (INNER * c.r).powi(2));
    if d2 > inner2 * (1.0 + HAIR) || d2 < inner2 * (1.0 - HAIR) {
        return d2 > inner2;
    }
    dx.hypot(dy) >= INNER * c.r
}

fn within_outer(c: &Circle, dx: f64, dy: f64) -> bool {
    let (d2, outer2) = (dx * dx + dy * dy, (OUTER * c.r).powi(2));
    if d2 > outer2 * (1.0 + HAIR) || d2 < outer2 * (1.0 - HAIR) {
        return d2 < outer2;
    }
    dx.hypot(dy) <= OUTER * c.r
}

/// The columns of row `y` in the annulus, as two runs (either may be empty): both tests are
/// monotone in |dx|, so each edge is found from its closed form and checked by the test
/// itself, pixel by pixel, where rounding could move it.
fn annulus_runs(c: &Circle, y: usize, cols: Range<usize>) -> [Range<usize>; 2] {
    let dy = y as f64 - c.cy;
    let half = |radius: f64| (radius * radius - dy * dy).max(0.0).sqrt();
    let dx = |x: usize| x as f64 - c.cx;
    let outer = run(&cols, c.cx, half(OUTER * c.r), |x| {
        within_outer(c, dx(x), dy)
    });
    let hole = run(&cols, c.cx, half(INNER * c.r), |x| {
        !beyond_inner(c, dx(x), dy)
    });
    if hole.is_empty() {
        return [outer, 0..0];
    }
    [outer.start..hole.start, hole.end..outer.end]
}

/// The columns of `cols` where `holds` is true, given that they form one run about `centre`
/// whose half-width `half` estimates to within a pixel.
fn run(cols: &Range<usize>, centre: f64, half: f64, holds: impl Fn(usize) -> bool) -> Range<usize> {
    let clamp = |v: f64| v.clamp(cols.start as f64, cols.end as f64) as usize;
    let mut lo = clamp((centre - half).ceil());
    let mut hi = clamp((centre + half).floor() + 1.0).max(lo);
    while lo > cols.start && holds(lo - 1) {
        lo -= 1;
    }
    while lo < hi && !holds(lo) {
        lo += 1;
    }
    while hi < cols.end && holds(hi) {
        hi += 1;
    }
    while hi > lo && !holds(hi - 1) {
        hi -= 1;
    }
    lo..hi
}

/// The rows and columns the annulus spans, clamped to the image.
fn span(c: &Circle, (h, w): (usize, usize)) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    let reach = OUTER * c.r + 1.0;
    let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
    (
        clamp((c.cy - reach).floor(), h)..clamp((c.cy + reach).ceil() + 1.0, h),
        clamp((c.cx - reach).floor(), w)..clamp((c.cx + reach).ceil() + 1.0, w),
    )
}

/// Fraction of the annulus's pixels at or above `full_scale`.
pub fn clipped_fraction(image: ArrayView2<f64>, c: &Circle, full_scale: f64) -> f64 {
    let (rows, cols) = span(c, image.dim());
    let ceiling = CLIPPED * full_scale;
    let (mut clipped, mut total) = (0usize, 0usize);
    for y in rows {
        let row = image.row(y);
        for run in annulus_runs(c, y, cols.clone()) {
            total += run.len();
            clipped += row
                .slice(ndarray::s![run])
                .iter()
                .filter(|&&v| v >= ceiling)
                .count();
        }
    }
    clipped as f64 / total.max(1) as f64
}

/// The noise at white of `image` (linear, white at `white`), from the blocks of the annulus
/// with no sample at or above `full_scale`.
pub fn noise_at_white(
    image: ArrayView2<f64>,
    c: &Circle,
    white: f64,
    full_scale: f64,
) -> Option<f64> {
    noise_at_white_where(image, c, white, full_scale, |_, _| true)
}

/// [`noise_at_white`] over the blocks whose four samples are all `observed` (row, column):
/// an object's equivalent sphere, whose missing cells carry no noise.
pub fn noise_at_white_where(
    image: ArrayView2<f64>,
    c: &Circle,
    white: f64,
    full_scale: f64,
    observed: impl Fn(usize, usize) -> bool,
) -> Option<f64> {
    let (rows, cols) = span(c, image.dim());
    let ceiling = CLIPPED * full_scale;
    let mut blocks: Vec<(f64, f64)> = Vec::new();
    for y in rows.step_by(2) {
        for x in cols.clone().step_by(2) {
            if y + 1 >= image.nrows() || x + 1 >= image.ncols() {
                continue;
            }
            if !inside(c, x as f64 + 0.5, y as f64 + 0.5)
                || ![(y, x), (y, x + 1), (y + 1, x), (y + 1, x + 1)]
                    .iter()
                    .all(|&(r, k)| observed(r, k))
            {
                continue;
            }
            let [a, b, p, q] = [
                image[[y, x]],
                image[[y, x + 1]],
                image[[y + 1, x]],
                image[[y + 1, x + 1]],
            ];
            if a.max(b).max(p).max(q) >= ceiling {
                continue;
            }
            let mean = (a + b + p + q) / (4.0 * white);
            let diagonal = ((a - b - p + q) / (2.0 * white)).abs();
            blocks.push((mean, diagonal));
        }
    }
    if blocks.len() < MIN_BLOCKS {
        return None;
    }
    // Bins of equal counts along the mean: (median mean, σ² from the MAD).
    blocks.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let per_bin = blocks.len() / BINS;
    let bins: Vec<(f64, f64, f64)> = (0..BINS)
        .map(|k| {
            let end = if k + 1 == BINS {
                blocks.len()
            } else {
                (k + 1) * per_bin
            };
            let bin = &mut blocks[k * per_bin..end];
            let mean = bin[bin.len() / 2].0;
            let mut diagonals: Vec<f64> = bin.iter().map(|b| b.1).collect();
            let mid = diagonals.len() / 2;
            let (_, median, _) = diagonals.select_nth_unstable_by(mid, f64::total_cmp);
            let sigma = 1.4826 * *median;
            (mean, sigma * sigma, bin.len() as f64)
        })
        .collect();
    let (a, b) = fit_affine(&bins);
    Some((a + b).max(0.0).sqrt())
}

/// Weighted least squares of σ² = a·m + b over (m, σ², weight), with a, b ≥ 0.
fn fit_affine(bins: &[(f64, f64, f64)]) -> (f64, f64) {
    let (mut sw, mut sm, mut sv, mut smm, mut smv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(m, v, w) in bins {
        sw += w;
        sm += w * m;
        sv += w * v;
        smm += w * m * m;
        smv += w * m * v;
    }
    let det = sw * smm - sm * sm;
    let (a, b) = if det.abs() > 1e-300 {
        ((sw * smv - sm * sv) / det, (smm * sv - sm * smv) / det)
    } else {
        (0.0, sv / sw)
    };
    if a < 0.0 {
        (0.0, (sv / sw).max(0.0))
    } else if b < 0.0 {
        let a = if smm > 0.0 { smv / smm } else { 0.0 };
        (a.max(0.0), 0.0)
    } else {
        (a, b)
    }
}

/// Rays across the rim for the blur estimate.
const BLUR_RAYS: usize = 180;
/// Squared width (px²) of a sharp rim's slope profile, σ² of the pixel area, the one-pixel
/// slope and bilinear sampling together (measured on sharp discs: 0.29).
const BLUR_BASELINE: f64 = 0.29;

/// The lens blur σ (px) at the rim of the sphere at `c` (`None`: no clear rim).
pub fn rim_blur(image: ArrayView2<f64>, c: &Circle) -> Option<f64> {
    // The circle may be off by a pixel and a few per cent of the radius.
    let window = 3.0 + 0.03 * c.r;
    let steps = (2.0 * window / RIM_STEP).ceil() as usize;
    let mut rays: Vec<(f64, f64)> = Vec::with_capacity(BLUR_RAYS);
    for k in 0..BLUR_RAYS {
        let theta = std::f64::consts::TAU * k as f64 / BLUR_RAYS as f64;
        let Some(RimSlopes {
            slope,
            steepest: i,
            peak,
        }) = rim_slopes(image, c, theta, window, steps)
        else {
            continue;
        };
        if peak <= 1e-12 {
            continue;
        }
        let sign = slope[i].signum();
        let half = 0.5 * peak;
        // Half-height crossings on either side, interpolated; a ray whose slope does not
        // fall to half within the window is no clean edge.
        let crossing = |range: &mut dyn Iterator<Item = usize>| {
            let mut previous = i;
            for j in range {
                let v = slope[j] * sign;
                if v <= half {
                    let u = slope[previous] * sign;
                    return Some(j as f64 + (u - half) / (u - v) * (previous as f64 - j as f64));
                }
                previous = j;
            }
            None
        };
        let (Some(left), Some(right)) = (
            crossing(&mut (0..i).rev()),
            crossing(&mut (i + 1..slope.len())),
        ) else {
            continue;
        };
        rays.push((peak, (right - left) * RIM_STEP));
    }
    if rays.len() < BLUR_RAYS / 4 {
        return None;
    }
    // The clearest half of the edges.
    rays.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut widths: Vec<f64> = rays[..rays.len() / 2].iter().map(|r| r.1).collect();
    let mid = widths.len() / 2;
    let (_, fwhm, _) = widths.select_nth_unstable_by(mid, f64::total_cmp);
    let variance = *fwhm * *fwhm / (8.0 * std::f64::consts::LN_2) - BLUR_BASELINE;
    Some(variance.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::rng::Rng;
    use ndarray::Array2;

    fn normal(rng: &mut Rng) -> f64 {
        let u = 1.0 - rng.next_f64();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * rng.next_f64()).cos()
    }

    const C: Circle = Circle {
        cx: 119.5,
        cy: 119.5,
        r: 110.0,
    };

    #[test]
    fn the_annulus_runs_hold_exactly_the_pixels_inside() {
        let mut rng = Rng::new(3);
        // Centres on and between pixels, radii whose edges land on pixel centres (r = 50:
        // 0.2 r = 10 and 0.9 r = 45), circles cut by the image's border, and random ones.
        let mut circles = vec![
            Circle {
                cx: 60.0,
                cy: 60.0,
                r: 50.0,
            },
            Circle {
                cx: 60.5,
                cy: 60.5,
                r: 50.0,
            },
            Circle {
                cx: 10.25,
                cy: 100.0,
                r: 40.0,
            },
            Circle {
                cx: 60.0,
                cy: 60.0,
                r: 0.7,
            },
        ];
        circles.extend((0..200).map(|_| Circle {
            cx: rng.next_f64() * 120.0,
            cy: rng.next_f64() * 120.0,
            r: 1.0 + rng.next_f64() * 70.0,
        }));
        let image = Array2::from_shape_fn((120, 120), |_| rng.next_f64());
        for c in &circles {
            let (rows, cols) = span(c, image.dim());
            for y in rows {
                let mut expected: Vec<usize> = cols
                    .clone()
                    .filter(|&x| inside(c, x as f64, y as f64))
                    .collect();
                let mut got: Vec<usize> = annulus_runs(c, y, cols.clone())
                    .into_iter()
                    .flatten()
                    .collect();
                expected.sort_unstable();
                got.sort_unstable();
                assert_eq!(got, expected, "{c:?}, row {y}");
            }
            let clipped = (span(c, image.dim()).0)
                .flat_map(|y| span(c, image.dim()).1.map(move |x| (y, x)))
                .filter(|&(y, x)| inside(c, x as f64, y as f64))
                .map(|(y, x)| usize::from(image[[y, x]] >= CLIPPED * 0.5))
                .collect::<Vec<_>>();
            let share = clipped.iter().sum::<usize>() as f64 / clipped.len().max(1) as f64;
            assert_eq!(clipped_fraction(image.view(), c, 0.5), share, "{c:?}");
        }
    }

    /// A smooth shaded sphere (white = 2) with shot and read noise at white of `k`.
    fn noisy(k: f64, shot_share: f64, seed: u64) -> Array2<f64> {
        let mut rng = Rng::new(seed);
        Array2::from_shape_fn((240, 240), |(y, x)| {
            let d = (x as f64 - C.cx).hypot(y as f64 - C.cy) / C.r;
            let level = 2.0 * (0.05 + 0.6 * (1.0 - d * d).max(0.0).sqrt());
            let variance = k * k * 4.0 * (shot_share * level / 2.0 + (1.0 - shot_share));
            level + variance.sqrt() * normal(&mut rng)
        })
    }

    #[test]
    fn the_noise_at_white_is_recovered() {
        for (k, share) in [(0.005, 1.0), (0.01, 0.5), (0.025, 0.8)] {
            let est = noise_at_white(noisy(k, share, 7).view(), &C, 2.0, f64::INFINITY).unwrap();
            assert!((est - k).abs() < 0.12 * k, "{k}: {est}");
        }
        let clean = noise_at_white(noisy(0.0, 1.0, 7).view(), &C, 2.0, f64::INFINITY).unwrap();
        assert!(clean < 1e-3, "{clean}");
    }

    #[test]
    fn sharp_reflections_are_not_noise() {
        // Stripes every 6 px across a noiseless sphere: few blocks straddle an edge.
        let image = Array2::from_shape_fn((240, 240), |(y, x)| {
            let d = (x as f64 - C.cx).hypot(y as f64 - C.cy) / C.r;
            if d > 1.0 {
                0.0
            } else if (x / 6) % 2 == 0 {
                1.5
            } else {
                0.2
            }
        });
        let est = noise_at_white(image.view(), &C, 2.0, f64::INFINITY).unwrap();
        assert!(est < 0.002, "{est}");
    }

    /// A shaded disc on a background, blurred by σ (0: sharp, area-sampled).
    fn disc(sigma: f64, circle: &Circle) -> Array2<f64> {
        let image = Array2::from_shape_fn((240, 240), |(y, x)| {
            let offsets = [-0.375, -0.125, 0.125, 0.375];
            let inside = offsets
                .iter()
                .flat_map(|dy| offsets.iter().map(move |dx| (dx, dy)))
                .filter(|(dx, dy)| {
                    (x as f64 + **dx - circle.cx).hypot(y as f64 + **dy - circle.cy) <= circle.r
                })
                .count() as f64
                / 16.0;
            let shade = 0.4 + 0.3 * (x as f64 / 240.0);
            inside * shade + (1.0 - inside) * 0.1
        });
        if sigma > 0.0 {
            crate::image::blur::gaussian_blur(image.view(), sigma)
        } else {
            image
        }
    }

    #[test]
    fn the_lens_blur_is_read_off_the_rim() {
        let c = Circle {
            cx: 119.3,
            cy: 120.6,
            r: 90.0,
        };
        for sigma in [0.0, 0.5, 1.0, 1.5, 2.5] {
            let image = disc(sigma, &c);
            // Also with the circle off by a pixel and 1.5 % of the radius.
            for given in [
                c,
                Circle {
                    cx: c.cx + 1.0,
                    r: c.r * 1.015,
                    ..c
                },
            ] {
                let est = rim_blur(image.view(), &given).unwrap();
                assert!((est - sigma).abs() < 0.2, "{sigma}: {est}");
            }
        }
        let flat = Array2::from_elem((240, 240), 0.3);
        assert_eq!(rim_blur(flat.view(), &c), None);
    }

    #[test]
    fn clipping_is_measured_and_excluded() {
        let mut image = noisy(0.01, 1.0, 3);
        // The left half clipped at full scale 1.5.
        image.indexed_iter_mut().for_each(
            |((_, x), v)| {
                if x < 120 { *v = 1.5 } else { *v = v.min(1.5) }
            },
        );
        let clipped = clipped_fraction(image.view(), &C, 1.5);
        assert!((clipped - 0.5).abs() < 0.03, "{clipped}");
        let est = noise_at_white(image.view(), &C, 2.0, 1.5).unwrap();
        assert!((est - 0.01).abs() < 0.002, "{est}");
        // A small or fully clipped annulus gives no estimate.
        let tiny = Circle { r: 4.0, ..C };
        assert_eq!(noise_at_white(image.view(), &tiny, 2.0, 1.5), None);
        let flat = Array2::from_elem((240, 240), 1.5);
        assert_eq!(noise_at_white(flat.view(), &C, 2.0, 1.5), None);
        assert_eq!(clipped_fraction(flat.view(), &C, 1.5), 1.0);
    }
}
