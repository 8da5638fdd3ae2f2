//! PNG, JPEG, WebP, TIFF and PNM through the `image` crate: header check, EXIF orientation,
//! then 8/16-bit samples through a transfer-function table (float TIFF stays linear).

use super::{
    DecodeError, DecodeOptions, Format, Limits, LinearImage, alpha_to_mask, luminance,
    validate_float,
};
use crate::image::colour::ColourCopy;
use image::{DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader};
use ndarray::Array2;
use std::io::Cursor;

pub(crate) fn decode(bytes: &[u8], options: &DecodeOptions) -> Result<LinearImage, DecodeError> {
    let (image, format) = decode_samples(bytes, options)?;
    to_linear(image, format, options)
}

/// The file's samples as decoded, after its EXIF orientation, and its format.
pub(crate) fn decode_samples(
    bytes: &[u8],
    options: &DecodeOptions,
) -> Result<(DynamicImage, Format), DecodeError> {
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|_| super::unsupported(bytes))?;
    let format = match reader.format() {
        Some(ImageFormat::Png) => Format::Png,
        Some(ImageFormat::Jpeg) => Format::Jpeg,
        Some(ImageFormat::Tiff) => Format::Tiff,
        Some(ImageFormat::Pnm) => Format::Pnm,
        Some(ImageFormat::WebP) => Format::WebP,
        _ => return Err(super::unsupported(bytes)),
    };
    reader.limits(image_limits(&options.limits));
    let limits = &options.limits;
    let mut decoder = reader
        .into_decoder()
        .map_err(|e| map_error(e, format, limits))?;
    let (width, height) = decoder.dimensions();
    options.limits.check(u64::from(width), u64::from(height))?;
    let orientation = decoder
        .orientation()
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut image =
        DynamicImage::from_decoder(decoder).map_err(|e| map_error(e, format, limits))?;
    image.apply_orientation(orientation);
    Ok((image, format))
}

fn image_limits(limits: &Limits) -> image::Limits {
    let mut out = image::Limits::default();
    out.max_image_width = Some(limits.max_width);
    out.max_image_height = Some(limits.max_height);
    // Room for the decoder's own buffer at up to 16 bytes per pixel (RGBA f32).
    out.max_alloc = Some(limits.max_pixels.saturating_mul(16));
    out
}

fn map_error(error: ImageError, format: Format, limits: &Limits) -> DecodeError {
    match error {
        ImageError::Limits(e) => DecodeError::LimitExceeded(format!(
            "{e} (the limits: {}×{} and {} pixels)",
            limits.max_width, limits.max_height, limits.max_pixels
        )),
        ImageError::Unsupported(e) => DecodeError::Unsupported {
            format,
            detail: e.to_string(),
        },
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            DecodeError::corrupt(format, "file is truncated")
        }
        other => DecodeError::corrupt(format, other),
    }
}

pub(super) fn to_linear(
    image: DynamicImage,
    format: Format,
    options: &DecodeOptions,
) -> Result<LinearImage, DecodeError> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let enc = options.encoding.unwrap_or_default();
    let c = options.colour;
    let planes = match image {
        DynamicImage::ImageLuma8(img) => integer_planes(img.as_raw(), 1, w, h, &enc.table(8), c),
        DynamicImage::ImageLumaA8(img) => integer_planes(img.as_raw(), 2, w, h, &enc.table(8), c),
        DynamicImage::ImageRgb8(img) => integer_planes(img.as_raw(), 3, w, h, &enc.table(8), c),
        DynamicImage::ImageRgba8(img) => integer_planes(img.as_raw(), 4, w, h, &enc.table(8), c),
        DynamicImage::ImageLuma16(img) => integer_planes(img.as_raw(), 1, w, h, &enc.table(16), c),
        DynamicImage::ImageLumaA16(img) => integer_planes(img.as_raw(), 2, w, h, &enc.table(16), c),
        DynamicImage::ImageRgb16(img) => integer_planes(img.as_raw(), 3, w, h, &enc.table(16), c),
        DynamicImage::ImageRgba16(img) => integer_planes(img.as_raw(), 4, w, h, &enc.table(16), c),
        float => return float_tiff(float.into_rgba32f(), format, c),
    };
    Ok(LinearImage {
        luminance: planes.luminance,
        alpha_mask: planes.alpha_mask,
        colour: planes.colour,
        format,
        is_float: false,
        warnings: Vec::new(),
    })
}

/// What an integer image becomes.
struct Planes {
    luminance: Array2<f64>,
    alpha_mask: Option<Array2<bool>>,
    colour: Option<ColourCopy>,
}

/// Luminance through `table`, the alpha mask and (with `colour`, for RGB) the colour copy of
/// interleaved integer samples (1 = grey, 2 = grey+alpha, 3 = RGB, 4 = RGBA).
fn integer_planes<T: Copy + Into<u32>>(
    samples: &[T],
    channels: usize,
    width: usize,
    height: usize,
    table: &[f64],
    colour: bool,
) -> Planes {
    let lookup = |s: T| table[s.into() as usize];
    let pixels = samples.chunks_exact(channels);
    let lum: Vec<f64> = match channels {
        1 | 2 => pixels.map(|p| lookup(p[0])).collect(),
        _ => pixels
            .map(|p| luminance(lookup(p[0]), lookup(p[1]), lookup(p[2])))
            .collect(),
    };
    let alpha_mask = channels.is_multiple_of(2).then(|| {
        let max = (table.len() - 1) as f64;
        let alpha = samples
            .chunks_exact(channels)
            .map(|p| f64::from(p[channels - 1].into()) / max)
            .collect();
        alpha_to_mask(&Array2::from_shape_vec((height, width), alpha).expect("plane size"))
    });
    let lum = Array2::from_shape_vec((height, width), lum).expect("plane size");
    let colour = (colour && channels >= 3).then(|| {
        ColourCopy::new(width, height, |i| {
            let p = &samples[i * channels..i * channels + 3];
            [lookup(p[0]), lookup(p[1]), lookup(p[2])]
        })
    });
    Planes {
        luminance: lum,
        alpha_mask: alpha_mask.flatten(),
        colour,
    }
}

fn float_tiff(
    image: image::Rgba32FImage,
    format: Format,
    colour: bool,
) -> Result<LinearImage, DecodeError> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let pixels = image.pixels();
    let nonfinite = pixels
        .clone()
        .flat_map(|p| p.0)
        .filter(|v| !v.is_finite())
        .count();
    let lum = pixels
        .clone()
        .map(|p| luminance(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        .collect();
    let lum = Array2::from_shape_vec((h, w), lum).expect("plane size");
    validate_float(&lum, nonfinite)?;
    let alpha = pixels.map(|p| f64::from(p[3])).collect();
    let alpha = Array2::from_shape_vec((h, w), alpha).expect("plane size");
    let colour = colour.then(|| {
        ColourCopy::new(w, h, |i| {
            let p = image.as_raw();
            [p[4 * i], p[4 * i + 1], p[4 * i + 2]].map(f64::from)
        })
    });
    Ok(LinearImage {
        luminance: lum,
        alpha_mask: alpha_to_mask(&alpha),
        colour,
        format,
        is_float: true,
        warnings: Vec::new(),
    })
}
