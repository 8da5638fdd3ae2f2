//! Canonical unwrap: the annulus ρ ∈ [inner·r, outer·r] resampled onto a rows × cols grid
//! (radius down, angle across), each cell the mean of s×s bilinear samples, s = ⌈r / r0⌉.

use crate::image::circle::Circle;
use crate::object::footprint::Footprint;
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

/// Sample directions of one supersampling factor, in two layouts: `pairs[j·s + b]` for the
/// scalar path and `lanes[g·s + b]` = (cos, sin) of columns 4g … 4g+3 for the SIMD path.
#[derive(Debug)]
pub struct AngleTable {
    pub s: usize,
    pub pairs: Vec<(f64, f64)>,
    lanes: Vec<[[f64; LANES]; 2]>,
}

/// Columns per SIMD step.
const LANES: usize = 4;

/// The directions θ = 2π(j + (b+0.5)/s)/W of every sub-column sample.
pub fn angle_table(cols: usize, s: usize) -> AngleTable {
    let (w, sf) = (cols as f64, s as f64);
    let theta = |j: usize, b: usize| 2.0 * PI * (j as f64 + (b as f64 + 0.5) / sf) / w;
    let pairs = (0..cols * s)
        .map(|q| {
            let t = theta(q / s, q % s);
            (t.cos(), t.sin())
        })
        .collect::<Vec<_>>();
    let lanes = (0..cols / LANES * s)
        .map(|q| {
            let (group, b) = (q / s, q % s);
            let pair = |k: usize| pairs[(group * LANES + k) * s + b];
            [
                std::array::from_fn(|k| pair(k).0),
                std::array::from_fn(|k| pair(k).1),
            ]
        })
        .collect();
    AngleTable { s, pairs, lanes }
}

/// Unwrap `image` around `circle`, every cell multiplied by `gain` (1/white, folded into
/// the cell normalization); `angles` must be [`angle_table`]`(cfg.cols, s)` for
/// `s = cfg.supersampling(circle.r)`.
pub fn unwrap(
    image: ArrayView2<f64>,
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &AngleTable,
    gain: f64,
) -> Array2<f64> {
    unwrap_with(image, circle, cfg, angles, gain, Kernel::detect())
}

/// Which inner loop samples the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    Scalar,
    /// AVX2 for the interior, the scalar loop compiled with FMA for the rest.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    pub fn detect() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Kernel::Avx2Fma;
        }
        Kernel::Scalar
    }
}

/// The sampling pattern of one unwrap: sub-row radii (`radii[i·s + a]`), the centre, and
/// the cell normalization gain/s².
struct Grid {
    cx: f64,
    cy: f64,
    radii: Vec<f64>,
    s: usize,
    cols: usize,
    norm: f64,
}

/// The radii ρ = r·(inner + span·(i + (a+0.5)/s)/rows) of every sub-row, `radii[i·s + a]`.
fn sample_radii(r: f64, cfg: &UnwrapConfig, s: usize) -> Vec<f64> {
    let (h, sf) = (cfg.rows as f64, s as f64);
    let span = cfg.outer - cfg.inner;
    (0..cfg.rows * s)
        .map(|q| {
            let (i, a) = ((q / s) as f64, (q % s) as f64);
            r * (cfg.inner + span * (i + (a + 0.5) / sf) / h)
        })
        .collect()
}

impl Grid {
    fn new(circle: &Circle, cfg: &UnwrapConfig, s: usize, gain: f64) -> Grid {
        Grid {
            cx: circle.cx,
            cy: circle.cy,
            radii: sample_radii(circle.r, cfg, s),
            s,
            cols: cfg.cols,
            norm: gain / (s * s) as f64,
        }
    }

