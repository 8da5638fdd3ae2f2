//! JPEG through libjpeg-turbo (its TurboJPEG 3 API): decoded at 1/1, 1/2, 1/4 or 1/8 of
//! its size, scaled in the DCT domain, and cropped to a region, so that only the region's
//! blocks are inverse-transformed and nothing below it is entropy-decoded.
//!
//! Only what this decoder reads as the full path would is taken: 8-bit lossy JPEGs in YCbCr
//! or grey. Whatever else (CMYK and YCCK, 12-bit and lossless JPEGs, a file it does not
//! read cleanly: any warning counts, a truncated scan say) is left to the full path
//! ([`super::integer`]), whose answers, errors and limits stand.

use std::ffi::c_int;
use turbojpeg_sys as tj;

/// The most progressive scans a file may hold: a file of thousands of scans is a known way
/// to make a JPEG decoder spin.
const SCAN_LIMIT: c_int = 500;

/// A TurboJPEG decompressor, destroyed with its value.
struct Handle(tj::tjhandle);

impl Handle {
    fn new() -> Option<Handle> {
        // SAFETY: tj3Init has no preconditions; a null handle is a failure.
        let handle = unsafe { tj::tj3Init(tj::TJINIT_TJINIT_DECOMPRESS as c_int) };
        (!handle.is_null()).then_some(Handle(handle))
    }

    fn set(&mut self, param: tj::TJPARAM, value: c_int) -> Option<()> {
        // SAFETY: the handle is live for `self`'s lifetime.
        (unsafe { tj::tj3Set(self.0, param as c_int, value) } == 0).then_some(())
    }

    fn get(&self, param: tj::TJPARAM) -> c_int {
        // SAFETY: as above; an unset parameter reads as -1.
        unsafe { tj::tj3Get(self.0, param as c_int) }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: the handle came from tj3Init and is destroyed once.
        unsafe { tj::tj3Destroy(self.0) }
    }
}

/// A JPEG's header, as far as decoding it in parts needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Header {
    /// Stored width (before any EXIF orientation).
    pub width: usize,
    /// Stored height.
    pub height: usize,
    /// Grey (one channel) rather than YCbCr.
    pub grey: bool,
    /// Width of a block row's unit (the iMCU) at full scale: a crop starts on a multiple of it.
    mcu_width: usize,
}

/// A rectangle of stored pixels at a decode's scale: columns `x..x + w`, rows `y..y + h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Window {
    pub x: usize,
    pub y: usize,
    pub w: usize,
    pub h: usize,
}

/// Samples of a decode: `channels` (1 or 3) interleaved, row-major, over the window asked.
pub(crate) struct Pixels {
    pub samples: Vec<u8>,
    pub channels: usize,
}

/// The header of `bytes` when TurboJPEG reads it as the full path would, else None.
pub(crate) fn header(bytes: &[u8]) -> Option<Header> {
    let mut handle = Handle::new()?;
    read_header(&mut handle, bytes)
}

fn read_header(handle: &mut Handle, bytes: &[u8]) -> Option<Header> {
    let length = tj::size_t::try_from(bytes.len()).ok()?;
    // SAFETY: `bytes` is valid for `length` bytes; the decoder only reads it.
    if unsafe { tj::tj3DecompressHeader(handle.0, bytes.as_ptr(), length) } != 0 {
        return None;
    }
    let lossy = handle.get(tj::TJPARAM_TJPARAM_LOSSLESS) == 0;
    let eight_bit = handle.get(tj::TJPARAM_TJPARAM_PRECISION) == 8;
    let colorspace = handle.get(tj::TJPARAM_TJPARAM_COLORSPACE);
    let cmyk = [tj::TJCS_TJCS_CMYK, tj::TJCS_TJCS_YCCK].map(|c| c as c_int);
    if !lossy || !eight_bit || cmyk.contains(&colorspace) {
        return None;
    }
    // The iMCU widths of TJSAMP_444, 422, 420, GRAY, 440, 411, 441 (TurboJPEG's tjMCUWidth).
    const MCU_WIDTHS: [usize; 7] = [8, 16, 16, 8, 8, 32, 8];
    let subsampling = usize::try_from(handle.get(tj::TJPARAM_TJPARAM_SUBSAMP)).ok()?;
    let dimension = |param| usize::try_from(handle.get(param)).ok().filter(|&d| d > 0);
    Some(Header {
        width: dimension(tj::TJPARAM_TJPARAM_JPEGWIDTH)?,
        height: dimension(tj::TJPARAM_TJPARAM_JPEGHEIGHT)?,
        grey: subsampling == tj::TJSAMP_TJSAMP_GRAY as usize,
        mcu_width: *MCU_WIDTHS.get(subsampling)?,
    })
}

impl Header {
    /// The stored image's size at 1/`denominator`: what the decoder gives (rounded up).
    pub fn scaled(&self, denominator: usize) -> (usize, usize) {
        (
            self.width.div_ceil(denominator),
            self.height.div_ceil(denominator),
        )
    }

