//! White reference (paper §5.4): the linear luminance an ideal white Lambertian surface
//! facing the viewer would have at the sphere. Given as a number, measured from a white card
//! (median luminance, divided by the card's reflectance) in a separate crop or in a
//! rectangle of the photograph itself, or absent.

use crate::decode::LinearImage;
use crate::image::colour::Rgb;
use ndarray::s;
use serde::Serialize;
use std::ops::Range;

/// Where the white reference came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Given as a number.
    Given,
    /// A separate image of a white card.
    WhiteImage,
    /// A rectangle of the photograph (a white card beside the sphere).
    WhiteRect,
    /// No reference: the image is taken as already normalized (white = 1).
    None,
}

/// The white reference used: its linear luminance, where it came from, and its colour when
/// known.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct White {
    /// White's linear luminance at the sphere (finite, > 0; 1 without a reference).
    pub value: f64,
    /// Where it came from.
    pub method: Method,
    /// White's linear RGB (the card's mean over its reflectance), when a card was measured
    /// in an image decoded with its colour.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rgb: Option<Rgb>,
}

/// Why a white reference cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WhiteError {
    /// A value that is not a finite number > 0.
    #[error("white must be a finite number > 0, not {0}")]
    NotPositive(f64),
    /// A card's reflectance outside (0, 1].
    #[error("white-card reflectance must be in (0, 1], not {0}")]
    BadReflectance(f64),
    /// A card whose median luminance (the value) is not positive.
    #[error("the white image is black (median luminance {0}); it cannot serve as a reference")]
    BlackImage(f64),
    /// A `white_rect` that is not `x,y,w,h` with w, h > 0.
    #[error("white_rect must be x,y,w,h: four finite numbers with w, h > 0, not {0:?}")]
    RectSyntax(String),
    /// A rectangle not inside the image.
    #[error(
        "white_rect {rect} is not inside the {width} × {height} image",
        rect = .rect.to_string()
    )]
    RectOutside {
        /// The rectangle.
        rect: Rect,
        /// The image's width (px).
        width: usize,
        /// The image's height (px).
        height: usize,
    },
}

/// A rectangle of the image in pixels: left, top, width, height (x across, y down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Left edge (px).
    pub x: f64,
    /// Top edge (px).
    pub y: f64,
    /// Width (px, > 0).
    pub w: f64,
    /// Height (px, > 0).
    pub h: f64,
}

impl std::fmt::Display for Rect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x, self.y, self.w, self.h)
    }
}

impl std::str::FromStr for Rect {
    type Err = WhiteError;

