//! Finding a sphere in a photograph: on a table top, in front of a scene, in a JPEG.
//!
//! 1. **Candidates** (on a copy at most [`WORK_SIZE`] px across, gamma-encoded so that
//!    edges in the shadows count as much as in the light, lightly smoothed against noise
//!    and JPEG blocks): Sobel gradients, thinned to their ridges; every edge point votes for
//!    the centres along its gradient line, on both sides and at every radius up to 0.6 of
//!    the shorter side (a sphere can be brighter than its background on one side and darker
//!    on the other; it can fill the frame), in cells that grow with the radius (a ball drawn
//!    a few percent elongated spreads its votes over as much); the strongest peaks are
//!    candidate centres, and each takes the radius at which the most of its circumference
//!    has an edge pointing at it ([`vote`]). In a photograph over twice [`WORK_SIZE`] across,
//!    the vote again on a copy twice as large for radii under a tenth of its shorter side (a
//!    ball of r 190 px in a 4096 px room is 29 px on the small copy), unless the first
//!    search has [`SETTLED`] on a ball. The circle a clean
//!    background gives (the caller's segmentation, on the same copy) is one more.
//! 2. **Sub-pixel fit** (a wide first fit on the reduced copy when the circle is large there,
//!    the narrow one on the full-resolution linear image): along 360 rays through the
//!    candidate's rim, the position of the steepest luminance change, interpolated between
//!    samples, kept where the luminance there changes across the rim rather than along it;
//!    a circle fitted to those positions with outliers (highlights and shadows near the
//!    rim, gaps in the contrast) down-weighted; twice, with a narrower window. The most
//!    confident are fitted again as a lens draws a ball off its axis (an outline longer away
//!    from the picture's centre, by what the widest lens allows there), or as an unevenly
//!    rescaled crop does (up to [`ANY_ELONGATION`] longer, any way), kept when that puts a
//!    clear edge under more of the rim; the circle reported is its centre and shortest radius.
//! 3. **Confidence**: the fraction of the rim inside the frame along which a clear edge lies
//!    on the fitted circle (a ball cut by the frame's edge is judged on the arc that shows
//!    when at least three quarters of it show; beyond, what is outside counts as missing).
//! 4. **Ranking**: balls before flat round things, then by confidence. A disc whose inside is
//!    flat (a plate, a coin, a sticker: no shading) or that has a second circle around or
//!    inside it at the same centre and a flat band between (a ring, a bezel, a plate's rim)
//!    is not a ball. The first candidate with confidence ≥ 0.5 is taken, or a ball ranked
//!    first at ≥ 0.4 whose runner-up is at most three quarters as confident (circles of
//!    radius under 57 px count for less, in proportion to their circumference: their rim
//!    is sampled on fewer distinct pixels; circles inside the first are its reflections, not
//!    runners-up).

pub(crate) mod clean;
mod vote;

use crate::image::circle::Circle;
use crate::image::plane::Plane;
use crate::locate::MIN_RADIUS;
use crate::util::parallel::{self, map_in_parts};
use ndarray::{Array2, ArrayView2};
use vote::{Edge, edge_points, rim_coverage, rough_circles};

/// The candidate search runs on a copy at most this many pixels across.
pub const WORK_SIZE: usize = 640;
/// Rays along the rim of a candidate.
const RAYS: usize = 360;
/// [`Acceptance::confidence`] as the service uses it.
pub const MIN_CONFIDENCE: f64 = 0.5;
/// A circle with less of its rim inside the frame is not judged.
pub const MIN_VISIBLE: f64 = 0.5;
/// A ball may have this much of its rim inside the frame and be judged as if it were whole;
/// below, what is outside counts as missing (half an arc is too weak a hint on its own).
const UNCUT: f64 = 0.75;

/// A circle found, the fraction of its visible rim with a clear edge on it, and whether it
/// looks like a ball rather than a flat round thing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found {
    /// The circle (the outline's mean circle when it was fitted elongated).
    pub circle: Circle,
    /// The share of its visible rim with a clear edge on it.
    pub confidence: f64,
    /// Neither flat inside nor ringed by a concentric circle with a flat band between.
    pub ball_like: bool,
}

/// Why no sphere was found: a sentence for the user.
#[derive(Clone, Debug, PartialEq)]
pub struct NotFound(pub String);

/// The thresholds by which [`chosen`] takes a circle or refuses: tuned on the development
/// photographs, a value so that a measurement can choose them without the source it judges
/// (tests/numerics/real_photos.rs, leave one source out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Acceptance {
    /// Any circle is taken from this confidence.
    pub confidence: f64,
    /// A ball whose rim shows only in part (a mirror ball reflecting what surrounds it, a
    /// point-lit ball in the dark) is taken from this evidence when no other circle comes near.
    pub alone: f64,
    /// ... near: a rival's evidence is at most this fraction of the first's.
    pub runner_up_share: f64,
}

/// The thresholds the service uses.
pub const ACCEPTANCE: Acceptance = Acceptance {
    confidence: MIN_CONFIDENCE,
    alone: MIN_CONFIDENCE_ALONE,
    runner_up_share: RUNNER_UP_SHARE,
};

/// The first of the ranked circles that is confident enough, else why not.
pub fn chosen(ranked: &[Found]) -> Result<Found, NotFound> {
    chosen_by(ranked, &ACCEPTANCE)
}

/// [`chosen`] by the thresholds of `acceptance`.
pub fn chosen_by(ranked: &[Found], acceptance: &Acceptance) -> Result<Found, NotFound> {
    if let Some(found) = ranked
        .iter()
        .find(|f| f.confidence >= acceptance.confidence)
    {
        return Ok(enclosing_ball(found, ranked, acceptance).unwrap_or(*found));
    }
    if let [first, rest @ ..] = ranked
        && stands_alone(first, rest, acceptance)
    {
        return Ok(*first);
    }
    match ranked.first() {
        Some(found) => Err(NotFound(format!(
            "the roundest edge found (centre {:.0}, {:.0}, radius {:.0}) has a clear rim along \
             only {:.0} % of its circumference",
            found.circle.cx,
            found.circle.cy,
            found.circle.r,
            100.0 * found.confidence
        ))),
        None => Err(NotFound("no round edge stands out".into())),
    }
}

/// [`Acceptance::alone`] as the service uses it.
pub const MIN_CONFIDENCE_ALONE: f64 = 0.4;
/// [`Acceptance::runner_up_share`] as the service uses it.
const RUNNER_UP_SHARE: f64 = 0.75;

/// A circle mostly inside the first (its centre's distance plus its radius within this many
/// of the first's radii) is no rival: in a mirror ball, round reflections.
const INSIDE: f64 = 1.1;

