//! Separable QMF wavelet pyramid with Simoncelli's 9-tap `qmf9` filters (as pyrtools).
//!
//! Per level: filter along y (axis 0) with stride 2, then along x (axis 1) with stride 2.
//! `corrDn(x, f, start)[m] = Σ_k f[k]·xe[start + 2m + k − 4]`; lowpass start 0, highpass 1.
//! Along y the edge is `reflect1`; along x it is periodic (the angle wraps) or `reflect1`
//! (which reproduces pyrtools' `WaveletPyramid(img, 'qmf9', 'reflect1')` exactly).

use ndarray::{Array2, ArrayView2, Axis};

/// qmf9 lowpass taps, not renormalized (they sum to √2).
pub const QMF9_LO: [f64; 9] = [
    0.02807382,
    -0.060944743,
    -0.073386624,
    0.41472545,
    0.7973934,
    0.41472545,
    -0.073386624,
    -0.060944743,
    0.02807382,
];

/// `HI[k] = LO[8−k]·(−1)^(4−k)`.
pub const QMF9_HI: [f64; 9] = {
    let mut hi = [0.0; 9];
    let mut k = 0;
    while k < 9 {
        hi[k] = if (4 + k) % 2 == 0 {
            QMF9_LO[8 - k]
        } else {
            -QMF9_LO[8 - k]
        };
        k += 1;
    }
    hi
};

const HALF: isize = 4;

/// Edge handling along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// Mirror about the edge sample without repeating it (numpy `pad(mode='reflect')`).
    Reflect1,
    /// Wrap around.
    Periodic,
}

impl Edge {
    /// The source index of extended index `i` in a signal of length `n`.
    #[inline]
    fn index(self, i: isize, n: usize) -> usize {
        let n = n as isize;
        match self {
            Edge::Periodic => i.rem_euclid(n) as usize,
            Edge::Reflect1 if n == 1 => 0,
            Edge::Reflect1 => {
                let period = 2 * (n - 1);
                let m = i.rem_euclid(period);
                (if m < n { m } else { period - m }) as usize
            }
        }
    }
}

/// The three oriented subbands of one level.
#[derive(Clone, Debug)]
pub struct Level {
    /// HI along y, LO along x: horizontal structure.
    pub h: Array2<f64>,
    /// LO along y, HI along x: vertical (on the sphere, radial) structure.
    pub v: Array2<f64>,
    /// HI along both.
    pub d: Array2<f64>,
}

#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Finest first.
    pub levels: Vec<Level>,
    /// The residual lowpass (not a feature).
    pub lowpass: Array2<f64>,
}

/// Output length of a stride-2 correlation starting at `start` (pyrtools: ⌈(n − start)/2⌉).
fn out_len(n: usize, start: usize) -> usize {
    (n.saturating_sub(start)).div_ceil(2)
}

/// Correlate along y (rows) with stride 2, reflect1 edges; vectorizes across columns.
fn corr_down_y(input: ArrayView2<f64>, taps: &[f64; 9], start: usize) -> Array2<f64> {
    let (n, w) = input.dim();
    let mut out = Array2::zeros((out_len(n, start), w));
    for (m, mut out_row) in out.axis_iter_mut(Axis(0)).enumerate() {
        let dst = out_row.as_slice_mut().expect("standard layout");
        for (k, &tap) in taps.iter().enumerate() {
            let src_index = Edge::Reflect1.index((start + 2 * m) as isize + k as isize - HALF, n);
            let src = input.row(src_index);
            let src = src.as_slice().expect("standard layout");
            dst.iter_mut().zip(src).for_each(|(d, &s)| *d += tap * s);
        }
    }
    out
}

/// Correlate along x (columns) with stride 2, for both filters at once.
fn corr_down_x(input: ArrayView2<f64>, edge: Edge) -> (Array2<f64>, Array2<f64>) {
    let (h, n) = input.dim();
    let (n_lo, n_hi) = (out_len(n, 0), out_len(n, 1));
    let mut lo = Array2::zeros((h, n_lo));
    let mut hi = Array2::zeros((h, n_hi));
    let mut padded = vec![0.0; n + 2 * HALF as usize];
    for y in 0..h {
        let row = input.row(y);
        for (i, p) in padded.iter_mut().enumerate() {
            *p = row[edge.index(i as isize - HALF, n)];
        }
        let lo_row = lo.row_mut(y).into_slice().expect("standard layout");
        for (m, out) in lo_row.iter_mut().enumerate() {
            *out = dot9(&QMF9_LO, &padded[2 * m..]);
        }
        let hi_row = hi.row_mut(y).into_slice().expect("standard layout");
        for (m, out) in hi_row.iter_mut().enumerate() {
            *out = dot9(&QMF9_HI, &padded[1 + 2 * m..]);
        }
    }
    (lo, hi)
}

