//! A circle fitted to the edge of a mask: a separate mask image, or the image's alpha.

use super::fit::{fit_circle, rms_residual};
use super::{Geometry, GeometryError, Method};
use ndarray::ArrayView2;

/// Least-squares circle fitted to the edge of a mask (`method` is Mask or Alpha).
pub fn fit_mask(mask: ArrayView2<bool>, method: Method) -> Result<Geometry, GeometryError> {
    if !mask.iter().any(|&m| m) {
        return Err(GeometryError::EmptyMask);
    }
    let edge = edge_points(mask);
    if edge.len() < 16 {
        return Err(GeometryError::NoMaskEdge);
    }
    let circle = fit_circle(&edge).ok_or(GeometryError::NoMaskEdge)?;
    let rms = rms_residual(&edge, &circle);
    if rms > (0.02 * circle.r).max(1.0) {
        return Err(GeometryError::NotCircular { rms });
    }
    Ok(Geometry::new(circle, method, None))
}

/// Midpoints between 4-neighbouring inside/outside pixel pairs: the mask's edge, to
/// sub-pixel accuracy on average. The image border is not an edge.
pub(crate) fn edge_points(mask: ArrayView2<bool>) -> Vec<(f64, f64)> {
    let (h, w) = mask.dim();
    let mut points = Vec::new();
    for ((y, x), &inside) in mask.indexed_iter() {
        if x + 1 < w && inside != mask[[y, x + 1]] {
            points.push((x as f64 + 0.5, y as f64));
        }
        if y + 1 < h && inside != mask[[y + 1, x]] {
            points.push((x as f64, y as f64 + 0.5));
        }
    }
    points
}
