//! The camera between a rendered sphere and the classifier: what a photograph does to a
//! clean, linear, noiseless render. Deterministic for a seed.
//!
//! In order, as light goes through a camera: the sphere is brought to the capture's radius
//! (area averaging down, bilinear up), set on a background, blurred by the lens (Gaussian
//! σ), exposed (white lands at `exposure` of full scale), made noisy (shot noise ∝ √signal
//! and read noise, together `noise` of white at white), clipped at full scale, quantized
//! (8-bit sRGB PNG, 8-bit sRGB JPEG, or 16-bit linear PNG) and encoded. The caller is then
//! told the white reference and the circle the way a user measures them: off by up to the
//! ranges' errors.
//!
//! Renders are grey (the map's luminance), so a JPEG's chroma planes are constant and its
//! chroma subsampling (4:2:0 in a camera) changes nothing: the luminance plane carries the
//! whole effect. [`capture_rgb`] takes three channel renders (a colour photograph, with a
//! white card in it) through the same camera.

use ndarray::{Array2, ArrayView2};
use reflectance_core::decode::Encoding;
use reflectance_core::image::blur::gaussian_blur;
use reflectance_core::image::display::{grey_png, linear_to_srgb};
use reflectance_core::locate::Circle;
pub use reflectance_core::material::{CaptureEnvelope, CaptureRanges, VIEW_TAG};
use reflectance_core::util::rng::Rng;
use serde::{Deserialize, Serialize};
use std::fmt;

/// How the captured samples are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Quantization {
    /// 8-bit sRGB PNG.
    Srgb8,
    /// 8-bit sRGB baseline JPEG at a quality (1–100, the IJG scale).
    Jpeg { quality: u8 },
    /// 16-bit linear PNG (decode with `encoding=linear`).
    Linear16,
}

impl Quantization {
    pub fn extension(self) -> &'static str {
        match self {
            Quantization::Jpeg { .. } => "jpg",
            _ => "png",
        }
    }

    /// How the file's samples decode to linear values.
    pub fn encoding(self) -> Encoding {
        match self {
            Quantization::Linear16 => Encoding::Linear,
            _ => Encoding::Srgb,
        }
    }
}

impl fmt::Display for Quantization {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Quantization::Srgb8 => f.write_str("png8"),
            Quantization::Jpeg { quality } => write!(f, "jpeg{quality}"),
            Quantization::Linear16 => f.write_str("png16"),
        }
    }
}

/// One capture's settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureSettings {
    /// The sphere's radius in the captured image (px).
    pub radius: f64,
    /// White's level as a fraction of full scale (what is brighter than 1/exposure × white
    /// clips).
    pub exposure: f64,
    /// Noise standard deviation at white, as a fraction of white.
    pub noise: f64,
    /// The shot-noise share of the noise variance at white (the rest is read noise).
    pub shot_share: f64,
    /// Lens blur: Gaussian σ in captured pixels.
    pub blur: f64,
    pub quantization: Quantization,
    /// Background luminance, as a fraction of white.
    pub background: f64,
    /// Relative error of the reported white reference.
    pub white_error: f64,
    /// Error of the reported circle's centre (px, x and y).
    pub centre_error: [f64; 2],
    /// Relative error of the reported radius.
    pub radius_error: f64,
}

impl CaptureSettings {
    /// A perfect camera at `radius`: no blur, no noise, 16-bit linear, exact white and circle.
    pub fn ideal(radius: f64) -> CaptureSettings {
        CaptureSettings {
            radius,
            exposure: 0.5,
            noise: 0.0,
            shot_share: 1.0,
            blur: 0.0,
            quantization: Quantization::Linear16,
            background: 0.0,
            white_error: 0.0,
            centre_error: [0.0; 2],
            radius_error: 0.0,
        }
    }

