//! Whether the circle follows a sphere's outline (the domain family, `dom.outline`,
//! docs/design.md §8): the evidence the domain check weighs against "this circle is on
//! something else", or "it misses the sphere".
//!
//! A sphere's silhouette is a luminance step at the same radius all around the circle,
//! while the edges inside a reflection or a photograph of anything else lie at every radius.
//! Along [`RAYS`] rays from 0.7 r to 1.3 r, the slope over about a pixel is divided by the
//! ray's own steepest slope (so a faint rim counts like a sharp one), and the rays are
//! averaged into a profile over the radius. The value is how far the profile rises near r
//! (within max(1.5 px, 2.5 % of r), the reported circle's slack) above its median away from r
//! (beyond twice that): about 1 for a clean silhouette on a plain background, near 0 when no
//! edge follows the circle.

use super::{Family, Kind, OfSphere, Seen};
use crate::features::stats;
use crate::image::circle::Circle;
use ndarray::ArrayView2;
use std::borrow::Cow;

/// Prefix of the domain measurements' names.
pub const DOMAIN_PREFIX: &str = "dom.";
/// The domain measurements: how well the circle follows a sphere's outline.
pub const DOMAIN_NAMES: [&str; 1] = ["dom.outline"];

/// The domain family, last.
pub const DOMAIN: Family = Family {
    option: "domain_features",
    help: "Also measure how well the circle follows a sphere's outline (`dom.outline`), which a\n\
           model's domain check reads (training always measures it).",
    key: "domain",
    recorded_when_off: false,
    prefix: DOMAIN_PREFIX,
    addition: None,
    kind: Kind::OfSphere(&Domain),
};

struct Domain;

impl OfSphere for Domain {
    fn names(&self) -> &'static [&'static str] {
        &DOMAIN_NAMES
    }

    /// On the image as given: the reduction to the working radius crops the rim's
    /// surroundings away.
    fn extract(&self, sphere: &Seen<'_>, wanted: &dyn Fn(usize) -> bool) -> Vec<f64> {
        vec![match wanted(0) {
            true => outline(sphere.given.view(), &sphere.circle),
            false => f64::NAN,
        }]
    }
}

/// An image's pixels in row-major order, for fast bilinear samples (the same arithmetic
/// as `image::detect`'s).
struct Pixels<'a> {
    data: Cow<'a, [f64]>,
    width: usize,
    height: usize,
}

