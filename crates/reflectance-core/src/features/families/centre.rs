//! The sphere's centre, which the annulus leaves out, measured against white (the centre
//! family, `ctr.*`).
//!
//! White is the brightness of a white Lambertian sphere at its centre, E(v)/π: the
//! cosine-weighted mean radiance of the hemisphere facing the camera. The centre of the
//! sphere sees that same hemisphere. Its diffuse part is ρd·E(n)/π with n near v, so ≈ ρd
//! times white. Its specular part, for a mirror, is ρs times the hemisphere itself: inside
//! r/√2 the reflected rays sweep the camera-facing hemisphere exactly, evenly in solid angle
//! (an orthographic mirror ball maps image area to solid angle at a constant 4/r²). So the
//! disc's brightness over white measures the total reflectance ρd + ρs, up to how unevenly
//! that hemisphere is lit. The annulus, whose rays mostly leave backwards, cannot tie the
//! image to white this way (docs/design.md §8).
//!
//! Weighting each pixel of the disc by the cosine of its mirror ray's angle to the camera,
//! 1 − 2d² at distance d·r from the centre, makes the mirror's share exact: a mirror's
//! weighted mean is ρs times white under any light, so only the diffuse share's uneven
//! lighting remains (over the 70 probes' renders of the 80 continuous materials, this value
//! alone is ρd + ρs within 0.045 on average, the unweighted mean within 0.144).
//!
//! Six values, each log10 of a multiple of white (floored at [`LOG_PIXEL_FLOOR`]): the mean
//! over the disc of radius r/√2 (`ctr.mean`), over its inner half (`ctr.core`, nearest the
//! white sphere's own normal), the 10th, 50th and 90th percentiles over the disc, and its
//! cosine-weighted mean (`ctr.cos`).
//!
//! The disc is read without the saturation ceiling of the annulus: a ceiling removes the very
//! energy of the bright reflections this measures (over the 70 probes, on hand6+log+cap+ctr,
//! the estimate's total reflectance error grows from 0.080 to 0.091 with it). What a camera
//! clipped is measured by `cap.clipped`.

use super::{Addition, Family, Kind, OfSphere, Seen};
use crate::features::LOG_PIXEL_FLOOR;
use crate::features::stats;
use crate::image::circle::Circle;
use ndarray::ArrayView2;

/// Prefix of the centre features' names.
pub const CENTRE_PREFIX: &str = "ctr.";
/// The centre features: log10 of the disc inside r/√2 against white, its mean, its inner
/// half's mean, its 10th, 50th and 90th percentiles and its cosine-weighted mean.
pub const CENTRE_NAMES: [&str; 6] = [
    "ctr.mean", "ctr.core", "ctr.p10", "ctr.p50", "ctr.p90", "ctr.cos",
];

/// The centre family, after the blocks and the capture measurements.
pub const CENTRE: Family = Family {
    option: "centre_features",
    help: "Also measure the sphere's centre against white (`ctr.*`: log10 of the disc inside\n\
           r/√2 over white, its mean, its inner half's mean and three percentiles), a cue to the\n\
           total reflectance that the annulus lacks.",
    key: "centre",
    recorded_when_off: false,
    prefix: CENTRE_PREFIX,
    // Model files from before `ctr.cos` extract the first five values.
    addition: Some(Addition {
        key: "centre_cos",
        before: 5,
    }),
    kind: Kind::OfSphere(&Centre),
};

struct Centre;

impl OfSphere for Centre {
    fn names(&self) -> &'static [&'static str] {
        &CENTRE_NAMES
    }

    /// On the image as the features see it (at the working radius).
    fn extract(&self, sphere: &Seen<'_>, wanted: &dyn Fn(usize) -> bool) -> Vec<f64> {
        if !(0..CENTRE_NAMES.len()).any(wanted) {
            return vec![f64::NAN; CENTRE_NAMES.len()];
        }
        let (image, circle) = sphere.seen();
        centre_features(image, circle, sphere.white).to_vec()
    }
}

/// The disc, as a fraction of the radius: the mirror's reflected rays cover the
/// camera-facing hemisphere inside it.
pub const DISC: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// The core, as a fraction of the radius.
pub const CORE: f64 = DISC / 2.0;

