//! Exact area-weighted downsampling, used to bring a large sphere to a model's working
//! radius before feature extraction.
//!
//! The finest scales of the canonical grid are finer than the pixels of a sphere of radius
//! below ≈ 140 px (radially) and ≈ 360 px (angularly at 0.2 r), so the fine-scale features
//! drift with the sphere's size. A model trained on spheres of radius R gives consistent
//! features when larger inputs are first reduced to radius R (measured: the largest hand6
//! change between r = 116 and r = 400 renders of a chrome sphere drops from 0.95 to 0.04).

use crate::image::circle::Circle;
use crate::util::parallel::fill_rows_in_parts;
use ndarray::{Array2, ArrayView2};
use std::borrow::Cow;

/// Per output index along one axis: (first source index, weights of consecutive sources).
fn axis_weights(source: usize, factor: f64) -> Vec<(usize, Vec<f64>)> {
    let out = ((source as f64) * factor).ceil() as usize;
    (0..out)
        .map(|k| {
            // Output pixel k covers source pixel edges [k/f, (k+1)/f).
            let (a, b) = (k as f64 / factor, (k as f64 + 1.0) / factor);
            let first = a.floor() as usize;
            let last = (b.ceil() as usize).min(source);
            let weights = (first..last)
                .map(|s| (b.min(s as f64 + 1.0) - a.max(s as f64)).max(0.0) * factor)
                .collect();
            (first, weights)
        })
        .collect()
}

/// Downsample by `factor` ∈ (0, 1]: every output pixel is the area-weighted mean of the
/// source pixels it covers (pixels beyond the border count as missing, so edge pixels are
/// means of the covered part).
///
/// Each output value is Σ qᵢ·vᵢ summed in source order from −0.0 (as `Iterator::sum` does),
/// divided by Σ qᵢ: the columns pass adds whole rows at a time, in the same order.
pub fn downsample(image: ArrayView2<f64>, factor: f64) -> Array2<f64> {
    let (h, w) = image.dim();
    let lines = image.rows().into_iter().map(|row| match row.to_slice() {
        Some(line) => Cow::Borrowed(line),
        None => Cow::Owned(row.to_vec()),
    });
    downsample_lines(lines, (h, w), factor)
}

/// [`downsample`] of an `h` × `w` image given line by line, top to bottom, to the same
/// bits: each line is reduced along x when it comes and each output row made once its
/// lines are in, so that neither the image nor its reduced rows are ever held whole.
pub fn downsample_lines<'a>(
    lines: impl Iterator<Item = Cow<'a, [f64]>>,
    (h, w): (usize, usize),
    factor: f64,
) -> Array2<f64> {
    let (wy, wx) = (axis_weights(h, factor), axis_weights(w, factor));
    let mut out = vec![0.0; wy.len() * wx.len()];
    reduce_rows(lines.take(h), 0, &wy, &wx, &mut out);
    Array2::from_shape_vec((wy.len(), wx.len()), out).expect("the shape of the weights")
}

/// [`downsample_lines`] with the output rows dealt in bands among `parts` threads, each
/// reading the lines its band needs (`line(y)`, line `y` of the `h` × `w` image): the same
/// bits, since an output row is made from its own lines only.
pub fn downsample_lines_in_parts<'a>(
    line: impl Fn(usize) -> Cow<'a, [f64]> + Sync,
    (h, w): (usize, usize),
    factor: f64,
    parts: usize,
) -> Array2<f64> {
    let (wy, wx) = (axis_weights(h, factor), axis_weights(w, factor));
    let mut out = vec![0.0; wy.len() * wx.len()];
    fill_rows_in_parts(parts, &mut out, wx.len(), |rows, band| {
        let band_weights = &wy[rows];
        let start = band_weights.first().map_or(0, |(first, _)| *first);
        let end = band_weights
            .iter()
            .map(|(first, weights)| first + weights.len())
            .max()
            .map_or(start, |end| end.min(h));
        reduce_rows((start..end).map(&line), start, band_weights, &wx, band);
    });
    Array2::from_shape_vec((wy.len(), wx.len()), out).expect("the shape of the weights")
}

