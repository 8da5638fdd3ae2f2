//! Circles fitted to points: the algebraic (Kåsa) fit, its residuals, and its trimmed refit
//! (the edge of a mask or of a clean background's region). The rim fits of photographs,
//! weighted by contrast and robust to clutter, are detection's ([`super::detect`]).

use crate::image::circle::{Circle, solve};

/// Algebraic (Kåsa) fit, in coordinates centred on the points' mean for conditioning.
pub(crate) fn fit_circle(points: &[(f64, f64)]) -> Option<Circle> {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    // Minimize Σ (u² + v² + D u + E v + F)²: normal equations in (D, E, F).
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for &(x, y) in points {
        let (u, v) = (x - mx, y - my);
        let row = [u, v, 1.0];
        let z = -(u * u + v * v);
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] += row[i] * row[j];
            }
            b[i] += row[i] * z;
        }
    }
    let [d, e, f] = solve(a, b)?;
    let r2 = d * d / 4.0 + e * e / 4.0 - f;
    (r2 > 0.0).then(|| Circle {
        cx: mx - d / 2.0,
        cy: my - e / 2.0,
        r: r2.sqrt(),
    })
}

pub(crate) fn residual(p: &(f64, f64), c: &Circle) -> f64 {
    ((p.0 - c.cx).hypot(p.1 - c.cy) - c.r).abs()
}

pub(crate) fn rms_residual(points: &[(f64, f64)], c: &Circle) -> f64 {
    (points.iter().map(|p| residual(p, c).powi(2)).sum::<f64>() / points.len() as f64).sqrt()
}

/// The algebraic fit, trimmed: fit, drop points far from the circle, refit (four times); returns the circle and the fraction
/// of all edge points within tolerance of it.
pub(crate) fn trimmed_fit(points: &[(f64, f64)]) -> Option<(Circle, f64)> {
    if points.len() < 16 {
        return None;
    }
    let mut circle = fit_circle(points)?;
    for _ in 0..4 {
        let tolerance = (0.01 * circle.r).max(1.5);
        let kept: Vec<(f64, f64)> = points
            .iter()
            .copied()
            .filter(|p| residual(p, &circle) <= 3.0 * tolerance)
            .collect();
        if kept.len() < 16 {
            return None;
        }
        circle = fit_circle(&kept)?;
    }
    let tolerance = (0.01 * circle.r).max(1.5);
    let inliers = points
        .iter()
        .filter(|p| residual(p, &circle) <= tolerance)
        .count();
    Some((circle, inliers as f64 / points.len() as f64))
}
