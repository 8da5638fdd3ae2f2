//! Canonical unwrap: the annulus ρ ∈ [inner·r, outer·r] resampled onto a rows × cols grid
//! (radius down, angle across), each cell the mean of s×s bilinear samples, s = ⌈r / r0⌉.

use crate::geometry::Circle;
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
/// scalar path and `cos[b][j]`, `sin[b][j]` (one row per sub-column) for the SIMD path.
#[derive(Debug)]
pub struct AngleTable {
    pub s: usize,
    pub pairs: Vec<(f64, f64)>,
    cos: Vec<Vec<f64>>,
    sin: Vec<Vec<f64>>,
}

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
    let by_b = |f: fn(&(f64, f64)) -> f64| -> Vec<Vec<f64>> {
        (0..s)
            .map(|b| (0..cols).map(|j| f(&pairs[j * s + b])).collect())
            .collect()
    };
    AngleTable {
        s,
        cos: by_b(|p| p.0),
        sin: by_b(|p| p.1),
        pairs,
    }
}

/// Unwrap `image` around `circle`; `angles` must be [`angle_table`]`(cfg.cols, s)` for
/// `s = cfg.supersampling(circle.r)`.
pub fn unwrap(
    image: ArrayView2<f64>,
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &AngleTable,
) -> Array2<f64> {
    unwrap_with(image, circle, cfg, angles, Kernel::detect())
}

/// Which inner loop samples the interior of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    Scalar,
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    pub fn detect() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Kernel::Avx2;
        }
        Kernel::Scalar
    }
}

/// [`unwrap`] with an explicit kernel (every kernel gives bit-identical results).
pub fn unwrap_with(
    image: ArrayView2<f64>,
    circle: &Circle,
    cfg: &UnwrapConfig,
    angles: &AngleTable,
    kernel: Kernel,
) -> Array2<f64> {
    let s = cfg.supersampling(circle.r);
    assert!(
        angles.s == s && angles.pairs.len() == cfg.cols * s,
        "angle table does not match"
    );
    let sampler = Bilinear::new(image);
    let (h, sf) = (cfg.rows as f64, s as f64);
    let span = cfg.outer - cfg.inner;
    // Clamping can be skipped when every sample's 2×2 neighbourhood is inside the image.
    let reach = circle.r * cfg.outer + 1.0;
    let interior = circle.cx - reach >= 0.0
        && circle.cy - reach >= 0.0
        && circle.cx + reach < sampler.max_x as f64
        && circle.cy + reach < sampler.max_y as f64;
    let radii: Vec<f64> = (0..cfg.rows * s)
        .map(|q| {
            let (i, a) = ((q / s) as f64, (q % s) as f64);
            circle.r * (cfg.inner + span * (i + (a + 0.5) / sf) / h)
        })
        .collect();
    let mut out = Array2::zeros((cfg.rows, cfg.cols));
    let data = out.as_slice_mut().expect("standard layout");
    // Angular wedges of WEDGE columns over all radii keep the pixels in cache; each cell
    // still sums its sub-rows in order, so the result does not depend on the wedge size.
    for start in (0..cfg.cols).step_by(WEDGE) {
        let cells = start..(start + WEDGE).min(cfg.cols);
        for (row, rhos) in data.chunks_exact_mut(cfg.cols).zip(radii.chunks_exact(s)) {
            for &rho in rhos {
                let ring = Ring {
                    cx: circle.cx,
                    cy: circle.cy,
                    rho,
                };
                let row = &mut row[cells.clone()];
                match (interior, kernel) {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: Kernel::Avx2 is only produced when the CPU supports AVX2, and
                    // `interior` guarantees every loaded index is inside the image.
                    (true, Kernel::Avx2) => unsafe {
                        avx2::accumulate(&ring, &sampler, angles, row, cells.start)
                    },
                    (true, _) => ring.accumulate::<true>(&sampler, angles, row, cells.start),
                    (false, _) => ring.accumulate::<false>(&sampler, angles, row, cells.start),
                }
            }
        }
    }
    let norm = 1.0 / (s * s) as f64;
    data.iter_mut().for_each(|v| *v *= norm);
    out
}

/// Columns per angular wedge.
const WEDGE: usize = 64;

/// One sub-row of samples: the circle of radius `rho` around the centre.
struct Ring {
    cx: f64,
    cy: f64,
    rho: f64,
}

impl Ring {
    /// Adds the samples of cells `first..first + row.len()` to `row`.
    #[inline(always)]
    fn accumulate<const INTERIOR: bool>(
        &self,
        sampler: &Bilinear,
        angles: &AngleTable,
        row: &mut [f64],
        first: usize,
    ) {
        let s = angles.s;
        let pairs = &angles.pairs[first * s..(first + row.len()) * s];
        for (cell, chunk) in row.iter_mut().zip(pairs.chunks_exact(s)) {
            let mut sum = 0.0;
            for &(cos, sin) in chunk {
                sum +=
                    sampler.sample::<INTERIOR>(self.cx + self.rho * cos, self.cy - self.rho * sin);
            }
            *cell += sum;
        }
    }
}

