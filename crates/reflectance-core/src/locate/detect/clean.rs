//! Detection on a clean (dark or uniform) background: the largest region that stands out
//! from the image's border, and the circle of its edge.

use crate::image::regions::{fill_holes, largest_component};
use crate::locate::MIN_RADIUS;
use crate::locate::fit::trimmed_fit;
use crate::locate::mask::edge_points;
use crate::locate::{Geometry, GeometryError, Method};
use ndarray::ArrayView2;

/// Automatic detection refuses below this confidence.
pub const MIN_CONFIDENCE: f64 = 0.9;

/// Find a sphere on a clean background.
///
/// The background level and noise come from the image border (median and MAD); pixels far
/// from it are foreground; background is what is connected to the border, so dark patches
/// inside the sphere do not make holes. A circle is fitted to the largest foreground
/// component's edge with outlier rejection. Confidence = fraction of edge points on the
/// circle × agreement between the component's area and the circle's.
pub fn detect_clean(luminance: ArrayView2<f64>) -> Result<Geometry, GeometryError> {
    let fail = |reason: String| GeometryError::DetectionFailed { reason };
    let (h, w) = luminance.dim();
    if h < 2 * MIN_RADIUS as usize || w < 2 * MIN_RADIUS as usize {
        return Err(fail(format!(
            "the image ({w}×{h}) is too small to hold a sphere"
        )));
    }
    let (background, noise) = border_level(luminance);
    let mut sorted: Vec<f64> = luminance.iter().map(|v| (v - background).abs()).collect();
    sorted.sort_unstable_by(f64::total_cmp);
    let contrast = sorted[(sorted.len() as f64 * 0.99) as usize];
    if contrast <= 0.0 || noise > 0.1 * contrast {
        return Err(fail("the background is not uniform enough".into()));
    }
    let threshold = (6.0 * noise).max(0.02 * contrast);
    let foreground = luminance.mapv(|v| (v - background).abs() > threshold);
    let component = largest_component(&fill_holes(&foreground));
    let area = component.iter().filter(|&&m| m).count() as f64;
    if area == 0.0 {
        return Err(fail("no object stands out from the background".into()));
    }
    let edge = edge_points(component.view());
    let (circle, inliers) =
        trimmed_fit(&edge).ok_or_else(|| fail("the object's edge is not round".into()))?;
    let disc_area = std::f64::consts::PI * circle.r * circle.r;
    let area_agreement = 1.0 - ((area - disc_area).abs() / disc_area).min(1.0);
    let confidence = inliers * area_agreement;
    if confidence < MIN_CONFIDENCE {
        return Err(fail(format!(
            "confidence {confidence:.2} is below {MIN_CONFIDENCE} (the object is not a clean disc)"
        )));
    }
    Ok(Geometry::new(circle, Method::Auto, Some(confidence)))
}

/// Median and robust spread (1.4826·MAD) of a 2-pixel frame around the image.
fn border_level(image: ArrayView2<f64>) -> (f64, f64) {
    let (h, w) = image.dim();
    let mut border: Vec<f64> = image
        .indexed_iter()
        .filter(|((y, x), _)| *y < 2 || *x < 2 || *y + 2 >= h || *x + 2 >= w)
        .map(|(_, &v)| v)
        .collect();
    let median = median_of(&mut border);
    let mut deviations: Vec<f64> = border.iter().map(|v| (v - median).abs()).collect();
    (median, 1.4826 * median_of(&mut deviations))
}

fn median_of(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    values.select_nth_unstable_by(mid, f64::total_cmp);
    values[mid]
}
