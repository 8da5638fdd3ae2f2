//! A photograph decoded at the scale each step needs ([`Photo`]): a JPEG is read by
//! libjpeg-turbo ([`super::jpeg`]) at 1/2, 1/4 or 1/8 of its size (what location searches)
//! or as the region around the ball at the scale the features need, so that a phone
//! photograph costs about what decoding it once costs; all of it at full size is the full
//! path's decode ([`super::decode`]), as is every other file and any JPEG libjpeg-turbo does
//! not read as the full path would (decoded whole once: every step reads that image).
//!
//! A [`Scaled`] copy says where its pixels lie on the full image: pixel (i, j) of a copy at
//! 1/d covers full pixels [i·d, (i + 1)·d) along each axis, shifted by the copy's origin
//! (a region's corner, or for an axis the EXIF orientation reversed, whose last decoded
//! pixel was the partial one, full − decoded × d).

use super::jpeg::{self, Header, Window};
use super::{DecodeError, DecodeOptions, Format, LinearImage, integer};
use crate::image::circle::Circle;
use image::metadata::Orientation;
use image::{DynamicImage, ImageBuffer, ImageDecoder};
use std::borrow::Cow;
use std::io::Cursor;

/// A copy of a photograph (whole or a region) at 1/`denominator` of its size.
#[derive(Clone, Debug)]
pub struct Scaled<'a> {
    /// The copy's pixels (the photograph itself when `denominator` is 1 and nothing was cut).
    pub image: Cow<'a, LinearImage>,
    /// Full-image pixels per copy pixel along each axis: 1, 2, 4 or 8.
    pub denominator: usize,
    /// Where the copy's pixel grid starts on the full image, per axis (x, y).
    offset: [f64; 2],
}

impl Scaled<'_> {
    /// The full image's coordinates (pixel centres are integers) of a point of the copy.
    pub fn to_full(&self, x: f64, y: f64) -> (f64, f64) {
        let d = self.denominator as f64;
        (
            (x + 0.5) * d - 0.5 + self.offset[0],
            (y + 0.5) * d - 0.5 + self.offset[1],
        )
    }

    /// The copy's coordinates of a point of the full image.
    pub fn from_full(&self, x: f64, y: f64) -> (f64, f64) {
        let d = self.denominator as f64;
        (
            (x - self.offset[0] + 0.5) / d - 0.5,
            (y - self.offset[1] + 0.5) / d - 0.5,
        )
    }

    /// A circle of the full image on the copy.
    pub fn circle_from_full(&self, c: &Circle) -> Circle {
        let (cx, cy) = self.from_full(c.cx, c.cy);
        let r = c.r / self.denominator as f64;
        Circle { cx, cy, r }
    }

    /// A circle of the copy on the full image.
    pub fn circle_to_full(&self, c: &Circle) -> Circle {
        let (cx, cy) = self.to_full(c.cx, c.cy);
        let r = c.r * self.denominator as f64;
        Circle { cx, cy, r }
    }
}

/// A photograph, decoded when and at the scale a step asks ([`Photo::whole`],
/// [`Photo::region`]).
pub struct Photo<'a> {
    bytes: &'a [u8],
    options: DecodeOptions,
    source: Source,
}

enum Source {
    /// A JPEG libjpeg-turbo reads, decoded piece by piece.
    Jpeg {
        header: Header,
        orientation: Orientation,
    },
    /// Anything else, decoded whole once.
    Decoded(LinearImage),
}

/// Which stored axis an oriented axis runs along, and whether reversed.
#[derive(Clone, Copy)]
struct Axis {
    stored_x: bool,
    reversed: bool,
}

/// The oriented x and y axes of an EXIF orientation, in stored terms.
fn axes(orientation: Orientation) -> [Axis; 2] {
    let axis = |stored_x, reversed| Axis { stored_x, reversed };
    // (reverse x, reverse y, transposed) as `image` applies each orientation.
    let (rx, ry, transposed) = match orientation {
        Orientation::NoTransforms => (false, false, false),
        Orientation::FlipHorizontal => (true, false, false),
        Orientation::FlipVertical => (false, true, false),
        Orientation::Rotate180 => (true, true, false),
        Orientation::Rotate90 => (true, false, true),
        Orientation::Rotate270 => (false, true, true),
        Orientation::Rotate90FlipH => (false, false, true),
        Orientation::Rotate270FlipH => (true, true, true),
    };
    match transposed {
        false => [axis(true, rx), axis(false, ry)],
        true => [axis(false, rx), axis(true, ry)],
    }
}