    /// Mean of the s×s samples of the cell whose sub-row radii are `radii` and whose
    /// sub-column directions are `pairs`. Every kernel sums in this order — sub-columns
    /// within a sub-row, then sub-rows — and rounds exactly as here (one FMA per position
    /// coordinate and per lerp), so all kernels agree bit for bit.
    #[inline(always)]
    fn cell<const INTERIOR: bool>(
        &self,
        sampler: &Bilinear,
        radii: &[f64],
        pairs: &[(f64, f64)],
    ) -> f64 {
        let mut acc = 0.0;
        for &rho in radii {
            let mut part = 0.0;
            for &(cos, sin) in pairs {
                let (x, y) = (rho.mul_add(cos, self.cx), (-rho).mul_add(sin, self.cy));
                part += sampler.sample::<INTERIOR>(x, y);
            }
            acc += part;
        }
        acc * self.norm
    }

    /// Fills columns `first..` of `out` (rows × cols, row-major) with the scalar loop,
    /// column by column so that consecutive sub-rows reuse cached pixels.
    #[inline(always)]
    fn fill_columns(
        &self,
        sampler: &Bilinear,
        angles: &AngleTable,
        interior: bool,
        out: &mut [f64],
        first: usize,
    ) {
        for j in first..self.cols {
            let pairs = &angles.pairs[j * self.s..(j + 1) * self.s];
            for (i, radii) in self.radii.chunks_exact(self.s).enumerate() {
                out[i * self.cols + j] = if interior {
                    self.cell::<true>(sampler, radii, pairs)
                } else {
                    self.cell::<false>(sampler, radii, pairs)
                };
            }
        }
    }
}

/// [`Grid::fill_columns`] compiled with FMA, so `mul_add` is one instruction instead of a
/// libm call.
///
/// # Safety
/// The CPU must support FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn fill_columns_fma(
    grid: &Grid,
    sampler: &Bilinear,
    angles: &AngleTable,
    interior: bool,
    out: &mut [f64],
    first: usize,
) {
    grid.fill_columns(sampler, angles, interior, out, first);
}

/// [`unwrap`] with an explicit kernel (every kernel gives bit-identical results).
pub fn unwrap_with(
    image: ArrayView2<f64>,
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &AngleTable,
    gain: f64,
    kernel: Kernel,
) -> Array2<f64> {
    let s = cfg.supersampling(circle.r);
    assert!(
        angles.s == s && angles.pairs.len() == cfg.cols * s,
        "angle table does not match"
    );
    let sampler = Bilinear::new(image);
    let grid = Grid::new(circle, cfg, s, gain);
    // Clamping can be skipped when every sample's 2×2 neighbourhood is inside the image.
    let reach = circle.r * cfg.outer + 1.0;
    let interior = circle.cx - reach >= 0.0
        && circle.cy - reach >= 0.0
        && circle.cx + reach < sampler.max_x as f64
        && circle.cy + reach < sampler.max_y as f64;
    let mut out = Array2::zeros((cfg.rows, cfg.cols));
    let data = out.as_slice_mut().expect("standard layout");
    match kernel {
        Kernel::Scalar => grid.fill_columns(&sampler, angles, interior, data, 0),
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2Fma => {
            // The SIMD kernel computes pixel indices in i32.
            let first = if interior && sampler.data.len() < i32::MAX as usize {
                // SAFETY: Avx2Fma is only produced when the CPU supports AVX2 and FMA, and
                // `interior` guarantees every loaded index is inside the image.
                unsafe { avx2::fill_groups(&grid, &sampler, angles, data) }
            } else {
                0
            };
            // SAFETY: as above, the CPU supports FMA.
            unsafe { fill_columns_fma(&grid, &sampler, angles, interior, data, first) };
        }
    }
    out
}

