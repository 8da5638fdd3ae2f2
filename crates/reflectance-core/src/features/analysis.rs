//! The front half of the pipeline shared by the CLI, training and the server: a decoded
//! image plus where the sphere is and how bright white is → features, with what was used
//! and every warning.

use crate::features::polar::UnwrapConfig;
use crate::features::{CaptureMeasurements, Extractor};
use crate::image::colour::{self, Rgb};
use crate::image::decode::{DecodeError, LinearImage};
use crate::image::geometry::{self, Geometry, GeometryError, Method};
use crate::image::white::{self, White, WhiteError};
use ndarray::Array2;
use serde::Serialize;

/// Where the sphere is.
#[derive(Clone, Debug)]
pub enum Locate {
    /// A circle in the image's pixels.
    Circle(geometry::Circle),
    /// A separate mask image (same size as the image): alpha if it has one, else
    /// linear luminance ≥ 0.5.
    Mask(Array2<bool>),
    /// The image's alpha channel if it has one, else automatic detection.
    Auto,
}

/// How bright white is.
#[derive(Clone, Debug)]
pub enum WhiteInput {
    /// White's linear luminance, given (finite, > 0).
    Value(f64),
    /// A separate image of a white card.
    Card {
        /// The card's image, decoded.
        image: LinearImage,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// A white card inside the image itself.
    Rect {
        /// The card's rectangle, in the image's pixels.
        rect: white::Rect,
        /// The card's reflectance, in (0, 1].
        reflectance: f64,
    },
    /// No reference: white = 1 (the image taken as normalized).
    Missing,
}

/// Why an image gives no features: it does not decode, the circle or white is unusable,
/// or the image divided by white is out of f32's range.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// The image (or the card) does not decode.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// No usable circle.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// No usable white reference.
    #[error(transparent)]
    White(#[from] WhiteError),
    /// Pixels are f32 once divided by white: the ratio must neither overflow nor vanish.
    #[error(
        "the image divided by white ({white:e}) is out of range: its brightest pixel becomes \
         {normalized:e} (usable: {min:e} to {max:e}); check the white value",
        min = f32::MIN_POSITIVE,
        max = f32::MAX
    )]
    Scale {
        /// White's linear luminance.
        white: f64,
        /// The brightest pixel divided by it.
        normalized: f64,
    },
}

/// Features of one sphere and what produced them.
#[derive(Clone, Debug, Serialize)]
pub struct Analysis {
    /// The features in canonical order (NaN for those a subset did not ask for).
    pub values: Vec<f64>,
    /// The circle used and how it was found.
    pub geometry: Geometry,
    /// The white reference used.
    pub white: White,
    /// What the caller should know (a small or cut-off sphere, clipping, …).
    pub warnings: Vec<String>,
    /// The capture measurements, when asked for.
    #[serde(skip)]
    pub measured: Option<CaptureMeasurements>,
    /// The sphere's RGB over white's ([`colour::appearance`]), when both were decoded
    /// with their colour.
    #[serde(skip)]
    pub appearance: Option<Rgb>,
}

/// The mask of a decoded mask image.
pub fn mask_from_image(mask: &LinearImage) -> Array2<bool> {
    match &mask.alpha_mask {
        Some(alpha) => alpha.clone(),
        None => mask.luminance.mapv(|v| v >= 0.5),
    }
}

/// Find the sphere and check it fits the image and the extractor's annulus.
pub fn locate(image: &LinearImage, how: &Locate, extractor: &Extractor) -> Located {
    locate_for(image, how, &extractor.config().unwrap)
}

/// Where the sphere is, with the warnings about it, or why it cannot be used.
pub type Located = Result<(Geometry, Vec<String>), GeometryError>;

/// [`locate`] without a circle, and the other circles detection weighed that fit the image
/// (most confident first, the chosen one among them; none for an image with an alpha
/// channel, which says where the sphere is).
pub fn locate_ranked(image: &LinearImage, extractor: &Extractor) -> (Located, Vec<Geometry>) {
    if image.alpha_mask.is_some() {
        return (locate(image, &Locate::Auto, extractor), Vec::new());
    }
    let unwrap = &extractor.config().unwrap;
    let (width, height) = (image.width(), image.height());
    let fits =
        |g: &Geometry| geometry::validate(&g.circle(), width, height, unwrap.outer, unwrap.r0);
    let (chosen, ranked) = geometry::detect_ranked(image.luminance.view());
    let chosen = chosen.and_then(|g| Ok((g, fits(&g)?)));
    let alternatives = ranked.into_iter().filter(|g| fits(g).is_ok()).collect();
    (chosen, alternatives)
}

/// Find the sphere and check it fits the image and the annulus `unwrap` samples.
pub(crate) fn locate_for(image: &LinearImage, how: &Locate, unwrap: &UnwrapConfig) -> Located {
    let (width, height) = (image.width(), image.height());
    let geometry = match how {
        Locate::Circle(c) => {
            geometry::given(Some(c.cx), Some(c.cy), Some(c.r))?.ok_or(GeometryError::Incomplete)?
        }
        Locate::Mask(mask) => {
            if mask.dim() != image.luminance.dim() {
                return Err(GeometryError::MaskSizeMismatch {
                    mask_width: mask.ncols(),
                    mask_height: mask.nrows(),
                    width,
                    height,
                });
            }
            geometry::fit_mask(mask.view(), Method::Mask)?
        }
        Locate::Auto => match &image.alpha_mask {
            Some(alpha) => geometry::fit_mask(alpha.view(), Method::Alpha)?,
            None => geometry::detect(image.luminance.view())?,
        },
    };
    let warnings = geometry::validate(&geometry.circle(), width, height, unwrap.outer, unwrap.r0)?;
    Ok((geometry, warnings))
}