impl<'a> Photo<'a> {
    /// The photograph of `bytes`: a JPEG that libjpeg-turbo reads (within the limits) is only
    /// looked at; anything else is decoded now, with the full path's errors.
    pub fn open(bytes: &'a [u8], options: &DecodeOptions) -> Result<Photo<'a>, DecodeError> {
        let source = match jpeg_source(bytes, options) {
            Some(source) => source,
            None => Source::Decoded(super::decode(bytes, options)?),
        };
        Ok(Photo {
            bytes,
            options: *options,
            source,
        })
    }

    /// A photograph decoded already (an array, a file read before).
    pub fn decoded(image: LinearImage) -> Photo<'static> {
        Photo {
            bytes: &[],
            options: DecodeOptions::default(),
            source: Source::Decoded(image),
        }
    }

    /// Width and height after the EXIF orientation.
    pub fn size(&self) -> (usize, usize) {
        match &self.source {
            Source::Jpeg {
                header,
                orientation,
            } => match axes(*orientation)[0].stored_x {
                true => (header.width, header.height),
                false => (header.height, header.width),
            },
            Source::Decoded(image) => (image.width(), image.height()),
        }
    }

    /// The photograph decoded whole, when it was (a JPEG is decoded in pieces).
    pub fn decoded_whole(&self) -> Option<&LinearImage> {
        match &self.source {
            Source::Decoded(image) => Some(image),
            Source::Jpeg { .. } => None,
        }
    }

    /// What the decode could not honour but went on (an encoding given for a float format).
    pub fn warnings(&self) -> &[String] {
        match &self.source {
            Source::Decoded(image) => &image.warnings,
            Source::Jpeg { .. } => &[],
        }
    }

    /// The whole photograph at full size as its decoded samples, for a JPEG decoded as
    /// 8-bit grey or RGB (None for a photograph decoded already, or other samples).
    pub fn whole_samples(&self) -> Result<Option<Samples>, DecodeError> {
        if let Source::Decoded(_) = self.source {
            return Ok(None);
        }
        let (image, format) = integer::decode_samples(self.bytes, &self.options)?;
        let channels = match &image {
            DynamicImage::ImageLuma8(_) => 1,
            DynamicImage::ImageRgb8(_) => 3,
            _ => return Ok(None),
        };
        let table = self.options.encoding.unwrap_or_default().table(8).to_vec();
        Ok(Some(Samples {
            image,
            channels,
            format,
            options: self.options,
            table,
        }))
    }

    /// The whole photograph at 1/`denominator` (1, 2, 4 or 8; clamped down to one of them). A
    /// photograph decoded whole answers itself, at 1/1.
    pub fn whole(&self, denominator: usize) -> Result<Scaled<'_>, DecodeError> {
        let (width, height) = self.size();
        self.region([0, 0, width, height], denominator)
    }

    /// The part `[x0, y0, x1)`×`[y0, y1)` of the full image (after orientation; clipped to
    /// it) at 1/`denominator`, a little larger where the decoder's blocks begin. A photograph
    /// decoded whole answers all of itself, at 1/1 (the steps read only what they need).
    pub fn region(
        &self,
        [x0, y0, x1, y1]: [usize; 4],
        denominator: usize,
    ) -> Result<Scaled<'_>, DecodeError> {
        let whole = |image| Scaled {
            image,
            denominator: 1,
            offset: [0.0; 2],
        };
        let (header, orientation) = match &self.source {
            Source::Decoded(image) => return Ok(whole(Cow::Borrowed(image))),
            Source::Jpeg {
                header,
                orientation,
            } => (header, *orientation),
        };
        let d = supported(denominator);
        let (width, height) = self.size();
        let everything = x0 == 0 && y0 == 0 && x1 >= width && y1 >= height;
        let window = [x0, y0, x1, y1];
        let decoded = match d == 1 && everything {
            // All of it at full size: the full path's decoder, as every decode of a whole
            // image ([`super::decode`]).
            true => None,
            false => decode_window(self.bytes, &self.options, header, orientation, window, d),
        };
        match decoded {
            Some(scaled) => Ok(scaled),
            // What libjpeg-turbo does not read cleanly, the image crate's decoder answers (or
            // refuses), as it does every other file.
            None => Ok(whole(Cow::Owned(integer::decode(
                self.bytes,
                &self.options,
            )?))),
        }
    }
}

