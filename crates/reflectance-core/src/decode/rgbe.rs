//! Radiance `.hdr` (RGBE / XYZE): header, all eight resolution-line orientations, flat,
//! old-style RLE and new-style (per-component) RLE scanlines.
//!
//! Values are `m · 2^(e − 136)` exactly (no +0.5 offset); `EXPOSURE` is ignored; XYZE gives Y
//! directly. Decoding is exact in f64.

use super::{DecodeError, DecodeOptions, FloatPlane, Format, Limits, luminance, validate_float};
use crate::image::colour::ColourCopy;
use ndarray::Array2;

const FORMAT: Format = Format::Hdr;

/// A decoded Radiance picture: linear RGB (or XYZ) per pixel, rows top to bottom.
pub struct RgbePicture {
    /// Width (px).
    pub width: usize,
    /// Height (px).
    pub height: usize,
    /// Whether the samples are CIE XYZ (`FORMAT=32-bit_rle_xyze`) rather than RGB.
    pub xyz: bool,
    /// Row-major `[c0, c1, c2]` per pixel.
    pub pixels: Vec<[f64; 3]>,
}

impl RgbePicture {
    /// Linear Rec. 709 luminance (XYZE: the Y channel).
    pub fn luminance(&self) -> Array2<f64> {
        let values = self
            .pixels
            .iter()
            .map(|&[a, b, c]| if self.xyz { b } else { luminance(a, b, c) })
            .collect();
        Array2::from_shape_vec((self.height, self.width), values)
            .expect("pixel count matches the header")
    }
}

/// Decode and validate (finite, non-negative): the image-input path.
pub(crate) fn decode(bytes: &[u8], options: &DecodeOptions) -> Result<FloatPlane, DecodeError> {
    let picture = read(bytes, &options.limits)?;
    let luminance = picture.luminance();
    validate_float(&luminance, 0)?;
    // XYZE holds no RGB: its colour is not read.
    let colour = (options.colour && !picture.xyz)
        .then(|| ColourCopy::new(picture.width, picture.height, |i| picture.pixels[i]));
    Ok(FloatPlane {
        luminance,
        alpha: None,
        colour,
    })
}

/// Parse a Radiance picture.
pub fn read(bytes: &[u8], limits: &Limits) -> Result<RgbePicture, DecodeError> {
    let mut cursor = Cursor { bytes, pos: 0 };
    let xyz = read_header(&mut cursor)?;
    let layout = Layout::parse(cursor.line()?)?;
    limits.check(layout.width() as u64, layout.height() as u64)?;
    let mut pixels = vec![[0.0; 3]; layout.width() * layout.height()];
    let mut scanline = vec![[0u8; 4]; layout.scan_len];
    for s in 0..layout.scan_count {
        read_scanline(&mut cursor, &mut scanline)?;
        for (p, rgbe) in scanline.iter().enumerate() {
            let (row, col) = layout.position(s, p);
            pixels[row * layout.width() + col] = rgbe_to_float(*rgbe);
        }
    }
    Ok(RgbePicture {
        width: layout.width(),
        height: layout.height(),
        xyz,
        pixels,
    })
}

/// `m · 2^(e − 136)` per component; exponent 0 is black.
#[inline]
pub fn rgbe_to_float([r, g, b, e]: [u8; 4]) -> [f64; 3] {
    if e == 0 {
        return [0.0; 3];
    }
    let scale = 2f64.powi(i32::from(e) - 136);
    [
        f64::from(r) * scale,
        f64::from(g) * scale,
        f64::from(b) * scale,
    ]
}

/// The RGBE code of a non-negative linear triple (largest component sets the exponent).
pub fn float_to_rgbe(rgb: [f64; 3]) -> [u8; 4] {
    let max = rgb[0].max(rgb[1]).max(rgb[2]);
    if max.is_nan() || max < 1e-38 {
        return [0; 4];
    }
    // max = f · 2^exp with f in [0.5, 1): mantissas are c · 256 / 2^exp.
    let exp = max.log2().floor() as i32 + 1;
    let scale = 256.0 / 2f64.powi(exp);
    let code = |c: f64| (c * scale).clamp(0.0, 255.0) as u8;
    [
        code(rgb[0]),
        code(rgb[1]),
        code(rgb[2]),
        (exp + 128).clamp(0, 255) as u8,
    ]
}

