//! Where the sphere is (docs/design.md §3): a circle given, a circle fitted to a mask's edge
//! ([`mask`]), or found in a photograph ([`detect`]). Pixel centres are at integer
//! coordinates, so an image spans [−0.5, width − 0.5] × [−0.5, height − 0.5].
//!
//! The stage's one type is [`Geometry`], the circle used and how it was found; [`validate`]
//! checks it against an image and the annulus the features sample.

pub(crate) mod detect;
pub(crate) mod fit;
pub mod mask;

pub use crate::image::circle::Circle;
use crate::image::plane::Plane;
pub use detect::clean::{MIN_CONFIDENCE, detect_clean};
pub use detect::{ACCEPTANCE, Acceptance, Found, chosen_by};
pub use mask::fit_mask;
use serde::{Deserialize, Serialize};

/// Radii below this are refused.
pub const MIN_RADIUS: f64 = 32.0;

/// How the sphere's circle was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Given by the caller.
    Given,
    /// Fitted to a separate mask image.
    Mask,
    /// Fitted to the image's alpha channel.
    Alpha,
    /// Detected against the background.
    Auto,
    /// An object of any shape seen as its equivalent sphere (from its normals): the circle
    /// is that sphere's, in its own pixels, not in the photograph's.
    Normals,
}

/// The circle used, how it was found, and (for detection) how sure we are.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Geometry {
    /// Centre's x (px; pixel centres at integer coordinates).
    pub cx: f64,
    /// Centre's y (px, down).
    pub cy: f64,
    /// Radius (px, ≥ [`MIN_RADIUS`]).
    pub r: f64,
    /// How the circle was found.
    pub method: Method,
    /// Detection's confidence, in [0, 1] (≥ [`MIN_CONFIDENCE`] when accepted); `None` unless
    /// detected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub confidence: Option<f64>,
}

impl Geometry {
    /// The circle alone.
    pub fn circle(&self) -> Circle {
        Circle {
            cx: self.cx,
            cy: self.cy,
            r: self.r,
        }
    }

    pub(crate) fn new(circle: Circle, method: Method, confidence: Option<f64>) -> Self {
        Geometry {
            cx: circle.cx,
            cy: circle.cy,
            r: circle.r,
            method,
            confidence,
        }
    }
}

/// Why a circle cannot be used, or cannot be found.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GeometryError {
    /// A circle parameter is NaN or infinite.
    #[error("circle parameters must be finite numbers (cx={cx}, cy={cy}, r={r})")]
    NotFinite {
        /// Centre's x (px).
        cx: f64,
        /// Centre's y (px).
        cy: f64,
        /// Radius (px).
        r: f64,
    },
    /// Some but not all of cx, cy and r were given.
    #[error("give all of cx, cy and r, or none of them")]
    Incomplete,
    /// The radius is below [`MIN_RADIUS`].
    #[error("sphere radius {r} px is below the minimum of {min} px")]
    TooSmall {
        /// The radius (px).
        r: f64,
        /// The smallest usable radius (px).
        min: f64,
    },
    /// The sampled annulus does not fit inside the image.
    #[error(
        "circle (cx={cx}, cy={cy}, r={r}) is outside the {width}×{height} image: the sampled annulus (up to {outer}·r) must lie inside it"
    )]
    OutsideImage {
        /// Centre's x (px).
        cx: f64,
        /// Centre's y (px).
        cy: f64,
        /// Radius (px).
        r: f64,
        /// The annulus's outer radius as a multiple of `r`.
        outer: f64,
        /// The image's width (px).
        width: usize,
        /// The image's height (px).
        height: usize,
    },
    /// A mask of another size than the image.
    #[error("mask is {mask_width}×{mask_height} but the image is {width}×{height}")]
    MaskSizeMismatch {
        /// The mask's width (px).
        mask_width: usize,
        /// The mask's height (px).
        mask_height: usize,
        /// The image's width (px).
        width: usize,
        /// The image's height (px).
        height: usize,
    },
    /// No pixel of the mask is set.
    #[error("mask is empty: no pixel is inside the sphere")]
    EmptyMask,
    /// The mask's edge is missing or only on the image's border.
    #[error("mask has no usable edge (it covers the whole image or touches only its border)")]
    NoMaskEdge,
    /// The mask's edge is too far from a circle.
    #[error("mask is not a disc: its edge is {rms:.2} px (RMS) from the best-fitting circle")]
    NotCircular {
        /// RMS distance of the edge from the best-fitting circle (px).
        rms: f64,
    },
    /// An object given by its normals is read as its equivalent sphere: it has no circle in
    /// the photograph to locate or unwrap.
    #[error(
        "the object is given by its normals: it has no circle in the photograph (classify it \
         instead)"
    )]
    ObjectByNormals,
    /// Each surface says what to do in its own words (fields, flags or the page's circle).
    #[error("could not find the sphere automatically: {reason}")]
    DetectionFailed {
        /// Why detection found no sphere.
        reason: String,
    },
}