/// A JPEG decoded whole at full size and kept as its 8-bit samples (oriented): location
/// reads their luminance where it looks ([`SamplesPlane`]) and the features a region made
/// linear ([`Samples::region`]), so that no 64-bit plane of the whole photograph is made.
/// Both read the values the whole decode's plane would hold.
pub struct Samples {
    /// 8-bit grey or RGB.
    image: DynamicImage,
    channels: usize,
    format: Format,
    options: DecodeOptions,
    table: Vec<f64>,
}

impl Samples {
    /// The luminance of the samples, as location reads it.
    pub fn plane(&self) -> SamplesPlane<'_> {
        SamplesPlane {
            samples: self.image.as_bytes(),
            channels: self.channels,
            width: self.image.width() as usize,
            height: self.image.height() as usize,
            table: &self.table,
        }
    }

    /// The part `[x0, y0, x1)`×`[y0, y1)` (clipped to the image, at least a pixel) made
    /// linear, as the whole decode makes every pixel.
    pub fn region(&self, [x0, y0, x1, y1]: [usize; 4]) -> Result<Scaled<'static>, DecodeError> {
        let (width, height) = (self.image.width() as usize, self.image.height() as usize);
        let span = |lo: usize, hi: usize, n: usize| {
            let lo = lo.min(n.saturating_sub(1));
            (lo, hi.clamp(lo + 1, n.max(lo + 1)))
        };
        let ((x0, x1), (y0, y1)) = (span(x0, x1, width), span(y0, y1, height));
        let crop = self
            .image
            .crop_imm(x0 as u32, y0 as u32, (x1 - x0) as u32, (y1 - y0) as u32);
        let image = integer::to_linear(crop, self.format, &self.options)?;
        Ok(Scaled {
            image: Cow::Owned(image),
            denominator: 1,
            offset: [x0 as f64, y0 as f64],
        })
    }
}

/// [`Samples`]' luminance: each pixel's samples through the file's transfer table and the
/// luminance weights when read ([`crate::image::plane::Plane`]).
#[derive(Clone, Copy)]
pub struct SamplesPlane<'a> {
    samples: &'a [u8],
    channels: usize,
    width: usize,
    height: usize,
    table: &'a [f64],
}

impl SamplesPlane<'_> {
    #[inline]
    fn at(&self, i: usize) -> f64 {
        let t = |k: usize| self.table[usize::from(self.samples[k])];
        match self.channels {
            1 => t(i),
            _ => super::luminance(t(i), t(i + 1), t(i + 2)),
        }
    }
}

impl crate::image::plane::Plane for SamplesPlane<'_> {
    fn size(self) -> (usize, usize) {
        (self.height, self.width)
    }

    #[inline]
    fn value(self, y: usize, x: usize) -> f64 {
        self.at((y * self.width + x) * self.channels)
    }

    fn fill_line(self, y: usize, x0: usize, line: &mut [f64]) {
        let first = (y * self.width + x0) * self.channels;
        let samples = &self.samples[first..first + line.len() * self.channels];
        let t = |s: u8| self.table[usize::from(s)];
        match self.channels {
            1 => line.iter_mut().zip(samples).for_each(|(v, &s)| *v = t(s)),
            _ => (line.iter_mut().zip(samples.chunks_exact(3)))
                .for_each(|(v, p)| *v = super::luminance(t(p[0]), t(p[1]), t(p[2]))),
        }
    }
}

