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

/// The three oriented subbands of one level (their coefficients, or with `T = bool` which
/// of them are [`supported`]).
#[derive(Clone, Debug)]
pub struct Level<T = f64> {
    /// HI along y, LO along x: horizontal structure.
    pub h: Array2<T>,
    /// LO along y, HI along x: vertical (on the sphere, radial) structure.
    pub v: Array2<T>,
    /// HI along both.
    pub d: Array2<T>,
}

/// The QMF wavelet pyramid of an image: each level's three oriented subbands and the
/// residual lowpass.
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

/// `out[m] = Σ_k taps[k]·inputs[k][m]`, summed in tap order (the order of a direct 9-tap
/// correlation), vectorized across `m`.
#[inline(always)]
fn weighted_sum9(out: &mut [f64], taps: &[f64; 9], inputs: [&[f64]; 9]) {
    let n = out.len();
    let inputs = inputs.map(|x| &x[..n]);
    for m in 0..n {
        let mut acc = taps[0] * inputs[0][m];
        for k in 1..9 {
            acc += taps[k] * inputs[k][m];
        }
        out[m] = acc;
    }
}

/// Correlate along y (rows) with stride 2, reflect1 edges.
#[inline(always)]
fn corr_down_y(input: ArrayView2<f64>, taps: &[f64; 9], start: usize) -> Array2<f64> {
    let (n, w) = input.dim();
    let data = input.to_slice().expect("standard layout");
    let mut out = Array2::zeros((out_len(n, start), w));
    for (m, out_row) in out
        .as_slice_mut()
        .expect("standard layout")
        .chunks_exact_mut(w)
        .enumerate()
    {
        let inputs: [&[f64]; 9] = std::array::from_fn(|k| {
            let row = Edge::Reflect1.index((start + 2 * m + k) as isize - HALF, n);
            &data[row * w..(row + 1) * w]
        });
        weighted_sum9(out_row, taps, inputs);
    }
    out
}

/// Correlate along x (columns) with stride 2, both filters. With the padded row split into
/// even and odd samples, each output is a tap-weighted sum of nine shifted slices.
#[inline(always)]
fn corr_down_x(input: ArrayView2<f64>, edge: Edge) -> (Array2<f64>, Array2<f64>) {
    let (h, n) = input.dim();
    let data = input.to_slice().expect("standard layout");
    let (n_lo, n_hi) = (out_len(n, 0), out_len(n, 1));
    let mut lo = Array2::zeros((h, n_lo));
    let mut hi = Array2::zeros((h, n_hi));
    let padded_len = n + 2 * HALF as usize;
    let mut even = vec![0.0; padded_len.div_ceil(2)];
    let mut odd = vec![0.0; padded_len / 2];
    let lo_rows = lo
        .as_slice_mut()
        .expect("standard layout")
        .chunks_exact_mut(n_lo);
    let hi_rows = hi
        .as_slice_mut()
        .expect("standard layout")
        .chunks_exact_mut(n_hi);
    for ((row, lo_row), hi_row) in data.chunks_exact(n).zip(lo_rows).zip(hi_rows) {
        let half = HALF as usize;
        let sample = |i: usize| {
            if (half..half + n).contains(&i) {
                row[i - half]
            } else {
                row[edge.index(i as isize - HALF, n)]
            }
        };
        for (t, e) in even.iter_mut().enumerate() {
            *e = sample(2 * t);
        }
        for (t, o) in odd.iter_mut().enumerate() {
            *o = sample(2 * t + 1);
        }
        // lo[m] = Σ LO[k]·padded[2m + k]; hi[m] = Σ HI[k]·padded[2m + 1 + k].
        let lo_inputs = std::array::from_fn(|k| {
            if k % 2 == 0 {
                &even[k / 2..]
            } else {
                &odd[k / 2..]
            }
        });
        let hi_inputs = std::array::from_fn(|k| {
            if k % 2 == 0 {
                &odd[k / 2..]
            } else {
                &even[k / 2 + 1..]
            }
        });
        weighted_sum9(lo_row, &QMF9_LO, lo_inputs);
        weighted_sum9(hi_row, &QMF9_HI, hi_inputs);
    }
    (lo, hi)
}