/// Validate a circle for an image of `width × height`: finite, r ≥ 32, and the sampled
/// annulus (ρ ≤ outer·r) inside the image. Returns warnings for small spheres and for
/// spheres that extend beyond the frame.
pub fn validate(
    circle: &Circle,
    width: usize,
    height: usize,
    outer: f64,
    r0: f64,
) -> Result<Vec<String>, GeometryError> {
    check_alone(circle)?;
    let Circle { cx, cy, r } = *circle;
    let inside = |reach: f64| {
        cx - reach >= -0.5
            && cy - reach >= -0.5
            && cx + reach <= width as f64 - 0.5
            && cy + reach <= height as f64 - 0.5
    };
    if !inside(outer * r) {
        return Err(GeometryError::OutsideImage {
            cx,
            cy,
            r,
            outer,
            width,
            height,
        });
    }
    let mut warnings = Vec::new();
    if r < r0 {
        warnings.push(format!(
            "sphere radius {r:.1} px is below {r0} px: the image is upsampled and the finest scales are less reliable"
        ));
    }
    if !inside(r) {
        warnings.push(
            "the sphere extends beyond the image edge (the sampled annulus is inside)".into(),
        );
    }
    Ok(warnings)
}

/// Circle from optional `cx, cy, r` request values: all or none, finite, and not too
/// small (what can be checked before the image is seen; [`validate`] checks the rest).
pub fn given(
    cx: Option<f64>,
    cy: Option<f64>,
    r: Option<f64>,
) -> Result<Option<Geometry>, GeometryError> {
    match (cx, cy, r) {
        (Some(cx), Some(cy), Some(r)) => {
            let circle = Circle { cx, cy, r };
            check_alone(&circle)?;
            Ok(Some(Geometry::new(circle, Method::Given, None)))
        }
        (None, None, None) => Ok(None),
        _ => Err(GeometryError::Incomplete),
    }
}

/// A circle's own checks, whatever the image: finite, and a radius of at least
/// [`MIN_RADIUS`].
fn check_alone(circle: &Circle) -> Result<(), GeometryError> {
    let Circle { cx, cy, r } = *circle;
    if !(cx.is_finite() && cy.is_finite() && r.is_finite()) {
        return Err(GeometryError::NotFinite { cx, cy, r });
    }
    if r < MIN_RADIUS {
        return Err(GeometryError::TooSmall { r, min: MIN_RADIUS });
    }
    Ok(())
}

/// Find the sphere in a photograph ([`crate::locate::detect`]: table tops, scenes, JPEG), with the
/// circle a clean background gives ([`detect_clean`]) as one more candidate. The
/// confidence is the fraction of the rim with a clear edge on the circle.
pub fn detect(luminance: impl Plane) -> Result<Geometry, GeometryError> {
    detect_ranked(luminance).0
}

/// Alternatives below this confidence are not offered.
pub const ALTERNATIVE_CONFIDENCE: f64 = 0.3;