/// The window of the oriented rectangle at 1/`d`, decoded and oriented, or None.
fn decode_window(
    bytes: &[u8],
    options: &DecodeOptions,
    header: &Header,
    orientation: Orientation,
    oriented: [usize; 4],
    d: usize,
) -> Option<Scaled<'static>> {
    let axes = axes(orientation);
    let (width, height) = (header.width, header.height);
    // The rectangle in stored pixels, then at 1/d, rounded outwards.
    let mut stored = [0usize; 4];
    for (k, axis) in axes.iter().enumerate() {
        let extent = if axis.stored_x { width } else { height };
        let (lo, hi) = (oriented[k].min(extent), oriented[k + 2].min(extent));
        let (lo, hi) = match axis.reversed {
            true => (extent - hi, extent - lo),
            false => (lo, hi),
        };
        let at = if axis.stored_x { 0 } else { 1 };
        stored[at] = lo / d;
        stored[at + 2] = hi.div_ceil(d);
    }
    let want = Window {
        x: stored[0],
        y: stored[1],
        w: stored[2].checked_sub(stored[0])?,
        h: stored[3].checked_sub(stored[1])?,
    };
    let window = header.window(want, d)?;
    let (scaled_w, scaled_h) = header.scaled(d);
    let crop = (window
        != Window {
            x: 0,
            y: 0,
            w: scaled_w,
            h: scaled_h,
        })
    .then_some(window);
    let pixels = jpeg::decode(bytes, d, crop)?;
    let stored_image = match pixels.channels {
        1 => DynamicImage::ImageLuma8(ImageBuffer::from_raw(
            u32::try_from(window.w).ok()?,
            u32::try_from(window.h).ok()?,
            pixels.samples,
        )?),
        _ => DynamicImage::ImageRgb8(ImageBuffer::from_raw(
            u32::try_from(window.w).ok()?,
            u32::try_from(window.h).ok()?,
            pixels.samples,
        )?),
    };
    let mut oriented_image = stored_image;
    oriented_image.apply_orientation(orientation);
    let image = integer::to_linear(oriented_image, Format::Jpeg, options).ok()?;
    // Where the oriented copy's first pixel lies, per oriented axis.
    let offset = axes.map(|axis| {
        let (start, length, extent) = match axis.stored_x {
            true => (window.x, window.w, width),
            false => (window.y, window.h, height),
        };
        match axis.reversed {
            true => extent as f64 - ((start + length) * d) as f64,
            false => (start * d) as f64,
        }
    });
    Some(Scaled {
        image: Cow::Owned(image),
        denominator: d,
        offset,
    })
}