/// Whether `first` (ranked first) is a ball, confident enough, with no rival among `rest`.
/// Both are weighed by [`evidence`]; circles inside the first are not rivals.
fn stands_alone(first: &Found, rest: &[Found], acceptance: &Acceptance) -> bool {
    let f = &first.circle;
    let inside = |c: &Circle| (c.cx - f.cx).hypot(c.cy - f.cy) + c.r <= INSIDE * f.r;
    first.ball_like
        && evidence(first) >= acceptance.alone
        && rest.iter().all(|other| {
            inside(&other.circle) || evidence(other) <= acceptance.runner_up_share * evidence(first)
        })
}

/// A ball 1.5 to 3 times the radius of a circle inside it is what that circle belongs to (a
/// billiard ball's printed disc, a mirror ball's round reflections); a circle many times
/// larger is more often a chance arc around a small ball (wood grain, a room's corners).
const ENCLOSING: std::ops::RangeInclusive<f64> = 1.5..=3.0;

/// The ball `found` lies inside, if one was found with the evidence a lone ball needs
/// ([`Acceptance::alone`]): the most confident such ball.
fn enclosing_ball(found: &Found, ranked: &[Found], acceptance: &Acceptance) -> Option<Found> {
    let f = &found.circle;
    ranked
        .iter()
        .filter(|outer| {
            let o = &outer.circle;
            outer.ball_like
                && ENCLOSING.contains(&(o.r / f.r))
                && (o.cx - f.cx).hypot(o.cy - f.cy) + f.r <= INSIDE * o.r
                && evidence(outer) >= acceptance.alone
        })
        .max_by(|a, b| a.confidence.total_cmp(&b.confidence))
        .copied()
}

/// A circle's confidence, less for a circle whose circumference is shorter than [`RAYS`]
/// pixels: its rays sample the same few pixels of the rim, and chance edges (texture, noise)
/// cover a larger share of it (on real photographs, rivals and wrong answers at r 32–47 px
/// reach 0.34–0.43 where the balls' own rims, 200–500 px, reach 0.40).
fn evidence(found: &Found) -> f64 {
    let circumference = std::f64::consts::TAU * found.circle.r;
    found.confidence * (circumference / RAYS as f64).min(1.0)
}

/// Two circles that find the same sphere: centres within a fifth of the radius, radii within
/// a fifth of each other.
fn same_sphere(a: &Circle, b: &Circle) -> bool {
    let r = a.r.max(b.r);
    (a.cx - b.cx).hypot(a.cy - b.cy) < 0.2 * r && (a.r - b.r).abs() < 0.2 * r
}

/// Every distinct circle the search finds in `luminance` (linear), refined, ranked (balls
/// first, then by confidence; [`chosen`] says which is taken). The circle `clean` finds on
/// the reduced copy (a segmentation of a clean background) is examined with the candidates.
pub fn find_spheres(
    luminance: impl Plane,
    clean: impl Fn(ArrayView2<f64>) -> Option<Circle>,
) -> Result<Vec<Found>, NotFound> {
    let (h, w) = luminance.size();
    if h < 2 * MIN_RADIUS as usize || w < 2 * MIN_RADIUS as usize {
        return Err(NotFound(format!(
            "the image ({w}×{h}) is too small to hold a sphere"
        )));
    }
    let (small, scale) = reduced(luminance);
    let clean = clean(small.view()).map(|c| (c.enlarged(scale), 2.0 / scale));
    let (work, norm) = working_copy(small.view());
    let edges = edge_points(work.view());
    if edges.len() < 32 {
        return Err(NotFound("the image has almost no edges".into()));
    }
    let min_r = (MIN_RADIUS * scale).max(6.0);
    let (wh, ww) = work.dim();
    // A ball that fills the frame may be cut by it.
    let max_r = 0.6 * wh.min(ww) as f64;
    if max_r <= min_r {
        return Err(NotFound("the image is too small to hold a sphere".into()));
    }
    let mut candidates: Vec<(Circle, f64)> = clean.into_iter().collect();
    candidates.extend(rough_circles(&edges, (wh, ww), scale, (min_r, max_r)));
    let refined = |candidates| refine_all(luminance, (small.view(), scale), candidates);
    let working = Working {
        image: work.view(),
        edges: &edges,
        scale,
        norm,
    };
    let rank = |found: Vec<Found>| ranked(luminance, found, &working);
    let mut found = refined(candidates);
    if scale < 0.5 {
        let first = rank(found.clone());
        if first.first().is_some_and(settled) {
            return Ok(first);
        }
        found.extend(refined(small_balls(luminance)));
    }
    Ok(rank(found))
}

/// A ball found with a clear edge along this share of its rim needs no search for a smaller
/// one: a small ball would have to show a clearer rim to be ranked above it.
const SETTLED: f64 = 0.8;

/// Whether `first`, ranked first by the search on the working copy, makes the search for
/// small balls needless.
fn settled(first: &Found) -> bool {
    first.ball_like && first.confidence >= SETTLED
}

/// The working copy of a search, its edges, its scale and the factor that normalized it.
struct Working<'a> {
    image: ArrayView2<'a, f64>,
    edges: &'a [Edge],
    scale: f64,
    norm: f64,
}

