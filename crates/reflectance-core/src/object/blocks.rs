//! A normal map reduced by square blocks: what the equivalent sphere reads of a large
//! photograph (with its mean luminance), and the grid the own-shadow test integrates.

use crate::image::resample;
use ndarray::Array2;

/// Per block, the normalized mean normal of its object pixels and their mean value; a block
/// is the object's when at least half its pixels are. Other blocks hold the zero normal
/// (background) and the value 0.
pub(crate) struct Blocks {
    pub normals: Vec<[f32; 3]>,
    pub values: Vec<f64>,
    pub object: Vec<bool>,
    pub w: usize,
    pub h: usize,
}

/// What to do with the blocks that the right and bottom borders cut.
#[derive(Clone, Copy)]
pub(crate) enum Border {
    /// Judged on the pixels they have: every pixel is in a block.
    Keep,
    /// Left out: every block is whole.
    Drop,
}

impl Blocks {
    /// `map` (`w`×`h`, row major) by `k`×`k` blocks, counting the pixels for which `object`
    /// holds; `values` (the same size), when given, are averaged over the same pixels.
    pub(crate) fn of(
        map: &[[f32; 3]],
        values: Option<&[f64]>,
        object: impl Fn(usize) -> bool,
        (w, h): (usize, usize),
        k: usize,
        border: Border,
    ) -> Blocks {
        let (bw, bh) = match border {
            Border::Keep => (w.div_ceil(k), h.div_ceil(k)),
            Border::Drop => (w / k, h / k),
        };
        let mut out = Blocks {
            normals: vec![[0.0; 3]; bw * bh],
            values: vec![0.0; if values.is_some() { bw * bh } else { 0 }],
            object: vec![false; bw * bh],
            w: bw,
            h: bh,
        };
        for b in 0..bw * bh {
            let (by, bx) = (b / bw, b % bw);
            let cols = bx * k..((bx + 1) * k).min(w);
            let (mut n, mut total, mut sum, mut value) = (0usize, 0usize, [0.0f32; 3], 0.0);
            for y in by * k..((by + 1) * k).min(h) {
                total += cols.len();
                for i in y * w + cols.start..y * w + cols.end {
                    if !object(i) {
                        continue;
                    }
                    let m = map[i];
                    n += 1;
                    sum = [sum[0] + m[0], sum[1] + m[1], sum[2] + m[2]];
                    if let Some(values) = values {
                        value += values[i];
                    }
                }
            }
            let length = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
            if 2 * n >= total && length > 0.0 {
                out.normals[b] = sum.map(|c| c / length);
                out.object[b] = true;
                if let Some(v) = out.values.get_mut(b) {
                    *v = value / n as f64;
                }
            }
        }
        out
    }
}

impl Blocks {
    /// `map` (`w`×`h`, row major) reduced by `factor` ∈ (0, 1] with area weights, as a
    /// sphere is brought to the working radius ([`resample::downsample`]): per output pixel,
    /// the normalized mean normal of the object pixels it covers and their mean value; the
    /// object's when they cover at least half of it. Only the object's bounding box (and a
    /// margin) is reduced.
    pub(crate) fn by_area(
        map: &[[f32; 3]],
        values: &[f64],
        object: impl Fn(usize) -> bool,
        (w, h): (usize, usize),
        factor: f64,
    ) -> Blocks {
        let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
        for i in (0..w * h).filter(|&i| object(i)) {
            let (y, x) = (i / w, i % w);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x + 1), y0.min(y), y1.max(y + 1));
        }
        let (x0, y0) = (
            x0.min(x1).saturating_sub(MARGIN),
            y0.min(y1).saturating_sub(MARGIN),
        );
        let (x1, y1) = ((x1 + MARGIN).min(w), (y1 + MARGIN).min(h));
        let reduced = |of: &dyn Fn(usize) -> f64| {
            let crop = Array2::from_shape_fn((y1 - y0, x1 - x0), |(y, x)| {
                let i = (y0 + y) * w + x0 + x;
                if object(i) { of(i) } else { 0.0 }
            });
            resample::downsample(crop.view(), factor)
        };
        let cover = reduced(&|_| 1.0);
        let value = reduced(&|i| values[i]);
        let axes = [0, 1, 2].map(|c| reduced(&|i| f64::from(map[i][c])));
        let (bh, bw) = cover.dim();
        let mut out = Blocks {
            normals: vec![[0.0; 3]; bw * bh],
            values: vec![0.0; bw * bh],
            object: vec![false; bw * bh],
            w: bw,
            h: bh,
        };
        for (b, ((y, x), &c)) in cover.indexed_iter().enumerate() {
            let sum = axes.each_ref().map(|a| a[(y, x)]);
            let length = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
            if c >= 0.5 && length > 0.0 {
                out.normals[b] = sum.map(|v| (v / length) as f32);
                out.object[b] = true;
                out.values[b] = value[(y, x)] / c;
            }
        }
        out
    }
}

