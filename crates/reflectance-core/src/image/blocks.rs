//! A normal map reduced by square blocks: what the equivalent sphere reads of a large
//! photograph (with its mean luminance), and the grid the own-shadow test integrates.

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
}