/// The annulus of pixels scattered over a sphere around `circle` (an object's, placed by
/// their normals on its equivalent sphere): each sample of [`unwrap`] takes the mean of the
/// footprints covering it, weighted by their tents, so the pixels are resampled once, as a
/// sphere's photograph is (on a sphere's own pixels the tents are bilinear interpolation);
/// each cell is the mean of its samples some footprint reached. Also returns which cells
/// had such a sample. `angles` as for [`unwrap`].
pub fn unwrap_footprints(
    footprints: &[(Footprint, f64)],
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &AngleTable,
) -> (Array2<f64>, Array2<bool>) {
    let s = cfg.supersampling(circle.r);
    assert!(angles.s == s, "angle table does not match");
    let radii = sample_radii(circle.r, cfg, s);
    let (sub_rows, sub_cols) = (cfg.rows * s, cfg.cols * s);
    let mut sum = vec![0.0; sub_rows * sub_cols];
    let mut weight = vec![0.0; sub_rows * sub_cols];
    for (footprint, value) in footprints {
        let span = SampleSpan::of(footprint, circle, cfg, s);
        let weights = footprint.weights(span.small);
        for a in span.rows {
            let rho = radii[a];
            for b in span.cols.clone() {
                let b = b.rem_euclid(sub_cols as isize) as usize;
                let (cos, sin) = angles.pairs[b];
                let (x, y) = (rho.mul_add(cos, circle.cx), (-rho).mul_add(sin, circle.cy));
                let w = weights.at(x, y);
                if w > 0.0 {
                    sum[a * sub_cols + b] += w * value;
                    weight[a * sub_cols + b] += w;
                }
            }
        }
    }
    let mut out = Array2::zeros((cfg.rows, cfg.cols));
    let mut reached = Array2::from_elem((cfg.rows, cfg.cols), false);
    for ((i, j), v) in out.indexed_iter_mut() {
        let (mut total, mut n) = (0.0, 0usize);
        for a in i * s..(i + 1) * s {
            for q in a * sub_cols + j * s..a * sub_cols + (j + 1) * s {
                if weight[q] > 0.0 {
                    total += sum[q] / weight[q];
                    n += 1;
                }
            }
        }
        if n > 0 {
            *v = total / n as f64;
            reached[(i, j)] = true;
        }
    }
    (out, reached)
}

/// The sub-rows and sub-columns (unwrapped modulo the width) of the samples a footprint
/// may reach, and whether it spreads bilinearly (a point).
struct SampleSpan {
    rows: std::ops::Range<usize>,
    cols: std::ops::RangeInclusive<isize>,
    small: bool,
}

impl SampleSpan {
    fn of(footprint: &Footprint, circle: &Circle, cfg: &UnwrapConfig, s: usize) -> SampleSpan {
        // Unlike the sphere's square grid, the samples need no wider spread for pixels
        // smaller than a cell: tents that reach the neighbours' centres sum to one wherever
        // the pixels are regular, and wider ones would not (their normalized mean ripples).
        let small = footprint.degenerate();
        let (dx, dy) = (footprint.at[0] - circle.cx, footprint.at[1] - circle.cy);
        let rho = dx.hypot(dy);
        let (radial, across) = (
            footprint.extent([dx / rho, dy / rho]),
            footprint.extent([-dy / rho, dx / rho]),
        );
        // A footprint over the centre is inside the annulus's hole (its inner radius is far
        // more than the widest reach): no rows.
        if rho <= radial + across || !rho.is_finite() {
            return SampleSpan {
                rows: 0..0,
                cols: 0..=0,
                small,
            };
        }
        let per_r = (cfg.rows * s) as f64 / (cfg.outer - cfg.inner);
        let sub_row = |rho: f64| (rho / circle.r - cfg.inner) * per_r - 0.5;
        let first = sub_row(rho - radial).ceil().max(0.0) as usize;
        // Sideways reach takes a point farther out too.
        let farthest = (rho + radial).hypot(across);
        let last = (sub_row(farthest).floor() + 1.0).clamp(0.0, (cfg.rows * s) as f64) as usize;
        // Seen from the centre, what reaches `across` sideways from ρ − `radial` out.
        let turn = (across / (rho - radial)).min(1.0).asin();
        let per_theta = (cfg.cols * s) as f64 / (2.0 * PI);
        let centre = (-dy).atan2(dx).rem_euclid(2.0 * PI) * per_theta - 0.5;
        SampleSpan {
            rows: first..last.max(first),
            cols: (centre - turn * per_theta).ceil() as isize
                ..=(centre + turn * per_theta).floor() as isize,
            small,
        }
    }
}