/// Write a grey picture as flat (uncompressed) RGBE, standard `-Y H +X W` orientation.
pub fn write_flat(width: usize, height: usize, luminance: &[f64]) -> Vec<u8> {
    let mut out =
        format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n").into_bytes();
    out.reserve(width * height * 4);
    for &y in luminance {
        out.extend_from_slice(&float_to_rgbe([y, y, y]));
    }
    out
}

struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn line(&mut self) -> Result<&'a str, DecodeError> {
        let rest = &self.bytes[self.pos..];
        let end = rest.iter().position(|&b| b == b'\n').ok_or_else(|| {
            DecodeError::corrupt(FORMAT, "header ends before the resolution line")
        })?;
        self.pos += end + 1;
        std::str::from_utf8(&rest[..end])
            .map(str::trim_end)
            .map_err(|_| DecodeError::corrupt(FORMAT, "header is not text"))
    }

    fn byte(&mut self) -> Result<u8, DecodeError> {
        let b = *self
            .bytes
            .get(self.pos)
            .ok_or_else(|| DecodeError::corrupt(FORMAT, "pixel data is truncated"))?;
        self.pos += 1;
        Ok(b)
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| DecodeError::corrupt(FORMAT, "pixel data is truncated"))?;
        let out = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(out)
    }
}

/// Reads the header up to the blank line; returns whether the pixels are XYZE.
fn read_header(cursor: &mut Cursor) -> Result<bool, DecodeError> {
    let magic = cursor.line()?;
    if !(magic.starts_with("#?RADIANCE") || magic.starts_with("#?RGBE")) {
        return Err(DecodeError::corrupt(FORMAT, "missing #?RADIANCE signature"));
    }
    let mut xyz = false;
    loop {
        let line = cursor.line()?;
        if line.is_empty() {
            return Ok(xyz);
        }
        if let Some(format) = line.strip_prefix("FORMAT=") {
            match format.trim() {
                "32-bit_rle_rgbe" => xyz = false,
                "32-bit_rle_xyze" => xyz = true,
                other => {
                    return Err(DecodeError::Unsupported {
                        format: FORMAT,
                        detail: format!("pixel format {other:?}"),
                    });
                }
            }
        }
    }
}

/// The resolution line: which axis is scanned first and in which directions.
struct Layout {
    /// true: scanlines are rows (`±Y h ±X w`); false: scanlines are columns (`±X w ±Y h`).
    rows_first: bool,
    scan_count: usize,
    scan_len: usize,
    /// Radiance Y grows upwards, so `-Y` means top row first; `+X` means left column first.
    outer_forward: bool,
    inner_forward: bool,
}

impl Layout {
    fn parse(line: &str) -> Result<Layout, DecodeError> {
        let bad = || DecodeError::corrupt(FORMAT, format!("bad resolution line {line:?}"));
        let parts: Vec<&str> = line.split_whitespace().collect();
        let [a1, n1, a2, n2] = parts[..] else {
            return Err(bad());
        };
        let n1: usize = n1.parse().map_err(|_| bad())?;
        let n2: usize = n2.parse().map_err(|_| bad())?;
        let (rows_first, outer_forward, inner_forward) = match (a1, a2) {
            ("-Y", "+X") => (true, true, true),
            ("-Y", "-X") => (true, true, false),
            ("+Y", "+X") => (true, false, true),
            ("+Y", "-X") => (true, false, false),
            ("+X", "-Y") => (false, true, true),
            ("+X", "+Y") => (false, true, false),
            ("-X", "-Y") => (false, false, true),
            ("-X", "+Y") => (false, false, false),
            _ => return Err(bad()),
        };
        Ok(Layout {
            rows_first,
            scan_count: n1,
            scan_len: n2,
            outer_forward,
            inner_forward,
        })
    }

    fn width(&self) -> usize {
        if self.rows_first {
            self.scan_len
        } else {
            self.scan_count
        }
    }

    fn height(&self) -> usize {
        if self.rows_first {
            self.scan_count
        } else {
            self.scan_len
        }
    }