#[inline(always)]
fn dot9(taps: &[f64; 9], window: &[f64]) -> f64 {
    let w = &window[..9];
    taps.iter().zip(w).fold(0.0, |acc, (t, x)| acc + t * x)
}

/// Build `levels` levels; `x_edge` is the edge rule along x (y is always reflect1).
pub fn build(image: ArrayView2<f64>, levels: usize, x_edge: Edge) -> Pyramid {
    let mut current = image.to_owned();
    let mut out = Vec::with_capacity(levels);
    for _ in 0..levels {
        let lo_y = corr_down_y(current.view(), &QMF9_LO, 0);
        let hi_y = corr_down_y(current.view(), &QMF9_HI, 1);
        let (lolo, v) = corr_down_x(lo_y.view(), x_edge);
        let (h, d) = corr_down_x(hi_y.view(), x_edge);
        out.push(Level { h, v, d });
        current = lolo;
    }
    Pyramid {
        levels: out,
        lowpass: current,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn highpass_taps_follow_the_modulate_flip_rule() {
        let expected = [
            0.02807382,
            0.060944743,
            -0.073386624,
            -0.41472545,
            0.7973934,
            -0.41472545,
            -0.073386624,
            0.060944743,
            0.02807382,
        ];
        assert_eq!(QMF9_HI, expected);
        // qmf9 is only approximately a QMF: DC gains √2 + 1.2e-4 and −7.9e-4.
        let lo_sum: f64 = QMF9_LO.iter().sum();
        assert!((lo_sum - 1.414_329_206).abs() < 1e-12);
        assert!((QMF9_HI.iter().sum::<f64>() + 0.000_793_622).abs() < 1e-12);
    }

    #[test]
    fn edge_indices() {
        let r: Vec<usize> = (-4..9).map(|i| Edge::Reflect1.index(i, 5)).collect();
        assert_eq!(r, [4, 3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1, 0]);
        let p: Vec<usize> = (-2..7).map(|i| Edge::Periodic.index(i, 5)).collect();
        assert_eq!(p, [3, 4, 0, 1, 2, 3, 4, 0, 1]);
    }

    #[test]
    fn sizes_halve_per_level() {
        let img = Array2::from_shape_fn((96, 448), |(y, x)| ((x * 7 + y * 3) % 11) as f64);
        let pyr = build(img.view(), 4, Edge::Periodic);
        let dims: Vec<_> = pyr.levels.iter().map(|l| l.v.dim()).collect();
        assert_eq!(dims, [(48, 224), (24, 112), (12, 56), (6, 28)]);
        assert_eq!(pyr.lowpass.dim(), (6, 28));
        let odd = Array2::from_shape_fn((75, 90), |(y, x)| (x + y) as f64);
        let level = &build(odd.view(), 1, Edge::Reflect1).levels[0];
        assert_eq!(
            (level.h.dim(), level.v.dim(), level.d.dim()),
            ((37, 45), (38, 45), (37, 45))
        );
    }

    #[test]
    fn constant_image_gives_the_filters_dc_gains() {
        let (lo, hi): (f64, f64) = (QMF9_LO.iter().sum(), QMF9_HI.iter().sum());
        let img = Array2::from_elem((48, 64), 2.5);
        let pyr = build(img.view(), 3, Edge::Periodic);
        let mut level_in = 2.5;
        for level in &pyr.levels {
            let expect = |band: &Array2<f64>, gain: f64| {
                assert!(
                    band.iter().all(|v| (v - level_in * gain).abs() < 1e-12),
                    "{band:?}"
                );
            };
            expect(&level.h, hi * lo);
            expect(&level.v, lo * hi);
            expect(&level.d, hi * hi);
            level_in *= lo * lo;
        }
        assert!(pyr.lowpass.iter().all(|v| (v - level_in).abs() < 1e-12));
    }

    #[test]
    fn circular_shift_shifts_subbands() {
        let img = Array2::from_shape_fn((96, 448), |(y, x)| {
            ((x as f64 * 0.37).sin() + (y as f64 * 0.11).cos()) * ((x * y) % 13) as f64
        });
        let shift = 16;
        let shifted = Array2::from_shape_fn((96, 448), |(y, x)| img[[y, (x + 448 - shift) % 448]]);
        let a = build(img.view(), 4, Edge::Periodic);
        let b = build(shifted.view(), 4, Edge::Periodic);
        for (k, (la, lb)) in a.levels.iter().zip(&b.levels).enumerate() {
            let s = shift >> (k + 1);
            for (ba, bb) in [(&la.h, &lb.h), (&la.v, &lb.v), (&la.d, &lb.d)] {
                let w = ba.ncols();
                for ((y, x), v) in ba.indexed_iter() {
                    assert!((bb[[y, (x + s) % w]] - v).abs() < 1e-12, "level {k}");
                }
            }
        }
    }
}
