//! Colour: a reduced linear-RGB copy that decoding keeps beside the luminance when asked
//! (`DecodeOptions::colour`), and the means a colour measurement reads from it. A mean
//! colour needs far fewer pixels than the features: the copy holds at most
//! [`MAX_PIXELS`], each the mean of a square block of the photograph.

use crate::image::circle::Circle;

/// Linear RGB.
pub type Rgb = [f64; 3];

/// The most pixels a copy holds (a larger photograph is reduced by whole-number blocks).
pub const MAX_PIXELS: usize = 1 << 20;

/// Rec. 709 luminance of linear RGB.
pub fn luminance(rgb: Rgb) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// A photograph's linear RGB, reduced by `factor` × `factor` block means.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourCopy {
    factor: usize,
    width: usize,
    height: usize,
    rgb: Vec<[f32; 3]>,
}

impl ColourCopy {
    /// The copy of a `width` × `height` photograph whose pixel `i` (row-major) is `pixel(i)`.
    pub fn new(width: usize, height: usize, pixel: impl Fn(usize) -> Rgb) -> ColourCopy {
        let mut factor = 1;
        while width.div_ceil(factor) * height.div_ceil(factor) > MAX_PIXELS {
            factor += 1;
        }
        let (w, h) = (width.div_ceil(factor), height.div_ceil(factor));
        let mut sums = vec![[0.0f64; 3]; w * h];
        let mut counts = vec![0u32; w * h];
        for y in 0..height {
            let row = (y / factor) * w;
            for x in 0..width {
                let [r, g, b] = pixel(y * width + x);
                let k = row + x / factor;
                sums[k][0] += r;
                sums[k][1] += g;
                sums[k][2] += b;
                counts[k] += 1;
            }
        }
        let rgb = sums
            .iter()
            .zip(&counts)
            .map(|(s, &n)| s.map(|v| (v / f64::from(n.max(1))) as f32))
            .collect();
        ColourCopy {
            factor,
            width: w,
            height: h,
            rgb,
        }
    }

    /// The mean of the copy's pixels whose centres, in the photograph's pixel coordinates
    /// (x across, y down), satisfy `inside`, leaving out the brightest `trim` fraction of
    /// them by luminance; `None` when no pixel is inside.
    pub fn mean(&self, inside: impl Fn(f64, f64) -> bool, trim: f64) -> Option<Rgb> {
        let half = (self.factor as f64 - 1.0) / 2.0;
        let mut chosen: Vec<Rgb> = Vec::new();
        for y in 0..self.height {
            for x in 0..self.width {
                let (cx, cy) = (
                    (x * self.factor) as f64 + half,
                    (y * self.factor) as f64 + half,
                );
                if inside(cx, cy) {
                    chosen.push(self.rgb[y * self.width + x].map(f64::from));
                }
            }
        }
        if chosen.is_empty() {
            return None;
        }
        let keep = ((chosen.len() as f64) * (1.0 - trim.clamp(0.0, 0.99))).ceil() as usize;
        chosen.sort_by(|a, b| luminance(*a).total_cmp(&luminance(*b)));
        let kept = &chosen[..keep.max(1)];
        let n = kept.len() as f64;
        Some(kept.iter().fold([0.0; 3], |acc, p| {
            [acc[0] + p[0] / n, acc[1] + p[1] / n, acc[2] + p[2] / n]
        }))
    }

    /// The photograph's pixels per copy pixel along a side.
    pub fn factor(&self) -> usize {
        self.factor
    }
}

/// The disc a sphere's colour is read from, in radii: its centre, whose normals face the
/// camera within 14.5°, as the white card does, so that the light on both has one colour
/// (farther out, the sky colours the top and the ground the bottom: the whole disc read
/// 2–5 times worse under the probes, docs/accuracy.md).
pub const DISC: f64 = 0.25;
/// The brightest share of that disc left out of its colour: highlights, the reflection of
/// what is behind the camera, whose colour is not the surface's.
pub const HIGHLIGHTS: f64 = 0.25;