impl<'a> Pixels<'a> {
    fn of(image: ArrayView2<'a, f64>) -> Pixels<'a> {
        let (height, width) = image.dim();
        let data = match image.to_slice() {
            Some(slice) => Cow::Borrowed(slice),
            None => Cow::Owned(image.iter().copied().collect()),
        };
        Pixels {
            data,
            width,
            height,
        }
    }

    /// Bilinear sample at (x, y), clamped to the image.
    fn sample(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (self.width, self.height);
        let x = x.clamp(0.0, (w - 1) as f64);
        let y = y.clamp(0.0, (h - 1) as f64);
        // Truncation is the floor of these non-negative coordinates, without a libm call.
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let (row0, row1) = (
            &self.data[y0 * w..(y0 + 1) * w],
            &self.data[y1 * w..(y1 + 1) * w],
        );
        let top = row0[x0] * (1.0 - fx) + row0[x1] * fx;
        let bottom = row1[x0] * (1.0 - fx) + row1[x1] * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// Rays around the circle.
pub const RAYS: usize = 48;
/// The rays reach this fraction of r inside and outside the circle.
const REACH: f64 = 0.3;
/// Samples along a ray, at most (with the rays, about 40 µs a request on a 512² image).
const SAMPLES: usize = 96;
/// The finest spacing of the samples, in pixels.
const MIN_STEP: f64 = 0.25;

/// The `dom.outline` value of the circle `c` in `image` (see the module).
pub fn outline(image: ArrayView2<f64>, c: &Circle) -> f64 {
    let span = 2.0 * REACH * c.r;
    let step = (span / (SAMPLES - 1) as f64).max(MIN_STEP);
    let n = ((span / step).floor() as usize + 1).min(SAMPLES);
    // Slopes over the whole step count nearest one pixel.
    let base = ((1.0 / step).round() as usize).max(1);
    if n <= base + 2 {
        return 0.0;
    }
    let slopes = n - base;
    let mut profile = vec![0.0f64; slopes];
    let mut values = vec![0.0f64; n];
    let mut slope = vec![0.0f64; slopes];
    let pixels = Pixels::of(image);
    for k in 0..RAYS {
        let theta = std::f64::consts::TAU * k as f64 / RAYS as f64;
        let (ux, uy) = (theta.cos(), -theta.sin());
        for (j, v) in values.iter_mut().enumerate() {
            let rho = c.r * (1.0 - REACH) + j as f64 * step;
            *v = pixels.sample(c.cx + rho * ux, c.cy + rho * uy);
        }
        let mut steepest = 0.0f64;
        for (j, s) in slope.iter_mut().enumerate() {
            *s = (values[j + base] - values[j]).abs();
            steepest = steepest.max(*s);
        }
        if steepest > 0.0 {
            for (p, s) in profile.iter_mut().zip(&slope) {
                *p += s / steepest;
            }
        }
    }
    let tolerance = (0.025 * c.r).max(1.5);
    let (mut peak, mut away) = (0.0f64, Vec::with_capacity(slopes));
    for (j, p) in profile.iter().enumerate() {
        let at = c.r * (1.0 - REACH) + (j as f64 + base as f64 / 2.0) * step;
        let offset = (at - c.r).abs();
        if offset <= tolerance {
            peak = peak.max(*p);
        } else if offset > 2.0 * tolerance {
            away.push(*p);
        }
    }
    if away.is_empty() {
        return 0.0;
    }
    let median = stats::percentiles(&away, [50.0])[0];
    (peak - median) / RAYS as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn disc(n: usize, c: &Circle, inside: impl Fn(f64, f64) -> f64, outside: f64) -> Array2<f64> {
        Array2::from_shape_fn((n, n), |(y, x)| {
            let (dx, dy) = (x as f64 - c.cx, y as f64 - c.cy);
            if dx.hypot(dy) <= c.r {
                inside(dx / c.r, dy / c.r)
            } else {
                outside
            }
        })
    }

    const C: Circle = Circle {
        cx: 100.0,
        cy: 96.0,
        r: 70.0,
    };

    #[test]
    fn a_plain_disc_on_a_plain_background_is_a_full_outline() {
        let image = disc(200, &C, |_, _| 0.8, 0.1);
        let value = outline(image.view(), &C);
        assert!(value > 0.8, "{value}");
        // A circle moved off the disc, or too large, or too small, follows no outline.
        for wrong in [
            Circle {
                cx: C.cx + 0.6 * C.r,
                ..C
            },
            Circle { r: C.r * 1.5, ..C },
            Circle { r: C.r * 0.6, ..C },
        ] {
            let value = outline(image.view(), &wrong);
            assert!(value < 0.3, "{wrong:?}: {value}");
        }
    }

    #[test]
    fn a_faint_rim_counts_like_a_sharp_one_and_texture_does_not() {
        // A textured inside (oblique stripes) on a dark background.
        let textured = |x: f64, y: f64| 0.5 + 0.4 * (40.0 * x + 13.0 * y).sin();
        let image = disc(200, &C, textured, 0.05);
        assert!(outline(image.view(), &C) > 0.5);
        // The same texture everywhere: no outline.
        let everywhere = Array2::from_shape_fn((200, 200), |(y, x)| {
            textured((x as f64 - C.cx) / C.r, (y as f64 - C.cy) / C.r)
        });
        let value = outline(everywhere.view(), &C);
        assert!(value.abs() < 0.2, "{value}");
        // A flat image has no slope at all.
        let flat = Array2::from_elem((200, 200), 0.3);
        assert_eq!(outline(flat.view(), &C), 0.0);
    }
}
