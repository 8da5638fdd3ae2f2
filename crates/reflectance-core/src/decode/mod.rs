//! Decoding: bytes → linear luminance plane (+ optional alpha mask), docs/design.md §3 "Pixels".
//!
//! Integer formats (PNG, JPEG, WebP, TIFF, PNM) go through the `image` crate; Radiance `.hdr`,
//! PFM and OpenEXR are read here (RGBE and PFM by our own small parsers, EXR through the
//! `exr` crate), because `image` has no PFM, no XYZE and no luminance-only EXR.
//! Every path checks the header's dimensions against [`Limits`] before allocating pixels.

mod color;
pub(crate) mod exr_file;
mod integer;
mod jpeg;
pub mod pfm;
pub mod rgbe;
pub mod scaled;

use crate::image::colour::ColourCopy;
use ndarray::Array2;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

pub use color::{Encoding, srgb_to_linear};
pub use scaled::{Photo, Samples, SamplesPlane, Scaled, denominator_for};

/// Rec. 709 luminance weights for linear R, G, B.
pub const LUMA_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Linear Rec. 709 luminance of one linear RGB triple (same operation order everywhere).
#[inline]
pub fn luminance(r: f64, g: f64, b: f64) -> f64 {
    LUMA_WEIGHTS[0] * r + LUMA_WEIGHTS[1] * g + LUMA_WEIGHTS[2] * b
}

/// Hard limits against decompression bombs; checked on the header, before pixels are allocated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Limits {
    /// The widest image accepted (px).
    pub max_width: u32,
    /// The tallest image accepted (px).
    pub max_height: u32,
    /// The most pixels (width × height) accepted.
    pub max_pixels: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_width: 20_000,
            max_height: 20_000,
            // A 48 MP phone photograph (8000 × 6000) and a 50 MP one (8160 × 6120).
            max_pixels: 50_000_000,
        }
    }
}

impl Limits {
    /// Ok when `width × height` is non-empty and within every limit.
    pub fn check(&self, width: u64, height: u64) -> Result<(), DecodeError> {
        if width == 0 || height == 0 {
            return Err(DecodeError::Empty { width, height });
        }
        let pixels = width.saturating_mul(height);
        if width > u64::from(self.max_width)
            || height > u64::from(self.max_height)
            || pixels > self.max_pixels
        {
            return Err(DecodeError::TooLarge {
                width,
                height,
                limits: *self,
            });
        }
        Ok(())
    }
}

/// What a file held, as far as the features care.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// PNG, 8 or 16 bits.
    Png,
    /// JPEG (baseline or progressive).
    Jpeg,
    /// TIFF, integer samples.
    Tiff,
    /// WebP, lossy or lossless (8 bits).
    WebP,
    /// Netpbm (PGM, PPM).
    Pnm,
    /// Radiance RGBE (`.hdr`), linear floats.
    Hdr,
    /// Portable float map, linear floats.
    Pfm,
    /// OpenEXR, linear floats.
    Exr,
    /// Linear luminance handed over as an array, not a file ([`from_luminance`]).
    Array,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            Format::Png => "PNG",
            Format::Jpeg => "JPEG",
            Format::Tiff => "TIFF",
            Format::WebP => "WebP",
            Format::Pnm => "PNM",
            Format::Hdr => "Radiance HDR",
            Format::Pfm => "PFM",
            Format::Exr => "OpenEXR",
            Format::Array => "array",
        };
        f.write_str(name)
    }
}

/// A decoded image: linear luminance (row-major, y = row) and the alpha channel as a mask.
#[derive(Clone, Debug)]
pub struct LinearImage {
    /// Linear luminance (Rec. 709 weights), in the file's units: integer formats in [0, 1]
    /// after linearization, float formats as stored.
    pub luminance: Array2<f64>,
    /// `true` where alpha ≥ 0.5; `None` when the file has no alpha or it is fully opaque.
    pub alpha_mask: Option<Array2<bool>>,
    /// The file's format.
    pub format: Format,
    /// The reduced linear-RGB copy, when asked for (`DecodeOptions::colour`) and the file
    /// has colour.
    pub colour: Option<ColourCopy>,
    /// Whether the samples were floating point (and so already linear).
    pub is_float: bool,
    /// What the decode could not honour but went on (an encoding given for a float
    /// format is ignored), for the answer's warnings.
    pub warnings: Vec<String>,
}

impl LinearImage {
    /// Width (px).
    pub fn width(&self) -> usize {
        self.luminance.ncols()
    }
    /// Height (px).
    pub fn height(&self) -> usize {
        self.luminance.nrows()
    }
}

