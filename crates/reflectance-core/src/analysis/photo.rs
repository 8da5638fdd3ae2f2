//! The front half for a photograph decoded at the scale each step needs
//! ([`crate::decode::Photo`]): location searches a copy whose long side is about
//! [`LOCATING_SIDE`] pixels, and the features read the ball's region at the largest
//! reduction that keeps its radius at least [`FEATURE_MARGIN`] times the model's working
//! radius (the extractor then reduces it exactly, by area, as it reduces any larger sphere).
//! A photograph decoded whole, or placed by a mask or normals, takes the path of a decoded
//! image ([`super::analyze_subset`]) unchanged.

use super::{Analysis, AnalysisError, Located, Placement, WhiteSpec, check_scale, resolve_white};
use crate::decode::{Photo, Scaled};
use crate::features::{Extracted, Extractor, Sphere};
use crate::image::circle::Circle;
use crate::image::colour;
use crate::locate::{self, Geometry, GeometryError};
use crate::white::{self, Rect};

/// The located copy's long side: at least this many pixels. Location reads the full
/// resolution for now: detection's figures were measured on it (docs/accuracy.md).
pub const LOCATING_SIDE: usize = usize::MAX;

/// The features read a copy on which the ball's radius is at least this many times the
/// working radius, reduced from there by area: the DCT-domain reduction averages
/// gamma-encoded samples, which the exact reduction of the last factor of two or more
/// outweighs.
pub const FEATURE_MARGIN: f64 = 2.0;

/// The share of the radius the features read beyond the rim (the outline's band reaches
/// 1.3 r), plus a few copy pixels for interpolation.
const REACH: f64 = 1.35;

/// What the features of a photograph read: a copy of it, and the sphere's circle there.
pub struct Read<'p> {
    /// The copy (the photograph itself when it was decoded whole).
    pub copy: Scaled<'p>,
    /// The sphere's circle on the copy.
    pub circle: Circle,
}

/// [`super::analyze_subset`] of a photograph, decoding only what each step reads; with
/// what its features read.
pub fn analyze_photo<'p>(
    extractor: &Extractor,
    photo: &'p Photo,
    how: &Placement,
    white_input: &WhiteSpec,
    wanted: Option<&[usize]>,
    measure: bool,
) -> Result<(Analysis, Read<'p>), AnalysisError> {
    let whole_path = photo.decoded_whole().is_some()
        || matches!(how, Placement::Mask(_) | Placement::Normals { .. });
    if whole_path {
        let copy = photo.whole(1)?;
        let analysis =
            super::analyze_subset(extractor, &copy.image, how, white_input, wanted, measure)?;
        let circle = analysis.geometry.circle();
        return Ok((analysis, Read { copy, circle }));
    }
    let started = std::time::Instant::now();
    let (geometry, located) = match how {
        Placement::Circle(c) => (given(c)?, None),
        _ => {
            let copy = photo.whole(locating_denominator(photo))?;
            (detect_on(&copy)?, Some(copy))
        }
    };
    let locate_ms = started.elapsed().as_secs_f64() * 1e3;
    let (width, height) = photo.size();
    let unwrap = &extractor.config().unwrap;
    let mut warnings = photo.warnings().to_vec();
    warnings.extend(locate::validate(
        &geometry.circle(),
        width,
        height,
        unwrap.outer,
        unwrap.r0,
    )?);
    let d = feature_denominator(geometry.r, extractor.config().working_radius);
    let copy = match located {
        Some(copy) if copy.denominator <= d => copy,
        _ => photo.region(around(&geometry.circle(), d), d)?,
    };
    let (white, white_warning) = match white_input {
        WhiteSpec::Rect { rect, reflectance } => (white_in(photo, rect, *reflectance)?, None),
        other => resolve_white(other, &copy.image)?,
    };
    check_scale(&copy.image, white.value)?;
    let circle = copy.circle_from_full(&geometry.circle());
    let sphere = Sphere::Photographed {
        luminance: copy.image.luminance.view(),
        circle: &circle,
    };
    // JPEG samples are integers: they clip at 1 once decoded.
    let Extracted {
        values, measured, ..
    } = extractor.extract_sphere(sphere, white.value, Some(1.0), wanted, measure)?;
    let appearance = copy
        .image
        .colour
        .as_ref()
        .zip(white.rgb)
        .and_then(|(colours, rgb)| colour::appearance(colours, &circle, rgb));
    warnings.extend(white_warning);
    let analysis = Analysis {
        values,
        geometry,
        white,
        warnings,
        measured,
        observed: None,
        equivalent: None,
        appearance,
        locate_ms,
    };
    Ok((analysis, Read { copy, circle }))
}

