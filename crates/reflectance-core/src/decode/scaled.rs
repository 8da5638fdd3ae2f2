//! A JPEG decoded at 1/2, 1/4 or 1/8 of its size by scaling in the DCT domain (the reduced
//! inverse transforms of `jpeg-decoder`): what a step that works on a reduced copy needs,
//! for a fraction of the pixels and the memory. At 12 MP it takes half the time of a full
//! decode (the entropy decoding, which every scale pays, is the rest); at 4 MP and below the
//! full decoder is as fast or faster (docs/performance.md, "Phone photographs").
//!
//! Whatever `jpeg-decoder` does not decode the way the full path does (CMYK, 12-bit and
//! lossless JPEG) or refuses (a corrupt, truncated or unsupported file), and every file
//! that is not a JPEG, goes through the full decode instead ([`super::decode`]): its
//! answers, its errors and its limits are those of the full path. A JPEG over the limits
//! is refused on its header before anything is allocated, as the full path does.

use super::{DecodeError, DecodeOptions, LinearImage, integer};
use image::metadata::Orientation;
use image::{DynamicImage, ImageBuffer};
use std::io::Cursor;

/// An image decoded at a reduction of its size, and how its pixels map onto the full image's.
#[derive(Clone, Debug)]
pub struct Reduced {
    /// The reduced image (the full one when [`Reduced::denominator`] is 1).
    pub image: LinearImage,
    /// The full image's width (after its EXIF orientation).
    pub full_width: usize,
    /// The full image's height (after its EXIF orientation).
    pub full_height: usize,
    /// Full-image pixels per reduced pixel along each axis: 1, 2, 4 or 8.
    pub denominator: usize,
    /// Where the reduced grid starts on the full image, per axis: 0, or (for an axis the
    /// orientation reversed, whose last reduced pixel was the partial one) full − reduced ×
    /// denominator.
    offset: [f64; 2],
}

impl Reduced {
    /// The full image's coordinates (pixel centres are integers) of a point of the reduced
    /// image.
    pub fn to_full(&self, x: f64, y: f64) -> (f64, f64) {
        let d = self.denominator as f64;
        (
            (x + 0.5) * d - 0.5 + self.offset[0],
            (y + 0.5) * d - 0.5 + self.offset[1],
        )
    }

    /// The reduced image's coordinates of a point of the full image.
    pub fn from_full(&self, x: f64, y: f64) -> (f64, f64) {
        let d = self.denominator as f64;
        (
            (x - self.offset[0] + 0.5) / d - 0.5,
            (y - self.offset[1] + 0.5) / d - 0.5,
        )
    }

    fn full(image: LinearImage) -> Reduced {
        Reduced {
            full_width: image.width(),
            full_height: image.height(),
            image,
            denominator: 1,
            offset: [0.0; 2],
        }
    }
}

/// The largest denominator (1, 2, 4 or 8) that keeps the longer side of a `width` × `height`
/// image at least `min_long_side` pixels.
pub fn denominator_for(width: usize, height: usize, min_long_side: usize) -> usize {
    let long = width.max(height);
    [8, 4, 2]
        .into_iter()
        .find(|&d| long.div_ceil(d) >= min_long_side)
        .unwrap_or(1)
}

/// Decode `bytes` at 1/`denominator` (1, 2, 4 or 8) of its size when it is a JPEG that the
/// scaled decoder reads as the full path would, else in full ([`Reduced::denominator`] says
/// which). `denominator` is clamped to those values (down to the nearest).
pub fn decode_reduced(
    bytes: &[u8],
    options: &DecodeOptions,
    denominator: usize,
) -> Result<Reduced, DecodeError> {
    let denominator = match denominator {
        0..=1 => 1,
        2..=3 => 2,
        4..=7 => 4,
        _ => 8,
    };
    if denominator > 1
        && bytes.starts_with(&[0xff, 0xd8, 0xff])
        && let Some(reduced) = jpeg_reduced(bytes, options, denominator)
    {
        return Ok(reduced);
    }
    super::decode(bytes, options).map(Reduced::full)
}