/// Build `levels` levels; `x_edge` is the edge rule along x (y is always reflect1).
///
/// Each level halves the size (rounding up). A constant image has next to no structure:
/// its subbands are near 0 (qmf9's highpass taps sum to nearly, not exactly, 0).
///
/// ```
/// use ndarray::Array2;
/// use reflectance_core::features::pyramid::{Edge, build};
///
/// let flat = Array2::from_elem((32, 64), 0.5);
/// let pyramid = build(flat.view(), 3, Edge::Periodic);
/// assert_eq!(pyramid.levels.len(), 3);
/// assert_eq!(pyramid.levels[0].h.dim(), (16, 32));
/// assert_eq!(pyramid.levels[2].d.dim(), (4, 8));
/// assert_eq!(pyramid.lowpass.dim(), (4, 8));
/// let finest = &pyramid.levels[0];
/// let bands = [&finest.h, &finest.v, &finest.d];
/// assert!(bands.iter().all(|b| b.iter().all(|v| v.abs() < 1e-3)));
/// ```
pub fn build(image: ArrayView2<f64>, levels: usize, x_edge: Edge) -> Pyramid {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2. The AVX2 build performs the same IEEE operations
        // in the same order (no FMA), so results are bit-identical to the portable one.
        return unsafe { build_avx2(image, levels, x_edge) };
    }
    build_portable(image, levels, x_edge)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn build_avx2(image: ArrayView2<f64>, levels: usize, x_edge: Edge) -> Pyramid {
    build_portable(image, levels, x_edge)
}

#[inline(always)]
fn build_portable(image: ArrayView2<f64>, levels: usize, x_edge: Edge) -> Pyramid {
    let mut current = image.as_standard_layout();
    let mut out = Vec::with_capacity(levels);
    for _ in 0..levels {
        let lo_y = corr_down_y(current.view(), &QMF9_LO, 0);
        let hi_y = corr_down_y(current.view(), &QMF9_HI, 1);
        let (lolo, v) = corr_down_x(lo_y.view(), x_edge);
        let (h, d) = corr_down_x(hi_y.view(), x_edge);
        out.push(Level { h, v, d });
        current = lolo.into();
    }
    Pyramid {
        levels: out,
        lowpass: current.into_owned(),
    }
}

/// Which coefficients of each level [`build`] computes from observed samples only: a
/// coefficient is supported when every sample its filters read, through every coarser
/// step, is observed (edges folded as `build` folds them). Over an image with missing
/// regions (the equivalent sphere of an object, issue #44), statistics over the supported
/// coefficients do not depend on what fills the missing samples.
pub fn supported(observed: ArrayView2<bool>, levels: usize, x_edge: Edge) -> Vec<Level<bool>> {
    let mut current = observed.to_owned();
    let mut out = Vec::with_capacity(levels);
    for _ in 0..levels {
        let lo_y = all_down(current.view(), Axis(0), 0, Edge::Reflect1);
        let hi_y = all_down(current.view(), Axis(0), 1, Edge::Reflect1);
        out.push(Level {
            h: all_down(hi_y.view(), Axis(1), 0, x_edge),
            v: all_down(lo_y.view(), Axis(1), 1, x_edge),
            d: all_down(hi_y.view(), Axis(1), 1, x_edge),
        });
        current = all_down(lo_y.view(), Axis(1), 0, x_edge);
    }
    out
}