    /// (row, column) of pixel `p` of scanline `s`.
    fn position(&self, s: usize, p: usize) -> (usize, usize) {
        let outer = if self.outer_forward {
            s
        } else {
            self.scan_count - 1 - s
        };
        let inner = if self.inner_forward {
            p
        } else {
            self.scan_len - 1 - p
        };
        if self.rows_first {
            (outer, inner)
        } else {
            (inner, outer)
        }
    }
}

fn read_scanline(cursor: &mut Cursor, out: &mut [[u8; 4]]) -> Result<(), DecodeError> {
    let len = out.len();
    let head = cursor.bytes.get(cursor.pos..cursor.pos + 4);
    match head {
        Some(&[2, 2, hi, lo]) if (8..0x8000).contains(&len) && hi & 0x80 == 0 => {
            if (usize::from(hi) << 8 | usize::from(lo)) != len {
                return Err(DecodeError::corrupt(FORMAT, "scanline length mismatch"));
            }
            cursor.pos += 4;
            for component in 0..4 {
                read_rle_component(cursor, out, component)?;
            }
            Ok(())
        }
        _ => read_old_scanline(cursor, out),
    }
}

/// New-style RLE: one component of the whole scanline, as runs and literal spans.
fn read_rle_component(
    cursor: &mut Cursor,
    out: &mut [[u8; 4]],
    component: usize,
) -> Result<(), DecodeError> {
    let mut x = 0;
    while x < out.len() {
        let count = usize::from(cursor.byte()?);
        let overflow = || DecodeError::corrupt(FORMAT, "run overflows the scanline");
        if count > 128 {
            let run = count - 128;
            let value = cursor.byte()?;
            let span = out.get_mut(x..x + run).ok_or_else(overflow)?;
            span.iter_mut().for_each(|px| px[component] = value);
            x += run;
        } else {
            if count == 0 {
                return Err(DecodeError::corrupt(FORMAT, "zero-length run"));
            }
            let values = cursor.take(count)?;
            let span = out.get_mut(x..x + count).ok_or_else(overflow)?;
            span.iter_mut()
                .zip(values)
                .for_each(|(px, &v)| px[component] = v);
            x += count;
        }
    }
    Ok(())
}