/// The scaled decode, or None for whatever the full path should answer instead.
fn jpeg_reduced(bytes: &[u8], options: &DecodeOptions, denominator: usize) -> Option<Reduced> {
    let mut decoder = jpeg_decoder::Decoder::new(Cursor::new(bytes));
    decoder.read_info().ok()?;
    let info = decoder.info()?;
    let (width, height) = (usize::from(info.width), usize::from(info.height));
    // Over the limits: the full path refuses it, on its header too.
    options.limits.check(width as u64, height as u64).ok()?;
    let (w, h) = (width.div_ceil(denominator), height.div_ceil(denominator));
    let (sw, sh) = decoder
        .scale(u16::try_from(w).ok()?, u16::try_from(h).ok()?)
        .ok()?;
    if (usize::from(sw), usize::from(sh)) != (w, h) {
        return None;
    }
    // Room for the reduced pixels only (at most three bytes each).
    decoder.set_max_decoding_buffer_size(w.checked_mul(h)?.checked_mul(3)?);
    let pixels = decoder.decode().ok()?;
    let info = decoder.info()?;
    let stored = match info.pixel_format {
        jpeg_decoder::PixelFormat::L8 => {
            DynamicImage::ImageLuma8(ImageBuffer::from_raw(w as u32, h as u32, pixels)?)
        }
        jpeg_decoder::PixelFormat::RGB24 => {
            DynamicImage::ImageRgb8(ImageBuffer::from_raw(w as u32, h as u32, pixels)?)
        }
        // CMYK and 16-bit (lossless) samples: as the full path converts them.
        _ => return None,
    };
    let orientation = decoder
        .exif_data()
        .and_then(Orientation::from_exif_chunk)
        .unwrap_or(Orientation::NoTransforms);
    let mut oriented = stored;
    oriented.apply_orientation(orientation);
    let image = integer::to_linear(oriented, super::Format::Jpeg, options).ok()?;
    let (reverse_x, reverse_y, transposed) = match orientation {
        Orientation::NoTransforms => (false, false, false),
        Orientation::FlipHorizontal => (true, false, false),
        Orientation::FlipVertical => (false, true, false),
        Orientation::Rotate180 => (true, true, false),
        Orientation::Rotate90 => (true, false, true),
        Orientation::Rotate270 => (false, true, true),
        Orientation::Rotate90FlipH => (false, false, true),
        Orientation::Rotate270FlipH => (true, true, true),
    };
    let (full_width, full_height) = if transposed {
        (height, width)
    } else {
        (width, height)
    };
    let shift = |reversed: bool, full: usize, reduced: usize| match reversed {
        true => full as f64 - (reduced * denominator) as f64,
        false => 0.0,
    };
    let offset = [
        shift(reverse_x, full_width, image.width()),
        shift(reverse_y, full_height, image.height()),
    ];
    Some(Reduced {
        image,
        full_width,
        full_height,
        denominator,
        offset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::{DecodeError, Limits, decode};

    /// A `width` × `height` JPEG (grey, or RGB when `colour`) of a bright square around
    /// (`x`, `y`), half-side `half`, on a mid-grey ramp.
    fn jpeg(width: u32, height: u32, spot: (f64, f64, f64), colour: bool) -> Vec<u8> {
        let (x0, y0, half) = spot;
        let value = |x: u32, y: u32| -> u8 {
            let inside = (f64::from(x) - x0).abs() <= half && (f64::from(y) - y0).abs() <= half;
            if inside { 250 } else { 40 + (x % 7) as u8 }
        };
        let mut samples = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let v = value(x, y);
                match colour {
                    true => samples.extend_from_slice(&[v, v / 2 + 10, v / 3 + 20]),
                    false => samples.push(v),
                }
            }
        }
        let kind = match colour {
            true => image::ExtendedColorType::Rgb8,
            false => image::ExtendedColorType::L8,
        };
        let mut out = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95),
            &samples,
            width,
            height,
            kind,
        )
        .expect("encode");
        out
    }

    /// `jpeg` with an EXIF orientation (1–8) in an APP1 segment after SOI.
    fn with_orientation(jpeg: &[u8], orientation: u16) -> Vec<u8> {
        let mut tiff = b"MM\0\x2a\0\0\0\x08\0\x01".to_vec();
        tiff.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1]);
        tiff.extend_from_slice(&orientation.to_be_bytes());
        tiff.extend_from_slice(&[0, 0, 0, 0, 0, 0]);
        let mut app1 = vec![0xff, 0xe1];
        app1.extend_from_slice(&((tiff.len() + 8) as u16).to_be_bytes());
        app1.extend_from_slice(b"Exif\0\0");
        app1.extend_from_slice(&tiff);
        [&jpeg[..2], &app1, &jpeg[2..]].concat()
    }

    /// The centroid of the pixels above half the brightest.
    fn bright_centroid(image: &LinearImage) -> (f64, f64) {
        let peak = image.luminance.iter().copied().fold(0.0, f64::max);
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for ((y, x), &v) in image.luminance.indexed_iter() {
            if v > 0.5 * peak {
                let w = v;
                sx += w * x as f64;
                sy += w * y as f64;
                n += w;
            }
        }
        (sx / n, sy / n)
    }

    #[test]
    fn reduced_pixels_land_where_the_full_image_has_them_in_every_orientation() {
        // Odd sizes: the last reduced column and row are partial.
        let plain = jpeg(203, 131, (150.0, 40.0, 9.5), false);
        for orientation in 1..=8 {
            let bytes = with_orientation(&plain, orientation);
            let full = decode(&bytes, &DecodeOptions::default()).unwrap();
            let (fx, fy) = bright_centroid(&full);
            for d in [2, 4, 8] {
                let reduced = decode_reduced(&bytes, &DecodeOptions::default(), d).unwrap();
                assert_eq!(reduced.denominator, d);
                assert_eq!(
                    (reduced.full_width, reduced.full_height),
                    (full.width(), full.height()),
                    "orientation {orientation}"
                );
                assert_eq!(
                    (reduced.image.width(), reduced.image.height()),
                    (full.width().div_ceil(d), full.height().div_ceil(d))
                );
                let (rx, ry) = bright_centroid(&reduced.image);
                let (x, y) = reduced.to_full(rx, ry);
                let tolerance = 0.3 * d as f64 + 0.5;
                assert!(
                    (x - fx).abs() <= tolerance && (y - fy).abs() <= tolerance,
                    "orientation {orientation}, 1/{d}: ({x:.2}, {y:.2}) for ({fx:.2}, {fy:.2})"
                );
                let (bx, by) = reduced.from_full(x, y);
                assert!((bx - rx).abs() < 1e-9 && (by - ry).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn reduced_luminance_is_the_full_one_averaged() {
        let bytes = jpeg(256, 192, (100.0, 90.0, 30.0), true);
        let options = DecodeOptions {
            colour: true,
            ..Default::default()
        };
        let full = decode(&bytes, &options).unwrap();
        for d in [2usize, 4, 8] {
            let reduced = decode_reduced(&bytes, &options, d).unwrap();
            assert!(reduced.image.colour.is_some() && !reduced.image.is_float);
            let averaged =
                crate::image::resample::downsample(full.luminance.view(), 1.0 / d as f64);
            assert_eq!(averaged.dim(), reduced.image.luminance.dim());
            // Averaged in the encoded (not linear) values, away from the square's edges.
            let worst = averaged
                .indexed_iter()
                .filter(|((y, x), _)| {
                    let (cx, cy) = ((*x as f64 + 0.5) * d as f64, (*y as f64 + 0.5) * d as f64);
                    let edge = ((cx - 100.0).abs() - 30.0)
                        .abs()
                        .min(((cy - 90.0).abs() - 30.0).abs());
                    edge > d as f64 + 2.0
                })
                .map(|((y, x), &a)| (a - reduced.image.luminance[[y, x]]).abs())
                .fold(0.0, f64::max);
            assert!(worst < 0.02, "1/{d}: {worst}");
        }
    }

    #[test]
    fn what_the_scaled_decoder_does_not_take_is_decoded_in_full() {
        let options = DecodeOptions::default();
        // Small files and other formats: in full, as `decode` gives them.
        let png = {
            let mut out = Vec::new();
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut out),
                &[10u8; 64 * 64],
                64,
                64,
                image::ExtendedColorType::L8,
            )
            .unwrap();
            out
        };
        let reduced = decode_reduced(&png, &options, 4).unwrap();
        assert_eq!((reduced.denominator, reduced.image.width()), (1, 64));
        assert_eq!(reduced.to_full(3.0, 5.0), (3.0, 5.0));
        let jpeg = jpeg(120, 80, (60.0, 40.0, 10.0), false);
        assert_eq!(decode_reduced(&jpeg, &options, 1).unwrap().denominator, 1);
        assert_eq!(decode_reduced(&jpeg, &options, 5).unwrap().denominator, 4);
        // Truncated (which the full path fills in grey or refuses) and corrupt: the full
        // path's answer, never a panic.
        for bytes in [&jpeg, &self::jpeg(200, 200, (90.0, 90.0, 40.0), true)] {
            let cut = &bytes[..bytes.len() / 3];
            match (decode_reduced(cut, &options, 4), decode(cut, &options)) {
                (Ok(reduced), Ok(full)) => {
                    assert_eq!(reduced.denominator, 1);
                    assert_eq!(reduced.image.luminance, full.luminance);
                }
                (Err(reduced), Err(full)) => assert_eq!(reduced.to_string(), full.to_string()),
                (reduced, full) => panic!("{:?} against {:?}", reduced.err(), full.err()),
            }
        }
        for cut in [4, 20, 200, jpeg.len() - 2] {
            let _ = decode_reduced(&jpeg[..cut], &options, 8);
        }
        let mut garbled = jpeg.clone();
        let middle = garbled.len() / 2;
        garbled[middle..middle + 40].fill(0xff);
        let _ = decode_reduced(&garbled, &options, 2);
        // Over the limits: refused as the full path refuses it.
        let tight = DecodeOptions {
            limits: Limits {
                max_width: 100,
                max_height: 100,
                max_pixels: 1_000_000,
            },
            ..options
        };
        assert!(matches!(
            decode_reduced(&jpeg, &tight, 8),
            Err(DecodeError::TooLarge { .. } | DecodeError::LimitExceeded(_))
        ));
    }

    #[test]
    fn denominators_keep_the_long_side() {
        assert_eq!(denominator_for(4096, 3072, 640), 4);
        assert_eq!(denominator_for(8000, 6000, 640), 8);
        assert_eq!(denominator_for(1200, 1200, 640), 1);
        assert_eq!(denominator_for(1300, 900, 640), 2);
        assert_eq!(denominator_for(300, 200, 640), 1);
    }
}