/// `out[m]`: whether all nine samples a stride-2 correlation from `start` reads along
/// `axis` are set.
fn all_down(input: ArrayView2<bool>, axis: Axis, start: usize, edge: Edge) -> Array2<bool> {
    let n = input.len_of(axis);
    let mut shape = input.raw_dim();
    shape[axis.index()] = out_len(n, start);
    let mut out = Array2::from_elem(shape, true);
    for (mut out_lane, in_lane) in out.lanes_mut(axis).into_iter().zip(input.lanes(axis)) {
        for (m, o) in out_lane.iter_mut().enumerate() {
            *o = (0..9).all(|k| in_lane[edge.index((start + 2 * m + k) as isize - HALF, n)]);
        }
    }
    out
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
    fn portable_and_dispatched_builds_are_bit_identical() {
        let img = Array2::from_shape_fn((96, 448), |(y, x)| {
            ((x * 31 + y * 17) % 23) as f64 / 7.0 - 1.3
        });
        let b = build_portable(img.view(), 4, Edge::Periodic);
        let same = |a: &Pyramid| {
            for (la, lb) in a.levels.iter().zip(&b.levels) {
                for (x, y) in [(&la.h, &lb.h), (&la.v, &lb.v), (&la.d, &lb.d)] {
                    assert!(x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()));
                }
            }
        };
        same(&build(img.view(), 4, Edge::Periodic));
        #[cfg(target_arch = "x86_64")]
        if crate::util::simd_under_test("avx2") {
            // SAFETY: the CPU supports AVX2.
            same(&unsafe { build_avx2(img.view(), 4, Edge::Periodic) });
        }
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

    /// Supported coefficients are exactly those the missing samples cannot reach: filling
    /// a hole with 0 or with 1000 leaves them bit-identical and changes every other one.
    #[test]
    fn supported_coefficients_are_those_a_hole_cannot_reach() {
        let (h, w) = (40, 72);
        let mut rng = crate::util::rng::Rng::new(7);
        let base = Array2::from_shape_fn((h, w), |_| rng.next_f64());
        // A hole inside, and one across the angle's wrap (x = 0) to test the periodic edge.
        let observed = Array2::from_shape_fn((h, w), |(y, x)| {
            let inside = (14..20).contains(&y) && (30..37).contains(&x);
            let wrap = (28..31).contains(&y) && !(2..=69).contains(&x);
            !(inside || wrap)
        });
        for edge in [Edge::Periodic, Edge::Reflect1] {
            let filled = |value: f64| {
                Array2::from_shape_fn((h, w), |i| if observed[i] { base[i] } else { value })
            };
            let (zero, big) = (
                build(filled(0.0).view(), 3, edge),
                build(filled(1e3).view(), 3, edge),
            );
            let support = supported(observed.view(), 3, edge);
            let mut counts = (0, 0);
            for ((a, b), s) in zero.levels.iter().zip(&big.levels).zip(&support) {
                for (a, b, s) in [(&a.h, &b.h, &s.h), (&a.v, &b.v, &s.v), (&a.d, &b.d, &s.d)] {
                    assert_eq!(a.dim(), s.dim());
                    for ((x, y), ok) in a.iter().zip(b).zip(s) {
                        assert_eq!(x == y, *ok, "{edge:?}: {x} vs {y}, supported {ok}");
                        counts = (counts.0 + usize::from(*ok), counts.1 + usize::from(!ok));
                    }
                }
            }
            assert!(counts.0 > 0 && counts.1 > 0, "{edge:?}: {counts:?}");
        }
    }

    #[test]
    fn every_coefficient_of_a_whole_image_is_supported() {
        let observed = Array2::from_elem((33, 64), true);
        let support = supported(observed.view(), 4, Edge::Periodic);
        let pyramid = build(Array2::zeros((33, 64)).view(), 4, Edge::Periodic);
        for (s, l) in support.iter().zip(&pyramid.levels) {
            assert_eq!(
                (s.h.dim(), s.v.dim(), s.d.dim()),
                (l.h.dim(), l.v.dim(), l.d.dim())
            );
            assert!(s.h.iter().chain(&s.v).chain(&s.d).all(|&ok| ok));
        }
    }
}
