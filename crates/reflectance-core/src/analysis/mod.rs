//! The front half of the pipeline shared by the CLI, training and the server: a decoded
//! image plus where the sphere is and how bright white is ([`input`]) → features, with what
//! was used and every warning.

pub mod input;
mod photo;

pub use input::{InputError, PartError, Placement, WhiteSpec, decode_mask, mask_from_image};
pub use photo::{
    FEATURE_MARGIN, LOCATING_SIDE, LocatedPhoto, Read, analyze_photo, feature_denominator,
    locate_photo_ranked,
};

use crate::decode::{DecodeError, LinearImage};
use crate::features::observed::ObservedError;
use crate::features::polar::UnwrapConfig;
use crate::features::{CaptureMeasurements, Extracted, Extractor, Sphere};
use crate::image::colour::{self, Rgb};
use crate::locate::{self, Geometry, GeometryError, Method};
use crate::object::normals::{self, EquivalentSphere, NormalMap, NormalsError};
use crate::white::{self, White, WhiteError};
use ndarray::Array2;
use serde::Serialize;

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
    /// The normals do not fit the image, or show the object nowhere.
    #[error("normals: {0}")]
    Normals(#[from] NormalsError),
    /// Too little of the object's equivalent sphere is observed.
    #[error(transparent)]
    Observed(#[from] ObservedError),
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

impl From<PartError> for AnalysisError {
    fn from(e: PartError) -> AnalysisError {
        match e {
            PartError::Mask(e) | PartError::WhiteCard(e) => AnalysisError::Decode(e),
            PartError::Normals(e) => AnalysisError::Normals(e),
        }
    }
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
    /// The fraction of the annulus an object's normals let the features read (`None`: a
    /// sphere, all of it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub observed: Option<f64>,
    /// An object's equivalent sphere, for the pictures of `include=images`.
    #[serde(skip)]
    pub equivalent: Option<EquivalentSphere>,
    /// The sphere's RGB over white's ([`colour::appearance`]), when both were decoded
    /// with their colour.
    #[serde(skip)]
    pub appearance: Option<Rgb>,
    /// Milliseconds spent finding the sphere (0 when the caller placed it).
    #[serde(skip)]
    pub locate_ms: f64,
}

/// Find the sphere and check it fits the image and the extractor's annulus.
pub fn locate(image: &LinearImage, how: &Placement, extractor: &Extractor) -> Located {
    locate_for(image, how, &extractor.config().unwrap)
}

/// Where the sphere is, with the warnings about it, or why it cannot be used.
pub type Located = Result<(Geometry, Vec<String>), GeometryError>;

/// [`locate`] without a circle, and the other circles detection weighed that fit the image
/// (most confident first, the chosen one among them; none for an image with an alpha
/// channel, which says where the sphere is).
pub fn locate_ranked(image: &LinearImage, extractor: &Extractor) -> (Located, Vec<Geometry>) {
    if image.alpha_mask.is_some() {
        return (locate(image, &Placement::Auto, extractor), Vec::new());
    }
    let unwrap = &extractor.config().unwrap;
    let (width, height) = (image.width(), image.height());
    let fits = |g: &Geometry| locate::validate(&g.circle(), width, height, unwrap.outer, unwrap.r0);
    let (chosen, ranked) = locate::detect_ranked(image.luminance.view());
    let chosen = chosen.and_then(|g| Ok((g, fits(&g)?)));
    let alternatives = ranked.into_iter().filter(|g| fits(g).is_ok()).collect();
    (chosen, alternatives)
}

/// Find the sphere and check it fits the image and the annulus `unwrap` samples.
pub(crate) fn locate_for(image: &LinearImage, how: &Placement, unwrap: &UnwrapConfig) -> Located {
    let (width, height) = (image.width(), image.height());
    let geometry = match how {
        Placement::Circle(c) => {
            locate::given(Some(c.cx), Some(c.cy), Some(c.r))?.ok_or(GeometryError::Incomplete)?
        }
        Placement::Mask(mask) => {
            if mask.dim() != image.luminance.dim() {
                return Err(GeometryError::MaskSizeMismatch {
                    mask_width: mask.ncols(),
                    mask_height: mask.nrows(),
                    width,
                    height,
                });
            }
            locate::fit_mask(mask.view(), Method::Mask)?
        }
        Placement::Normals { .. } => return Err(GeometryError::ObjectByNormals),
        Placement::Auto => match &image.alpha_mask {
            Some(alpha) => locate::fit_mask(alpha.view(), Method::Alpha)?,
            None => locate::detect(image.luminance.view())?,
        },
    };
    let warnings = locate::validate(&geometry.circle(), width, height, unwrap.outer, unwrap.r0)?;
    Ok((geometry, warnings))
}

/// Resolve the white reference, with a warning when there is none.
pub fn resolve_white(
    input: &WhiteSpec,
    image: &LinearImage,
) -> Result<(White, Option<String>), WhiteError> {
    match input {
        WhiteSpec::Value(v) => Ok((white::given(*v)?, white::implausible(*v, image.is_float))),
        WhiteSpec::Card { image, reflectance } => {
            Ok((white::from_card(image, *reflectance)?, None))
        }
        WhiteSpec::Rect { rect, reflectance } => {
            Ok((white::from_rect(image, rect, *reflectance)?, None))
        }
        WhiteSpec::Missing => Ok((white::missing(), Some(white::MISSING_WARNING.to_string()))),
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
    how: &Placement,
    white_input: &WhiteSpec,
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
    /// Milliseconds spent finding the sphere (0 when the caller placed it).
    pub locate_ms: f64,
}

/// The front half of [`analyze`]: the white reference resolved and checked against the
/// image's range, and the sphere located.
pub fn place(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Placement,
    white_input: &WhiteSpec,
) -> Result<Placed, AnalysisError> {
    let mut warnings = image.warnings.clone();
    let (white, white_warning) = resolve_white(white_input, image)?;
    check_scale(image, white.value)?;
    let started = std::time::Instant::now();
    let (geometry, geometry_warnings) = locate(image, how, extractor)?;
    let locate_ms = started.elapsed().as_secs_f64() * 1e3;
    warnings.extend(geometry_warnings);
    warnings.extend(white_warning);
    Ok(Placed {
        geometry,
        white,
        warnings,
        locate_ms,
    })
}

/// The white-normalized annulus the features read (rows: radius, columns: angle), as
/// [`analyze`] unwraps it.
pub fn unwrapped(
    extractor: &Extractor,
    image: &LinearImage,
    how: &Placement,
    white_input: &WhiteSpec,
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
    how: &Placement,
    white_input: &WhiteSpec,
    wanted: Option<&[usize]>,
    measure: bool,
) -> Result<Analysis, AnalysisError> {
    if let Placement::Normals { normals, mask } = how {
        return analyze_object(extractor, image, normals, mask.as_ref(), white_input);
    }
    let Placed {
        geometry,
        white,
        warnings,
        locate_ms,
    } = place(extractor, image, how, white_input)?;
    let (luminance, circle) = (image.luminance.view(), geometry.circle());
    // Integer samples clip at 1 once decoded; floating-point ones do not clip.
    let full_scale = (!image.is_float).then_some(1.0);
    let sphere = Sphere::Photographed {
        luminance,
        circle: &circle,
    };
    let Extracted {
        values, measured, ..
    } = extractor.extract_sphere(sphere, white.value, full_scale, wanted, measure)?;
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
        observed: None,
        equivalent: None,
        appearance,
        locate_ms,
    })
}

/// [`analyze`] of an object of any shape from its normals: the white reference, the
/// object's equivalent sphere at the working radius, its features over the observed part.
fn analyze_object(
    extractor: &Extractor,
    image: &LinearImage,
    normals: &NormalMap,
    mask: Option<&Array2<bool>>,
    white_input: &WhiteSpec,
) -> Result<Analysis, AnalysisError> {
    let mut warnings = image.warnings.clone();
    let (white, white_warning) = resolve_white(white_input, image)?;
    check_scale(image, white.value)?;
    let config = extractor.config();
    let radius = config.working_radius.unwrap_or(config.unwrap.r0);
    let sphere = normals::equivalent_sphere(&image.luminance, normals, mask, radius)?;
    let full_scale = (!image.is_float).then_some(1.0);
    let Extracted {
        values, observed, ..
    } = extractor.extract_sphere(
        Sphere::Equivalent(&sphere),
        white.value,
        full_scale,
        None,
        false,
    )?;
    if normals.back_facing() > 0 {
        warnings.push(format!(
            "{} normals face away from the camera (z < 0) and were left out",
            normals.back_facing()
        ));
    }
    warnings.extend(white_warning);
    let circle = sphere.circle;
    Ok(Analysis {
        values,
        geometry: Geometry {
            cx: circle.cx,
            cy: circle.cy,
            r: circle.r,
            method: Method::Normals,
            confidence: None,
        },
        white,
        warnings,
        measured: None,
        observed: observed.map(|o| o.fraction),
        equivalent: Some(sphere),
        appearance: None,
        locate_ms: 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::{self, Limits};
    use crate::features::{FeatureConfig, MIN_OBSERVED, default_names};
    use crate::locate::Circle;

    /// A shiny sphere of radius `r` centred in a `size`² image under a sky with a sun: its
    /// luminance and its normal map (the shading depends on the normal only).
    fn glossy_sphere(size: usize, r: f64) -> (LinearImage, NormalMap, Circle) {
        let c = (size - 1) as f64 / 2.0;
        let sun = [-0.45f64, 0.55, 0.70];
        let normal = |row: usize, col: usize| {
            let (x, y) = ((col as f64 - c) / r, (c - row as f64) / r);
            let z2 = 1.0 - x * x - y * y;
            (z2 > 0.0).then(|| [x, y, z2.sqrt()])
        };
        let shade = |n: [f64; 3]| {
            // The mirror direction of the view (0, 0, 1) about n, against the sun.
            let reflected = [
                2.0 * n[2] * n[0],
                2.0 * n[2] * n[1],
                2.0 * n[2] * n[2] - 1.0,
            ];
            let cos = reflected.iter().zip(sun).map(|(a, b)| a * b).sum::<f64>();
            let diffuse = n.iter().zip(sun).map(|(a, b)| a * b).sum::<f64>().max(0.0);
            // A sky of bands seen in the mirror direction: structure at every scale, down to
            // the finest the sphere's pixels resolve.
            let band = |f: f64, g: f64| (f * reflected[0]).sin() * (g * reflected[1]).cos();
            let sky = 0.6 + 0.3 * band(6.0, 4.0) + 0.2 * band(50.0, 45.0);
            0.3 * diffuse + 0.2 * sky + 2.0 * cos.max(0.0).powf(40.0)
        };
        let luminance = Array2::from_shape_fn((size, size), |(row, col)| {
            normal(row, col).map_or(0.02, shade)
        });
        let normals = Array2::from_shape_fn((size, size), |(row, col)| {
            normal(row, col).map_or([0.0; 3], |n| n.map(|v| v as f32))
        });
        let image = decode::from_luminance(luminance, &Limits::default()).unwrap();
        let circle = Circle { cx: c, cy: c, r };
        (image, NormalMap::from_vectors(normals).unwrap(), circle)
    }

    fn extractor() -> Extractor {
        let config = FeatureConfig {
            working_radius: Some(116.36),
            ..FeatureConfig::default()
        };
        Extractor::new(config).unwrap()
    }

    /// The analyses of a sphere of radius `r` in a `size`² image by its circle and by its
    /// normals agree on the pixel statistics and the subband variances; the one by normals
    /// sees the whole sphere.
    fn normals_agree_with_the_circle(size: usize, r: f64) {
        let extractor = extractor();
        let (image, normals, circle) = glossy_sphere(size, r);
        let white = WhiteSpec::Value(1.0);
        let by_circle = analyze(&extractor, &image, &Placement::Circle(circle), &white).unwrap();
        let how = Placement::Normals {
            normals,
            mask: None,
        };
        let by_normals = analyze(&extractor, &image, &how, &white).unwrap();
        assert_eq!(by_normals.geometry.method, Method::Normals);
        let fraction = by_normals.observed.unwrap();
        assert!(fraction > 0.99, "{fraction}");
        let names = default_names();
        for (name, tolerance) in [
            ("pix.mean", 0.02),
            ("pix.var", 0.05),
            ("pix.p50", 0.02),
            ("wav.s2.v.var", 0.15),
            ("wav.s3.h.var", 0.15),
            // The finest bands: what a second resampling would smooth.
            ("wav.s1.h.var", 0.1),
            ("wav.s1.v.var", 0.1),
            ("wav.s1.d.var", 0.1),
        ] {
            let at = names.iter().position(|n| n == name).unwrap();
            let (a, b) = (by_normals.values[at], by_circle.values[at]);
            assert!(
                (a - b).abs() < tolerance,
                "r {r}: {name}: {a} by normals, {b} by circle"
            );
        }
    }

    #[test]
    fn a_sphere_given_by_its_normals_has_the_features_of_its_circle() {
        // At the working radius, and larger (reduced by area weights, as by its circle).
        normals_agree_with_the_circle(261, 116.36);
        normals_agree_with_the_circle(300, 130.0);
        normals_agree_with_the_circle(400, 180.0);
    }

    #[test]
    fn a_large_sphere_given_by_its_normals_is_reduced_and_keeps_its_features() {
        // r = 700 px against the working radius of 116: normals turn by a sixth of a cell per
        // pixel, and the photograph is reduced before mapping.
        normals_agree_with_the_circle(1500, 700.0);
    }

    #[test]
    fn an_object_showing_too_little_of_the_sphere_is_refused_with_the_fraction() {
        let extractor = extractor();
        let (image, normals, _) = glossy_sphere(300, 130.0);
        // A thin vertical strip through the centre: normals of a narrow band of the sphere.
        let strip = Array2::from_shape_fn((300, 300), |(_, col)| (140..160).contains(&col));
        let how = Placement::Normals {
            normals,
            mask: Some(strip),
        };
        let e = analyze(&extractor, &image, &how, &WhiteSpec::Value(1.0)).unwrap_err();
        match e {
            AnalysisError::Observed(ObservedError::TooLittle { fraction, needed }) => {
                assert!(fraction < MIN_OBSERVED && fraction > 0.0, "{fraction}");
                assert_eq!(needed, MIN_OBSERVED);
            }
            other => panic!("{other}"),
        }
    }

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
