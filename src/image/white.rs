//! White reference (paper §5.4): the linear luminance an ideal white Lambertian surface
//! facing the viewer would have at the sphere. Given as a number, measured from a white-card
//! image (median luminance, divided by the card's reflectance), or absent.

use crate::image::decode::LinearImage;
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    Given,
    WhiteImage,
    /// No reference: the image is taken as already normalized (white = 1).
    None,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct White {
    pub value: f64,
    pub method: Method,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WhiteError {
    #[error("white must be a finite number > 0, not {0}")]
    NotPositive(f64),
    #[error("white-card reflectance must be in (0, 1], not {0}")]
    BadReflectance(f64),
    #[error("the white image is black (median luminance {0}); it cannot serve as a reference")]
    BlackImage(f64),
}

pub const MISSING_WARNING: &str =
    "no white reference given: the image is assumed to be normalized already (white = 1)";

/// Validate a white value given as a number.
pub fn given(value: f64) -> Result<White, WhiteError> {
    if value.is_finite() && value > 0.0 {
        Ok(White {
            value,
            method: Method::Given,
        })
    } else {
        Err(WhiteError::NotPositive(value))
    }
}

/// White from a crop of a white card of reflectance `card_reflectance` (1 = ideal white):
/// the median of its luminance (pixels inside its alpha mask, if it has one).
pub fn from_card(card: &LinearImage, card_reflectance: f64) -> Result<White, WhiteError> {
    if !(card_reflectance > 0.0 && card_reflectance <= 1.0) {
        return Err(WhiteError::BadReflectance(card_reflectance));
    }
    let mut values: Vec<f64> = match &card.alpha_mask {
        Some(mask) => card
            .luminance
            .iter()
            .zip(mask)
            .filter(|(_, inside)| **inside)
            .map(|(v, _)| *v)
            .collect(),
        None => card.luminance.iter().copied().collect(),
    };
    let median = median(&mut values);
    if median.is_nan() || median <= 0.0 {
        return Err(WhiteError::BlackImage(median));
    }
    Ok(White {
        value: median / card_reflectance,
        method: Method::WhiteImage,
    })
}

/// No reference given.
pub fn missing() -> White {
    White {
        value: 1.0,
        method: Method::None,
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
    use super::*;
    use crate::image::decode::Format;
    use ndarray::Array2;

    fn card(values: &[f64]) -> LinearImage {
        LinearImage {
            luminance: Array2::from_shape_vec((1, values.len()), values.to_vec()).unwrap(),
            alpha_mask: None,
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
}