/// Why bytes are not an image the pipeline reads.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// The file could not be read.
    #[error("could not read the file: {0}")]
    Io(#[source] std::io::Error),
    /// The bytes are none of the formats read, nor one recognized.
    #[error(
        "unsupported image format: the bytes are not an image format known here (expected {READ_FORMATS})"
    )]
    UnsupportedFormat,
    /// The bytes are a format recognized but not read ([`recognize`]).
    #[error(
        "unsupported image format: this is {name}, not read here (expected {READ_FORMATS}){advice}"
    )]
    NotRead {
        /// The format found, in words ("a GIF image").
        name: &'static str,
        /// What to do instead, beginning with "; " (or empty).
        advice: &'static str,
    },
    /// A known format with content this decoder does not read (e.g. a colour type).
    #[error("unsupported {format} content: {detail}")]
    Unsupported {
        /// The format.
        format: Format,
        /// What is not read.
        detail: String,
    },
    /// The file ends early or is damaged.
    #[error("corrupt or truncated {format} file: {detail}")]
    Corrupt {
        /// The format.
        format: Format,
        /// The decoder's words.
        detail: String,
    },
    /// The header gives no pixels.
    #[error("image has zero size ({width}×{height})")]
    Empty {
        /// Width (px).
        width: u64,
        /// Height (px).
        height: u64,
    },
    #[error(
        "image is {width}×{height} pixels, over the limits (max {}×{}, {} pixels)",
        limits.max_width, limits.max_height, limits.max_pixels
    )]
    /// The header gives more pixels than the limits allow (checked before allocation).
    TooLarge {
        /// Width (px).
        width: u64,
        /// Height (px).
        height: u64,
        /// The limits passed.
        limits: Limits,
    },
    /// A decoder's own allocation limit was reached.
    #[error("image exceeds the decoding limits: {0}")]
    LimitExceeded(String),
    /// Float samples that are NaN or infinite.
    #[error("image has {count} non-finite sample values (NaN or infinity)")]
    NonFinite {
        /// How many samples.
        count: usize,
    },
    /// Float pixels of negative luminance.
    #[error(
        "image has {count} pixels of negative luminance (minimum {min}); HDR input must be non-negative"
    )]
    Negative {
        /// How many pixels.
        count: usize,
        /// The lowest luminance.
        min: f64,
    },
    /// An encoding name that is none of srgb, linear and gamma:<g>.
    #[error("invalid encoding {0:?} (expected srgb, linear or gamma:<g> with g > 0)")]
    BadEncoding(String),
}

impl DecodeError {
    pub(crate) fn corrupt(format: Format, detail: impl fmt::Display) -> Self {
        DecodeError::Corrupt {
            format,
            detail: detail.to_string(),
        }
    }
}

/// Options of one decode.
#[derive(Clone, Copy, Debug, Default)]
pub struct DecodeOptions {
    /// How integer samples are linearized; ignored (with a warning) for float formats.
    /// `None` means the default, sRGB, without a warning.
    pub encoding: Option<Encoding>,
    /// The size limits, checked on the header.
    pub limits: Limits,
    /// Keep a reduced linear-RGB copy beside the luminance (for a colour measurement).
    pub colour: bool,
}

impl FromStr for Encoding {
    type Err = DecodeError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Encoding::parse(s).ok_or_else(|| DecodeError::BadEncoding(s.to_string()))
    }
}

/// The formats read, in words.
pub const READ_FORMATS: &str = "PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM or OpenEXR";

/// How to turn an iPhone's photograph into one of the formats read.
const HEIC_ADVICE: &str = "; HEIC/HEIF (an iPhone's default) is not read: share it as JPEG \
     (iPhone: Settings › Camera › Formats › Most Compatible, or share it by mail or to a \
     computer, which converts it), or convert it: `heif-convert photo.heic photo.jpg` \
     (libheif), `sips -s format jpeg photo.heic --out photo.jpg` (macOS), or \
     `magick photo.heic photo.jpg`";

/// What to do with base64 text sent where a file's bytes belong.
const BASE64_ADVICE: &str = "; a file field takes the file's own bytes (curl -F \
     image=@photo.jpg): base64 belongs in a JSON body";

