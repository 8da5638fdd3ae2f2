//! Canonical unwrap: the annulus ρ ∈ [inner·r, outer·r] resampled onto a rows × cols grid
//! (radius down, angle across), each cell the mean of s×s bilinear samples, s = ⌈r / r0⌉.

use crate::geometry::Circle;
use ndarray::{Array2, ArrayView2};
use std::f64::consts::PI;

/// Grid constants of the unwrap; part of a model's feature configuration.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UnwrapConfig {
    /// Inner radius of the annulus, as a fraction of r.
    pub inner: f64,
    /// Outer radius of the annulus, as a fraction of r.
    pub outer: f64,
    pub rows: usize,
    pub cols: usize,
    /// Radius (px) up to which one sample per cell is taken; s = max(1, ⌈r / r0⌉).
    pub r0: f64,
}

impl Default for UnwrapConfig {
    fn default() -> Self {
        UnwrapConfig {
            inner: 0.2,
            outer: 0.9,
            rows: 96,
            cols: 448,
            r0: 80.0,
        }
    }
}

impl UnwrapConfig {
    /// Samples per cell side for a sphere of radius `r` pixels.
    pub fn supersampling(&self, r: f64) -> usize {
        ((r / self.r0).ceil() as usize).max(1)
    }
}

/// `(cos θ, sin θ)` of every sub-column sample `q = j·s + b`, θ = 2π(j + (b+0.5)/s)/W.
pub fn angle_table(cols: usize, s: usize) -> Vec<(f64, f64)> {
    let (w, sf) = (cols as f64, s as f64);
    (0..cols * s)
        .map(|q| {
            let (j, b) = ((q / s) as f64, (q % s) as f64);
            let theta = 2.0 * PI * (j + (b + 0.5) / sf) / w;
            (theta.cos(), theta.sin())
        })
        .collect()
}

/// Unwrap `image` around `circle`; `angles` must be [`angle_table`]`(cfg.cols, s)` for
/// `s = cfg.supersampling(circle.r)`.
pub fn unwrap(
    image: ArrayView2<f64>,
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &[(f64, f64)],
) -> Array2<f64> {
    let s = cfg.supersampling(circle.r);
    assert_eq!(
        angles.len(),
        cfg.cols * s,
        "angle table does not match the supersampling"
    );
    let sampler = Bilinear::new(image);
    let (h, sf) = (cfg.rows as f64, s as f64);
    let span = cfg.outer - cfg.inner;
    let norm = 1.0 / (s * s) as f64;
    let mut out = Array2::zeros((cfg.rows, cfg.cols));
    for (i, mut out_row) in out.rows_mut().into_iter().enumerate() {
        let row = out_row.as_slice_mut().expect("standard layout");
        for a in 0..s {
            let rho = circle.r * (cfg.inner + span * (i as f64 + (a as f64 + 0.5) / sf) / h);
            for (cell, chunk) in row.iter_mut().zip(angles.chunks_exact(s)) {
                for &(cos, sin) in chunk {
                    *cell += sampler.sample(circle.cx + rho * cos, circle.cy - rho * sin);
                }
            }
        }
        row.iter_mut().for_each(|v| *v *= norm);
    }
    out
}

/// Bilinear lookup at pixel-centre coordinates; weights from the unclamped position, then
/// the four indices clamped to the image.
struct Bilinear<'a> {
    data: &'a [f64],
    width: usize,
    max_x: isize,
    max_y: isize,
}

impl<'a> Bilinear<'a> {
    fn new(image: ArrayView2<'a, f64>) -> Self {
        let (height, width) = image.dim();
        Bilinear {
            data: image.to_slice().expect("standard layout"),
            width,
            max_x: width as isize - 1,
            max_y: height as isize - 1,
        }
    }

    #[inline(always)]
    fn sample(&self, x: f64, y: f64) -> f64 {
        let (x0, fx) = floor_split(x);
        let (y0, fy) = floor_split(y);
        let xa = x0.clamp(0, self.max_x) as usize;
        let xb = (x0 + 1).clamp(0, self.max_x) as usize;
        let ya = (y0.clamp(0, self.max_y) as usize) * self.width;
        let yb = ((y0 + 1).clamp(0, self.max_y) as usize) * self.width;
        let d = self.data;
        let top = (1.0 - fx) * d[ya + xa] + fx * d[ya + xb];
        let bottom = (1.0 - fx) * d[yb + xa] + fx * d[yb + xb];
        (1.0 - fy) * top + fy * bottom
    }
}