/// The output rows `wy` (each its first line and the lines' weights), reduced along x by `wx`,
/// into `out`, from `lines` given top to bottom from line `base` on: each line is reduced along x when it
/// comes and each output row made once its lines are in, so that neither the lines nor their
/// reduced rows are ever held whole.
fn reduce_rows<'a>(
    mut lines: impl Iterator<Item = Cow<'a, [f64]>>,
    mut base: usize,
    wy: &[(usize, Vec<f64>)],
    wx: &[(usize, Vec<f64>)],
    out: &mut [f64],
) {
    let across = wx.len();
    let covered: Vec<f64> = wx.iter().map(|(_, q)| q.iter().sum()).collect();
    let mut outputs = wy.iter().zip(out.chunks_exact_mut(across)).peekable();
    // The lines reduced along x and still needed: rows `base..` of the image.
    let mut window = Vec::new();
    loop {
        let block: Vec<Cow<[f64]>> = lines.by_ref().take(ROWS_AT_ONCE).collect();
        if block.is_empty() {
            break;
        }
        let start = window.len();
        window.resize(start + block.len() * across, 0.0);
        reduce_lines(&block, wx, &mut window[start..]);
        // Divided apart from the sums, so that the divisions run four at a time.
        for row in window[start..].chunks_exact_mut(across) {
            for (sum, c) in row.iter_mut().zip(&covered) {
                *sum /= c;
            }
        }
        let available = base + window.len() / across;
        while let Some(((first, weights), line)) =
            outputs.next_if(|((first, weights), _)| first + weights.len() <= available)
        {
            let sources = &window[(first - base) * across..(first - base + weights.len()) * across];
            reduce_columns(sources, weights, line);
            let covered: f64 = weights.iter().sum();
            for v in line.iter_mut() {
                *v /= covered;
            }
        }
        let needed = outputs.peek().map_or(available, |((first, _), _)| *first);
        let done = needed.clamp(base, available) - base;
        window.drain(..done * across);
        base += done;
    }
}

/// Columns summed at once by the second pass, in registers.
const COLUMNS_AT_ONCE: usize = 8;

/// The second pass for one output row: `line[x]` = Σ qᵢ·rowᵢ[x] over the consecutive rows
/// of `sources` (each `line.len()` long), in row order from −0.0.
fn reduce_columns(sources: &[f64], weights: &[f64], line: &mut [f64]) {
    let across = line.len();
    for (start, chunk) in (0..across)
        .step_by(COLUMNS_AT_ONCE)
        .zip(line.chunks_mut(COLUMNS_AT_ONCE))
    {
        let mut acc = [-0.0; COLUMNS_AT_ONCE];
        for (q, row) in weights.iter().zip(sources.chunks_exact(across)) {
            let row = &row[start..start + chunk.len()];
            for (a, v) in acc.iter_mut().zip(row) {
                *a += q * v;
            }
        }
        chunk.copy_from_slice(&acc[..chunk.len()]);
    }
}

/// Rows reduced at once by the first pass: each output's sum is one chain of dependent
/// additions, so several rows' chains run side by side.
const ROWS_AT_ONCE: usize = 8;

/// Up to [`ROWS_AT_ONCE`] lines reduced along x by the weights `wx` into `sums` (a row of
/// `wx.len()` per line).
fn reduce_lines(lines: &[Cow<[f64]>], wx: &[(usize, Vec<f64>)], sums: &mut [f64]) {
    match <&[Cow<[f64]>; ROWS_AT_ONCE]>::try_from(lines) {
        Ok(block) => reduce_block(block.each_ref().map(|line| &line[..]), wx, sums),
        Err(_) => {
            for (line, sums) in lines.iter().zip(sums.chunks_exact_mut(wx.len())) {
                reduce_block([&line[..]], wx, sums);
            }
        }
    }
}

/// `N` lines reduced along x into `sums` (`N` rows of `wx.len()`): each sum is Σ qᵢ·vᵢ in
/// source order from −0.0, as `Iterator::sum` adds.
fn reduce_block<const N: usize>(lines: [&[f64]; N], wx: &[(usize, Vec<f64>)], sums: &mut [f64]) {
    let across = wx.len();
    for (k, (first, weights)) in wx.iter().enumerate() {
        let sources = lines.map(|line| &line[*first..*first + weights.len()]);
        let mut acc = [-0.0; N];
        for (i, q) in weights.iter().enumerate() {
            for (a, source) in acc.iter_mut().zip(&sources) {
                *a += q * source[i];
            }
        }
        for (r, a) in acc.into_iter().enumerate() {
            sums[r * across + k] = a;
        }
    }
}