    /// `x,y,w,h`, e.g. `10,20,64,48`.
    fn from_str(text: &str) -> Result<Rect, WhiteError> {
        let bad = || WhiteError::RectSyntax(text.to_string());
        let numbers: Vec<f64> = text
            .split(',')
            .map(|t| t.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(bad)?;
        match numbers[..] {
            [x, y, w, h] if w > 0.0 && h > 0.0 => Ok(Rect { x, y, w, h }),
            _ => Err(bad()),
        }
    }
}

impl Rect {
    /// The pixels it covers, as row and column ranges (any pixel it touches), or `None`
    /// when it reaches outside the image.
    fn pixels(&self, width: usize, height: usize) -> Option<(Range<usize>, Range<usize>)> {
        let (x0, y0) = (self.x.floor(), self.y.floor());
        let (x1, y1) = ((self.x + self.w).ceil(), (self.y + self.h).ceil());
        let inside = x0 >= 0.0 && y0 >= 0.0 && x1 <= width as f64 && y1 <= height as f64;
        inside.then_some((y0 as usize..y1 as usize, x0 as usize..x1 as usize))
    }
}

/// The warning of an answer without a white reference.
pub const MISSING_WARNING: &str =
    "no white reference given: the image is assumed to be normalized already (white = 1)";

/// How the warning of a white value far outside what a photograph can hold begins
/// ([`implausible`]); the answer also gives it as a reason when the input is out of domain.
pub const IMPLAUSIBLE: &str = "the white reference given, ";

/// Above this a white value given for a photograph of integer samples (linear luminance
/// in [0, 1], where a white card reads at most 1) is taken to be a mistake, not a card.
pub const IMPLAUSIBLE_ABOVE: f64 = 2.0;

/// A warning for a white value far outside what a photograph of integer samples can hold
/// (its linear luminance is in [0, 1]), with what it likely meant: a percentage, or an 8-
/// or 16-bit pixel value. `None` for a plausible value or a floating-point image (HDR
/// units are the file's own).
pub fn implausible(value: f64, is_float: bool) -> Option<String> {
    if is_float || value <= IMPLAUSIBLE_ABOVE {
        return None;
    }
    let short = |v: f64| format!("{:?}", (v * 1e4).round() / 1e4);
    let meant = if value <= 100.0 {
        format!(
            "a percentage? {} % is white={}",
            short(value),
            short(value / 100.0)
        )
    } else if let Some((bits, full)) = [("an 8", 255.0), ("a 16", 65535.0)]
        .into_iter()
        .find(|&(_, full)| value <= full)
    {
        let linear = crate::decode::srgb_to_linear(value / full);
        format!(
            "{bits}-bit pixel value? {} in sRGB is white={}",
            short(value),
            short(linear)
        )
    } else {
        "a raw sensor value? give the white card's linear luminance in [0, 1]".to_string()
    };
    Some(format!(
        "{IMPLAUSIBLE}{}, is far outside what is expected: this photograph's samples are linear \
         luminance from 0 to 1, where a white card reads at most 1 (a well-exposed one about \
         0.5 to 0.9), so the sphere reads as darker than any surface can be. Did you mean \
         {meant}",
        short(value)
    ))
}

/// Validate a white value given as a number.
pub fn given(value: f64) -> Result<White, WhiteError> {
    if value.is_finite() && value > 0.0 {
        Ok(White {
            value,
            method: Method::Given,
            rgb: None,
        })
    } else {
        Err(WhiteError::NotPositive(value))
    }
}

/// White from a crop of a white card of reflectance `card_reflectance` (1 = ideal white):
/// the median of its luminance (pixels inside its alpha mask, if it has one).
pub fn from_card(card: &LinearImage, card_reflectance: f64) -> Result<White, WhiteError> {
    let values: Vec<f64> = match &card.alpha_mask {
        Some(mask) => card
            .luminance
            .iter()
            .zip(mask)
            .filter(|(_, inside)| **inside)
            .map(|(v, _)| *v)
            .collect(),
        None => card.luminance.iter().copied().collect(),
    };
    let rgb = card.colour.as_ref().and_then(|c| c.mean(|_, _| true, 0.0));
    from_samples(values, card_reflectance, Method::WhiteImage, rgb)
}

/// White from a white card inside the photograph: the median luminance of the pixels
/// `rect` touches (inside the alpha mask, if the image has one).
pub fn from_rect(
    image: &LinearImage,
    rect: &Rect,
    card_reflectance: f64,
) -> Result<White, WhiteError> {
    let (width, height) = (image.width(), image.height());
    let (rows, cols) = rect.pixels(width, height).ok_or(WhiteError::RectOutside {
        rect: *rect,
        width,
        height,
    })?;
    let luminance = image.luminance.slice(s![rows.clone(), cols.clone()]);
    let values: Vec<f64> = match &image.alpha_mask {
        Some(mask) => luminance
            .iter()
            .zip(mask.slice(s![rows, cols]))
            .filter(|(_, inside)| **inside)
            .map(|(v, _)| *v)
            .collect(),
        None => luminance.iter().copied().collect(),
    };
    // The copy's pixels whose centres lie in the rectangle (at least the one nearest its
    // centre, for a rectangle smaller than a copy pixel).
    let rgb = image.colour.as_ref().and_then(|copy| {
        let inside = |x: f64, y: f64| {
            x >= rect.x - 0.5
                && x <= rect.x + rect.w - 0.5
                && y >= rect.y - 0.5
                && y <= rect.y + rect.h - 0.5
        };
        copy.mean(inside, 0.0).or_else(|| {
            let (cx, cy) = (rect.x + rect.w / 2.0, rect.y + rect.h / 2.0);
            let half = copy.factor() as f64 / 2.0;
            copy.mean(|x, y| (x - cx).abs() <= half && (y - cy).abs() <= half, 0.0)
        })
    });
    from_samples(values, card_reflectance, Method::WhiteRect, rgb)
}

fn from_samples(
    mut values: Vec<f64>,
    card_reflectance: f64,
    method: Method,
    rgb: Option<Rgb>,
) -> Result<White, WhiteError> {
    if !(card_reflectance > 0.0 && card_reflectance <= 1.0) {
        return Err(WhiteError::BadReflectance(card_reflectance));
    }
    let median = median(&mut values);
    if median.is_nan() || median <= 0.0 {
        return Err(WhiteError::BlackImage(median));
    }
    Ok(White {
        value: median / card_reflectance,
        method,
        rgb: rgb.map(|c| c.map(|v| v / card_reflectance)),
    })
}

/// No reference given.
pub fn missing() -> White {
    White {
        value: 1.0,
        method: Method::None,
        rgb: None,
    }
}

/// Median; the mean of the two middle values for an even count (0 for no values).
fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return 0.0;
    }
    let (_, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if n % 2 == 1 {
        return upper;
    }
    let lower = values[..n / 2]
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    (lower + upper) / 2.0
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_white_no_photograph_can_hold_is_named_with_what_it_likely_meant() {
        assert_eq!(implausible(0.8, false), None);
        assert_eq!(implausible(2.0, false), None);
        assert_eq!(
            implausible(80.0, true),
            None,
            "HDR units are the file's own"
        );
        let percent = implausible(80.0, false).unwrap();
        assert!(percent.starts_with(IMPLAUSIBLE), "{percent}");
        assert!(
            percent.ends_with("a percentage? 80.0 % is white=0.8"),
            "{percent}"
        );
        let byte = implausible(255.0, false).unwrap();
        assert!(
            byte.ends_with("an 8-bit pixel value? 255.0 in sRGB is white=1.0"),
            "{byte}"
        );
        let word = implausible(65535.0, false).unwrap();
        assert!(
            word.ends_with("a 16-bit pixel value? 65535.0 in sRGB is white=1.0"),
            "{word}"
        );
        let raw = implausible(1e6, false).unwrap();
        assert!(raw.contains("a raw sensor value?"), "{raw}");
    }
    use super::*;
    use crate::decode::Format;
    use ndarray::Array2;

    fn card(values: &[f64]) -> LinearImage {
        LinearImage {
            luminance: Array2::from_shape_vec((1, values.len()), values.to_vec()).unwrap(),
            alpha_mask: None,
            colour: None,
            format: Format::Png,
            is_float: false,
            warnings: vec![],
        }
    }

    #[test]
    fn given_values() {
        assert_eq!(given(0.8).unwrap().value, 0.8);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(given(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn card_median_and_reflectance() {
        assert_eq!(from_card(&card(&[3.0, 1.0, 2.0]), 1.0).unwrap().value, 2.0);
        assert_eq!(
            from_card(&card(&[4.0, 1.0, 2.0, 3.0]), 1.0).unwrap().value,
            2.5
        );
        assert_eq!(from_card(&card(&[0.45, 0.45]), 0.9).unwrap().value, 0.5);
        assert_eq!(
            from_card(&card(&[0.0, 0.0, 1.0]), 1.0),
            Err(WhiteError::BlackImage(0.0))
        );
        assert!(from_card(&card(&[1.0]), 0.0).is_err());
    }

    #[test]
    fn rect_syntax() {
        let r: Rect = "1, 2.5,3,4".parse().unwrap();
        assert_eq!(
            r,
            Rect {
                x: 1.0,
                y: 2.5,
                w: 3.0,
                h: 4.0
            }
        );
        for bad in [
            "",
            "1,2,3",
            "1,2,3,4,5",
            "1,2,0,4",
            "1,2,3,-4",
            "a,2,3,4",
            "1,2,inf,4",
        ] {
            assert_eq!(
                bad.parse::<Rect>(),
                Err(WhiteError::RectSyntax(bad.into())),
                "{bad}"
            );
        }
    }

    #[test]
    fn rect_median_covers_every_touched_pixel() {
        // 4 × 3 image, value = 10·row + column.
        let mut image = card(&[0.0; 12]);
        image.luminance = Array2::from_shape_fn((3, 4), |(y, x)| (10 * y + x) as f64);
        // Columns 1..3 and rows 1..3 (the fractional edges round outwards): 11 12 21 22.
        let white = from_rect(&image, &"1.5,1,1.2,2".parse().unwrap(), 0.5).unwrap();
        assert_eq!(white.value, 16.5 / 0.5);
        assert_eq!(white.method, Method::WhiteRect);
        let whole = from_rect(&image, &"0,0,4,3".parse().unwrap(), 1.0).unwrap();
        assert_eq!(whole.value, 11.5);
        for outside in ["-1,0,2,2", "3,0,1.5,1", "0,2,1,2"] {
            let err = from_rect(&image, &outside.parse().unwrap(), 1.0).unwrap_err();
            assert!(
                matches!(
                    err,
                    WhiteError::RectOutside {
                        width: 4,
                        height: 3,
                        ..
                    }
                ),
                "{outside}"
            );
        }
    }
}