/// Resolve the white reference, with a warning when there is none.
pub fn resolve_white(
    input: &WhiteInput,
    image: &LinearImage,
) -> Result<(White, Option<String>), WhiteError> {
    match input {
        WhiteInput::Value(v) => Ok((white::given(*v)?, None)),
        WhiteInput::Card { image, reflectance } => {
            Ok((white::from_card(image, *reflectance)?, None))
        }
        WhiteInput::Rect { rect, reflectance } => {
            Ok((white::from_rect(image, rect, *reflectance)?, None))
        }
        WhiteInput::Missing => Ok((white::missing(), Some(white::MISSING_WARNING.to_string()))),
    }
}

/// Refuse a white value that pushes the image's brightest pixel out of f32's normal range
/// (an all-black image is fine: it stays zero).
fn check_scale(image: &LinearImage, white: f64) -> Result<(), AnalysisError> {
    let peak = match image.luminance.as_slice() {
        Some(samples) => peak_of(samples),
        None => peak_of(&image.luminance.iter().copied().collect::<Vec<_>>()),
    };
    let normalized = peak / white;
    let representable = f64::from(f32::MIN_POSITIVE)..=f64::from(f32::MAX);
    if peak > 0.0 && !representable.contains(&normalized) {
        return Err(AnalysisError::Scale { white, normalized });
    }
    Ok(())
}

/// The largest sample (0 for none). Samples are finite and non-negative (decoding refuses
/// others): a plain comparison, in eight independent lanes, vectorizes, where `f64::max`'s
/// NaN handling and one running maximum do not.
fn peak_of(samples: &[f64]) -> f64 {
    let larger = |m: f64, v: f64| if v > m { v } else { m };
    let mut lanes = [0.0f64; 8];
    let chunks = samples.chunks_exact(8);
    let rest = chunks.remainder().iter().fold(0.0, |m, &v| larger(m, v));
    for chunk in chunks {
        for (lane, &v) in lanes.iter_mut().zip(chunk) {
            *lane = larger(*lane, v);
        }
    }
    lanes.into_iter().fold(rest, larger)
}

/// Locate, normalize and extract.
pub fn analyze(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Locate,
    white_input: &WhiteInput,
) -> Result<Analysis, AnalysisError> {
    analyze_subset(extractor, image, how, white_input, None, false)
}

/// Where the sphere is and how bright white is, checked against the image and the
/// extractor, with the warnings so far.
pub struct Placed {
    /// The circle, checked against the image.
    pub geometry: Geometry,
    /// The white reference, measured or given.
    pub white: White,
    /// Warnings so far.
    pub warnings: Vec<String>,
}

/// The front half of [`analyze`]: the white reference resolved and checked against the
/// image's range, and the sphere located.
pub fn place(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Locate,
    white_input: &WhiteInput,
) -> Result<Placed, AnalysisError> {
    let mut warnings = image.warnings.clone();
    let (white, white_warning) = resolve_white(white_input, image)?;
    check_scale(image, white.value)?;
    let (geometry, geometry_warnings) = locate(image, how, extractor)?;
    warnings.extend(geometry_warnings);
    warnings.extend(white_warning);
    Ok(Placed {
        geometry,
        white,
        warnings,
    })
}

/// The white-normalized annulus the features read (rows: radius, columns: angle), as
/// [`analyze`] unwraps it.
pub fn unwrapped(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Locate,
    white_input: &WhiteInput,
) -> Result<Array2<f64>, AnalysisError> {
    let placed = place(extractor, image, how, white_input)?;
    Ok(extractor.unwrap(
        image.luminance.view(),
        &placed.geometry.circle(),
        placed.white.value,
    ))
}

/// [`analyze`], extracting only the features at `wanted` (the others are NaN; see
/// [`Extractor::extract_subset`]), or all of them for `None`; with `measure`, also the
/// capture measurements.
pub fn analyze_subset(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Locate,
    white_input: &WhiteInput,
    wanted: Option<&[usize]>,
    measure: bool,
) -> Result<Analysis, AnalysisError> {
    let Placed {
        geometry,
        white,
        warnings,
    } = place(extractor, image, how, white_input)?;
    let (luminance, circle) = (image.luminance.view(), geometry.circle());
    // Integer samples clip at 1 once decoded; floating-point ones do not clip.
    let full_scale = (!image.is_float).then_some(1.0);
    let (values, measured) =
        extractor.extract_measured(luminance, &circle, white.value, full_scale, wanted, measure);
    let appearance = image
        .colour
        .as_ref()
        .zip(white.rgb)
        .and_then(|(copy, rgb)| colour::appearance(copy, &circle, rgb));
    Ok(Analysis {
        values,
        geometry,
        white,
        warnings,
        measured,
        appearance,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_peak_is_the_largest_sample_wherever_it_stands() {
        let mut rng = crate::util::rng::Rng::new(11);
        for len in 0..40 {
            let samples: Vec<f64> = (0..len).map(|_| rng.next_f64() * 5.0).collect();
            let expected = samples.iter().copied().fold(0.0, f64::max);
            assert_eq!(super::peak_of(&samples), expected, "{len} samples");
        }
    }
}