    /// The window a crop of `want` (at 1/`denominator`) decodes: `want` within the image,
    /// its left edge moved left to the scaled iMCU's boundary, as the decoder requires.
    pub fn window(&self, want: Window, denominator: usize) -> Option<Window> {
        let (width, height) = self.scaled(denominator);
        let unit = self.mcu_width.div_ceil(denominator).max(1);
        let x = want.x.min(width) / unit * unit;
        let right = want.x.saturating_add(want.w).min(width);
        let bottom = want.y.saturating_add(want.h).min(height);
        let window = Window {
            x,
            y: want.y.min(height),
            w: right.checked_sub(x)?,
            h: bottom.checked_sub(want.y.min(height))?,
        };
        (window.w > 0 && window.h > 0).then_some(window)
    }
}

/// Decode `bytes` at 1/`denominator` (1, 2, 4 or 8), the stored `window` of that scale
/// (the whole image for None; a window from [`Header::window`]), as grey or RGB samples.
/// None for anything the decoder does not read cleanly.
pub(crate) fn decode(bytes: &[u8], denominator: usize, window: Option<Window>) -> Option<Pixels> {
    let mut handle = Handle::new()?;
    handle.set(tj::TJPARAM_TJPARAM_STOPONWARNING, 1)?;
    handle.set(tj::TJPARAM_TJPARAM_SCANLIMIT, SCAN_LIMIT)?;
    let header = read_header(&mut handle, bytes)?;
    let scaling = tj::tjscalingfactor {
        num: 1,
        denom: c_int::try_from(denominator).ok()?,
    };
    // SAFETY: the handle is live; an unsupported factor is refused with -1.
    if unsafe { tj::tj3SetScalingFactor(handle.0, scaling) } != 0 {
        return None;
    }
    let (width, height) = header.scaled(denominator);
    let whole = Window {
        x: 0,
        y: 0,
        w: width,
        h: height,
    };
    let window = window.unwrap_or(whole);
    if window != whole {
        let region = tj::tjregion {
            x: c_int::try_from(window.x).ok()?,
            y: c_int::try_from(window.y).ok()?,
            w: c_int::try_from(window.w).ok()?,
            h: c_int::try_from(window.h).ok()?,
        };
        // SAFETY: as above; a region off the iMCU grid or outside the image is refused.
        if unsafe { tj::tj3SetCroppingRegion(handle.0, region) } != 0 {
            return None;
        }
    }
    let (channels, format) = match header.grey {
        true => (1, tj::TJPF_TJPF_GRAY),
        false => (3, tj::TJPF_TJPF_RGB),
    };
    let pitch = window.w.checked_mul(channels)?;
    let mut samples = vec![0u8; pitch.checked_mul(window.h)?];
    let length = tj::size_t::try_from(bytes.len()).ok()?;
    // SAFETY: `samples` holds `window.h` rows of `pitch` bytes, what the decoder writes for
    // the window (or the whole scaled image) in this format; `bytes` is only read.
    let status = unsafe {
        tj::tj3Decompress8(
            handle.0,
            bytes.as_ptr(),
            length,
            samples.as_mut_ptr(),
            c_int::try_from(pitch).ok()?,
            format as c_int,
        )
    };
    (status == 0).then_some(Pixels { samples, channels })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A `width` × `height` JPEG at quality 95 (grey or RGB), its samples a function of the
    /// pixel.
    pub(crate) fn encoded(
        width: u32,
        height: u32,
        colour: bool,
        value: impl Fn(u32, u32) -> u8,
    ) -> Vec<u8> {
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

    #[test]
    fn a_crop_decodes_the_pixels_of_the_whole_image_there() {
        let bytes = encoded(203, 131, true, |x, y| ((x * 7 + y * 3) % 251) as u8);
        let header = header(&bytes).unwrap();
        assert_eq!(
            (header.width, header.height, header.grey),
            (203, 131, false)
        );
        for d in [1, 2, 4, 8] {
            let whole = decode(&bytes, d, None).unwrap();
            let (w, h) = header.scaled(d);
            assert_eq!(whole.samples.len(), w * h * 3);
            let want = Window {
                x: 37 / d,
                y: 21 / d,
                w: 60 / d + 3,
                h: 50 / d + 2,
            };
            let window = header.window(want, d).unwrap();
            assert!(window.x <= want.x && window.x + window.w >= want.x + want.w);
            let crop = decode(&bytes, d, Some(window)).unwrap();
            // Rows and columns away from the crop's edges equal the whole decode's (the
            // upsampled chroma at a crop's very edge may differ by a level or two).
            for row in 2..window.h - 2 {
                for col in 2..window.w - 2 {
                    for c in 0..3 {
                        let a = crop.samples[(row * window.w + col) * 3 + c];
                        let b = whole.samples[((row + window.y) * w + col + window.x) * 3 + c];
                        assert!(a.abs_diff(b) <= 2, "d {d} ({col}, {row}): {a} against {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn what_the_full_path_reads_otherwise_is_left_to_it() {
        assert!(header(b"not a jpeg").is_none());
        let bytes = encoded(64, 48, false, |x, _| (x * 4) as u8);
        assert!(header(&bytes).unwrap().grey);
        // Cut short: the decoder's warning makes it refuse rather than guess.
        let cut = &bytes[..bytes.len() * 2 / 3];
        assert!(decode(cut, 1, None).is_none());
    }
}