/// Background pixels kept around the object's bounding box by [`Blocks::by_area`], so that
/// its border pixels are not the object's.
const MARGIN: usize = 2;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_average_the_object_pixels_they_hold() {
        // 5 × 3, blocks of 2: the right column and bottom row are cut by the border.
        let up = [0.0, 0.0, 1.0];
        let right = [1.0, 0.0, 0.0];
        let mut map = vec![up; 15];
        map[1] = right;
        map[14] = [0.0; 3];
        let values: Vec<f64> = (0..15).map(f64::from).collect();
        let object = |i: usize| map[i] != [0.0; 3] && i != 5;
        let kept = Blocks::of(&map, Some(&values), object, (5, 3), 2, Border::Keep);
        assert_eq!((kept.w, kept.h), (3, 2));
        // Pixels 0, 1 and 6 (5 is not the object's): two up, one right.
        let s = 5f32.sqrt();
        assert_eq!(kept.normals[0], [1.0 / s, 0.0, 2.0 / s]);
        assert!((kept.values[0] - 7.0 / 3.0).abs() < 1e-12);
        // The cut corner block holds pixel 14 alone, which is background.
        assert!(!kept.object[5]);
        assert_eq!(kept.normals[5], [0.0; 3]);
        // The cut right column: pixels 4 and 9, both up.
        assert_eq!(kept.normals[2], up);
        assert!((kept.values[2] - 6.5).abs() < 1e-12);
        let dropped = Blocks::of(&map, None, object, (5, 3), 2, Border::Drop);
        assert_eq!((dropped.w, dropped.h), (2, 1));
        assert_eq!(dropped.normals[0], kept.normals[0]);
        assert!(dropped.values.is_empty());
    }

    #[test]
    fn by_area_averages_the_object_pixels_each_output_pixel_covers() {
        // 8 × 8, the object all but the two left columns, values the column; halved.
        let (w, h) = (8, 8);
        let up = [0.0, 0.0, 1.0];
        let tilted = [0.6, 0.0, 0.8];
        let map: Vec<[f32; 3]> = (0..w * h)
            .map(|i| if i % w < 6 { up } else { tilted })
            .collect();
        let values: Vec<f64> = (0..w * h).map(|i| (i % w) as f64).collect();
        let object = |i: usize| i % w >= 2;
        let half = Blocks::by_area(&map, &values, object, (w, h), 0.5);
        assert_eq!((half.w, half.h), (4, 4));
        for y in 0..4 {
            let row = &half.object[y * 4..y * 4 + 4];
            assert_eq!(row, [false, true, true, true]);
            assert!((half.values[y * 4 + 1] - 2.5).abs() < 1e-12);
            assert!((half.values[y * 4 + 3] - 6.5).abs() < 1e-12);
            assert_eq!(half.normals[y * 4 + 3], tilted);
        }
        // A quarter: one output pixel covers four columns, two of them the object's.
        let quarter = Blocks::by_area(&map, &values, object, (w, h), 0.25);
        assert_eq!(quarter.object, [true, true, true, true]);
        assert!((quarter.values[0] - 2.5).abs() < 1e-12);
        // Between up and tilted: their normalized mean.
        let n = quarter.normals[1];
        assert!((n[0] / n[2] - 0.3 / 0.9).abs() < 1e-6, "{n:?}");
    }
}
