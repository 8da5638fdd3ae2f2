//! Portable Float Map: `PF` (RGB) or `Pf` (grey), rows stored bottom-up, the sign of the
//! scale gives the byte order (negative = little-endian), its magnitude is ignored.

use super::{DecodeError, DecodeOptions, FloatPlane, Format, luminance, validate_float};
use crate::image::colour::ColourCopy;
use ndarray::Array2;

const FORMAT: Format = Format::Pfm;

pub(crate) fn decode(bytes: &[u8], options: &DecodeOptions) -> Result<FloatPlane, DecodeError> {
    let header = Header::parse(bytes)?;
    options
        .limits
        .check(header.width as u64, header.height as u64)?;
    let samples = header.width * header.height * header.channels;
    let data = bytes
        .get(header.data_start..)
        .filter(|d| d.len() >= samples * 4)
        .ok_or_else(|| DecodeError::corrupt(FORMAT, "pixel data is truncated"))?;
    let read = |i: usize| -> f64 {
        let raw: [u8; 4] = data[i * 4..i * 4 + 4].try_into().expect("4 bytes");
        f64::from(if header.little_endian {
            f32::from_le_bytes(raw)
        } else {
            f32::from_be_bytes(raw)
        })
    };
    let mut nonfinite = 0;
    let lum = Array2::from_shape_fn((header.height, header.width), |(row, col)| {
        let stored_row = header.height - 1 - row;
        let base = (stored_row * header.width + col) * header.channels;
        let rgb = if header.channels == 1 {
            [read(base); 3]
        } else {
            [read(base), read(base + 1), read(base + 2)]
        };
        nonfinite += rgb[..header.channels]
            .iter()
            .filter(|v| !v.is_finite())
            .count();
        if header.channels == 1 {
            rgb[0]
        } else {
            luminance(rgb[0], rgb[1], rgb[2])
        }
    });
    validate_float(&lum, nonfinite)?;
    let colour = (options.colour && header.channels == 3).then(|| {
        ColourCopy::new(header.width, header.height, |i| {
            let (row, col) = (i / header.width, i % header.width);
            let base = ((header.height - 1 - row) * header.width + col) * 3;
            [read(base), read(base + 1), read(base + 2)]
        })
    });
    Ok(FloatPlane {
        luminance: lum,
        alpha: None,
        colour,
    })
}

struct Header {
    channels: usize,
    width: usize,
    height: usize,
    little_endian: bool,
    data_start: usize,
}

impl Header {
    /// `PF|Pf <ws> width <ws> height <ws> scale <one whitespace byte>` then the samples.
    fn parse(bytes: &[u8]) -> Result<Header, DecodeError> {
        let channels = match bytes.get(..2) {
            Some(b"PF") => 3,
            Some(b"Pf") => 1,
            _ => return Err(DecodeError::corrupt(FORMAT, "missing PF/Pf signature")),
        };
        let mut pos = 2;
        let mut token = || -> Result<&str, DecodeError> {
            while bytes.get(pos).is_some_and(u8::is_ascii_whitespace) {
                pos += 1;
            }
            let start = pos;
            while bytes.get(pos).is_some_and(|b| !b.is_ascii_whitespace()) {
                pos += 1;
            }
            if start == pos || pos >= bytes.len() || pos - start > 32 {
                return Err(DecodeError::corrupt(FORMAT, "truncated header"));
            }
            std::str::from_utf8(&bytes[start..pos])
                .map_err(|_| DecodeError::corrupt(FORMAT, "header is not text"))
        };
        let bad = |what: &str| DecodeError::corrupt(FORMAT, format!("bad {what} in header"));
        let width: usize = token()?.parse().map_err(|_| bad("width"))?;
        let height: usize = token()?.parse().map_err(|_| bad("height"))?;
        let scale: f64 = token()?.parse().map_err(|_| bad("scale"))?;
        if !scale.is_finite() || scale == 0.0 {
            return Err(bad("scale"));
        }
        Ok(Header {
            channels,
            width,
            height,
            little_endian: scale < 0.0,
            // Exactly one whitespace byte separates the scale from the samples.
            data_start: pos + 1,
        })
    }
}

