//! A circle in an image's pixels, and the small linear solve that circle and outline fits
//! share.

use serde::{Deserialize, Serialize};

/// A circle in an image's pixels: pixel centres at integer coordinates, x across and y down.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Circle {
    /// Centre's x (px).
    pub cx: f64,
    /// Centre's y (px).
    pub cy: f64,
    /// Radius (px, > 0).
    pub r: f64,
}

impl Circle {
    /// The circle on a copy of the image resampled by `scale` (pixel centres map to pixel
    /// centres).
    pub fn reduced(&self, scale: f64) -> Circle {
        let at = |v: f64| (v + 0.5) * scale - 0.5;
        Circle {
            cx: at(self.cx),
            cy: at(self.cy),
            r: self.r * scale,
        }
    }

    /// The circle on the original image, of one found on a copy resampled by `scale`.
    pub fn enlarged(&self, scale: f64) -> Circle {
        let at = |v: f64| (v + 0.5) / scale - 0.5;
        Circle {
            cx: at(self.cx),
            cy: at(self.cy),
            r: self.r / scale,
        }
    }
}

/// Gaussian elimination with partial pivoting; None when singular.
pub(crate) fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..N {
            let factor = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (target, &p) in a[row].iter_mut().zip(&pivot_row).skip(col) {
                *target -= factor * p;
            }
            b[row] -= factor * b[col];
        }
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let tail: f64 = (row + 1..N).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - tail) / a[row][row];
    }
    Some(x)
}
