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
    if h == 0 || w == 0 {
        return image.to_owned();
    }
    let image = image.as_standard_layout();
    let clamped = |i: usize, n: usize| (i as isize - reach).clamp(0, n as isize - 1) as usize;
    // Along rows, each row padded with its edge values.
    let mut rows = vec![0.0; h * w];
    let mut padded = vec![0.0; w + 2 * reach as usize];
    for (line, out) in image.rows().into_iter().zip(rows.chunks_exact_mut(w)) {
        for (i, p) in padded.iter_mut().enumerate() {
            *p = line[clamped(i, w)];
        }
        for (x, o) in out.iter_mut().enumerate() {
            *o = kernel
                .iter()
                .zip(&padded[x..x + kernel.len()])
                .map(|(k, v)| k * v)
                .sum();
        }
    }
    // Along columns, a row at a time (the taps in the same order, from −0.0 as `sum` does).
    let mut out = vec![-0.0; h * w];
    for (y, o) in out.chunks_exact_mut(w).enumerate() {
        for (i, k) in kernel.iter().enumerate() {
            let source = clamped(y + i, h);
            for (a, b) in o.iter_mut().zip(&rows[source * w..(source + 1) * w]) {
                *a += k * b;
            }
        }
    }
    Array2::from_shape_vec((h, w), out).expect("h × w samples")
}
