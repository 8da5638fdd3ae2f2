//! Gaussian blur: the lens of the capture model, and the smoothing before detection's edges.

use crate::util::parallel::fill_rows_in_parts;
use ndarray::{Array2, ArrayView2};
use std::ops::Range;

/// Separable Gaussian blur of σ px (kernel to 3σ, normalized; borders clamped).
pub fn gaussian_blur(image: ArrayView2<f64>, sigma: f64) -> Array2<f64> {
    gaussian_blur_in_parts(image, sigma, 1)
}

/// [`gaussian_blur`] with the output rows dealt in bands among `parts` threads: the same bits,
/// since an output row reads only its own neighbourhood.
pub fn gaussian_blur_in_parts(image: ArrayView2<f64>, sigma: f64, parts: usize) -> Array2<f64> {
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
    let mut out = vec![-0.0; h * w];
    fill_rows_in_parts(parts, &mut out, w, |rows, band| {
        blur_rows(image.view(), &kernel, rows, band)
    });
    Array2::from_shape_vec((h, w), out).expect("h × w samples")
}

/// Rows `rows` of the blur of `image` by the normalized, odd-length `kernel`, into `out`
/// (filled with −0.0).
fn blur_rows(image: ArrayView2<f64>, kernel: &[f64], rows: Range<usize>, out: &mut [f64]) {
    let (h, w) = image.dim();
    let taps = kernel.len();
    let reach = (taps / 2) as isize;
    let clamped = |i: usize| (i as isize - reach).clamp(0, h as isize - 1) as usize;
    // The rows blurred along x that the column pass still needs: source row s in slot
    // s mod taps (an output row reads `taps` consecutive source rows, clamped at the borders).
    let mut window = vec![0.0; taps * w];
    let mut padded = vec![0.0; w + 2 * reach as usize];
    let mut next = clamped(rows.start);
    // Along columns, a row at a time (the taps in the same order, from −0.0 as `sum` does).
    for (y, o) in rows.zip(out.chunks_exact_mut(w)) {
        while next <= clamped(y + taps - 1) {
            let slot = next % taps;
            blur_row(
                image.row(next),
                kernel,
                &mut padded,
                &mut window[slot * w..(slot + 1) * w],
            );
            next += 1;
        }
        for (i, k) in kernel.iter().enumerate() {
            let slot = clamped(y + i) % taps;
            for (a, b) in o.iter_mut().zip(&window[slot * w..(slot + 1) * w]) {
                *a += k * b;
            }
        }
    }
}

/// One row blurred along x into `out`, padded with its edge values (`padded` is scratch of
/// the row's length plus both reaches).
fn blur_row(line: ndarray::ArrayView1<f64>, kernel: &[f64], padded: &mut [f64], out: &mut [f64]) {
    let (w, reach) = (out.len(), kernel.len() / 2);
    for (i, p) in padded.iter_mut().enumerate() {
        *p = line[i.saturating_sub(reach).min(w - 1)];
    }
    // Tap by tap across the row: each output's taps in order from −0.0, as `sum` adds them,
    // while the row's outputs are computed side by side.
    out.fill(-0.0);
    for (i, k) in kernel.iter().enumerate() {
        for (o, v) in out.iter_mut().zip(&padded[i..i + w]) {
            *o += k * v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blur as its definition reads: each output the kernel's taps over the clamped
    /// neighbours, summed in order, first along rows, then along columns.
    fn by_definition(image: ArrayView2<f64>, sigma: f64) -> Array2<f64> {
        let reach = (3.0 * sigma).ceil() as isize;
        let weights: Vec<f64> = (-reach..=reach)
            .map(|k| (-0.5 * (k as f64 / sigma).powi(2)).exp())
            .collect();
        let total: f64 = weights.iter().sum();
        let kernel: Vec<f64> = weights.iter().map(|k| k / total).collect();
        let (h, w) = image.dim();
        let at = |i: usize, k: usize, n: usize| {
            (i as isize + k as isize - reach).clamp(0, n as isize - 1) as usize
        };
        let rows = Array2::from_shape_fn((h, w), |(y, x)| {
            kernel
                .iter()
                .enumerate()
                .map(|(k, q)| q * image[[y, at(x, k, w)]])
                .sum::<f64>()
        });
        Array2::from_shape_fn((h, w), |(y, x)| {
            kernel
                .iter()
                .enumerate()
                .map(|(k, q)| q * rows[[at(y, k, h), x]])
                .sum::<f64>()
        })
    }

    #[test]
    fn the_blur_is_its_definition_to_the_bit() {
        let image = Array2::from_shape_fn((23, 37), |(y, x)| {
            ((x * 7 + y * 13) % 17) as f64 / 17.0 + if (x / 5 + y / 3) % 2 == 0 { 2.0 } else { 0.0 }
        });
        // A corner smaller than the kernel too.
        for image in [image.view(), image.slice(ndarray::s![..3, ..4])] {
            for sigma in [0.6, 1.0, 2.5] {
                let slow = by_definition(image, sigma);
                for parts in 1..=4 {
                    let fast = gaussian_blur_in_parts(image, sigma, parts);
                    for (a, b) in fast.iter().zip(&slow) {
                        assert_eq!(a.to_bits(), b.to_bits(), "σ {sigma}, {parts} parts");
                    }
                }
            }
        }
    }

    #[test]
    fn the_blur_keeps_a_constant_and_the_mean_of_an_impulse() {
        let flat = Array2::from_elem((9, 12), 0.25);
        assert!(
            gaussian_blur(flat.view(), 1.5)
                .iter()
                .all(|v| (v - 0.25).abs() < 1e-15)
        );
        let mut impulse = Array2::zeros((41, 41));
        impulse[[20, 20]] = 1.0;
        let blurred = gaussian_blur(impulse.view(), 2.0);
        assert!((blurred.sum() - 1.0).abs() < 1e-12);
        assert!(blurred[[20, 20]] > blurred[[20, 22]] && blurred[[20, 22]] > blurred[[20, 25]]);
    }
}