/// `found` as distinct circles, the most confident tried as elongated outlines, judged for
/// ball-likeness ([`judge_ball_likeness`]), balls first, then by confidence.
fn ranked(luminance: impl Plane, found: Vec<Found>, working: &Working) -> Vec<Found> {
    let mut distinct = distinct_circles(found);
    // A sphere off the lens's axis, among the most confident: as the lens draws it.
    for f in distinct.iter_mut().take(ELONGATE_FIRST) {
        if let Some(better) = elongated(luminance, f) {
            *f = better;
        }
    }
    let mut distinct = distinct_circles(distinct);
    judge_ball_likeness(&mut distinct, luminance, working);
    distinct.sort_by(|a, b| {
        (b.ball_like, b.confidence)
            .partial_cmp(&(a.ball_like, a.confidence))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    distinct
}

/// The most confident of each group of circles that find the same sphere, most confident first.
fn distinct_circles(mut found: Vec<Found>) -> Vec<Found> {
    found.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
    let mut distinct: Vec<Found> = Vec::new();
    for f in found {
        if !distinct.iter().any(|d| same_sphere(&d.circle, &f.circle)) {
            distinct.push(f);
        }
    }
    distinct
}

/// Mark the circles that are not balls: a flat inside, or a concentric circle with a flat
/// band between them.
fn judge_ball_likeness(found: &mut [Found], luminance: impl Plane, working: &Working) {
    for f in found.iter_mut() {
        let on_work = f.circle.reduced(working.scale);
        f.ball_like = if on_work.r >= SMALL_ON_WORK || working.scale >= 1.0 {
            ball_like(working.image, working.edges, &on_work)
        } else {
            let (around, circle) = surroundings(luminance, &f.circle, working.norm);
            ball_like(around.view(), &edge_points(around.view()), &circle)
        };
    }
}

/// A circle under this radius on the working copy is judged on a copy of its surroundings:
/// on the working copy a plate's rim band is a pixel or two wide ...
const SMALL_ON_WORK: f64 = 32.0;
/// ... in which its radius is at most this.
const JUDGED_RADIUS: f64 = 64.0;

/// Neither flat inside nor ringed, on a working copy (`image`, its `edges`).
fn ball_like(image: ArrayView2<f64>, edges: &[Edge], circle: &Circle) -> bool {
    !flat_band(image, circle, 0.0, 0.8) && !ringed(image, edges, circle)
}

/// A working copy of `circle`'s surroundings in `luminance` (to 1.8 r, as far as [`ringed`]
/// looks), reduced so that its radius there is at most [`JUDGED_RADIUS`], in the units `norm`
/// gives; and the circle on it.
fn surroundings(luminance: impl Plane, circle: &Circle, norm: f64) -> (Array2<f64>, Circle) {
    let (h, w) = luminance.size();
    let reach = 1.8 * circle.r;
    let span = |centre: f64, n: usize| {
        let lo = (centre - reach).floor().clamp(0.0, n as f64) as usize;
        let hi = ((centre + reach).ceil().clamp(0.0, n as f64) as usize).max(lo);
        lo..hi
    };
    let (rows, cols) = (span(circle.cy, h), span(circle.cx, w));
    let factor = (JUDGED_RADIUS / circle.r).min(1.0);
    let shifted = Circle {
        cx: circle.cx - cols.start as f64,
        cy: circle.cy - rows.start as f64,
        r: circle.r,
    };
    let small = luminance.part(rows, cols, factor);
    (encoded(small.view(), norm), shifted.reduced(factor))
}

/// A second circle, inside or around a circle at its centre (0.5–1.6 r), with an edge along
/// more than this share of it, and a flat band between the two, makes a ring: a plate's rim,
/// a bezel, a washer. (A mirror ball's reflections can be concentric circles too, but what
/// lies between them is a reflection, not flat.)
const RING_COVERAGE: u32 = 54;

/// Whether the working copy's edges draw a ring with `circle` (working coordinates).
fn ringed(work: ArrayView2<f64>, edges: &[Edge], circle: &Circle) -> bool {
    let Circle { cx, cy, r } = *circle;
    let coverage = rim_coverage(edges, cx, cy, 0.5 * r, 1.6 * r);
    let own = (0.07 * r).max(2.0);
    ((0.5 * r).floor() as usize..=(1.6 * r).ceil() as usize)
        .filter(|&d| (d as f64 - r).abs() > own && coverage(d) >= RING_COVERAGE)
        .any(|d| {
            let ratio = d as f64 / r;
            // The band between the circles, a little inside both edges.
            let (inner, outer) = (ratio.min(1.0), ratio.max(1.0));
            let margin = 0.25 * (outer - inner);
            flat_band(work, circle, inner + margin, outer - margin)
        })
}

/// Spread (10th to 90th percentile) below which a region, gamma-encoded in units of the
/// picture's 99th percentile and smoothed, is flat: a ball's shading and reflections spread
/// wider, even a black one's.
const FLAT_SPREAD: f64 = 0.04;

/// Whether the band from `inner` to `outer` radii of `circle` (working coordinates) is flat.
fn flat_band(work: ArrayView2<f64>, circle: &Circle, inner: f64, outer: f64) -> bool {
    let (h, w) = work.dim();
    let Circle { cx, cy, r } = *circle;
    let (near, far) = (inner * r, outer * r);
    let rows = (cy - far).max(0.0) as usize..((cy + far).ceil().max(0.0) as usize).min(h);
    let cols = (cx - far).max(0.0) as usize..((cx + far).ceil().max(0.0) as usize).min(w);
    // Every pixel of a small band; of a large one, a grid of about 128 across.
    let stride = ((far / 64.0).ceil() as usize).max(1);
    let mut band: Vec<f64> = Vec::new();
    let (near2, far2) = (near * near, far * far);
    for y in rows.step_by(stride) {
        for x in cols.clone().step_by(stride) {
            let (dx, dy) = (x as f64 - cx, y as f64 - cy);
            if (near2..=far2).contains(&(dx * dx + dy * dy)) {
                band.push(work[[y, x]]);
            }
        }
    }
    if band.len() < 16 {
        return false;
    }
    let high = quantile(band.clone(), 0.9);
    high - quantile(band, 0.1) < FLAT_SPREAD
}

/// Small balls in a large photograph (under a tenth of the shorter side): the vote again on a
/// copy twice [`WORK_SIZE`] across, where they are twice as many pixels across.
fn small_balls(luminance: impl Plane) -> Vec<(Circle, f64)> {
    let (small, scale) = reduced_to(luminance, 2 * WORK_SIZE);
    let (work, _) = working_copy_of(small);
    let edges = edge_points(work.view());
    let (wh, ww) = work.dim();
    let min_r = (MIN_RADIUS * scale).max(6.0);
    let max_r = 0.1 * wh.min(ww) as f64;
    if edges.len() < 32 || max_r <= min_r {
        return Vec::new();
    }
    rough_circles(&edges, (wh, ww), scale, (min_r, max_r))
}

/// A copy at most [`WORK_SIZE`] across, and its scale.
fn reduced(luminance: impl Plane) -> (Array2<f64>, f64) {
    reduced_to(luminance, WORK_SIZE)
}

/// A copy at most `size` across, and its scale.
fn reduced_to(luminance: impl Plane, size: usize) -> (Array2<f64>, f64) {
    let (h, w) = luminance.size();
    let scale = (size as f64 / h.max(w) as f64).min(1.0);
    (luminance.part(0..h, 0..w, scale), scale)
}

/// `small` gamma-encoded (so that edges in the shadows count as much as in the light) in
/// units of its 99th percentile, and smoothed (σ = 1 px); and the factor to those units.
fn working_copy(small: ArrayView2<f64>) -> (Array2<f64>, f64) {
    let norm = p99_norm(small);
    (encoded(small, norm), norm)
}

/// [`working_copy`] made from `small` itself (it is not needed after).
fn working_copy_of(small: Array2<f64>) -> (Array2<f64>, f64) {
    let norm = p99_norm(small.view());
    (encoded_from(small, norm), norm)
}

/// The factor that puts the 99th percentile of `small` at 1 (1 for a black copy).
fn p99_norm(small: ArrayView2<f64>) -> f64 {
    let p99 = quantile(small.iter().copied().collect(), 0.99);
    if p99 > 0.0 { 1.0 / p99 } else { 1.0 }
}

/// A linear value times `norm`, clamped and gamma-encoded as the working copies are.
fn gamma_encoded(v: f64, norm: f64) -> f64 {
    (v * norm).clamp(0.0, 4.0).powf(1.0 / 2.2)
}

/// `image` times `norm`, gamma-encoded and smoothed as [`working_copy`] makes it.
fn encoded(image: ArrayView2<f64>, norm: f64) -> Array2<f64> {
    encoded_from(image.to_owned(), norm)
}

/// [`encoded`] made from `image` itself; a large one in bands, one per core.
fn encoded_from(mut image: Array2<f64>, norm: f64) -> Array2<f64> {
    let parts = parallel::parts_for(image.len());
    match image.as_slice_mut() {
        Some(values) => parallel::update_in_parts(parts, values, |v| gamma_encoded(v, norm)),
        None => image.mapv_inplace(|v| gamma_encoded(v, norm)),
    }
    crate::image::blur::gaussian_blur_in_parts(image.view(), 1.0, parts)
}

/// The `q` quantile of non-empty `values`.
fn quantile(mut values: Vec<f64>, q: f64) -> f64 {
    let k = ((values.len() as f64 * q) as usize).min(values.len().saturating_sub(1));
    let (_, v, _) = values.select_nth_unstable_by(k, f64::total_cmp);
    *v
}

/// Bilinear sample of the image at (x, y) (clamped to the image).
fn sample(image: impl Plane, x: f64, y: f64) -> f64 {
    let (h, w) = image.size();
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    // Truncation is the floor of the clamped, non-negative coordinates (and no libm call).
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let top = image.value(y0, x0) * (1.0 - fx) + image.value(y0, x1) * fx;
    let bottom = image.value(y1, x0) * (1.0 - fx) + image.value(y1, x1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The length of (dx, dy): `hypot` without its guard against overflow, which distances in
/// an image never reach, and at a fraction of its cost in the search's inner loops.
#[inline]
pub(super) fn length(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

/// Spacing (px) of the samples along a ray through a rim.
pub(crate) const RIM_STEP: f64 = 0.25;

/// How slopes along a ray are taken: over `base` samples spaced `step` px.
#[derive(Clone, Copy)]
struct Slopes {
    step: f64,
    base: usize,
}

/// A sharp rim's slopes: over one pixel, every [`RIM_STEP`].
const SHARP: Slopes = Slopes {
    step: RIM_STEP,
    base: 4,
};

impl Slopes {
    /// The slopes of a rim whose edge is `width` px wide: over its width, sampled finely
    /// enough to place it to a sixteenth of it (and never coarser than [`RIM_STEP`]).
    fn over(width: f64) -> Slopes {
        let step = (width / 16.0).max(RIM_STEP);
        Slopes {
            step,
            base: (width / step) as usize,
        }
    }

    /// The length (px) a slope spans.
    fn span(self) -> f64 {
        self.base as f64 * self.step
    }
}

/// The luminance sampled `n` times every `step` px along the ray at angle `theta` through
/// the rim of `circle`, from `window` px inside it outwards.
fn ray_profile(
    image: impl Plane,
    circle: &Circle,
    theta: f64,
    window: f64,
    step: f64,
    n: usize,
) -> Vec<f64> {
    let (ux, uy) = (theta.cos(), theta.sin());
    (0..n)
        .map(|s| {
            let d = circle.r - window + s as f64 * step;
            sample(image, circle.cx + d * ux, circle.cy + d * uy)
        })
        .collect()
}

/// The luminance slopes along one ray through a rim, and the steepest of them.
pub(crate) struct RimSlopes {
    /// Over one pixel, every [`RIM_STEP`], starting `window` px inside the rim.
    pub slope: Vec<f64>,
    pub steepest: usize,
    /// The steepest slope's magnitude.
    pub peak: f64,
}

/// [`RimSlopes`] of `steps` samples along the ray at angle `theta` through the rim of
/// `circle`, from `window` px inside it outwards.
pub(crate) fn rim_slopes(
    image: impl Plane,
    circle: &Circle,
    theta: f64,
    window: f64,
    steps: usize,
) -> Option<RimSlopes> {
    rim_slopes_over(image, circle, theta, window, steps, SHARP)
}

/// [`rim_slopes`] with slopes taken as `slopes` says.
fn rim_slopes_over(
    image: impl Plane,
    circle: &Circle,
    theta: f64,
    window: f64,
    steps: usize,
    slopes: Slopes,
) -> Option<RimSlopes> {
    let base = slopes.base;
    let profile = ray_profile(image, circle, theta, window, slopes.step, steps + base);
    let slope: Vec<f64> = profile.windows(base + 1).map(|p| p[base] - p[0]).collect();
    let (steepest, peak) = slope
        .iter()
        .enumerate()
        .map(|(i, v)| (i, v.abs()))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    Some(RimSlopes {
        slope,
        steepest,
        peak,
    })
}

/// Where along each ray through the rim of `circle` the luminance changes fastest, within
/// `window` px of the rim: (x, y, contrast) per ray that has a clear edge. Slopes are taken
/// over one pixel every quarter pixel, and the steepest is interpolated between samples:
/// for a step blurred by any symmetric lens, the step itself.
fn rim_points(image: impl Plane, outline: &Outline, window: f64) -> Vec<(f64, f64, f64)> {
    rim_points_over(image, outline, window, SHARP)
}

/// [`rim_points`] with slopes taken as `slopes` says (a blurred rim's edge spans more than
/// a pixel).
fn rim_points_over(
    image: impl Plane,
    outline: &Outline,
    window: f64,
    slopes: Slopes,
) -> Vec<(f64, f64, f64)> {
    let steps = (2.0 * window / slopes.step).ceil() as usize + 1;
    let mut out = Vec::with_capacity(RAYS);
    for k in 0..RAYS {
        let theta = std::f64::consts::TAU * k as f64 / RAYS as f64;
        let (ux, uy) = (theta.cos(), theta.sin());
        let circle = &outline.circle_at(theta);
        let rho = |s: f64| circle.r - window + s * slopes.step;
        let Some(RimSlopes {
            slope,
            steepest: i,
            peak,
        }) = rim_slopes_over(image, circle, theta, window, steps, slopes)
        else {
            continue;
        };
        if peak <= 0.0 {
            continue;
        }
        // Parabolic interpolation of the peak between samples.
        let magnitude = |j: usize| slope[j].abs();
        let offset = if i > 0 && i + 1 < slope.len() {
            let (a, c) = (magnitude(i - 1), magnitude(i + 1));
            let denominator = a - 2.0 * peak + c;
            if denominator < 0.0 {
                (0.5 * (a - c) / denominator).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        } else {
            0.0
        };
        let at = rho(i as f64 + offset + slopes.base as f64 / 2.0);
        let (x, y) = (circle.cx + at * ux, circle.cy + at * uy);
        if radial(image, x, y, ux, uy) {
            out.push((x, y, peak));
        }
    }
    // A clear edge: at least a third of the median ray's.
    let mut contrasts: Vec<f64> = out.iter().map(|p| p.2).collect();
    if contrasts.is_empty() {
        return out;
    }
    let mid = contrasts.len() / 2;
    let (_, median, _) = contrasts.select_nth_unstable_by(mid, f64::total_cmp);
    let floor = *median / 3.0;
    out.retain(|p| p.2 > floor);
    out
}

/// Whether the luminance at (x, y) changes mostly along the direction (ux, uy): a rim's
/// edge runs along the circle; a texture's edges (wood grain, a tiled floor) run every way.
fn radial(image: impl Plane, x: f64, y: f64, ux: f64, uy: f64) -> bool {
    let gx = sample(image, x + 1.5, y) - sample(image, x - 1.5, y);
    let gy = sample(image, x, y + 1.5) - sample(image, x, y - 1.5);
    let magnitude = length(gx, gy);
    magnitude > 0.0 && (gx * ux + gy * uy).abs() >= MIN_RADIAL_ALIGNMENT * magnitude
}

/// The cosine of the largest angle between a rim's gradient and the ray through it (about 40°).
const MIN_RADIAL_ALIGNMENT: f64 = 0.75;

/// One Gauss-Newton step of a robust fit to rim points (x, y, contrast): `residual` gives a
/// point's distance residual and its derivatives by the parameters (None to pass the point
/// by); points count by their contrast and Tukey's biweight at `tolerance` px. None when
/// fewer than an eighth of the rays count, or the equations are singular.
fn biweight_step<const N: usize>(
    points: &[(f64, f64, f64)],
    tolerance: f64,
    residual: impl Fn(f64, f64) -> Option<([f64; N], f64)>,
) -> Option<[f64; N]> {
    let mut a = [[0.0f64; N]; N];
    let mut b = [0.0f64; N];
    let mut used = 0usize;
    for &(x, y, contrast) in points {
        let Some((j, e)) = residual(x, y) else {
            continue;
        };
        let u = e / (2.0 * tolerance);
        if u.abs() >= 1.0 {
            continue;
        }
        let w = contrast * (1.0 - u * u).powi(2);
        for p in 0..N {
            for q in 0..N {
                a[p][q] += w * j[p] * j[q];
            }
            b[p] += w * j[p] * e;
        }
        used += 1;
    }
    if used < RAYS / 8 {
        return None;
    }
    crate::image::circle::solve(a, b)
}

/// Fit a circle to rim points (x, y, contrast): a geometric least-squares fit weighted by
/// contrast, with Tukey's biweight on the distances to the circle so that points off the
/// rim (highlights, shadows, clutter) stop counting; from `start`.
fn robust_fit(points: &[(f64, f64, f64)], start: &Circle) -> Option<Circle> {
    if points.len() < RAYS / 8 {
        return None;
    }
    let mut c = *start;
    for round in 0..8 {
        let tolerance = if round < 2 { 3.0 } else { 1.5 } * (0.01 * c.r).max(1.0);
        let [dcx, dcy, dr] = biweight_step(points, tolerance, |x, y| {
            let (dx, dy) = (x - c.cx, y - c.cy);
            let d = length(dx, dy);
            (d > 0.0).then(|| ([dx / d, dy / d, 1.0], d - c.r))
        })?;
        c = Circle {
            cx: c.cx + dcx,
            cy: c.cy + dcy,
            r: c.r + dr,
        };
        if !(c.r.is_finite() && c.r > 0.0) {
            return None;
        }
        if dcx.abs() + dcy.abs() + dr.abs() < 1e-3 && round >= 2 {
            break;
        }
    }
    Some(c)
}

/// A sphere's outline as a lens draws it: a circle, or, seen off the lens's axis, a slightly
/// elongated one. Radius `r0 + a cos 2θ + b sin 2θ` around (cx, cy): an ellipse to first order
/// in its elongation.
#[derive(Clone, Copy, Debug)]
struct Outline {
    cx: f64,
    cy: f64,
    r0: f64,
    a: f64,
    b: f64,
}

/// An outline longer than this (over r0) one way than the other is not a sphere's (a lens
/// 65° across draws a ball in its corner about 1.25 times longer).
const MAX_ELONGATION: f64 = 0.12;

impl Outline {
    fn of(c: &Circle) -> Self {
        Outline {
            cx: c.cx,
            cy: c.cy,
            r0: c.r,
            a: 0.0,
            b: 0.0,
        }
    }

    fn radius_at(&self, theta: f64) -> f64 {
        self.r0 + self.a * (2.0 * theta).cos() + self.b * (2.0 * theta).sin()
    }

    /// The circle through the outline's point at `theta`, around its centre.
    fn circle_at(&self, theta: f64) -> Circle {
        Circle {
            cx: self.cx,
            cy: self.cy,
            r: self.radius_at(theta),
        }
    }

    fn elongation(&self) -> f64 {
        self.a.hypot(self.b)
    }

    /// The circle that stands for it: its centre and its shortest radius, so that the annulus
    /// sampled stays on the sphere.
    fn circle(&self) -> Circle {
        Circle {
            cx: self.cx,
            cy: self.cy,
            r: self.r0 - self.elongation(),
        }
    }
}

/// Fit an outline to rim points (x, y, contrast) from `start`: the distances from the centre
/// against their angle, least squares weighted by contrast with Tukey's biweight, narrowing.
fn fit_outline(points: &[(f64, f64, f64)], start: &Outline) -> Option<Outline> {
    if points.len() < RAYS / 8 {
        return None;
    }
    let mut o = *start;
    for round in 0..10 {
        let share = match round {
            0 | 1 => 0.08,
            2 | 3 => 0.03,
            _ => 0.015,
        };
        let tolerance = (share * o.r0).max(1.0);
        // The distance from the centre is the radius at θ plus the centre's error along θ.
        let [dr, da, db, dcx, dcy] = biweight_step(points, tolerance, |x, y| {
            let (dx, dy) = (x - o.cx, y - o.cy);
            let theta = dy.atan2(dx);
            let gradient = [
                1.0,
                (2.0 * theta).cos(),
                (2.0 * theta).sin(),
                theta.cos(),
                theta.sin(),
            ];
            Some((gradient, length(dx, dy) - o.radius_at(theta)))
        })?;
        o = Outline {
            cx: o.cx + dcx,
            cy: o.cy + dcy,
            r0: o.r0 + dr,
            a: o.a + da,
            b: o.b + db,
        };
        if !(o.r0.is_finite() && o.r0 > 0.0) || o.elongation() > MAX_ELONGATION * o.r0 {
            return None;
        }
        if dcx.abs() + dcy.abs() + dr.abs() + da.abs() + db.abs() < 1e-3 && round >= 4 {
            break;
        }
    }
    Some(o)
}

/// The fraction of the rim with a clear edge on `outline`, of the rays that cross it inside
/// the frame (or of [`UNCUT`] of them); None when less than [`MIN_VISIBLE`] is inside.
fn rim_confidence(luminance: impl Plane, outline: &Outline) -> Option<f64> {
    let circle = outline.circle();
    let visible = visible_rays(&circle, luminance.size());
    if visible < (MIN_VISIBLE * RAYS as f64).ceil() as usize {
        return None;
    }
    let sharp = rim_share(luminance, outline, visible, SHARP, 0.0);
    if !SOFT_TRIED.contains(&sharp) {
        return Some(sharp);
    }
    // A soft rim (out of focus, a blurred reflection): slopes over its width, and its place
    // known to a quarter of it.
    let width = edge_width(luminance, outline).min(SOFT_WIDTH * outline.r0);
    if width <= 2.0 {
        return Some(sharp);
    }
    let soft = rim_share(
        luminance,
        outline,
        visible,
        Slopes::over(width),
        0.25 * width,
    );
    Some(sharp.max(soft))
}

/// A rim is measured again as a soft one when its sharp confidence is in this range: below, it
/// is no sphere's (a soft rim reads 0.3–0.5 sharp); above, it is clear enough.
const SOFT_TRIED: std::ops::Range<f64> = 0.25..MIN_CONFIDENCE;

/// The widest rim (over r) measured over its width: a blur of σ 2 % of r.
const SOFT_WIDTH: f64 = 0.05;

/// The share of `visible` rays with a clear edge on `outline`, slopes taken as `slopes` says,
/// the edge within 1 % of r, 1 px or `spread` px of the outline, whichever is the most.
fn rim_share(
    luminance: impl Plane,
    outline: &Outline,
    visible: usize,
    slopes: Slopes,
    spread: f64,
) -> f64 {
    // Wider by half the slopes' span, so that a slope centred on the window's edge fits in it.
    let window = 0.015 * outline.r0 + 2.0 + 0.5 * slopes.span();
    let points = rim_points_over(luminance, outline, window, slopes);
    let tolerance = (0.01 * outline.r0).max(1.0).max(spread);
    let on = points
        .iter()
        .filter(|p| {
            let (dx, dy) = (p.0 - outline.cx, p.1 - outline.cy);
            (length(dx, dy) - outline.radius_at(dy.atan2(dx))).abs() <= tolerance
        })
        .count();
    (on as f64 / (visible as f64).max(UNCUT * RAYS as f64)).min(1.0)
}

/// The width (px) of the edge along `outline`: the median over rays of its 10–90 % rise (2.56 σ
/// for a step blurred by a Gaussian of σ), from its 25–75 % rise (1.35 σ), which noise on the
/// flat parts does not reach. Each level's crossing is where as many samples lie below it as a
/// step would put there.
fn edge_width(luminance: impl Plane, outline: &Outline) -> f64 {
    let window = 0.04 * outline.r0 + 4.0;
    let steps = (2.0 * window / RIM_STEP).ceil() as usize + 1;
    let widths: Vec<f64> = (0..RAYS)
        .step_by(8)
        .filter_map(|k| {
            let theta = std::f64::consts::TAU * k as f64 / RAYS as f64;
            let circle = outline.circle_at(theta);
            let profile = ray_profile(luminance, &circle, theta, window, RIM_STEP, steps);
            let end = |part: &[f64]| part.iter().sum::<f64>() / part.len() as f64;
            let ends = SHARP.base;
            let (first, last) = (end(&profile[..ends]), end(&profile[steps - ends..]));
            let height = last - first;
            let below = |level: f64| {
                let count = profile
                    .iter()
                    .filter(|&&v| (v - first) / height < level)
                    .count();
                count as f64 * RIM_STEP
            };
            (height.abs() > 1e-9).then(|| (below(0.75) - below(0.25)).abs() * 2.56 / 1.35)
        })
        .collect();
    if widths.is_empty() {
        return 0.0;
    }
    quantile(widths, 0.5)
}

/// Elongation (over r0) allowed in any direction: a crop rescaled unevenly, a sensor's
/// non-square pixels.
const ANY_ELONGATION: f64 = 0.03;

/// The most confident candidates tried as elongated outlines.
const ELONGATE_FIRST: usize = 4;
/// A candidate is tried as an elongated outline when its confidence as a circle is in this
/// range: below, it is no sphere; above, the circle already follows its rim.
const TRY_ELONGATED: std::ops::Range<f64> = 0.25..0.9;

/// Refine rough circles on the full image: each (circle, slack) is the rough circle and its
/// uncertainty (px). A circle whose first fit lands where an earlier one's did is the same
/// circle, and is refined once.
fn refine_all(
    luminance: impl Plane,
    small: (ArrayView2<f64>, f64),
    candidates: Vec<(Circle, f64)>,
) -> Vec<Found> {
    let parts = parallel::parts();
    let first = map_in_parts(parts, &candidates, |&(rough, slack)| {
        first_fit(luminance, small, rough, slack).map(|circle| (circle, rough.r))
    });
    let mut distinct: Vec<(Circle, f64)> = Vec::new();
    for (circle, rough_r) in first.into_iter().flatten() {
        if !distinct.iter().any(|(c, _)| same_fit(c, &circle)) {
            distinct.push((circle, rough_r));
        }
    }
    map_in_parts(parts, &distinct, |&(circle, rough_r)| {
        narrow_fit(luminance, circle, rough_r)
    })
    .into_iter()
    .flatten()
    .collect()
}

/// Two first fits that landed on the same circle: centres and radii within a tenth of a
/// percent of r (plus a tenth of a pixel).
fn same_fit(a: &Circle, b: &Circle) -> bool {
    let tolerance = 0.001 * a.r + 0.1;
    (a.cx - b.cx).hypot(a.cy - b.cy) <= tolerance && (a.r - b.r).abs() <= tolerance
}

/// A rough circle at least this large on the reduced copy (px) takes its first fit there.
const COARSE_FIT_MIN_RADIUS: f64 = 40.0;

/// The first, wide fit of a rough circle with uncertainty `slack` (px). It runs on the reduced
/// copy `small` (at `scale`) when the circle is large there: its rim is as sharp relative to
/// r, and the wide window costs a fraction of the samples.
fn first_fit(
    luminance: impl Plane,
    (small, scale): (ArrayView2<f64>, f64),
    rough: Circle,
    slack: f64,
) -> Option<Circle> {
    if rough.r < MIN_RADIUS * 0.9 {
        return None;
    }
    let wide = slack + 0.04 * rough.r + 2.0;
    if scale < 1.0 && rough.r * scale >= COARSE_FIT_MIN_RADIUS {
        let start = rough.reduced(scale);
        let points = rim_points(small, &Outline::of(&start), wide * scale);
        Some(robust_fit(&points, &start)?.enlarged(scale))
    } else {
        let points = rim_points(luminance, &Outline::of(&rough), wide);
        robust_fit(&points, &rough)
    }
}

/// The narrow fit on the full image after the first (the window set by the rough radius
/// `rough_r`), and its confidence.
fn narrow_fit(luminance: impl Plane, first: Circle, rough_r: f64) -> Option<Found> {
    let points = rim_points(luminance, &Outline::of(&first), 0.015 * rough_r + 2.0);
    let circle = robust_fit(&points, &first)?;
    if circle.r < MIN_RADIUS {
        return None;
    }
    let confidence = rim_confidence(luminance, &Outline::of(&circle))?;
    Some(Found {
        circle,
        confidence,
        ball_like: true,
    })
}

/// `found` as an elongated outline, when that puts a clear edge under more of its rim.
fn elongated(luminance: impl Plane, found: &Found) -> Option<Found> {
    if !TRY_ELONGATED.contains(&found.confidence) {
        return None;
    }
    let outline = elongate(luminance, &found.circle)?;
    let confidence = rim_confidence(luminance, &outline)?;
    let circle = outline.circle();
    (confidence > found.confidence + 0.05 && circle.r >= MIN_RADIUS).then_some(Found {
        circle,
        confidence,
        ball_like: true,
    })
}

/// The elongated outline around a fitted circle: a wide search for the rim, then a narrow one.
/// Only what a lens or a rescaling can draw is kept: longer away from the picture's centre,
/// by no more than the widest lens would at that distance from it, or by at most
/// [`ANY_ELONGATION`] any way.
fn elongate(luminance: impl Plane, circle: &Circle) -> Option<Outline> {
    let (h, w) = luminance.size();
    let from_centre = |c: (f64, f64)| (c.0 - 0.5 * (w as f64 - 1.0), c.1 - 0.5 * (h as f64 - 1.0));
    let (dx, dy) = from_centre((circle.cx, circle.cy));
    // The widest lenses in use see about 84° across the diagonal: focal length ≥ 0.55 of it.
    let stretch = (dx.hypot(dy) / (0.55 * (w as f64).hypot(h as f64))).hypot(1.0);
    let lens = ((stretch - 1.0) / (stretch + 1.0)).min(MAX_ELONGATION);
    let most = lens.max(ANY_ELONGATION);
    let mut outline = Outline::of(circle);
    for window in [(most + 0.02) * circle.r + 2.0, 0.03 * circle.r + 2.0] {
        let points = rim_points(luminance, &outline, window);
        outline = fit_outline(&points, &outline)?;
    }
    let (dx, dy) = from_centre((outline.cx, outline.cy));
    let long_axis = 0.5 * outline.b.atan2(outline.a);
    // The angle between the two directions, as lines (modulo half a turn).
    let apart = (long_axis - dy.atan2(dx)).rem_euclid(std::f64::consts::PI);
    let aligned = apart.min(std::f64::consts::PI - apart) <= 20f64.to_radians();
    let elongation = outline.elongation() / outline.r0;
    let drawn = elongation <= ANY_ELONGATION || (aligned && elongation <= lens + 0.01);
    (elongation > 0.005 && drawn).then_some(outline)
}

/// How many of the [`RAYS`] cross the rim at least a pixel inside the frame.
fn visible_rays(circle: &Circle, (h, w): (usize, usize)) -> usize {
    (0..RAYS)
        .filter(|&k| {
            let theta = std::f64::consts::TAU * k as f64 / RAYS as f64;
            let (x, y) = (
                circle.cx + circle.r * theta.cos(),
                circle.cy + circle.r * theta.sin(),
            );
            x >= 0.5 && y >= 0.5 && x <= w as f64 - 1.5 && y <= h as f64 - 1.5
        })
        .count()
}

#[cfg(test)]
mod tests {
    //! Each rule by which [`chosen`] refuses, pinned on both sides of its line: loosen one
    //! (a threshold, the ball-likeness, the rival check, the short-rim discount) and a
    //! refusal here becomes an answer.

    use super::*;

    fn found(cx: f64, r: f64, confidence: f64, ball_like: bool) -> Found {
        let circle = Circle { cx, cy: 200.0, r };
        Found {
            circle,
            confidence,
            ball_like,
        }
    }

    fn ball(cx: f64, r: f64, confidence: f64) -> Found {
        found(cx, r, confidence, true)
    }

    fn refused(ranked: &[Found]) -> String {
        match chosen(ranked) {
            Ok(found) => panic!("{found:?} taken from {ranked:?}"),
            Err(NotFound(reason)) => reason,
        }
    }

    #[test]
    fn nothing_found_is_refused() {
        assert_eq!(refused(&[]), "no round edge stands out");
    }

    #[test]
    fn a_confident_circle_is_taken_and_below_the_line_it_is_not() {
        // A flat disc too: at MIN_CONFIDENCE any circle is clear enough.
        let disc = found(200.0, 100.0, MIN_CONFIDENCE, false);
        assert_eq!(chosen(&[disc]), Ok(disc));
        let below = found(200.0, 100.0, MIN_CONFIDENCE - 0.01, false);
        let reason = refused(&[below]);
        assert!(
            reason.contains("radius 100") && reason.contains("only 49 %"),
            "{reason}"
        );
    }

    #[test]
    fn a_lone_ball_is_taken_from_its_own_line_and_not_below() {
        let alone = ball(200.0, 100.0, MIN_CONFIDENCE_ALONE);
        assert_eq!(chosen(&[alone]), Ok(alone));
        let reason = refused(&[ball(200.0, 100.0, MIN_CONFIDENCE_ALONE - 0.01)]);
        assert!(reason.contains("only 39 %"), "{reason}");
        // Below it, a rival no stronger changes nothing.
        refused(&[
            ball(200.0, 100.0, MIN_CONFIDENCE_ALONE - 0.01),
            ball(600.0, 100.0, 0.1),
        ]);
    }

    #[test]
    fn a_lone_flat_disc_is_not_taken_under_the_confidence() {
        // Ranked first only because no ball was found: it is not a ball.
        refused(&[found(200.0, 100.0, 0.49, false)]);
    }

    #[test]
    fn a_short_rim_needs_more_evidence() {
        // r 40: 251 px of rim for 360 rays, so 0.49 counts as 0.34.
        let small = ball(200.0, 40.0, 0.49);
        assert!(
            evidence(&small) < MIN_CONFIDENCE_ALONE,
            "{}",
            evidence(&small)
        );
        refused(&[small]);
        // From r 57.3 the rim is long enough to count whole.
        let whole = ball(200.0, 58.0, 0.41);
        assert_eq!(chosen(&[whole]), Ok(whole));
    }

    #[test]
    fn a_lone_ball_with_a_rival_near_it_is_refused() {
        let first = ball(200.0, 100.0, 0.48);
        // A rival outside it, ball or not, over three quarters as confident: ambiguous.
        for rival_is_a_ball in [true, false] {
            let rival = found(600.0, 100.0, 0.37, rival_is_a_ball);
            assert!(evidence(&rival) > RUNNER_UP_SHARE * evidence(&first));
            refused(&[first, rival]);
            // Any rival down the list counts, not only the runner-up.
            refused(&[first, ball(900.0, 100.0, 0.1), rival]);
        }
        // Under three quarters, it is no rival.
        let weak = ball(600.0, 100.0, 0.35);
        assert_eq!(chosen(&[first, weak]), Ok(first));
        // A rival with a short rim is weighed by its evidence: at r 50, 0.40 counts as 0.35
        // and 0.45 as 0.39.
        assert_eq!(chosen(&[first, ball(600.0, 50.0, 0.40)]), Ok(first));
        refused(&[first, ball(600.0, 50.0, 0.45)]);
    }

    #[test]
    fn a_confident_disc_printed_on_a_ball_gives_way_to_the_ball() {
        // A billiard ball's number disc (r 39, 0.66) inside the ball (r 93, 0.46).
        let disc = ball(253.0, 39.0, 0.66);
        let ball_around = ball(243.0, 93.0, 0.46);
        assert_eq!(chosen(&[disc, ball_around]), Ok(ball_around));
        // Not a ball, or without the evidence a lone ball needs: the disc stays.
        let flat = found(243.0, 93.0, 0.46, false);
        assert_eq!(chosen(&[disc, flat]), Ok(disc));
        let faint = ball(243.0, 93.0, MIN_CONFIDENCE_ALONE - 0.01);
        assert_eq!(chosen(&[disc, faint]), Ok(disc));
        // A circle more than 3 times larger is a chance arc around a small ball.
        let arc = ball(243.0, 125.0, 0.46);
        let small = ball(253.0, 40.0, 0.66);
        assert_eq!(chosen(&[small, arc]), Ok(small));
        // Nor is a circle under 1.5 times larger, or one the first reaches out of.
        assert_eq!(chosen(&[disc, ball(253.0, 55.0, 0.46)]), Ok(disc));
        assert_eq!(chosen(&[disc, ball(330.0, 93.0, 0.46)]), Ok(disc));
    }

    /// A disc of r 150 (0.6 on 0.2) blurred by a Gaussian of `sigma`, with noise (σ 0.03).
    fn blurred_disc(sigma: f64) -> (ndarray::Array2<f64>, Circle) {
        let circle = Circle {
            cx: 200.3,
            cy: 190.7,
            r: 150.0,
        };
        let disc = ndarray::Array2::from_shape_fn((380, 400), |(y, x)| {
            if (x as f64 - circle.cx).hypot(y as f64 - circle.cy) <= circle.r {
                0.6
            } else {
                0.2
            }
        });
        let mut rng = crate::util::rng::Rng::new(3);
        let noisy = crate::image::blur::gaussian_blur(disc.view(), sigma)
            .mapv(|v| v + 0.06 * (rng.next_f64() + rng.next_f64() + rng.next_f64() - 1.5));
        (noisy, circle)
    }

    #[test]
    fn a_soft_rim_is_measured_over_its_own_width() {
        let (image, circle) = blurred_disc(5.0);
        let outline = Outline::of(&circle);
        // A Gaussian's step is 2.5 σ wide by height over steepest slope, less where noise
        // steepens the steepest.
        let width = edge_width(image.view(), &outline);
        assert!((6.0..15.0).contains(&width), "{width}");
        // Over one pixel the noise moves the steepest slope off the rim; over its width, not.
        let visible = visible_rays(&circle, image.dim());
        let sharp = rim_share(image.view(), &outline, visible, SHARP, 0.0);
        let confidence = rim_confidence(image.view(), &outline).unwrap();
        assert!(
            sharp < MIN_CONFIDENCE && confidence >= 0.6,
            "{sharp} {confidence}"
        );
        // A sharp rim keeps the one-pixel measure.
        let (image, circle) = blurred_disc(0.7);
        let outline = Outline::of(&circle);
        assert!(edge_width(image.view(), &outline) < 2.0);
        assert!(rim_confidence(image.view(), &outline).unwrap() >= 0.9);
    }

    #[test]
    fn a_plate_is_told_from_a_ball_in_a_large_photograph() {
        // 3000 × 2000: a plate (a rim band from 0.8 to 1 of r 120 around a textured inside)
        // and a shaded ball of r 120; 26 px each on the working copy.
        let plate = Circle {
            cx: 800.0,
            cy: 1000.0,
            r: 120.0,
        };
        let ball = Circle {
            cx: 2200.0,
            ..plate
        };
        let image = ndarray::Array2::from_shape_fn((2000, 3000), |(y, x)| {
            let (x, y) = (x as f64, y as f64);
            let from = |c: &Circle| (x - c.cx).hypot(y - c.cy) / c.r;
            let (p, b) = (from(&plate), from(&ball));
            if p <= 0.8 {
                0.3 + 0.2 * (x / 9.0).sin() * (y / 7.0).cos()
            } else if p <= 1.0 {
                0.9
            } else if b <= 1.0 {
                0.1 + 0.8 * (1.0 - b * b).sqrt()
            } else {
                0.25
            }
        });
        let (small, scale) = reduced(image.view());
        let (work, norm) = working_copy(small.view());
        let edges = edge_points(work.view());
        let working = Working {
            image: work.view(),
            edges: &edges,
            scale,
            norm,
        };
        assert!(plate.reduced(scale).r < SMALL_ON_WORK);
        let mut found = [plate, ball].map(|circle| Found {
            circle,
            confidence: 0.9,
            ball_like: true,
        });
        judge_ball_likeness(&mut found, image.view(), &working);
        assert!(!found[0].ball_like && found[1].ball_like, "{found:?}");
    }

    #[test]
    fn circles_inside_the_ball_are_its_reflections_not_rivals() {
        let first = ball(200.0, 100.0, 0.45);
        // Entirely inside (centre 30 px off, r 60: 90 ≤ 110): a reflection.
        let reflection = found(230.0, 60.0, 0.44, false);
        assert_eq!(chosen(&[first, reflection]), Ok(first));
        // Reaching beyond 1.1 r of the first (30 + 85 = 115): a rival.
        refused(&[first, found(230.0, 85.0, 0.44, false)]);
    }
}