/// The `ctr.*` values (see the module) of the sphere `circle` in `luminance`, whose white is
/// `white`.
pub fn centre_features(luminance: ArrayView2<f64>, circle: &Circle, white: f64) -> [f64; 6] {
    let (h, w) = luminance.dim();
    let reach = DISC * circle.r;
    let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
    let rows = clamp((circle.cy - reach).floor(), h)..clamp((circle.cy + reach).ceil() + 1.0, h);
    let cols = clamp((circle.cx - reach).floor(), w)..clamp((circle.cx + reach).ceil() + 1.0, w);
    // Squared distances in units of r²: the disc is d² ≤ 1/2, the core d² ≤ 1/8.
    let (disc2, core2) = (DISC * DISC, CORE * CORE);
    let scale = 1.0 / (circle.r * circle.r);
    let capacity = (std::f64::consts::PI * reach * reach) as usize + cols.len();
    let (mut disc, mut core_sum, mut core_n) = (Vec::with_capacity(capacity), 0.0, 0usize);
    let (mut cos_sum, mut cos_weight) = (0.0, 0.0);
    for y in rows {
        let dy2 = (y as f64 - circle.cy).powi(2) * scale;
        let row = luminance.row(y);
        for x in cols.clone() {
            let d2 = (x as f64 - circle.cx).powi(2) * scale + dy2;
            if d2 > disc2 {
                continue;
            }
            let v = row[x] / white;
            disc.push(v);
            let cos = 1.0 - 2.0 * d2;
            cos_sum += cos * v;
            cos_weight += cos;
            if d2 <= core2 {
                core_sum += v;
                core_n += 1;
            }
        }
    }
    let log = |v: f64| v.max(LOG_PIXEL_FLOOR).log10();
    let ratio = |sum: f64, n: usize| if n == 0 { 0.0 } else { sum / n as f64 };
    let [p10, p50, p90] = match disc.is_empty() {
        true => [0.0; 3],
        false => stats::percentiles(&disc, [10.0, 50.0, 90.0]),
    };
    let mean = ratio(stats::sum(&disc), disc.len());
    let cos_mean = match cos_weight > 0.0 {
        true => cos_sum / cos_weight,
        false => 0.0,
    };
    [mean, ratio(core_sum, core_n), p10, p50, p90, cos_mean].map(log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn circle() -> Circle {
        Circle {
            cx: 50.0,
            cy: 50.0,
            r: 40.0,
        }
    }

    #[test]
    fn a_uniform_sphere_at_white_times_rho_reads_log10_rho_everywhere() {
        let image = Array2::from_elem((101, 101), 0.3);
        let values = centre_features(image.view(), &circle(), 0.6);
        for v in values {
            assert!((v - 0.5f64.log10()).abs() < 1e-12, "{values:?}");
        }
    }

    #[test]
    fn the_disc_ends_at_r_over_root_two_and_the_core_at_half_that() {
        // Bright (4 × white) outside 0.75 r, white inside: the disc never sees the ring.
        let c = circle();
        let image = Array2::from_shape_fn((101, 101), |(y, x)| {
            let d = (x as f64 - c.cx).hypot(y as f64 - c.cy) / c.r;
            if d > 0.75 { 4.0 } else { 1.0 }
        });
        assert_eq!(centre_features(image.view(), &c, 1.0), [0.0; 6]);
        // A core at 4 × white: the core reads 4, the disc's median and 10th percentile 1,
        // its 90th percentile 4, and its mean (a quarter of the area at 4) ≈ 1.75.
        let image = Array2::from_shape_fn((101, 101), |(y, x)| {
            let d = (x as f64 - c.cx).hypot(y as f64 - c.cy) / c.r;
            if d <= CORE { 4.0 } else { 1.0 }
        });
        let [mean, core, p10, p50, p90, _] = centre_features(image.view(), &c, 1.0);
        assert!((core - 4f64.log10()).abs() < 1e-12, "{core}");
        assert_eq!([p10, p50], [0.0, 0.0]);
        assert!((p90 - 4f64.log10()).abs() < 1e-12, "{p90}");
        assert!(
            (10f64.powf(mean) - 1.75).abs() < 0.1,
            "{}",
            10f64.powf(mean)
        );
    }
}