/// AVX2 interior kernel: four adjacent cells per step, one per lane, each lane performing
/// exactly the operations of [`Grid::cell`] in the same order, so results are bit-identical.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{AngleTable, Bilinear, Grid, LANES};
    use std::arch::x86_64::*;

    /// Fills every complete group of four columns of `out`; returns the first column left.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; every sample's 2×2 neighbourhood must lie inside
    /// the image, and the image must have fewer than 2³¹ pixels.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn fill_groups(
        grid: &Grid,
        sampler: &Bilinear,
        angles: &AngleTable,
        out: &mut [f64],
    ) -> usize {
        let groups = grid.cols / LANES;
        let (cx, cy) = (_mm256_set1_pd(grid.cx), _mm256_set1_pd(grid.cy));
        let norm = _mm256_set1_pd(grid.norm);
        let width = _mm256_set1_pd(sampler.width as f64);
        assert!(out.len() == grid.radii.len() / grid.s * grid.cols);
        for (g, lanes) in angles.lanes.chunks_exact(grid.s).enumerate().take(groups) {
            for (i, radii) in grid.radii.chunks_exact(grid.s).enumerate() {
                let mut acc = _mm256_setzero_pd();
                for &rho in radii {
                    let rho = _mm256_set1_pd(rho);
                    let mut part = _mm256_setzero_pd();
                    for [cos, sin] in lanes {
                        // SAFETY: each array holds exactly four values.
                        let (cos, sin) = unsafe {
                            (_mm256_loadu_pd(cos.as_ptr()), _mm256_loadu_pd(sin.as_ptr()))
                        };
                        let x = _mm256_fmadd_pd(rho, cos, cx);
                        let y = _mm256_fnmadd_pd(rho, sin, cy);
                        // SAFETY: forwarded from the caller.
                        part = _mm256_add_pd(part, unsafe { sample(sampler, width, x, y) });
                    }
                    acc = _mm256_add_pd(acc, part);
                }
                let cell = i * grid.cols + g * LANES;
                // SAFETY: cell + 4 ≤ (i + 1)·cols ≤ out.len(), asserted above.
                unsafe { _mm256_storeu_pd(out.as_mut_ptr().add(cell), _mm256_mul_pd(acc, norm)) };
            }
        }
        groups * LANES
    }

    /// Bilinear samples at four positions, as [`Bilinear::sample`] computes each.
    ///
    /// # Safety
    /// As [`fill_groups`].
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn sample(sampler: &Bilinear, width: __m256d, x: __m256d, y: __m256d) -> __m256d {
        let (x0, y0) = (_mm256_floor_pd(x), _mm256_floor_pd(y));
        let (fx, fy) = (_mm256_sub_pd(x, x0), _mm256_sub_pd(y, y0));
        // y0·width + x0 is an exact integer below 2³¹ (the caller's guarantee).
        let index = _mm256_cvttpd_epi32(_mm256_fmadd_pd(y0, width, x0));
        let mut base = [0i32; 4];
        // SAFETY: `base` holds exactly four i32.
        unsafe { _mm_storeu_si128(base.as_mut_ptr().cast(), index) };
        // SAFETY: every sample's 2×2 neighbourhood is inside the image (the caller's
        // guarantee), so base .. base + 1 and base + width .. base + width + 1 index into it.
        let (q0, q1, q2, q3) = unsafe {
            quads(
                sampler.data.as_ptr(),
                base.map(|i| i as usize),
                sampler.width,
            )
        };
        let top = _mm256_fmadd_pd(fx, _mm256_sub_pd(q1, q0), q0);
        let bottom = _mm256_fmadd_pd(fx, _mm256_sub_pd(q3, q2), q2);
        _mm256_fmadd_pd(fy, _mm256_sub_pd(bottom, top), top)
    }

    /// The four bilinear corners of four samples, one sample per lane: the horizontal pairs
    /// are adjacent in memory, so two 128-bit loads per sample and an unpack transpose
    /// replace four gathers (which are slow on several x86 cores).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn quads(
        data: *const f64,
        base: [usize; 4],
        width: usize,
    ) -> (__m256d, __m256d, __m256d, __m256d) {
        // SAFETY: the caller guarantees base[k] + width + 1 is inside the image.
        unsafe {
            let pair = |offset: usize, k: usize| _mm_loadu_pd(data.add(base[k] + offset));
            let lanes = |offset: usize| {
                // [k0, k2] and [k1, k3] so that the unpacks come out in lane order 0..3.
                let even = _mm256_insertf128_pd(
                    _mm256_castpd128_pd256(pair(offset, 0)),
                    pair(offset, 2),
                    1,
                );
                let odd = _mm256_insertf128_pd(
                    _mm256_castpd128_pd256(pair(offset, 1)),
                    pair(offset, 3),
                    1,
                );
                (_mm256_unpacklo_pd(even, odd), _mm256_unpackhi_pd(even, odd))
            };
            let (q0, q1) = lanes(0);
            let (q2, q3) = lanes(width);
            (q0, q1, q2, q3)
        }
    }
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

    /// `INTERIOR`: the caller guarantees 0 ≤ x < width − 1 and 0 ≤ y < height − 1, so
    /// truncation is floor and no index needs clamping.
    #[inline(always)]
    fn sample<const INTERIOR: bool>(&self, x: f64, y: f64) -> f64 {
        let (x0, fx, y0, fy) = if INTERIOR {
            let (x0, y0) = (x as usize, y as usize);
            (x0, x - x0 as f64, y0, y - y0 as f64)
        } else {
            let (x0, fx) = floor_split(x);
            let (y0, fy) = floor_split(y);
            if x0 < 0 || y0 < 0 || x0 >= self.max_x || y0 >= self.max_y {
                return self.sample_clamped(x0, fx, y0, fy);
            }
            (x0 as usize, fx, y0 as usize, fy)
        };
        let base = y0 * self.width + x0;
        let quad = &self.data[base..base + self.width + 2];
        lerp2(
            fx,
            fy,
            [quad[0], quad[1], quad[self.width], quad[self.width + 1]],
        )
    }

    #[cold]
    fn sample_clamped(&self, x0: isize, fx: f64, y0: isize, fy: f64) -> f64 {
        let xa = x0.clamp(0, self.max_x) as usize;
        let xb = (x0 + 1).clamp(0, self.max_x) as usize;
        let ya = (y0.clamp(0, self.max_y) as usize) * self.width;
        let yb = ((y0 + 1).clamp(0, self.max_y) as usize) * self.width;
        let d = self.data;
        lerp2(fx, fy, [d[ya + xa], d[ya + xb], d[yb + xa], d[yb + xb]])
    }
}