/// Flat pixels, with old-style `(1, 1, 1, n)` repeat codes.
fn read_old_scanline(cursor: &mut Cursor, out: &mut [[u8; 4]]) -> Result<(), DecodeError> {
    let mut x = 0;
    let mut shift = 0u32;
    while x < out.len() {
        let px: [u8; 4] = cursor.take(4)?.try_into().expect("4 bytes");
        if px[0] == 1 && px[1] == 1 && px[2] == 1 {
            let previous = x
                .checked_sub(1)
                .map(|i| out[i])
                .ok_or_else(|| DecodeError::corrupt(FORMAT, "repeat code at scanline start"))?;
            let run = usize::from(px[3])
                .checked_shl(shift)
                .filter(|&r| r <= out.len() - x)
                .ok_or_else(|| DecodeError::corrupt(FORMAT, "run overflows the scanline"))?;
            out[x..x + run].iter_mut().for_each(|p| *p = previous);
            x += run;
            shift += 8;
        } else {
            out[x] = px;
            x += 1;
            shift = 0;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(res: &str) -> Vec<u8> {
        format!("#?RADIANCE\nEXPOSURE=4.0\nFORMAT=32-bit_rle_rgbe\n\n{res}\n").into_bytes()
    }

    #[test]
    fn rgbe_values_are_exact_without_offset() {
        assert_eq!(rgbe_to_float([128, 64, 0, 129]), [1.0, 0.5, 0.0]);
        assert_eq!(rgbe_to_float([255, 1, 7, 0]), [0.0; 3]);
        assert_eq!(rgbe_to_float([200, 0, 0, 136]), [200.0, 0.0, 0.0]);
        assert_eq!(rgbe_to_float([1, 0, 0, 1]), [2f64.powi(-135), 0.0, 0.0]);
    }

    #[test]
    fn float_to_rgbe_round_trips_representable_values() {
        for v in [1.0, 0.5, 3.0, 1000.0, 0.0078125] {
            let [r, _, _] = rgbe_to_float(float_to_rgbe([v, v, v]));
            assert_eq!(r, v);
        }
        assert_eq!(float_to_rgbe([0.0; 3]), [0; 4]);
    }

    #[test]
    fn flat_file_orientations() {
        // 2×3 image, values 1..6 in reading order; -Y +X stores them in that order.
        let values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let flat = write_flat(3, 2, &values);
        let pic = read(&flat, &Limits::default()).unwrap();
        assert_eq!((pic.width, pic.height), (3, 2));
        let lum = pic.luminance();
        assert!((lum[[1, 2]] - 6.0).abs() < 1e-12);
        // +Y: the first scanline stored is the bottom row.
        let mut bytes = header("+Y 2 +X 3");
        for v in values {
            bytes.extend_from_slice(&float_to_rgbe([v, v, v]));
        }
        let lum = read(&bytes, &Limits::default()).unwrap().luminance();
        assert!((lum[[0, 0]] - 4.0).abs() < 1e-12 && (lum[[1, 0]] - 1.0).abs() < 1e-12);
        // +X 3 -Y 2: scanlines are columns, left first, each top to bottom.
        let mut bytes = header("+X 3 -Y 2");
        for v in values {
            bytes.extend_from_slice(&float_to_rgbe([v, v, v]));
        }
        let lum = read(&bytes, &Limits::default()).unwrap().luminance();
        assert_eq!(lum.dim(), (2, 3));
        assert!((lum[[1, 0]] - 2.0).abs() < 1e-12 && (lum[[0, 1]] - 3.0).abs() < 1e-12);
    }

    #[test]
    fn new_style_rle_scanline() {
        let mut bytes = header("-Y 1 +X 8");
        bytes.extend_from_slice(&[2, 2, 0, 8]);
        // R: run of 8 × 128; G: literal 8 values; B: two runs of 4; E: run of 8 × 129.
        bytes.extend_from_slice(&[136, 128]);
        bytes.extend_from_slice(&[8, 0, 16, 32, 48, 64, 80, 96, 112]);
        bytes.extend_from_slice(&[132, 0, 132, 255]);
        bytes.extend_from_slice(&[136, 129]);
        let pic = read(&bytes, &Limits::default()).unwrap();
        assert_eq!(pic.pixels[3], [1.0, 48.0 / 128.0, 0.0]);
        assert_eq!(pic.pixels[7], [1.0, 112.0 / 128.0, 255.0 / 128.0]);
    }

    #[test]
    fn old_style_repeat() {
        let mut bytes = header("-Y 1 +X 5");
        bytes.extend_from_slice(&[128, 128, 128, 129, 1, 1, 1, 4]);
        let pic = read(&bytes, &Limits::default()).unwrap();
        assert!(pic.pixels.iter().all(|p| *p == [1.0, 1.0, 1.0]));
    }

    #[test]
    fn xyze_gives_y_directly() {
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n".to_vec();
        bytes.extend_from_slice(&[10, 128, 30, 129]);
        let lum = read(&bytes, &Limits::default()).unwrap().luminance();
        assert_eq!(lum[[0, 0]], 1.0);
    }

    #[test]
    fn corrupt_inputs_are_errors() {
        let limits = Limits::default();
        let mut truncated = header("-Y 4 +X 4");
        truncated.extend_from_slice(&[1, 2, 3]);
        assert!(matches!(
            read(&truncated, &limits),
            Err(DecodeError::Corrupt { .. })
        ));
        let huge = header("-Y 100000 +X 100000");
        assert!(matches!(
            read(&huge, &limits),
            Err(DecodeError::TooLarge { .. })
        ));
        let zero = header("-Y 0 +X 5");
        assert!(matches!(
            read(&zero, &limits),
            Err(DecodeError::Empty { .. })
        ));
        let garbage = header("Y 5 X 5");
        assert!(matches!(
            read(&garbage, &limits),
            Err(DecodeError::Corrupt { .. })
        ));
        let mut overflow = header("-Y 1 +X 8");
        overflow.extend_from_slice(&[2, 2, 0, 8, 200, 1]);
        assert!(matches!(
            read(&overflow, &limits),
            Err(DecodeError::Corrupt { .. })
        ));
        let other = b"#?RADIANCE\nFORMAT=32-bit_rle_foo\n\n-Y 1 +X 1\n\0\0\0\0".to_vec();
        assert!(matches!(
            read(&other, &limits),
            Err(DecodeError::Unsupported { .. })
        ));
    }
}