/// `(floor(x), x − floor(x))` without a libm call (x86-64 baseline has no SSE4.1 `roundsd`).
#[inline(always)]
fn floor_split(x: f64) -> (isize, f64) {
    let t = x as isize;
    let t = if (t as f64) > x { t - 1 } else { t };
    (t, x - t as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn circle(cx: f64, cy: f64, r: f64) -> Circle {
        Circle { cx, cy, r }
    }

    #[test]
    fn floor_split_matches_floor() {
        for x in [-1.5, -0.5, -0.0, 0.0, 0.25, 1.0, 2.999_999_999, 511.5, -3.0] {
            let (i, f) = floor_split(x);
            assert_eq!(i as f64, x.floor(), "{x}");
            assert_eq!(f, x - x.floor(), "{x}");
        }
    }

    #[test]
    fn bilinear_reproduces_linear_ramps_and_clamps() {
        let img = Array2::from_shape_fn((8, 10), |(y, x)| 2.0 * x as f64 + 3.0 * y as f64);
        let b = Bilinear::new(img.view());
        assert!((b.sample(3.25, 4.5) - (6.5 + 13.5)).abs() < 1e-12);
        // Outside the image the indices clamp: x = -0.5 gives weights 0.5/0.5 on column 0.
        assert!((b.sample(-0.5, 0.0) - 0.0).abs() < 1e-12);
        assert!((b.sample(9.5, 7.0) - (18.0 + 21.0)).abs() < 1e-12);
    }

    #[test]
    fn supersampling_grows_with_radius() {
        let cfg = UnwrapConfig::default();
        assert_eq!(cfg.supersampling(32.0), 1);
        assert_eq!(cfg.supersampling(80.0), 1);
        assert_eq!(cfg.supersampling(80.5), 2);
        assert_eq!(cfg.supersampling(232.7), 3);
    }

    #[test]
    fn radial_ramp_unwraps_to_row_means() {
        // Image value = distance from the centre: every cell is (close to) its mean radius,
        // constant along each row and increasing down the rows.
        let (cx, cy, r) = (100.3, 99.7, 90.0);
        let img = Array2::from_shape_fn((201, 201), |(y, x)| {
            ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt()
        });
        let cfg = UnwrapConfig::default();
        let s = cfg.supersampling(r);
        let u = unwrap(
            img.view(),
            &circle(cx, cy, r),
            &cfg,
            &angle_table(cfg.cols, s),
        );
        for i in 0..cfg.rows {
            let expected = r * (0.2 + 0.7 * (i as f64 + 0.5) / 96.0);
            for j in 0..cfg.cols {
                assert!(
                    (u[[i, j]] - expected).abs() < 0.05,
                    "cell {i},{j}: {}",
                    u[[i, j]]
                );
            }
        }
    }

    #[test]
    fn columns_start_at_three_oclock_and_turn_counter_clockwise() {
        // Bright right half (x > cx) and bright top half (y < cy) in two images.
        let (cx, cy, r) = (60.0, 60.0, 50.0);
        let right = Array2::from_shape_fn((121, 121), |(_, x)| f64::from(x as f64 > cx));
        let top = Array2::from_shape_fn((121, 121), |(y, _)| f64::from((y as f64) < cy));
        let cfg = UnwrapConfig::default();
        let angles = angle_table(cfg.cols, 1);
        let u_right = unwrap(right.view(), &circle(cx, cy, r), &cfg, &angles);
        let u_top = unwrap(top.view(), &circle(cx, cy, r), &cfg, &angles);
        // Column 20 (θ ≈ 16°) lies right of and above the centre; column 200 (θ ≈ 161°) left.
        assert_eq!(u_right[[50, 20]], 1.0);
        assert_eq!(u_top[[50, 20]], 1.0);
        assert_eq!(u_right[[50, 200]], 0.0);
        assert_eq!(u_top[[50, 300]], 0.0);
    }
}