/// Bilinear blend of the corners [top-left, top-right, bottom-left, bottom-right].
#[inline(always)]
fn lerp2(fx: f64, fy: f64, [q0, q1, q2, q3]: [f64; 4]) -> f64 {
    let top = fx.mul_add(q1 - q0, q0);
    let bottom = fx.mul_add(q3 - q2, q2);
    fy.mul_add(bottom - top, top)
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
        assert!((b.sample::<false>(3.25, 4.5) - (6.5 + 13.5)).abs() < 1e-12);
        // Outside the image the indices clamp: x = -0.5 gives weights 0.5/0.5 on column 0.
        assert!((b.sample::<false>(-0.5, 0.0) - 0.0).abs() < 1e-12);
        assert!((b.sample::<false>(9.5, 7.0) - (18.0 + 21.0)).abs() < 1e-12);
        assert_eq!(b.sample::<true>(3.25, 4.5), b.sample::<false>(3.25, 4.5));
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
            1.0,
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
    fn kernels_are_bit_identical() {
        let kernel = match crate::util::simd_under_test("avx2,fma") {
            #[cfg(target_arch = "x86_64")]
            true => Kernel::Avx2Fma,
            _ => Kernel::detect(),
        };
        let mut state = 5u64;
        let img = Array2::from_shape_fn((300, 320), |_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        });
        // 450 columns leave two for the scalar tail of the SIMD kernel; the last circle
        // reaches the border, so the clamping path runs.
        let odd = UnwrapConfig {
            cols: 450,
            ..UnwrapConfig::default()
        };
        for cfg in [UnwrapConfig::default(), odd] {
            for c in [
                circle(160.3, 149.6, 140.2),
                circle(90.0, 80.0, 60.0),
                circle(150.0, 150.0, 165.0),
            ] {
                let angles = angle_table(cfg.cols, cfg.supersampling(c.r));
                let gain = 1.0 / 0.7;
                let scalar = unwrap_with(img.view(), &c, &cfg, &angles, gain, Kernel::Scalar);
                let fast = unwrap_with(img.view(), &c, &cfg, &angles, gain, kernel);
                assert!(
                    scalar
                        .iter()
                        .zip(&fast)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{cfg:?} {c:?}"
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
        let u_right = unwrap(right.view(), &circle(cx, cy, r), &cfg, &angles, 1.0);
        let u_top = unwrap(top.view(), &circle(cx, cy, r), &cfg, &angles, 1.0);
        // Column 20 (θ ≈ 16°) lies right of and above the centre; column 200 (θ ≈ 161°) left.
        assert_eq!(u_right[[50, 20]], 1.0);
        assert_eq!(u_top[[50, 20]], 1.0);
        assert_eq!(u_right[[50, 200]], 0.0);
        assert_eq!(u_top[[50, 300]], 0.0);
    }

    /// Every pixel of a picture as its own footprint: at its centre, reaching its neighbours.
    fn pixel_footprints(
        image: &Array2<f64>,
        keep: impl Fn(usize, usize) -> bool,
    ) -> Vec<(Footprint, f64)> {
        image
            .indexed_iter()
            .filter(|&((y, x), _)| keep(y, x))
            .map(|((y, x), &v)| {
                let footprint = Footprint {
                    at: [x as f64, y as f64],
                    across: [0.5, 0.0],
                    down: [0.0, 0.5],
                };
                (footprint, v)
            })
            .collect()
    }

    #[test]
    fn pixels_as_footprints_unwrap_as_the_picture_does() {
        let image = Array2::from_shape_fn((260, 250), |(y, x)| {
            let (x, y) = (x as f64, y as f64);
            (0.3 * x).sin() * (0.17 * y).cos() + 0.01 * x + ((x * 7.0 + y * 13.0) % 5.0)
        });
        let cfg = UnwrapConfig::default();
        for r in [60.0, 116.36] {
            let c = circle(124.3, 129.6, r);
            let angles = angle_table(cfg.cols, cfg.supersampling(r));
            let want = unwrap(image.view(), &c, &cfg, &angles, 1.0);
            let footprints = pixel_footprints(&image, |_, _| true);
            let (got, reached) = unwrap_footprints(&footprints, &c, &cfg, &angles);
            assert!(reached.iter().all(|&r| r));
            let worst = (&got - &want).iter().fold(0.0f64, |m, d| m.max(d.abs()));
            assert!(worst < 1e-9, "r {r}: {worst}");
        }
    }

    #[test]
    fn cells_no_footprint_reaches_are_not_reached() {
        let image = Array2::from_elem((200, 200), 1.0);
        let cfg = UnwrapConfig::default();
        let c = circle(99.5, 99.5, 90.0);
        let angles = angle_table(cfg.cols, cfg.supersampling(c.r));
        // The left half of the picture only: the cells of angles around π.
        let footprints = pixel_footprints(&image, |_, x| x < 100);
        let (got, reached) = unwrap_footprints(&footprints, &c, &cfg, &angles);
        for ((_, j), &r) in reached.indexed_iter() {
            let theta = 2.0 * PI * (j as f64 + 0.5) / cfg.cols as f64;
            if theta.cos() < -0.05 {
                assert!(r, "column {j}");
            } else if theta.cos() > 0.05 {
                assert!(!r, "column {j}");
            }
        }
        assert!(
            got.iter()
                .zip(&reached)
                .all(|(&v, &r)| !r || (v - 1.0).abs() < 1e-12)
        );
    }
}