/// AVX2 interior kernel: four cells per step, one per lane; each lane performs exactly the
/// scalar path's operations in the same order (no FMA), so results are bit-identical.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{AngleTable, Bilinear, Ring};
    use std::arch::x86_64::*;

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn accumulate(
        ring: &Ring,
        sampler: &Bilinear,
        angles: &AngleTable,
        row: &mut [f64],
        first: usize,
    ) {
        let cols = row.len();
        let width = sampler.width as i32;
        let data = sampler.data.as_ptr();
        let (cx, cy, rho) = (
            _mm256_set1_pd(ring.cx),
            _mm256_set1_pd(ring.cy),
            _mm256_set1_pd(ring.rho),
        );
        let one = _mm256_set1_pd(1.0);
        let vwidth = _mm_set1_epi32(width);
        let full = cols / 4 * 4;
        for j in (0..full).step_by(4) {
            let mut sum = _mm256_setzero_pd();
            for b in 0..angles.s {
                let (cos, sin) = (
                    &angles.cos[b][first + j..first + j + 4],
                    &angles.sin[b][first + j..first + j + 4],
                );
                // SAFETY: both slices hold exactly four values.
                let (cos, sin) =
                    unsafe { (_mm256_loadu_pd(cos.as_ptr()), _mm256_loadu_pd(sin.as_ptr())) };
                let x = _mm256_add_pd(cx, _mm256_mul_pd(rho, cos));
                let y = _mm256_sub_pd(cy, _mm256_mul_pd(rho, sin));
                let (x0, y0) = (_mm256_floor_pd(x), _mm256_floor_pd(y));
                let (fx, fy) = (_mm256_sub_pd(x, x0), _mm256_sub_pd(y, y0));
                let base = _mm_add_epi32(
                    _mm_mullo_epi32(_mm256_cvttpd_epi32(y0), vwidth),
                    _mm256_cvttpd_epi32(x0),
                );
                let mut index = [0i32; 4];
                // SAFETY: `index` holds exactly four i32.
                unsafe { _mm_storeu_si128(index.as_mut_ptr().cast(), base) };
                // SAFETY: the caller checked that x0, y0 ≥ 0, x0 + 1 < width and y0 + 1 <
                // height for every sample, so base .. base + 1 and base + width ..
                // base + width + 1 index into the image.
                let (q0, q1, q2, q3) =
                    unsafe { quads(data, index.map(|i| i as usize), width as usize) };
                let gx = _mm256_sub_pd(one, fx);
                let top = _mm256_add_pd(_mm256_mul_pd(gx, q0), _mm256_mul_pd(fx, q1));
                let bottom = _mm256_add_pd(_mm256_mul_pd(gx, q2), _mm256_mul_pd(fx, q3));
                let gy = _mm256_sub_pd(one, fy);
                let value = _mm256_add_pd(_mm256_mul_pd(gy, top), _mm256_mul_pd(fy, bottom));
                sum = _mm256_add_pd(sum, value);
            }
            // SAFETY: j + 4 ≤ cols = row.len().
            unsafe {
                let cell = row.as_mut_ptr().add(j);
                _mm256_storeu_pd(cell, _mm256_add_pd(_mm256_loadu_pd(cell), sum));
            }
        }
        ring.accumulate::<true>(sampler, angles, &mut row[full..], first + full);
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
        let top = (1.0 - fx) * quad[0] + fx * quad[1];
        let bottom = (1.0 - fx) * quad[self.width] + fx * quad[self.width + 1];
        (1.0 - fy) * top + fy * bottom
    }

    #[cold]
    fn sample_clamped(&self, x0: isize, fx: f64, y0: isize, fy: f64) -> f64 {
        let xa = x0.clamp(0, self.max_x) as usize;
        let xb = (x0 + 1).clamp(0, self.max_x) as usize;
        let ya = (y0.clamp(0, self.max_y) as usize) * self.width;
        let yb = ((y0 + 1).clamp(0, self.max_y) as usize) * self.width;
        let d = self.data;
        let top = (1.0 - fx) * d[ya + xa] + fx * d[ya + xb];
        let bottom = (1.0 - fx) * d[yb + xa] + fx * d[yb + xb];
        (1.0 - fy) * top + fy * bottom
    }
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
        let mut state = 5u64;
        let img = Array2::from_shape_fn((300, 320), |_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        });
        let cfg = UnwrapConfig::default();
        for c in [
            circle(160.3, 149.6, 140.2),
            circle(90.0, 80.0, 60.0),
            circle(150.0, 150.0, 165.0),
        ] {
            let angles = angle_table(cfg.cols, cfg.supersampling(c.r));
            let scalar = unwrap_with(img.view(), &c, &cfg, &angles, Kernel::Scalar);
            let fast = unwrap_with(img.view(), &c, &cfg, &angles, Kernel::detect());
            assert!(
                scalar
                    .iter()
                    .zip(&fast)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
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
        let u_right = unwrap(right.view(), &circle(cx, cy, r), &cfg, &angles);
        let u_top = unwrap(top.view(), &circle(cx, cy, r), &cfg, &angles);
        // Column 20 (θ ≈ 16°) lies right of and above the centre; column 200 (θ ≈ 161°) left.
        assert_eq!(u_right[[50, 20]], 1.0);
        assert_eq!(u_top[[50, 20]], 1.0);
        assert_eq!(u_right[[50, 200]], 0.0);
        assert_eq!(u_top[[50, 300]], 0.0);
    }
}