/// [`super::locate_ranked`] of a photograph: detection on the located copy, the circles on
/// the full image; and that copy (for a preview).
pub fn locate_photo_ranked<'p>(
    photo: &'p Photo,
    extractor: &Extractor,
) -> Result<(Located, Vec<Geometry>, Scaled<'p>), crate::decode::DecodeError> {
    let copy = photo.whole(locating_denominator(photo))?;
    if photo.decoded_whole().is_some() {
        let (chosen, ranked) = super::locate_ranked(&copy.image, extractor);
        return Ok((chosen, ranked, copy));
    }
    let unwrap = &extractor.config().unwrap;
    let (width, height) = photo.size();
    let fits = |g: &Geometry| locate::validate(&g.circle(), width, height, unwrap.outer, unwrap.r0);
    let (chosen, ranked) = locate::detect_ranked(copy.image.luminance.view());
    let on_full = |g: Geometry| on_full_image(&copy, g);
    let chosen = chosen.map(on_full).and_then(|g| Ok((g, fits(&g)?)));
    let alternatives = ranked
        .into_iter()
        .map(on_full)
        .filter(|g| fits(g).is_ok())
        .collect();
    Ok((chosen, alternatives, copy))
}

/// The circle given, checked on its own.
fn given(c: &Circle) -> Result<Geometry, GeometryError> {
    locate::given(Some(c.cx), Some(c.cy), Some(c.r))?.ok_or(GeometryError::Incomplete)
}

/// Detection on the located copy, its circle on the full image.
fn detect_on(copy: &Scaled) -> Result<Geometry, GeometryError> {
    locate::detect(copy.image.luminance.view()).map(|g| on_full_image(copy, g))
}

/// A circle found on `copy`, on the full image.
fn on_full_image(copy: &Scaled, g: Geometry) -> Geometry {
    let Circle { cx, cy, r } = copy.circle_to_full(&g.circle());
    Geometry { cx, cy, r, ..g }
}

/// The denominator of the located copy: the largest that keeps its long side at least
/// [`LOCATING_SIDE`].
fn locating_denominator(photo: &Photo) -> usize {
    let (width, height) = photo.size();
    crate::decode::denominator_for(width, height, LOCATING_SIDE)
}

/// The largest denominator (1, 2, 4 or 8) that keeps a ball of radius `r` at least
/// [`FEATURE_MARGIN`] times the working radius; 1 without one (the features then read the
/// pixels as they are, docs/design.md §3).
pub fn feature_denominator(r: f64, working_radius: Option<f64>) -> usize {
    let Some(working) = working_radius else {
        return 1;
    };
    [8, 4, 2]
        .into_iter()
        .find(|&d| r / d as f64 >= FEATURE_MARGIN * working)
        .unwrap_or(1)
}

/// The full image's pixels the features of `circle` read at 1/`d`, as `[x0, y0, x1, y1]`
/// (clipped to the image by the decode).
fn around(circle: &Circle, d: usize) -> [usize; 4] {
    let reach = REACH * circle.r + 4.0 * d as f64;
    let low = |c: f64| (c - reach).floor().max(0.0) as usize;
    let high = |c: f64| (c + reach).ceil().max(0.0) as usize + 1;
    [
        low(circle.cx),
        low(circle.cy),
        high(circle.cx),
        high(circle.cy),
    ]
}

/// The white card inside the photograph: its rectangle decoded at full size.
fn white_in(photo: &Photo, rect: &Rect, reflectance: f64) -> Result<white::White, AnalysisError> {
    let low = |v: f64| v.floor().max(0.0) as usize;
    let high = |v: f64| v.ceil().max(0.0) as usize + 1;
    let bounds = [
        low(rect.x),
        low(rect.y),
        high(rect.x + rect.w),
        high(rect.y + rect.h),
    ];
    let copy = photo.region(bounds, 1)?;
    let (x, y) = copy.from_full(rect.x, rect.y);
    let on_copy = Rect { x, y, ..*rect };
    Ok(white::from_rect(&copy.image, &on_copy, reflectance)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_features_read_the_largest_reduction_that_keeps_twice_the_working_radius() {
        assert_eq!(feature_denominator(1000.0, None), 1);
        assert_eq!(feature_denominator(1000.0, Some(116.36)), 4);
        assert_eq!(feature_denominator(1862.0, Some(116.36)), 8);
        assert_eq!(feature_denominator(400.0, Some(116.36)), 1);
        assert_eq!(feature_denominator(466.0, Some(116.36)), 2);
    }
}
