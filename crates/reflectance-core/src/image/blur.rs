//! Gaussian blur: the lens of the capture model, and the smoothing before detection's edges.

use ndarray::{Array2, ArrayView2};

/// Separable Gaussian blur of σ px (kernel to 3σ, normalized; borders clamped).
pub fn gaussian_blur(image: ArrayView2<f64>, sigma: f64) -> Array2<f64> {
    let reach = (3.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f64> = (-reach..=reach)
        .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
        .collect();
    let total: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let (h, w) = image.dim();
    let pass = |source: ArrayView2<f64>, along_rows: bool| {
        Array2::from_shape_fn((h, w), |(y, x)| {
            kernel
                .iter()
                .enumerate()
                .map(|(i, k)| {
                    let offset = i as isize - reach;
                    let (sy, sx) = if along_rows {
                        (y, (x as isize + offset).clamp(0, w as isize - 1) as usize)
                    } else {
                        ((y as isize + offset).clamp(0, h as isize - 1) as usize, x)
                    };
                    k * source[[sy, sx]]
                })
                .sum()
        })
    };
    let rows = pass(image, true);
    pass(rows.view(), false)
}
