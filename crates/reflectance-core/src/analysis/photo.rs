//! The front half for a photograph decoded at the scale each step needs
//! ([`crate::decode::Photo`]): location searches a copy whose long side is about
//! [`LOCATING_SIDE`] pixels, and the features read the ball's region at the largest
//! reduction that keeps its radius at least [`FEATURE_MARGIN`] times the model's working
//! radius (the extractor then reduces it exactly, by area, as it reduces any larger sphere).
//! A photograph decoded whole, or placed by a mask or normals, takes the path of a decoded
//! image ([`super::analyze_subset`]) unchanged.

use super::{Analysis, AnalysisError, Located, Placement, WhiteSpec, check_scale, resolve_white};
use crate::decode::{Photo, Samples, Scaled};
use crate::features::{Extracted, Extractor, Sphere};
use crate::image::circle::Circle;
use crate::image::{colour, display};
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
            let searched = searched(photo)?;
            (searched.detect()?, Some(searched))
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
        Some(Searched::Copy(copy)) if copy.denominator <= d => copy,
        // The features read what the whole decode holds around the ball.
        Some(Searched::Samples(samples)) => samples.region(around(&geometry.circle(), 1))?,
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

/// [`super::locate_ranked`] of a photograph: detection on what location searches
/// ([`searched`]), the circles on the full image; and with a `preview` side, a picture of
/// the photograph at most that many pixels across (PNG).
pub fn locate_photo_ranked(
    photo: &Photo,
    extractor: &Extractor,
    preview: Option<usize>,
) -> Result<LocatedPhoto, crate::decode::DecodeError> {
    if let Some(image) = photo.decoded_whole() {
        let (chosen, alternatives) = super::locate_ranked(image, extractor);
        let preview_png = preview.map(|side| display::preview_png(image.luminance.view(), side));
        return Ok(LocatedPhoto {
            chosen,
            alternatives,
            preview_png,
        });
    }
    let searched = searched(photo)?;
    let unwrap = &extractor.config().unwrap;
    let (width, height) = photo.size();
    let fits = |g: &Geometry| locate::validate(&g.circle(), width, height, unwrap.outer, unwrap.r0);
    let (chosen, ranked) = searched.detect_ranked();
    let chosen = chosen.and_then(|g| Ok((g, fits(&g)?)));
    Ok(LocatedPhoto {
        chosen,
        alternatives: ranked.into_iter().filter(|g| fits(g).is_ok()).collect(),
        preview_png: preview.map(|side| searched.preview_png(side)),
    })
}

/// [`locate_photo_ranked`]'s answer.
pub struct LocatedPhoto {
    /// The circle chosen, or why none was.
    pub chosen: Located,
    /// The circles weighed that fit the unwrap, most confident first.
    pub alternatives: Vec<Geometry>,
    /// The preview asked for (PNG).
    pub preview_png: Option<Vec<u8>>,
}

/// What location searched: a copy of the photograph, or (at full size) its decoded samples,
/// whose luminance it reads where it looks.
enum Searched<'p> {
    Copy(Scaled<'p>),
    Samples(Samples),
}

/// The photograph as location searches it: at full size a JPEG's 8-bit samples, with no
/// 64-bit plane of all its pixels; otherwise the located copy.
fn searched<'p>(photo: &'p Photo) -> Result<Searched<'p>, crate::decode::DecodeError> {
    let d = locating_denominator(photo);
    if d == 1
        && let Some(samples) = photo.whole_samples()?
    {
        return Ok(Searched::Samples(samples));
    }
    Ok(Searched::Copy(photo.whole(d)?))
}

impl Searched<'_> {
    /// Detection on what was searched, the circle on the full image.
    fn detect(&self) -> Result<Geometry, GeometryError> {
        self.detect_ranked().0
    }

    /// [`locate::detect_ranked`] on what was searched, the circles on the full image.
    fn detect_ranked(&self) -> (Result<Geometry, GeometryError>, Vec<Geometry>) {
        match self {
            Searched::Copy(copy) => {
                let (chosen, ranked) = locate::detect_ranked(copy.image.luminance.view());
                let on_full = |g: Geometry| on_full_image(copy, g);
                (
                    chosen.map(on_full),
                    ranked.into_iter().map(on_full).collect(),
                )
            }
            Searched::Samples(samples) => locate::detect_ranked(samples.plane()),
        }
    }

    /// A picture of the photograph at most `side` pixels across (PNG).
    fn preview_png(&self, side: usize) -> Vec<u8> {
        match self {
            Searched::Copy(copy) => display::preview_png(copy.image.luminance.view(), side),
            Searched::Samples(samples) => display::preview_png(samples.plane(), side),
        }
    }
}

/// The circle given, checked on its own.
fn given(c: &Circle) -> Result<Geometry, GeometryError> {
    locate::given(Some(c.cx), Some(c.cy), Some(c.r))?.ok_or(GeometryError::Incomplete)
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