/// The sphere's appearance relative to white: the mean RGB of its disc (without its
/// highlights) over white's RGB, channel by channel. White's colour is the light's, so this
/// is the light's colour taken out; `None` without pixels or with a black channel of white.
pub fn appearance(copy: &ColourCopy, circle: &Circle, white: Rgb) -> Option<Rgb> {
    if !white.iter().all(|&w| w > 0.0) {
        return None;
    }
    let r2 = (DISC * circle.r).powi(2);
    let inside = |x: f64, y: f64| (x - circle.cx).powi(2) + (y - circle.cy).powi(2) <= r2;
    let mean = copy.mean(inside, HIGHLIGHTS)?;
    Some([mean[0] / white[0], mean[1] / white[1], mean[2] / white[2]])
}

/// The surface's own colour, scaled to luminance 1, from its appearance: the diffuse
/// albedo's colour for a dielectric (the centre without its highlights is diffuse light),
/// a metal's F0 colour for a metal. Taking a grey specular share out by the model's
/// estimate of it read worse (its share there is smaller than the whole sphere's).
/// `None` for a black appearance.
pub fn surface_colour(appearance: Rgb) -> Option<Rgb> {
    let y = luminance(appearance);
    (y > 0.0 && y.is_finite() && appearance.iter().all(|c| *c >= 0.0))
        .then(|| appearance.map(|c| c / y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_picture_is_kept_whole_and_a_large_one_reduced() {
        let small = ColourCopy::new(4, 3, |i| [i as f64, 0.0, 1.0]);
        assert_eq!((small.factor(), small.width, small.height), (1, 4, 3));
        assert_eq!(small.rgb[5], [5.0, 0.0, 1.0]);
        let (w, h) = (3000, 2000);
        let large = ColourCopy::new(w, h, |i| [((i % w) / 1000) as f64, 1.0, 0.0]);
        assert!(large.width * large.height <= MAX_PIXELS);
        assert_eq!(large.factor(), 3);
        // Block means: the three thirds of the picture keep their values.
        let third = |x0: f64, x1: f64| {
            large
                .mean(|x, _| x >= x0 && x < x1, 0.0)
                .expect("pixels inside")
        };
        for (range, value) in [
            ((0.0, 999.0), 0.0),
            ((1001.0, 1998.0), 1.0),
            ((2001.0, 3000.0), 2.0),
        ] {
            let mean = third(range.0, range.1);
            assert!(
                (mean[0] - value).abs() < 1e-9 && (mean[1] - 1.0).abs() < 1e-9,
                "{mean:?}"
            );
        }
    }

    #[test]
    fn the_mean_leaves_out_the_brightest_pixels_asked() {
        // 8 grey pixels of 1 and 2 highlights of 10.
        let copy = ColourCopy::new(10, 1, |i| if i < 8 { [1.0; 3] } else { [10.0; 3] });
        assert_eq!(copy.mean(|_, _| true, 0.0), Some([2.8; 3]));
        assert_eq!(copy.mean(|_, _| true, 0.2), Some([1.0; 3]));
        assert_eq!(copy.mean(|x, _| x > 100.0, 0.0), None);
    }

    #[test]
    fn the_surface_colour_is_the_appearance_at_luminance_one() {
        let look = [0.6, 0.18, 0.12];
        let colour = surface_colour(look).unwrap();
        assert!((luminance(colour) - 1.0).abs() < 1e-12);
        assert!((colour[0] / colour[1] - 10.0 / 3.0).abs() < 1e-12);
        assert_eq!(surface_colour([0.0; 3]), None);
        assert_eq!(surface_colour([f64::NAN, 1.0, 1.0]), None);
    }

    #[test]
    fn appearance_is_the_disc_over_white() {
        // A 40 × 40 picture: a centre of (0.4, 0.2, 0.1) in a sphere of another colour,
        // white (0.8, 0.4, 0.2); the centre's brightest quarter, a highlight, left out.
        let circle = Circle {
            cx: 19.5,
            cy: 19.5,
            r: 16.0,
        };
        let copy = ColourCopy::new(40, 40, |i| {
            let (x, y) = ((i % 40) as f64, (i / 40) as f64);
            match (x - 19.5).hypot(y - 19.5) {
                d if d < 1.0 => [5.0; 3],
                d if d < 4.0 => [0.4, 0.2, 0.1],
                _ => [0.1, 0.3, 0.5],
            }
        });
        let seen = appearance(&copy, &circle, [0.8, 0.4, 0.2]).unwrap();
        for c in seen {
            assert!((c - 0.5).abs() < 1e-6, "{seen:?}");
        }
        assert_eq!(appearance(&copy, &circle, [0.8, 0.0, 0.2]), None);
    }
}