/// [`detect`]'s answer, and the distinct circles it weighed, most confident first, those
/// with a clear rim along at least [`ALTERNATIVE_CONFIDENCE`] of their circumference: what a
/// person may pick when the first is not the sphere.
pub fn detect_ranked(luminance: impl Plane) -> (Result<Geometry, GeometryError>, Vec<Geometry>) {
    let ranked = match candidates(luminance) {
        Ok(ranked) => ranked,
        Err(e) => return (Err(e), vec![]),
    };
    let chosen = detect::chosen(&ranked)
        .map(|found| Geometry::new(found.circle, Method::Auto, Some(found.confidence)))
        .map_err(|detect::NotFound(reason)| GeometryError::DetectionFailed { reason });
    let alternatives = ranked
        .iter()
        .filter(|f| f.confidence >= ALTERNATIVE_CONFIDENCE)
        .map(|f| Geometry::new(f.circle, Method::Auto, Some(f.confidence)))
        .collect();
    (chosen, alternatives)
}

/// Every distinct circle [`detect`] weighs, ranked (balls first, then by confidence), before
/// [`chosen_by`] takes one or refuses: what a measurement of the acceptance rule reads.
pub fn candidates(luminance: impl Plane) -> Result<Vec<Found>, GeometryError> {
    detect::find_spheres(luminance, |small| {
        detect_clean(small).ok().map(|g| g.circle())
    })
    .map_err(|detect::NotFound(reason)| GeometryError::DetectionFailed { reason })
}