/// A format that is not read, recognized by its first bytes: its name and what to do (an
/// advice beginning with "; ", or empty).
pub fn recognize(bytes: &[u8]) -> Option<(&'static str, &'static str)> {
    const CONVERT: &str = "; convert it to PNG or JPEG";
    // ISO base media files (HEIF, AVIF): a box `ftyp` whose major brand says which.
    if let Some(brand) = bytes.get(4..12).filter(|b| b.starts_with(b"ftyp")) {
        return match &brand[4..] {
            b"avif" | b"avis" => Some(("an AVIF image", CONVERT)),
            b"heic" | b"heix" | b"hevc" | b"hevx" | b"heim" | b"heis" | b"hevm" | b"hevs"
            | b"mif1" | b"msf1" => Some(("a HEIC/HEIF image", HEIC_ADVICE)),
            _ => Some((
                "an ISO media file (MP4, MOV or similar), not a still image",
                "",
            )),
        };
    }
    let known: [(&[u8], &str, &str); 17] = [
        (b"GIF8", "a GIF image", CONVERT),
        (b"BM", "a BMP image", CONVERT),
        (&[0xff, 0x0a], "a JPEG XL image", CONVERT),
        (b"\0\0\0\x0cJXL ", "a JPEG XL image", CONVERT),
        (&[0, 0, 1, 0], "an ICO icon", CONVERT),
        (b"qoif", "a QOI image", CONVERT),
        (b"8BPS", "a Photoshop document", CONVERT),
        (b"%PDF", "a PDF document", ""),
        (b"<svg", "an SVG drawing", "; render it to PNG"),
        (b"RIFF", "a RIFF file that is not WebP", ""),
        (b"data:", "a data: URL (text)", BASE64_ADVICE),
        // The base64 of the formats read: PNG, JPEG, WebP (RIFF), TIFF.
        (b"iVBORw0KGgo", "base64 text of a PNG image", BASE64_ADVICE),
        (b"/9j/", "base64 text of a JPEG image", BASE64_ADVICE),
        (b"UklGR", "base64 text of a RIFF (WebP) file", BASE64_ADVICE),
        (b"SUkq", "base64 text of a TIFF image", BASE64_ADVICE),
        (b"<", "text (HTML or XML), not an image", ""),
        (b"{", "text (JSON), not an image", ""),
    ];
    known
        .iter()
        .find(|(magic, ..)| bytes.starts_with(magic))
        .map(|&(_, name, advice)| (name, advice))
}

/// [`DecodeError::NotRead`] for a format [`recognize`] names, else
/// [`DecodeError::UnsupportedFormat`].
pub(crate) fn unsupported(bytes: &[u8]) -> DecodeError {
    match recognize(bytes) {
        Some((name, advice)) => DecodeError::NotRead { name, advice },
        None => DecodeError::UnsupportedFormat,
    }
}

enum Container {
    Hdr,
    Pfm,
    Exr,
    Other,
}

fn sniff(bytes: &[u8]) -> Container {
    if bytes.starts_with(b"#?RADIANCE") || bytes.starts_with(b"#?RGBE") {
        Container::Hdr
    } else if bytes.starts_with(b"PF") || bytes.starts_with(b"Pf") {
        Container::Pfm
    } else if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        Container::Exr
    } else {
        Container::Other
    }
}

/// Decode an in-memory image file into linear luminance.
pub fn decode(bytes: &[u8], options: &DecodeOptions) -> Result<LinearImage, DecodeError> {
    let mut image = match sniff(bytes) {
        Container::Hdr => float_image(rgbe::decode(bytes, options)?, Format::Hdr),
        Container::Pfm => float_image(pfm::decode(bytes, options)?, Format::Pfm),
        Container::Exr => float_image(exr_file::decode(bytes, options)?, Format::Exr),
        Container::Other => integer::decode(bytes, options)?,
    };
    let ignored = options
        .encoding
        .filter(|e| image.is_float && *e != Encoding::Linear);
    if let Some(encoding) = ignored {
        image.warnings.push(format!(
            "encoding {encoding} ignored: {} samples are floating point and already linear",
            image.format
        ));
    }
    Ok(image)
}

/// Read and decode an image file.
pub fn decode_file(path: &Path, options: &DecodeOptions) -> Result<LinearImage, DecodeError> {
    let bytes = std::fs::read(path).map_err(DecodeError::Io)?;
    decode(&bytes, options)
}

/// Linear luminance handed over as an array (y = row) rather than a file: checked as a
/// floating-point file is (within the limits, finite, non-negative), and laid out row-major
/// as decoded images are.
pub fn from_luminance(luminance: Array2<f64>, limits: &Limits) -> Result<LinearImage, DecodeError> {
    let (height, width) = luminance.dim();
    limits.check(width as u64, height as u64)?;
    let luminance = match luminance.is_standard_layout() {
        true => luminance,
        false => luminance.as_standard_layout().into_owned(),
    };
    let nonfinite = luminance.iter().filter(|v| !v.is_finite()).count();
    validate_float(&luminance, nonfinite)?;
    Ok(float_image(
        FloatPlane {
            luminance,
            alpha: None,
            colour: None,
        },
        Format::Array,
    ))
}