/// Encode a grey plane (rows top to bottom) as little-endian `Pf`.
pub fn encode_gray(width: usize, height: usize, values: &[f32]) -> Vec<u8> {
    assert_eq!(values.len(), width * height, "plane size");
    let mut out = format!("Pf\n{width} {height}\n-1.0\n").into_bytes();
    out.reserve(values.len() * 4);
    for row in values.chunks_exact(width).rev() {
        for v in row {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray_round_trip_and_row_order() {
        let values = [0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0];
        let bytes = encode_gray(3, 2, &values);
        let plane = decode(&bytes, &DecodeOptions::default()).unwrap();
        assert_eq!(plane.luminance.dim(), (2, 3));
        assert_eq!(plane.luminance[[0, 0]], 0.0);
        assert_eq!(plane.luminance[[1, 2]], 5.0);
        // The first stored row is the bottom one.
        assert_eq!(
            &bytes[bytes.len() - 12..bytes.len() - 8],
            &0.0f32.to_le_bytes()
        );
    }

    #[test]
    fn big_endian_rgb() {
        let mut bytes = b"PF\n1 2\n1.0\n".to_vec();
        for v in [1.0f32, 0.0, 0.0, 0.0, 0.0, 1.0] {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        let lum = decode(&bytes, &DecodeOptions::default()).unwrap().luminance;
        // Bottom row stored first: row 1 is pure red, row 0 pure blue.
        assert_eq!(lum[[1, 0]], 0.2126);
        assert_eq!(lum[[0, 0]], 0.0722);
        // The colour copy, asked for, in the same row order.
        let with_colour = DecodeOptions {
            colour: true,
            ..DecodeOptions::default()
        };
        let copy = decode(&bytes, &with_colour).unwrap().colour.unwrap();
        assert_eq!(copy.mean(|_, y| y < 0.5, 0.0), Some([0.0, 0.0, 1.0]));
        assert_eq!(copy.mean(|_, y| y > 0.5, 0.0), Some([1.0, 0.0, 0.0]));
        assert!(
            decode(&bytes, &DecodeOptions::default())
                .unwrap()
                .colour
                .is_none()
        );
    }

    #[test]
    fn bad_files_are_errors() {
        let limits = DecodeOptions::default();
        let short = &encode_gray(4, 4, &[1.0; 16])[..30];
        assert!(matches!(
            decode(short, &limits),
            Err(DecodeError::Corrupt { .. })
        ));
        let huge = b"Pf\n100000 100000\n-1.0\n";
        assert!(matches!(
            decode(huge, &limits),
            Err(DecodeError::TooLarge { .. })
        ));
        let zero = b"Pf\n0 5\n-1.0\n";
        assert!(matches!(
            decode(zero, &limits),
            Err(DecodeError::Empty { .. })
        ));
        let nan = encode_gray(2, 1, &[f32::NAN, 1.0]);
        assert!(matches!(
            decode(&nan, &limits),
            Err(DecodeError::NonFinite { count: 1 })
        ));
        let inf = encode_gray(2, 1, &[f32::INFINITY, f32::NEG_INFINITY]);
        assert!(matches!(
            decode(&inf, &limits),
            Err(DecodeError::NonFinite { count: 2 })
        ));
        let neg = encode_gray(2, 1, &[-0.5, 1.0]);
        assert!(matches!(
            decode(&neg, &limits),
            Err(DecodeError::Negative { count: 1, .. })
        ));
        let bad_scale = b"Pf\n1 1\nabc\n\0\0\0\0";
        assert!(matches!(
            decode(bad_scale, &limits),
            Err(DecodeError::Corrupt { .. })
        ));
    }
}