/// The part of `image` around `circle` (with a margin), reduced so that the circle has
/// radius `target`, and the circle in the new image. None when no reduction is needed.
pub fn to_radius(
    image: ArrayView2<f64>,
    circle: &Circle,
    target: f64,
) -> Option<(Array2<f64>, Circle)> {
    if target.is_nan() || target <= 0.0 || circle.r <= target * 1.01 {
        return None;
    }
    let (h, w) = image.dim();
    let margin = 2.0;
    let clamp = |v: f64, n: usize| v.max(0.0).min(n as f64) as usize;
    let (x0, x1) = (
        clamp((circle.cx - circle.r - margin).floor(), w),
        clamp((circle.cx + circle.r + margin).ceil() + 1.0, w),
    );
    let (y0, y1) = (
        clamp((circle.cy - circle.r - margin).floor(), h),
        clamp((circle.cy + circle.r + margin).ceil() + 1.0, h),
    );
    let crop = image.slice(ndarray::s![y0..y1, x0..x1]);
    let factor = target / circle.r;
    let small = downsample(crop, factor);
    // Pixel centres are at integers: a source coordinate u maps to (u + ½)·f − ½.
    let moved = Circle {
        cx: (circle.cx - x0 as f64 + 0.5) * factor - 0.5,
        cy: (circle.cy - y0 as f64 + 0.5) * factor - 0.5,
        r: target,
    };
    Some((small, moved))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bands_reduced_apart_are_the_whole_reduction_to_the_bit() {
        let image = Array2::from_shape_fn((157, 93), |(y, x)| {
            ((y * 31 + x * 17) % 101) as f64 / 7.0 + (x as f64 * 0.3).sin()
        });
        for factor in [0.37, 0.5, 0.1, 0.93] {
            let whole = downsample(image.view(), factor);
            for parts in 1..=4 {
                let line = |y: usize| Cow::Owned(image.row(y).to_vec());
                let banded = downsample_lines_in_parts(line, image.dim(), factor, parts);
                assert_eq!(banded.dim(), whole.dim());
                let bits = |a: &Array2<f64>| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&banded),
                    bits(&whole),
                    "factor {factor}, {parts} parts"
                );
            }
        }
    }

    #[test]
    fn halving_averages_two_by_two_blocks() {
        let img = Array2::from_shape_fn((4, 6), |(y, x)| (y * 6 + x) as f64);
        let half = downsample(img.view(), 0.5);
        assert_eq!(half.dim(), (2, 3));
        assert_eq!(half[[0, 0]], (0.0 + 1.0 + 6.0 + 7.0) / 4.0);
        assert_eq!(half[[1, 2]], (16.0 + 17.0 + 22.0 + 23.0) / 4.0);
    }

    #[test]
    fn fractional_factors_preserve_constants_and_means() {
        let flat = Array2::from_elem((37, 53), 2.5);
        let small = downsample(flat.view(), 0.37);
        assert!(small.iter().all(|v| (v - 2.5).abs() < 1e-12));
        // Interior mean preserved for a ramp (area averaging is exact on linear functions).
        let ramp = Array2::from_shape_fn((40, 40), |(_, x)| x as f64);
        let small = downsample(ramp.view(), 0.25);
        assert!((small[[3, 2]] - 9.5).abs() < 1e-12, "{}", small[[3, 2]]);
    }

    /// The definition, one output value at a time: the fast passes must give the same bits.
    fn downsample_by_definition(image: ArrayView2<f64>, factor: f64) -> Array2<f64> {
        let (h, w) = image.dim();
        let (wy, wx) = (axis_weights(h, factor), axis_weights(w, factor));
        let rows = Array2::from_shape_fn((h, wx.len()), |(y, k)| {
            let (first, weights) = &wx[k];
            let sum: f64 = (weights.iter().enumerate())
                .map(|(i, q)| q * image[[y, first + i]])
                .sum();
            sum / weights.iter().sum::<f64>()
        });
        Array2::from_shape_fn((wy.len(), wx.len()), |(k, x)| {
            let (first, weights) = &wy[k];
            let sum: f64 = (weights.iter().enumerate())
                .map(|(i, q)| q * rows[[first + i, x]])
                .sum();
            sum / weights.iter().sum::<f64>()
        })
    }

    #[test]
    fn equals_the_definition_bit_for_bit() {
        let mut rng = crate::util::rng::Rng::new(7);
        let image = Array2::from_shape_fn((61, 83), |_| rng.next_f64() * 3.0);
        // A crop: rows that are not contiguous in memory.
        let crop = image.slice(ndarray::s![3..58, 5..80]);
        for factor in [0.5, 0.37, 0.499_999, 0.8, 1.0] {
            let fast = downsample(crop, factor);
            let slow = downsample_by_definition(crop, factor);
            assert_eq!(fast.dim(), slow.dim());
            assert!(
                fast.iter()
                    .zip(&slow)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "factor {factor}"
            );
        }
    }

    #[test]
    fn circle_follows_the_reduction() {
        // A disc of radius 100 centred at (150.5, 140.25) reduced to radius 50.
        let img = Array2::from_shape_fn((300, 320), |(y, x)| {
            f64::from(((x as f64 - 150.5).hypot(y as f64 - 140.25)) < 100.0)
        });
        let circle = Circle {
            cx: 150.5,
            cy: 140.25,
            r: 100.0,
        };
        let (small, moved) = to_radius(img.view(), &circle, 50.0).unwrap();
        // The disc's area is preserved in proportion, and its centroid is the moved centre.
        let (mut area, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for ((y, x), v) in small.indexed_iter() {
            area += v;
            sx += v * x as f64;
            sy += v * y as f64;
        }
        assert!((area - std::f64::consts::PI * 2500.0).abs() < 0.01 * area);
        assert!(
            (sx / area - moved.cx).abs() < 0.05 && (sy / area - moved.cy).abs() < 0.05,
            "{moved:?}"
        );
        assert!(to_radius(img.view(), &circle, 100.5).is_none());
    }
}