/// The fraction of a circle's circumference inside a `width` × `height` image.
pub fn visible_rim(circle: &Circle, width: usize, height: usize) -> f64 {
    const STEPS: usize = 360;
    let inside = (0..STEPS)
        .filter(|&k| {
            let t = 2.0 * std::f64::consts::PI * k as f64 / STEPS as f64;
            let (x, y) = (
                circle.cx + circle.r * t.cos(),
                circle.cy + circle.r * t.sin(),
            );
            (-0.5..=width as f64 - 0.5).contains(&x) && (-0.5..=height as f64 - 0.5).contains(&y)
        })
        .count();
    inside as f64 / STEPS as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn disc(h: usize, w: usize, c: Circle) -> Array2<bool> {
        Array2::from_shape_fn((h, w), |(y, x)| {
            (x as f64 - c.cx).hypot(y as f64 - c.cy) <= c.r
        })
    }

    const C: Circle = Circle {
        cx: 101.3,
        cy: 96.8,
        r: 70.4,
    };

    #[test]
    fn validation_rules() {
        let v = |c: Circle| validate(&c, 200, 200, 0.9, 80.0);
        assert!(matches!(
            v(Circle { r: 31.9, ..C }),
            Err(GeometryError::TooSmall { .. })
        ));
        assert!(matches!(
            v(Circle { r: f64::NAN, ..C }),
            Err(GeometryError::NotFinite { .. })
        ));
        assert!(matches!(
            v(Circle { cx: 500.0, ..C }),
            Err(GeometryError::OutsideImage { .. })
        ));
        assert!(matches!(
            v(Circle { r: 1e9, ..C }),
            Err(GeometryError::OutsideImage { .. })
        ));
        assert!(matches!(
            v(Circle { r: -5.0, ..C }),
            Err(GeometryError::TooSmall { .. })
        ));
        // r = 70.4 < 80: accepted with a warning.
        assert_eq!(v(C).unwrap().len(), 1);
        // Annulus inside but the rim outside: accepted with a warning.
        let edge = Circle {
            cx: 60.0,
            cy: 100.0,
            r: 64.0,
        };
        let warnings = v(edge).unwrap();
        assert!(
            warnings.iter().any(|w| w.contains("beyond")),
            "{warnings:?}"
        );
        assert!(
            v(Circle {
                cx: 100.0,
                cy: 100.0,
                r: 99.0
            })
            .unwrap()
            .is_empty()
        );
    }

    #[test]
    fn partial_circle_parameters_are_refused() {
        assert_eq!(
            given(Some(1.0), None, Some(3.0)),
            Err(GeometryError::Incomplete)
        );
        assert_eq!(given(None, None, None), Ok(None));
    }

    #[test]
    fn mask_fit_recovers_the_circle() {
        let g = fit_mask(disc(200, 210, C).view(), Method::Mask).unwrap();
        assert!(
            (g.cx - C.cx).abs() < 0.1 && (g.cy - C.cy).abs() < 0.1,
            "{g:?}"
        );
        assert!((g.r - C.r).abs() < 0.15, "{g:?}");
    }

    #[test]
    fn bad_masks_are_refused() {
        let empty = Array2::from_elem((100, 100), false);
        assert_eq!(
            fit_mask(empty.view(), Method::Mask),
            Err(GeometryError::EmptyMask)
        );
        let full = Array2::from_elem((100, 100), true);
        assert_eq!(
            fit_mask(full.view(), Method::Mask),
            Err(GeometryError::NoMaskEdge)
        );
        let square = Array2::from_shape_fn((100, 100), |(y, x)| {
            (20..80).contains(&y) && (20..80).contains(&x)
        });
        assert!(matches!(
            fit_mask(square.view(), Method::Mask),
            Err(GeometryError::NotCircular { .. })
        ));
    }

    #[test]
    fn detection_on_a_dark_background() {
        let mask = disc(220, 230, C);
        // A shaded sphere with a dark patch touching nothing: detection must fill it.
        let img = Array2::from_shape_fn((220, 230), |(y, x)| {
            if !mask[[y, x]] {
                return 0.01;
            }
            let dark_patch = (x as f64 - 100.0).hypot(y as f64 - 90.0) < 15.0;
            if dark_patch {
                0.01
            } else {
                0.3 + 0.002 * x as f64
            }
        });
        let g = detect(img.view()).unwrap();
        assert!(
            (g.cx - C.cx).abs() < 0.3 && (g.cy - C.cy).abs() < 0.3 && (g.r - C.r).abs() < 0.5,
            "{g:?}"
        );
        assert!(g.confidence.unwrap() >= MIN_CONFIDENCE);
    }

    #[test]
    fn detection_refuses_noise_and_squares() {
        let mut state = 99u64;
        let noise = Array2::from_shape_fn((150, 150), |_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
            (state >> 40) as f64
        });
        assert!(matches!(
            detect(noise.view()),
            Err(GeometryError::DetectionFailed { .. })
        ));
        let square = Array2::from_shape_fn((150, 150), |(y, x)| {
            if (30..120).contains(&y) && (30..120).contains(&x) {
                1.0
            } else {
                0.0
            }
        });
        assert!(matches!(
            detect(square.view()),
            Err(GeometryError::DetectionFailed { .. })
        ));
        let flat = Array2::from_elem((150, 150), 0.5);
        assert!(matches!(
            detect(flat.view()),
            Err(GeometryError::DetectionFailed { .. })
        ));
    }
    /// A Lambertian-looking ball's luminance (brighter towards the top left) at (dx, dy) in
    /// units of its radius from its centre; None outside it.
    fn shade(dx: f64, dy: f64) -> Option<f64> {
        let d2 = dx * dx + dy * dy;
        (d2 <= 1.0).then(|| 0.05 + 0.6 * (0.5 * (-dx - dy) + 0.7 * (1.0 - d2).sqrt()).max(0.0))
    }

    /// The ball of `c` painted over `image`.
    fn shaded_ball(image: &mut Array2<f64>, c: &Circle) {
        for ((y, x), v) in image.indexed_iter_mut() {
            if let Some(value) = shade((x as f64 - c.cx) / c.r, (y as f64 - c.cy) / c.r) {
                *v = value;
            }
        }
    }

    fn paint_disc(image: &mut Array2<f64>, c: &Circle, level: f64) {
        for ((y, x), v) in image.indexed_iter_mut() {
            if (x as f64 - c.cx).hypot(y as f64 - c.cy) <= c.r {
                *v = level;
            }
        }
    }

    fn near(g: &Geometry, c: &Circle) -> bool {
        (g.cx - c.cx).hypot(g.cy - c.cy) <= 0.02 * c.r && (g.r - c.r).abs() <= 0.02 * c.r
    }

    #[test]
    fn a_ball_cut_by_the_frame_is_judged_on_the_arc_that_shows() {
        // A fifth of the rim beyond the right-hand edge: judged on the rest, as if whole;
        // nearly a third: found, what is outside beyond a quarter counted as missing.
        for (cx, seen_range, confidence_range) in
            [(307.0, 0.75..0.85, 0.8..1.01), (330.0, 0.6..0.75, 0.5..0.9)]
        {
            let ball = Circle {
                cx,
                cy: 150.0,
                r: 90.0,
            };
            let mut image = Array2::from_elem((300, 380), 0.4);
            shaded_ball(&mut image, &ball);
            let g = detect(image.view()).unwrap();
            assert!(near(&g, &ball), "{g:?}");
            assert!(confidence_range.contains(&g.confidence.unwrap()), "{g:?}");
            let seen = visible_rim(&g.circle(), 380, 300);
            assert!(seen_range.contains(&seen), "{seen}");
        }
    }

    #[test]
    fn balls_come_before_flat_discs_and_rings() {
        let ball = Circle {
            cx: 420.0,
            cy: 150.0,
            r: 70.0,
        };
        let plate = Circle {
            cx: 130.0,
            cy: 150.0,
            r: 80.0,
        };
        for ring in [false, true] {
            let mut image = Array2::from_elem((300, 560), 0.3);
            paint_disc(&mut image, &plate, 0.8);
            if ring {
                paint_disc(&mut image, &Circle { r: 64.0, ..plate }, 0.3);
            }
            shaded_ball(&mut image, &ball);
            let (chosen, ranked) = detect_ranked(image.view());
            let chosen = chosen.unwrap();
            assert!(near(&chosen, &ball), "ring {ring}: {chosen:?}");
            // The plate is still offered, after the ball.
            assert!(ranked.iter().skip(1).any(|g| near(g, &plate)), "{ranked:?}");
        }
    }
    /// A `w`×`h` picture of `ball` drawn `stretch` times longer along (ux, uy), on a checkered
    /// background.
    fn stretched_ball(
        (w, h): (usize, usize),
        ball: &Circle,
        (ux, uy): (f64, f64),
        stretch: f64,
    ) -> Array2<f64> {
        Array2::from_shape_fn((h, w), |(y, x)| {
            let (px, py) = (x as f64 - ball.cx, y as f64 - ball.cy);
            let along = (px * ux + py * uy) / stretch;
            let across = -px * uy + py * ux;
            shade(
                (along * ux - across * uy) / ball.r,
                (along * uy + across * ux) / ball.r,
            )
            .unwrap_or(0.4 + 0.05 * ((x / 40 + y / 40) % 2) as f64)
        })
    }

    /// Found by its centre and shortest radius, its rim clear along at least `confidence`.
    fn assert_found_by_centre(g: &Geometry, ball: &Circle, confidence: f64) {
        assert!(
            (g.cx - ball.cx).hypot(g.cy - ball.cy) <= 0.02 * ball.r,
            "{g:?}"
        );
        assert!((0.98 * ball.r..=1.02 * ball.r).contains(&g.r), "{g:?}");
        assert!(g.confidence.unwrap() >= confidence, "{g:?}");
    }

    #[test]
    fn a_ball_off_the_lens_axis_is_found_by_its_centre() {
        // Drawn 1.12 times longer away from the picture's centre, as a wide lens draws a ball
        // near its corner: the centre, and the shortest radius.
        let ball = Circle {
            cx: 1010.0,
            cy: 730.0,
            r: 80.0,
        };
        let (dx, dy) = (ball.cx - 599.5, ball.cy - 449.5);
        let along = (dx / dx.hypot(dy), dy / dx.hypot(dy));
        let image = stretched_ball((1200, 900), &ball, along, 1.12);
        assert_found_by_centre(&detect(image.view()).unwrap(), &ball, 0.6);
    }

    #[test]
    fn a_ball_in_an_unevenly_rescaled_crop_is_found_by_its_centre() {
        // At the picture's centre, where no lens stretches it, 5 % longer one way: a crop
        // rescaled to a square, the dev set's tight crops (docs/accuracy.md).
        let ball = Circle {
            cx: 200.0,
            cy: 195.0,
            r: 170.0,
        };
        for along in [(1.0, 0.0), (0.0, 1.0), (0.6, 0.8)] {
            let image = stretched_ball((400, 390), &ball, along, 1.05);
            assert_found_by_centre(&detect(image.view()).unwrap(), &ball, 0.7);
        }
    }
}