/// 1, 2, 4 or 8: the largest of them not above `denominator`.
fn supported(denominator: usize) -> usize {
    match denominator {
        0..=1 => 1,
        2..=3 => 2,
        4..=7 => 4,
        _ => 8,
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

/// A JPEG libjpeg-turbo reads as the full path would, within the limits, with its EXIF
/// orientation; None for whatever the full path should decode (or refuse).
fn jpeg_source(bytes: &[u8], options: &DecodeOptions) -> Option<Source> {
    if !bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        return None;
    }
    let header = jpeg::header(bytes)?;
    options
        .limits
        .check(header.width as u64, header.height as u64)
        .ok()?;
    let mut decoder = image::codecs::jpeg::JpegDecoder::new(Cursor::new(bytes)).ok()?;
    let orientation = decoder.orientation().unwrap_or(Orientation::NoTransforms);
    Some(Source::Jpeg {
        header,
        orientation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::decode;
    use crate::decode::jpeg::tests::encoded;

    /// A JPEG (grey or RGB) with a bright square around (`x`, `y`), half-side `half`, on a
    /// mid-grey ramp.
    fn spot(width: u32, height: u32, (x0, y0, half): (f64, f64, f64), colour: bool) -> Vec<u8> {
        encoded(width, height, colour, |x, y| {
            let inside = (f64::from(x) - x0).abs() <= half && (f64::from(y) - y0).abs() <= half;
            if inside { 250 } else { 40 + (x % 7) as u8 }
        })
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

    /// The centroid of the pixels above half the brightest, in the full image's coordinates.
    fn bright_centroid(scaled: &Scaled) -> (f64, f64) {
        let image = &scaled.image;
        let peak = image.luminance.iter().copied().fold(0.0, f64::max);
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for ((y, x), &v) in image.luminance.indexed_iter() {
            if v > 0.5 * peak {
                sx += v * x as f64;
                sy += v * y as f64;
                n += v;
            }
        }
        scaled.to_full(sx / n, sy / n)
    }

    #[test]
    fn the_samples_read_what_the_whole_decode_holds_in_every_orientation() {
        use crate::image::plane::Plane;
        for colour in [false, true] {
            let plain = spot(75, 41, (50.0, 20.0, 6.5), colour);
            for orientation in [1, 6, 8] {
                let bytes = with_orientation(&plain, orientation);
                let options = DecodeOptions::default();
                let full = decode(&bytes, &options).unwrap();
                let photo = Photo::open(&bytes, &options).unwrap();
                let samples = photo.whole_samples().unwrap().unwrap();
                let plane = samples.plane();
                assert_eq!(plane.size(), full.luminance.dim());
                let (h, w) = plane.size();
                let by_lines = plane.part(0..h, 0..w, 1.0);
                for ((y, x), v) in full.luminance.indexed_iter() {
                    assert_eq!(plane.value(y, x).to_bits(), v.to_bits(), "({x}, {y})");
                    assert_eq!(by_lines[[y, x]].to_bits(), v.to_bits(), "({x}, {y})");
                }
                // A region, and one reaching past the border (clipped).
                for [x0, y0, x1, y1] in [[5, 3, 30, 17], [20, 10, 500, 500]] {
                    let region = samples.region([x0, y0, x1, y1]).unwrap();
                    let (x, y) = region.to_full(0.0, 0.0);
                    assert_eq!((x, y), (x0 as f64, y0 as f64));
                    let part = full
                        .luminance
                        .slice(ndarray::s![y0..y1.min(h), x0..x1.min(w)]);
                    assert_eq!(region.image.luminance, part);
                }
            }
        }
        let png = Photo::decoded(
            decode(
                &spot(20, 20, (9.0, 9.0, 3.0), false),
                &DecodeOptions::default(),
            )
            .unwrap(),
        );
        assert!(png.whole_samples().unwrap().is_none());
    }

    #[test]
    fn copies_and_regions_land_where_the_full_image_has_them_in_every_orientation() {
        // Odd sizes: the last reduced column and row are partial.
        let plain = spot(203, 131, (150.0, 40.0, 9.5), true);
        for orientation in 1..=8 {
            let bytes = with_orientation(&plain, orientation);
            let options = DecodeOptions::default();
            let full = decode(&bytes, &options).unwrap();
            let photo = Photo::open(&bytes, &options).unwrap();
            assert_eq!(photo.size(), (full.width(), full.height()));
            let whole = Scaled {
                image: Cow::Owned(full.clone()),
                denominator: 1,
                offset: [0.0; 2],
            };
            let (fx, fy) = bright_centroid(&whole);
            for d in [1, 2, 4, 8] {
                let copy = photo.whole(d).unwrap();
                assert_eq!(copy.denominator, d);
                let (cx, cy) = bright_centroid(&copy);
                let tolerance = 0.6 * d as f64;
                assert!(
                    (cx - fx).abs() < tolerance && (cy - fy).abs() < tolerance,
                    "orientation {orientation}, 1/{d}: ({cx}, {cy}) against ({fx}, {fy})"
                );
                // The spot's region alone, wherever the orientation put it.
                let (x, y) = (fx.round() as usize, fy.round() as usize);
                let region = photo.region([x - 15, y - 15, x + 16, y + 16], d).unwrap();
                assert!(region.image.width() < copy.image.width());
                let (rx, ry) = bright_centroid(&region);
                assert!(
                    (rx - cx).abs() < 0.3 && (ry - cy).abs() < 0.3,
                    "orientation {orientation}, 1/{d}: region ({rx}, {ry}), copy ({cx}, {cy})"
                );
            }
        }
    }

    #[test]
    fn a_full_size_region_is_the_full_decode_there() {
        let bytes = spot(96, 80, (40.0, 30.0, 6.0), false);
        let options = DecodeOptions::default();
        let full = decode(&bytes, &options).unwrap();
        let photo = Photo::open(&bytes, &options).unwrap();
        assert_eq!(photo.whole(1).unwrap().image.luminance, full.luminance);
        let copy = photo.region([0, 0, 96, 79], 1).unwrap();
        assert_eq!(copy.image.height(), 79);
        // Two decoders' rounding: within a level of the 8-bit samples.
        let worst = full
            .luminance
            .iter()
            .zip(copy.image.luminance.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.02, "{worst}");
    }

    #[test]
    fn other_files_are_decoded_whole_once_and_read_as_they_are() {
        let options = DecodeOptions::default();
        let bytes = spot(64, 48, (20.0, 20.0, 4.0), false);
        // A truncated JPEG: libjpeg-turbo's warning hands it to the full path, whose answer
        // (an error, or the image it makes of what is there) stands.
        for cut in [bytes.len() / 3, bytes.len() / 2, bytes.len() - 3] {
            let full = decode(&bytes[..cut], &options);
            let answer = Photo::open(&bytes[..cut], &options).and_then(|photo| {
                let copy = photo.whole(4)?;
                Ok((copy.denominator, copy.image.luminance.clone()))
            });
            match (full, answer) {
                (Ok(full), Ok((d, luminance))) => assert_eq!((d, luminance), (1, full.luminance)),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                (a, b) => panic!("cut at {cut}: {:?} against {:?}", a.is_ok(), b.is_ok()),
            }
        }
        let png = {
            let mut out = Vec::new();
            let samples = vec![128u8; 40 * 30];
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut out),
                &samples,
                40,
                30,
                image::ExtendedColorType::L8,
            )
            .unwrap();
            out
        };
        let photo = Photo::open(&png, &options).unwrap();
        assert!(photo.decoded_whole().is_some());
        let copy = photo.whole(4).unwrap();
        assert_eq!((copy.denominator, copy.image.width()), (1, 40));
    }
}
