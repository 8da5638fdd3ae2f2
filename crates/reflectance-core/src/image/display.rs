//! Pictures for people: linear luminance and signed subbands as 8-bit grey PNG (the page's
//! unwrapped annulus, subbands and training thumbnails), and PNG data URLs.

use super::plane::Plane;
use base64::Engine;
use image::ImageEncoder;
use ndarray::{Array2, ArrayView2};

/// sRGB transfer function (IEC 61966-2-1) from linear `v ∈ [0, 1]`.
pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// An 8-bit grey PNG of `samples`, row by row.
pub fn grey_png(width: usize, height: usize, samples: &[u8]) -> Result<Vec<u8>, image::ImageError> {
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png).write_image(
        samples,
        width as u32,
        height as u32,
        image::ExtendedColorType::L8,
    )?;
    Ok(png)
}

fn png_of(values: ArrayView2<f64>, level: impl Fn(f64) -> f64) -> Vec<u8> {
    let (h, w) = values.dim();
    let samples: Vec<u8> = values
        .iter()
        .map(|&v| (255.0 * level(v).clamp(0.0, 1.0)).round() as u8)
        .collect();
    // The samples match the size, and PNG encoding into memory has no other failure.
    grey_png(w, h, &samples).unwrap_or_default()
}

/// Linear luminance relative to white (1 = white; brighter clips), sRGB-encoded.
pub fn luminance_png(values: ArrayView2<f64>) -> Vec<u8> {
    png_of(values, |v| linear_to_srgb(v.clamp(0.0, 1.0)))
}

/// The 99th percentile (`None` for no values).
fn percentile99(mut values: Vec<f64>) -> Option<f64> {
    let k = (values.len() * 99 / 100).min(values.len().checked_sub(1)?);
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// Signed values around mid-grey: 0 is grey, ± the 99th percentile of |v| is white/black.
pub fn signed_png(values: ArrayView2<f64>) -> Vec<u8> {
    let scale = percentile99(values.iter().map(|v| v.abs()).collect()).unwrap_or(0.0);
    let scale = if scale > 0.0 { scale } else { 1.0 };
    png_of(values, |v| 0.5 + 0.5 * v / scale)
}

/// `luminance` area-averaged so that its longest side is at most `side` pixels.
fn fit(luminance: impl Plane, side: usize) -> Array2<f64> {
    let (h, w) = luminance.size();
    let factor = side as f64 / h.max(w).max(1) as f64;
    luminance.part(0..h, 0..w, factor)
}

/// A thumbnail of linear luminance (relative to white) whose longest side is at most `side`
/// pixels.
pub fn thumbnail_png(luminance: ArrayView2<f64>, side: usize) -> Vec<u8> {
    luminance_png(fit(luminance, side).view())
}

/// A picture of any linear image (high dynamic range included): the longest side at most
/// `side` pixels, the 99th percentile of luminance at full brightness.
pub fn preview_png(luminance: impl Plane, side: usize) -> Vec<u8> {
    let small = fit(luminance, side);
    let top = percentile99(small.iter().copied().collect()).unwrap_or(0.0);
    let gain = if top > 0.0 { 1.0 / top } else { 1.0 };
    luminance_png(small.mapv(|v| v * gain).view())
}

/// A `data:image/png;base64,…` URL of PNG bytes.
pub fn data_url(png: &[u8]) -> String {
    let encoded = base64::engine::general_purpose::STANDARD.encode(png);
    format!("data:image/png;base64,{encoded}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decoded(png: &[u8]) -> image::GrayImage {
        image::load_from_memory(png).unwrap().to_luma8()
    }

    #[test]
    fn srgb_round_trips_the_decoder() {
        for v in [0.0, 0.001, 0.0031308, 0.2, 0.5, 1.0] {
            let back = crate::decode::srgb_to_linear(linear_to_srgb(v));
            assert!((back - v).abs() < 1e-12, "{v} → {back}");
        }
    }

    #[test]
    fn luminance_is_srgb_and_clips_above_white() {
        let values = Array2::from_shape_vec((1, 4), vec![0.0, 0.5, 1.0, 7.0]).unwrap();
        let picture = decoded(&luminance_png(values.view()));
        assert_eq!(picture.dimensions(), (4, 1));
        // sRGB(0.5) = 0.73536 → 187.5 → 188.
        assert_eq!(picture.into_raw(), vec![0, 188, 255, 255]);
    }

    #[test]
    fn signed_values_centre_on_grey() {
        let values = Array2::from_shape_fn((10, 10), |(y, x)| (x as f64 - 4.5) * (y + 1) as f64);
        let picture = decoded(&signed_png(values.view()));
        let raw = picture.as_raw();
        // Antisymmetric about the middle column pair: mirrored pixels sum to 255.
        for y in 0..10 {
            for x in 0..5 {
                let (a, b) = (raw[y * 10 + x] as u32, raw[y * 10 + 9 - x] as u32);
                assert!((a + b).abs_diff(255) <= 1, "{a} + {b}");
            }
        }
        assert_eq!(
            decoded(&signed_png(Array2::zeros((2, 3)).view())).as_raw(),
            &vec![128; 6]
        );
    }

    #[test]
    fn thumbnails_fit_the_box_and_keep_the_mean() {
        let flat = Array2::from_elem((200, 100), 0.5);
        let picture = decoded(&thumbnail_png(flat.view(), 48));
        assert_eq!(picture.dimensions(), (24, 48));
        assert!(picture.pixels().all(|p| p.0[0] == 188));
        let small = Array2::from_elem((10, 20), 1.0);
        assert_eq!(
            decoded(&thumbnail_png(small.view(), 48)).dimensions(),
            (20, 10)
        );
    }

    #[test]
    fn previews_put_the_99th_percentile_at_white() {
        // 1000 samples 0.001…1.0 in units of 10: the 99th percentile (990) maps to white.
        let values = Array2::from_shape_fn((10, 100), |(y, x)| 10.0 * (y * 100 + x + 1) as f64);
        let picture = decoded(&preview_png(values.view(), 1024));
        assert_eq!(picture.dimensions(), (100, 10));
        let raw = picture.as_raw();
        assert_eq!((raw[990], raw[999]), (255, 255));
        assert_eq!(
            raw[500],
            (255.0 * linear_to_srgb(5010.0 / 9910.0)).round() as u8
        );
        assert!(raw[900] < 255);
        assert_eq!(
            decoded(&preview_png(values.view(), 50)).dimensions(),
            (50, 5)
        );
    }

    #[test]
    fn data_urls_carry_the_png() {
        let png = luminance_png(Array2::zeros((1, 1)).view());
        let url = data_url(&png);
        let encoded = url.strip_prefix("data:image/png;base64,").unwrap();
        let back = base64::engine::general_purpose::STANDARD
            .decode(encoded)
            .unwrap();
        assert_eq!(back, png);
    }
}