    /// A short, file-name-safe description, e.g. `r92-e0.45-n0.012-b0.40-jpeg85`.
    pub fn label(&self) -> String {
        format!(
            "r{:.0}-e{:.2}-n{:.3}-b{:.2}-{}",
            self.radius, self.exposure, self.noise, self.blur, self.quantization
        )
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CaptureError {
    #[error("invalid capture settings: {0}")]
    Settings(String),
    #[error("cannot encode the capture: {0}")]
    Encode(String),
}

/// Capture settings drawn from [`CaptureRanges`].
pub trait DrawSettings {
    /// Settings drawn from the ranges: a quarter 8-bit PNG, half JPEG, a quarter 16-bit.
    fn sample(&self, rng: &mut Rng) -> CaptureSettings;
}

impl DrawSettings for CaptureRanges {
    fn sample(&self, rng: &mut Rng) -> CaptureSettings {
        let mut uniform = |[lo, hi]: [f64; 2]| lo + (hi - lo) * rng.next_f64();
        let radius = uniform([self.radius[0].ln(), self.radius[1].ln()]).exp();
        let exposure = uniform(self.exposure);
        let noise = uniform(self.noise);
        let shot_share = uniform([0.5, 1.0]);
        let blur = uniform(self.blur);
        let background = uniform([0.0, 1.0]);
        let white_error = uniform([-self.white_error, self.white_error]);
        let centre_error = [
            uniform([-self.centre_error, self.centre_error]),
            uniform([-self.centre_error, self.centre_error]),
        ];
        let radius_error = uniform([-self.radius_error, self.radius_error]);
        let [q0, q1] = self.jpeg_quality;
        let quantization = match rng.below(4) {
            0 => Quantization::Srgb8,
            1 => Quantization::Linear16,
            _ => Quantization::Jpeg {
                quality: q0 + rng.below(u64::from(q1 - q0) + 1) as u8,
            },
        };
        CaptureSettings {
            radius,
            exposure,
            noise,
            shot_share,
            blur,
            quantization,
            background,
            white_error,
            centre_error,
            radius_error,
        }
    }
}

/// What a capture's file holds and what its user would report with it.
#[derive(Clone, Debug)]
pub struct Capture {
    pub bytes: Vec<u8>,
    pub quantization: Quantization,
    /// The circle as reported (with the settings' errors), in captured pixels.
    pub circle: Circle,
    /// The white reference as reported (with its error), in decoded linear units.
    pub white: f64,
    /// Fraction of the sphere's pixels at full scale.
    pub clipped: f64,
}

/// Capture a render: `luminance` (linear; its background is replaced by the settings'),
/// the sphere at `circle`, white at `white`.
pub fn capture(
    luminance: ArrayView2<f64>,
    circle: &Circle,
    white: f64,
    settings: &CaptureSettings,
    rng: &mut Rng,
) -> Result<Capture, CaptureError> {
    capture_channels(&[luminance], circle, white, None, settings, rng)
}

/// A white card in a capture: a rectangle of captured pixels (x, y, width, height) whose
/// linear radiance is `rgb` (white's colour times the card's reflectance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Card {
    pub rect: [usize; 4],
    pub rgb: [f64; 3],
}

/// A colour photograph of three channel renders (linear R, G and B; `white` is white's
/// luminance, which sets the exposure) with a white `card` beside the sphere: every channel
/// goes through the same camera (noise drawn per channel), and the file is RGB.
pub fn capture_rgb(
    channels: [ArrayView2<f64>; 3],
    circle: &Circle,
    white: f64,
    card: Option<Card>,
    settings: &CaptureSettings,
    rng: &mut Rng,
) -> Result<Capture, CaptureError> {
    capture_channels(&channels, circle, white, card.as_ref(), settings, rng)
}

fn capture_channels(
    channels: &[ArrayView2<f64>],
    circle: &Circle,
    white: f64,
    card: Option<&Card>,
    settings: &CaptureSettings,
    rng: &mut Rng,
) -> Result<Capture, CaptureError> {
    check(settings, circle, white)?;
    let factor = settings.radius / circle.r;
    let dim = channels.first().map_or((0, 0), ArrayView2::dim);
    let coverage = disc_coverage(dim, circle);
    let inside = scale(coverage.view(), factor);
    let scenes: Vec<Array2<f64>> = channels.iter().map(|c| scale(*c, factor)).collect();
    let (bytes, clipped) = photograph(&scenes, inside.view(), white, card, settings, rng)?;
    let (circle, white) = reported(circle, settings);
    Ok(Capture {
        bytes,
        quantization: settings.quantization,
        circle,
        white,
        clipped,
    })
}

/// Capture a render of an object with its geometry kept, so that its normal map still fits:
/// the camera of [`capture`] (background, blur, exposure, noise, clipping, the file, white's
/// error) without the resizing and the circle's errors, which no normal map would follow.
/// `coverage` is the object's share of each pixel; the capture's circle is `circle`, as given.
pub fn capture_object(
    luminance: ArrayView2<f64>,
    coverage: ArrayView2<f64>,
    circle: &Circle,
    white: f64,
    settings: &CaptureSettings,
    rng: &mut Rng,
) -> Result<Capture, CaptureError> {
    let kept = CaptureSettings {
        radius: circle.r,
        centre_error: [0.0; 2],
        radius_error: 0.0,
        ..*settings
    };
    check(&kept, circle, white)?;
    if coverage.dim() != luminance.dim() {
        return Err(CaptureError::Settings(
            "the coverage must be the render's size".into(),
        ));
    }
    let scene = [luminance.to_owned()];
    let (bytes, clipped) = photograph(&scene, coverage, white, None, &kept, rng)?;
    let (circle, white) = reported(circle, &kept);
    Ok(Capture {
        bytes,
        quantization: kept.quantization,
        circle,
        white,
        clipped,
    })
}

/// The camera: each channel's `scene` over the settings' background where `inside` < 1,
/// the card, the lens blur, the exposure with its noise and clipping, then the file; the
/// file's bytes and the clipped share of the pixels at least half inside.
fn photograph(
    scenes: &[Array2<f64>],
    inside: ArrayView2<f64>,
    white: f64,
    card: Option<&Card>,
    settings: &CaptureSettings,
    rng: &mut Rng,
) -> Result<(Vec<u8>, f64), CaptureError> {
    let background = settings.background * white;
    let e = settings.exposure;
    let (shot, read) = (
        settings.noise * settings.noise * settings.shot_share,
        settings.noise * settings.noise * (1.0 - settings.shot_share),
    );
    let mut clipped = (0usize, 0usize);
    let mut exposed_channels = Vec::with_capacity(scenes.len());
    for (c, scene) in scenes.iter().enumerate() {
        let mut signal = Array2::from_shape_fn(scene.dim(), |p| {
            let inside = inside[p].clamp(0.0, 1.0);
            inside * scene[p] + (1.0 - inside) * background
        });
        if let Some(card) = card {
            let [x, y, w, h] = card.rect;
            let (rows, cols) = signal.dim();
            signal
                .slice_mut(ndarray::s![
                    y.min(rows)..(y + h).min(rows),
                    x.min(cols)..(x + w).min(cols)
                ])
                .fill(card.rgb[c]);
        }
        if settings.blur > 0.0 {
            signal = gaussian_blur(signal.view(), settings.blur);
        }
        let exposed = Array2::from_shape_fn(signal.dim(), |p| {
            // Full scale is 1: white lands at e.
            let x = signal[p] / white * e;
            let variance = shot * e * x.max(0.0) + read * e * e;
            let v = (x + variance.sqrt() * normal(rng)).clamp(0.0, 1.0);
            if inside[p] >= 0.5 {
                clipped.0 += usize::from(v >= 1.0);
                clipped.1 += 1;
            }
            v
        });
        exposed_channels.push(exposed);
    }
    let bytes = match &exposed_channels[..] {
        [grey] => encode(grey.view(), settings.quantization)?,
        channels => encode_rgb(channels, settings.quantization)?,
    };
    Ok((bytes, clipped.0 as f64 / clipped.1.max(1) as f64))
}

/// The circle (in captured pixels) and white (in decoded units) a user of a capture of a
/// render whose sphere is at `circle` reports: the true ones, off by the settings' errors.
pub fn reported(circle: &Circle, settings: &CaptureSettings) -> (Circle, f64) {
    let factor = settings.radius / circle.r;
    let [dx, dy] = settings.centre_error;
    let circle = Circle {
        cx: (circle.cx + 0.5) * factor - 0.5 + dx,
        cy: (circle.cy + 0.5) * factor - 0.5 + dy,
        r: settings.radius * (1.0 + settings.radius_error),
    };
    (circle, settings.exposure * (1.0 + settings.white_error))
}

fn check(settings: &CaptureSettings, circle: &Circle, white: f64) -> Result<(), CaptureError> {
    let s = settings;
    let finite = [
        s.radius,
        s.exposure,
        s.noise,
        s.shot_share,
        s.blur,
        s.background,
        s.white_error,
        s.radius_error,
        s.centre_error[0],
        s.centre_error[1],
        circle.r,
        white,
    ]
    .iter()
    .all(|v| v.is_finite());
    let fail = |what: &str| Err(CaptureError::Settings(what.to_string()));
    if !finite {
        return fail("every value must be finite");
    }
    if !(s.radius >= reflectance_core::locate::MIN_RADIUS && s.radius <= 4096.0) {
        return fail("radius must be within 32–4096 px");
    }
    if !(s.exposure > 0.0 && s.exposure <= 1.0) {
        return fail("exposure must be in (0, 1]");
    }
    if s.noise < 0.0 || !(0.0..=1.0).contains(&s.shot_share) || s.blur < 0.0 || s.blur > 20.0 {
        return fail("noise ≥ 0, shot share in [0, 1] and blur in [0, 20] px");
    }
    if let Quantization::Jpeg { quality } = s.quantization
        && !(1..=100).contains(&quality)
    {
        return fail("JPEG quality must be in 1–100");
    }
    if !(circle.r > 0.0 && white > 0.0) {
        return fail("the render's radius and white must be positive");
    }
    Ok(())
}

/// The fraction of each pixel inside the circle (4 × 4 samples per pixel near the rim).
fn disc_coverage((h, w): (usize, usize), c: &Circle) -> Array2<f64> {
    Array2::from_shape_fn((h, w), |(y, x)| {
        let d = (x as f64 - c.cx).hypot(y as f64 - c.cy);
        if d <= c.r - 0.75 {
            1.0
        } else if d >= c.r + 0.75 {
            0.0
        } else {
            let offsets = [-0.375, -0.125, 0.125, 0.375];
            let inside = offsets
                .iter()
                .flat_map(|dy| offsets.iter().map(move |dx| (dx, dy)))
                .filter(|(dx, dy)| (x as f64 + *dx - c.cx).hypot(y as f64 + *dy - c.cy) <= c.r)
                .count();
            inside as f64 / 16.0
        }
    })
}

/// A standard normal deviate (Box–Muller; one of the pair).
fn normal(rng: &mut Rng) -> f64 {
    let u = 1.0 - rng.next_f64();
    let v = rng.next_f64();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Resample by `factor`: exact area averaging when reducing, bilinear when enlarging (pixel
/// centres map as (x + ½)·factor − ½).
pub fn scale(image: ArrayView2<f64>, factor: f64) -> Array2<f64> {
    if factor <= 1.0 {
        return reflectance_core::image::resample::downsample(image, factor);
    }
    let (h, w) = image.dim();
    // (Less a hair: 110 × 150/50 must be 330, not 331.)
    let out = |n: usize| ((n as f64) * factor - 1e-9).ceil() as usize;
    let taps = |n: usize, k: usize| {
        let x = ((k as f64 + 0.5) / factor - 0.5).clamp(0.0, (n - 1) as f64);
        let i = (x.floor() as usize).min(n.saturating_sub(2));
        (i, x - i as f64)
    };
    Array2::from_shape_fn((out(h), out(w)), |(y, x)| {
        let (i, fy) = taps(h, y);
        let (j, fx) = taps(w, x);
        let (i1, j1) = ((i + 1).min(h - 1), (j + 1).min(w - 1));
        let top = image[[i, j]] * (1.0 - fx) + image[[i, j1]] * fx;
        let bottom = image[[i1, j]] * (1.0 - fx) + image[[i1, j1]] * fx;
        top * (1.0 - fy) + bottom * fy
    })
}

/// Quantize normalized linear samples (in [0, 1]) and encode them.
fn encode(samples: ArrayView2<f64>, quantization: Quantization) -> Result<Vec<u8>, CaptureError> {
    use image::ImageEncoder;
    let (h, w) = samples.dim();
    let (width, height) = (w as u32, h as u32);
    let fail = |e: image::ImageError| CaptureError::Encode(e.to_string());
    let srgb8 = || -> Vec<u8> {
        samples
            .iter()
            .map(|&v| (255.0 * linear_to_srgb(v)).round() as u8)
            .collect()
    };
    let mut out = Vec::new();
    match quantization {
        Quantization::Srgb8 => out = grey_png(w, h, &srgb8()).map_err(fail)?,
        Quantization::Linear16 => {
            let bytes: Vec<u8> = samples
                .iter()
                .flat_map(|&v| ((65535.0 * v).round() as u16).to_ne_bytes())
                .collect();
            image::codecs::png::PngEncoder::new(&mut out)
                .write_image(&bytes, width, height, image::ExtendedColorType::L16)
                .map_err(fail)?
        }
        Quantization::Jpeg { quality } => {
            // An RGB file, as cameras write: grey, so its chroma planes are constant.
            let rgb: Vec<u8> = srgb8().into_iter().flat_map(|v| [v, v, v]).collect();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality)
                .write_image(&rgb, width, height, image::ExtendedColorType::Rgb8)
                .map_err(fail)?
        }
    }
    Ok(out)
}

/// Quantize three normalized linear channels (in [0, 1]) and encode them as an RGB file.
fn encode_rgb(
    channels: &[Array2<f64>],
    quantization: Quantization,
) -> Result<Vec<u8>, CaptureError> {
    use image::ImageEncoder;
    let (h, w) = channels.first().map_or((0, 0), Array2::dim);
    let (width, height) = (w as u32, h as u32);
    let fail = |e: image::ImageError| CaptureError::Encode(e.to_string());
    let interleaved = |f: &dyn Fn(f64) -> u16| -> Vec<u16> {
        (0..h * w)
            .flat_map(|i| channels.iter().map(move |c| (i / w, i % w, c)))
            .map(|(y, x, c)| f(c[[y, x]]))
            .collect()
    };
    let srgb8 = || -> Vec<u8> {
        interleaved(&|v| (255.0 * linear_to_srgb(v)).round() as u16)
            .into_iter()
            .map(|v| v as u8)
            .collect()
    };
    let mut out = Vec::new();
    match quantization {
        Quantization::Srgb8 => image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&srgb8(), width, height, image::ExtendedColorType::Rgb8)
            .map_err(fail)?,
        Quantization::Linear16 => {
            let bytes: Vec<u8> = interleaved(&|v| (65535.0 * v).round() as u16)
                .into_iter()
                .flat_map(u16::to_ne_bytes)
                .collect();
            image::codecs::png::PngEncoder::new(&mut out)
                .write_image(&bytes, width, height, image::ExtendedColorType::Rgb16)
                .map_err(fail)?
        }
        Quantization::Jpeg { quality } => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality)
                .write_image(&srgb8(), width, height, image::ExtendedColorType::Rgb8)
                .map_err(fail)?
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use reflectance_core::decode::{DecodeOptions, decode};

    fn decoded(capture: &Capture) -> Array2<f64> {
        let options = DecodeOptions {
            encoding: Some(capture.quantization.encoding()),
            ..DecodeOptions::default()
        };
        decode(&capture.bytes, &options).unwrap().luminance
    }

    /// A uniform image of `level`, its sphere at the renderer's circle; the background is
    /// set to the same level, so every pixel sees it.
    fn flat(level: f64, white: f64, size: usize) -> (Array2<f64>, Circle, CaptureSettings) {
        let c = (size as f64 - 1.0) / 2.0;
        let r = size as f64 / 2.2;
        let settings = CaptureSettings {
            background: level / white,
            ..CaptureSettings::ideal(r)
        };
        let image = Array2::from_elem((size, size), level);
        (image, Circle { cx: c, cy: c, r }, settings)
    }

    fn mean_sd(values: &Array2<f64>) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.sum() / n;
        let var = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var.sqrt())
    }

    #[test]
    fn noise_at_white_and_in_the_shadows_has_the_set_standard_deviation() {
        // White is 2.0; at exposure 0.5 it lands at 0.5 of full scale.
        let (image, circle, flat_settings) = flat(2.0, 2.0, 220);
        let settings = CaptureSettings {
            noise: 0.02,
            shot_share: 0.75,
            ..flat_settings
        };
        let cap = capture(image.view(), &circle, 2.0, &settings, &mut Rng::new(3)).unwrap();
        let (mean, sd) = mean_sd(&decoded(&cap));
        // σ = 2 % of white (0.5) at white: 0.01 in decoded units.
        assert!((mean - 0.5).abs() < 5e-4, "{mean}");
        assert!((sd - 0.01).abs() < 3e-4, "{sd}");
        // A quarter of white: the shot variance scales with the level, read noise does not.
        let (image, circle, flat_settings) = flat(0.5, 2.0, 220);
        let settings = CaptureSettings {
            background: flat_settings.background,
            ..settings
        };
        let cap = capture(image.view(), &circle, 2.0, &settings, &mut Rng::new(4)).unwrap();
        let (mean, sd) = mean_sd(&decoded(&cap));
        let expected = (0.02f64.powi(2) * 0.5 * (0.75 * 0.125 + 0.25 * 0.5)).sqrt();
        assert!((mean - 0.125).abs() < 5e-4, "{mean}");
        assert!(
            (sd - expected).abs() < 0.05 * expected,
            "{sd} vs {expected}"
        );
    }

    #[test]
    fn captures_are_deterministic_for_a_seed() {
        let (image, circle, _) = flat(1.0, 1.0, 120);
        let settings = CaptureSettings {
            noise: 0.01,
            ..CaptureRanges::default().sample(&mut Rng::new(9))
        };
        let run = |seed| {
            capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(seed))
                .unwrap()
                .bytes
        };
        assert_eq!(run(5), run(5));
        assert_ne!(run(5), run(6));
    }

    #[test]
    fn jpeg_round_trip_stays_within_its_quality() {
        let size = 200;
        let image = Array2::from_shape_fn((size, size), |(y, x)| {
            0.2 + 0.6 * (x + y) as f64 / 400.0 + 0.05 * (x as f64 / 3.0).sin()
        });
        let circle = Circle {
            cx: 99.5,
            cy: 99.5,
            r: 90.0,
        };
        let run = |quantization| {
            let settings = CaptureSettings {
                quantization,
                background: 0.5,
                ..CaptureSettings::ideal(90.0)
            };
            capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(1)).unwrap()
        };
        let png = decoded(&run(Quantization::Srgb8));
        let mut errors = Vec::new();
        for quality in [70, 90, 98] {
            let cap = run(Quantization::Jpeg { quality });
            assert_eq!(&cap.bytes[..2], &[0xff, 0xd8], "a JPEG file");
            let jpeg = decoded(&cap);
            assert_eq!(jpeg.dim(), png.dim());
            let rms = (jpeg
                .iter()
                .zip(png.iter())
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / jpeg.len() as f64)
                .sqrt();
            errors.push(rms);
        }
        // Mean errors of a fraction of a code value at q70, shrinking with quality.
        assert!(errors[0] < 0.01 && errors[0] > 0.0, "{errors:?}");
        assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    }

    #[test]
    fn exposure_clips_what_is_brighter_than_full_scale() {
        // Half the image at 3 × white: at exposure 0.5 it reaches 1.5 × full scale.
        let size = 220;
        let image = Array2::from_shape_fn((size, size), |(_, x)| if x < 110 { 3.0 } else { 0.5 });
        let circle = Circle {
            cx: 109.5,
            cy: 109.5,
            r: 100.0,
        };
        let settings = CaptureSettings::ideal(100.0);
        let cap = capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(1)).unwrap();
        assert!((cap.clipped - 0.5).abs() < 0.02, "{}", cap.clipped);
        let decoded = decoded(&cap);
        assert_eq!(decoded[[110, 20]], 1.0);
        assert!((decoded[[110, 200]] - 0.25).abs() < 1e-4);
        assert_eq!(cap.white, 0.5);
    }

    #[test]
    fn radius_and_reported_errors() {
        let (image, circle, flat_settings) = flat(1.0, 1.0, 110);
        let settings = CaptureSettings {
            radius: 150.0,
            centre_error: [0.5, -1.0],
            radius_error: 0.01,
            white_error: -0.05,
            ..flat_settings
        };
        let cap = capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(1)).unwrap();
        let factor = 150.0 / circle.r;
        assert_eq!(decoded(&cap).dim(), (330, 330));
        assert!((cap.circle.cx - ((circle.cx + 0.5) * factor - 0.5 + 0.5)).abs() < 1e-9);
        assert!((cap.circle.cy - ((circle.cy + 0.5) * factor - 0.5 - 1.0)).abs() < 1e-9);
        assert!((cap.circle.r - 151.5).abs() < 1e-9);
        assert!((cap.white - 0.475).abs() < 1e-12);
        // Enlarged or reduced, a uniform image stays uniform.
        for radius in [40.0, 150.0] {
            let settings = CaptureSettings {
                radius,
                ..flat_settings
            };
            let cap = capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(1)).unwrap();
            assert!(decoded(&cap).iter().all(|&v| (v - 0.5).abs() < 1e-4));
        }
    }

    #[test]
    fn a_blurred_impulse_keeps_its_sum_and_spreads_by_sigma_squared() {
        let mut impulse = Array2::zeros((41, 41));
        impulse[[20, 20]] = 1.0;
        let blurred = gaussian_blur(impulse.view(), 0.8);
        let variance: f64 = blurred
            .indexed_iter()
            .map(|((_, x), v)| v * (x as f64 - 20.0).powi(2))
            .sum();
        assert!((blurred.sum() - 1.0).abs() < 1e-12);
        assert!((variance - 0.64).abs() < 0.01, "{variance}");
    }

    #[test]
    fn the_sphere_sits_on_the_background() {
        // A black render on a background of half white: the rim is a mix of both.
        let image = Array2::zeros((110, 110));
        let circle = Circle {
            cx: 54.5,
            cy: 54.5,
            r: 50.0,
        };
        let settings = CaptureSettings {
            background: 0.5,
            quantization: Quantization::Srgb8,
            ..CaptureSettings::ideal(50.0)
        };
        let cap = capture(image.view(), &circle, 1.0, &settings, &mut Rng::new(1)).unwrap();
        let d = decoded(&cap);
        assert_eq!(d[[54, 54]], 0.0);
        assert!((d[[2, 2]] - 0.25).abs() < 0.01, "{}", d[[2, 2]]);
        // At 45°, 50.2 px from the centre: partly covered.
        let rim = d[[90, 90]];
        assert!(rim > 0.0 && rim < 0.25, "{rim}");
    }

    #[test]
    fn an_object_keeps_its_pixels_where_they_were() {
        // An object that is no disc: a bright L of full coverage on black, a half-covered
        // pixel at its foot. Captured without noise at another radius asked for: nothing moves.
        let mut image = Array2::zeros((90, 120));
        let mut coverage = Array2::zeros((90, 120));
        for (y, x) in (10..70).map(|y| (y, 20)).chain((30..100).map(|x| (69, x))) {
            image[[y, x]] = 1.5;
            coverage[[y, x]] = 1.0;
        }
        coverage[[70, 20]] = 0.5;
        let circle = Circle {
            cx: 59.5,
            cy: 44.5,
            r: 40.0,
        };
        let settings = CaptureSettings {
            background: 0.2,
            centre_error: [3.0, -2.0],
            radius_error: 0.1,
            ..CaptureSettings::ideal(300.0)
        };
        let (view, cover) = (image.view(), coverage.view());
        let shot = capture_object(view, cover, &circle, 2.0, &settings, &mut Rng::new(1)).unwrap();
        assert_eq!(shot.circle, circle);
        assert_eq!(shot.white, 0.5);
        let d = decoded(&shot);
        assert_eq!(d.dim(), (90, 120));
        // White (2) lands at 0.5: the object at 0.375, the background (0.2 of white) at 0.1.
        let expected = |y: usize, x: usize| {
            let c = coverage[[y, x]];
            (c * image[[y, x]] / 2.0 + (1.0 - c) * 0.2) * 0.5
        };
        for ((y, x), v) in d.indexed_iter() {
            assert!((v - expected(y, x)).abs() < 1e-4, "({y}, {x}): {v}");
        }
        let bad = capture_object(
            view,
            cover.slice(ndarray::s![1.., ..]),
            &circle,
            2.0,
            &settings,
            &mut Rng::new(1),
        );
        assert!(bad.is_err());
    }

    #[test]
    fn sampled_settings_stay_within_the_ranges() {
        let ranges = CaptureRanges::default();
        ranges.validate().unwrap();
        let mut rng = Rng::new(11);
        let mut kinds = [0usize; 3];
        for _ in 0..400 {
            let s = ranges.sample(&mut rng);
            assert!((60.0..=400.0).contains(&s.radius), "{s:?}");
            assert!((0.2..=0.8).contains(&s.exposure));
            assert!((0.0..=0.025).contains(&s.noise));
            assert!((0.0..=1.0).contains(&s.blur));
            assert!(s.white_error.abs() <= 0.05 && s.radius_error.abs() <= 0.015);
            assert!(s.centre_error.iter().all(|e| e.abs() <= 1.0));
            kinds[match s.quantization {
                Quantization::Srgb8 => 0,
                Quantization::Jpeg { quality } => {
                    assert!((70..=98).contains(&quality));
                    1
                }
                Quantization::Linear16 => 2,
            }] += 1;
        }
        assert!(kinds.iter().all(|&k| k > 50), "{kinds:?}");
        let bad = CaptureRanges {
            exposure: [0.8, 0.2],
            ..ranges
        };
        assert!(bad.validate().is_err());
    }
}