/// A float image's luminance plane after validation: finite and non-negative.
pub(crate) struct FloatPlane {
    pub luminance: Array2<f64>,
    pub alpha: Option<Array2<f64>>,
    pub colour: Option<ColourCopy>,
}

fn float_image(plane: FloatPlane, format: Format) -> LinearImage {
    LinearImage {
        alpha_mask: plane.alpha.as_ref().and_then(alpha_to_mask),
        luminance: plane.luminance,
        colour: plane.colour,
        format,
        is_float: true,
        warnings: Vec::new(),
    }
}

/// Reject NaN/±Inf samples and negative luminance; shared by every float decoder.
pub(crate) fn validate_float(
    luminance: &Array2<f64>,
    nonfinite_samples: usize,
) -> Result<(), DecodeError> {
    if nonfinite_samples > 0 {
        return Err(DecodeError::NonFinite {
            count: nonfinite_samples,
        });
    }
    let (count, min) = luminance
        .iter()
        .filter(|v| **v < 0.0)
        .fold((0usize, 0.0f64), |(n, m), &v| (n + 1, m.min(v)));
    if count > 0 {
        return Err(DecodeError::Negative { count, min });
    }
    Ok(())
}

/// Alpha ≥ 0.5 is inside; a fully opaque alpha carries no mask.
pub(crate) fn alpha_to_mask(alpha: &Array2<f64>) -> Option<Array2<bool>> {
    if alpha.iter().all(|&a| a >= 0.5) {
        return None;
    }
    Some(alpha.mapv(|a| a >= 0.5))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_reject_zero_and_huge_sizes() {
        let limits = Limits::default();
        assert!(matches!(
            limits.check(0, 10),
            Err(DecodeError::Empty { .. })
        ));
        assert!(matches!(
            limits.check(100_000, 100_000),
            Err(DecodeError::TooLarge { .. })
        ));
        assert!(matches!(
            limits.check(10_000, 10_000),
            Err(DecodeError::TooLarge { .. })
        ));
        assert!(limits.check(6_000, 4_000).is_ok());
    }

    #[test]
    fn unknown_bytes_are_unsupported() {
        let err = decode(b"hello world, not an image", &DecodeOptions::default()).unwrap_err();
        assert!(matches!(err, DecodeError::UnsupportedFormat), "{err}");
    }

    #[test]
    fn formats_not_read_are_named_with_what_to_do() {
        let options = DecodeOptions::default();
        let heic = b"\0\0\0\x18ftypheic\0\0\0\0mif1heic";
        let cases: [(&[u8], &str, &str); 5] = [
            (b"GIF89a\x01\0\x01\0", "a GIF image", "PNG, JPEG, WebP"),
            (b"BM\x3a\0\0\0\0\0", "a BMP image", "convert it"),
            (heic, "HEIC/HEIF", "heif-convert"),
            (b"\0\0\0\x1cftypavif", "an AVIF image", "convert it"),
            (
                b"iVBORw0KGgoAAAANSUhEUg",
                "base64 text of a PNG",
                "JSON body",
            ),
        ];
        for (bytes, name, advice) in cases {
            let err = decode(bytes, &options).unwrap_err();
            assert!(matches!(err, DecodeError::NotRead { .. }), "{err}");
            let text = err.to_string();
            assert!(text.contains(name) && text.contains(advice), "{text}");
            assert!(text.contains(READ_FORMATS), "{text}");
        }
    }

    #[test]
    fn arrays_are_checked_as_float_files_and_laid_out_row_major() {
        let limits = Limits::default();
        let ramp = Array2::from_shape_fn((3, 4), |(y, x)| (y * 4 + x) as f64);
        let columns_first = ramp.t().as_standard_layout().into_owned().reversed_axes();
        assert!(!columns_first.is_standard_layout());
        let image = from_luminance(columns_first, &limits).unwrap();
        assert!(image.luminance.is_standard_layout());
        assert_eq!(image.luminance, ramp);
        assert_eq!((image.format, image.is_float), (Format::Array, true));
        let mut bad = ramp.clone();
        bad[[1, 2]] = f64::NAN;
        assert!(matches!(
            from_luminance(bad, &limits),
            Err(DecodeError::NonFinite { count: 1 })
        ));
        assert!(matches!(
            from_luminance(-ramp, &limits),
            Err(DecodeError::Negative { count: 11, .. })
        ));
        assert!(matches!(
            from_luminance(Array2::zeros((0, 5)), &limits),
            Err(DecodeError::Empty { .. })
        ));
    }

    #[test]
    fn luminance_weights_sum_to_one() {
        assert!((luminance(1.0, 1.0, 1.0) - 1.0).abs() < 1e-15);
    }
}
