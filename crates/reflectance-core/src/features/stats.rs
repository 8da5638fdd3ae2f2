//! Population moments (two passes, f64) and numpy-style linear-interpolation percentiles.

/// Floor of a variance, kurtosis or power before its log10.
const LOG_FLOOR: f64 = 1e-30;

/// log10 of a variance, kurtosis or power, floored at 1e-30: as the features take it.
pub(crate) fn log10_floor(v: f64) -> f64 {
    v.max(LOG_FLOOR).log10()
}

/// The seven statistics of one set of values, in canonical feature order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    /// Mean.
    pub mean: f64,
    /// Population variance `m2`.
    pub var: f64,
    /// Skewness `m3 / m2^1.5` (0 for constant values).
    pub skew: f64,
    /// Pearson kurtosis `m4 / m2²` (3 for a normal distribution and for constant values).
    pub kurt: f64,
    /// 10th percentile (numpy's linear method).
    pub p10: f64,
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
}

/// Statistic names in the order [`Summary::to_array`] returns them.
pub const STAT_NAMES: [&str; 7] = ["mean", "var", "skew", "kurt", "p10", "p50", "p90"];

impl Summary {
    /// The statistics in [`STAT_NAMES`] order.
    pub fn to_array(&self) -> [f64; 7] {
        [
            self.mean, self.var, self.skew, self.kurt, self.p10, self.p50, self.p90,
        ]
    }
}

/// Independent accumulators per pass: breaks the add-latency chain; the summation order is
/// fixed, so results are deterministic.
const LANES: usize = 8;

/// Sum with [`LANES`] independent accumulators: a single running sum is one long chain of
/// dependent additions, several times slower.
pub fn sum(values: &[f64]) -> f64 {
    let (chunks, tail) = values.split_at(values.len() / LANES * LANES);
    let mut lanes = [0.0f64; LANES];
    for chunk in chunks.chunks_exact(LANES) {
        for k in 0..LANES {
            lanes[k] += chunk[k];
        }
    }
    lanes.iter().sum::<f64>() + tail.iter().sum::<f64>()
}

/// Mean, variance `m2`, skewness `m3/m2^1.5` and Pearson kurtosis `m4/m2²`.
/// A numerically constant input (min == max, or m2 ≤ (1e-12·max|x|)²) has skew 0, kurt 3.
pub fn moments(values: &[f64]) -> Moments {
    let n = values.len() as f64;
    let (chunks, tail) = values.split_at(values.len() / LANES * LANES);
    let (total, min, max) = sum_and_range(values);
    let mean = total / n;
    let [m2, m3, m4] = lane_central_sums(chunks, mean);
    let (mut m2, mut m3, mut m4) = (
        m2.iter().sum::<f64>(),
        m3.iter().sum::<f64>(),
        m4.iter().sum::<f64>(),
    );
    for &x in tail {
        let d = x - mean;
        let d2 = d * d;
        m2 += d2;
        m3 += d2 * d;
        m4 += d2 * d2;
    }
    let (m2, m3, m4) = (m2 / n, m3 / n, m4 / n);
    let scale = 1e-12 * min.abs().max(max.abs());
    let constant = min == max || m2 <= scale * scale;
    Moments {
        mean,
        var: m2,
        skew: if constant { 0.0 } else { m3 / m2.powf(1.5) },
        kurt: if constant { 3.0 } else { m4 / (m2 * m2) },
        min,
        max,
    }
}

/// Σx, min and max (NaN values are skipped by min and max, not by the sum).
fn sum_and_range(values: &[f64]) -> (f64, f64, f64) {
    let (chunks, tail) = values.split_at(values.len() / LANES * LANES);
    let [sum, lo, hi] = lane_sums_and_range(chunks);
    let mut total: f64 = sum.iter().sum();
    let (mut min, mut max) = (
        lo.iter().copied().fold(f64::INFINITY, f64::min),
        hi.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    for &x in tail {
        total += x;
        min = min.min(x);
        max = max.max(x);
    }
    (total, min, max)
}

/// Per lane of `chunks` (a whole number of [`LANES`]-chunks): Σx, min and max.
fn lane_sums_and_range(chunks: &[f64]) -> [[f64; LANES]; 3] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX.
        return unsafe { avx::lane_sums_and_range(chunks) };
    }
    portable_sums_and_range(chunks)
}

fn portable_sums_and_range(chunks: &[f64]) -> [[f64; LANES]; 3] {
    let mut sum = [0.0f64; LANES];
    let (mut lo, mut hi) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
    for chunk in chunks.chunks_exact(LANES) {
        for k in 0..LANES {
            sum[k] += chunk[k];
            lo[k] = if chunk[k] < lo[k] { chunk[k] } else { lo[k] };
            hi[k] = if chunk[k] > hi[k] { chunk[k] } else { hi[k] };
        }
    }
    [sum, lo, hi]
}

/// Per lane of `chunks`: Σd², Σd³, Σd⁴ with d = x − mean.
fn lane_central_sums(chunks: &[f64], mean: f64) -> [[f64; LANES]; 3] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX.
        return unsafe { avx::lane_central_sums(chunks, mean) };
    }
    portable_central_sums(chunks, mean)
}

fn portable_central_sums(chunks: &[f64], mean: f64) -> [[f64; LANES]; 3] {
    let (mut m2, mut m3, mut m4) = ([0.0f64; LANES], [0.0f64; LANES], [0.0f64; LANES]);
    for chunk in chunks.chunks_exact(LANES) {
        for k in 0..LANES {
            let d = chunk[k] - mean;
            let d2 = d * d;
            m2[k] += d2;
            m3[k] += d2 * d;
            m4[k] += d2 * d2;
        }
    }
    [m2, m3, m4]
}

/// The lane loops with the eight lanes in two AVX registers, each lane performing exactly
/// the portable loop's operations (`minpd`/`maxpd` are its compare-selects): results are
/// bit-identical. The compiler's own vectorization of those loops shuffles badly.
#[cfg(target_arch = "x86_64")]
mod avx {
    use super::LANES;
    use std::arch::x86_64::*;

    const _: () = assert!(LANES == 8);

    /// # Safety
    /// The CPU must support AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn lane_sums_and_range(chunks: &[f64]) -> [[f64; LANES]; 3] {
        let mut sum = [_mm256_setzero_pd(); 2];
        let mut lo = [_mm256_set1_pd(f64::INFINITY); 2];
        let mut hi = [_mm256_set1_pd(f64::NEG_INFINITY); 2];
        for chunk in chunks.chunks_exact(LANES) {
            for half in 0..2 {
                let x = load(chunk, half);
                sum[half] = _mm256_add_pd(sum[half], x);
                lo[half] = _mm256_min_pd(x, lo[half]);
                hi[half] = _mm256_max_pd(x, hi[half]);
            }
        }
        [lanes(sum), lanes(lo), lanes(hi)]
    }

    /// # Safety
    /// The CPU must support AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn lane_central_sums(chunks: &[f64], mean: f64) -> [[f64; LANES]; 3] {
        let mean = _mm256_set1_pd(mean);
        let (mut m2, mut m3, mut m4) = (
            [_mm256_setzero_pd(); 2],
            [_mm256_setzero_pd(); 2],
            [_mm256_setzero_pd(); 2],
        );
        for chunk in chunks.chunks_exact(LANES) {
            for half in 0..2 {
                let d = _mm256_sub_pd(load(chunk, half), mean);
                let d2 = _mm256_mul_pd(d, d);
                m2[half] = _mm256_add_pd(m2[half], d2);
                m3[half] = _mm256_add_pd(m3[half], _mm256_mul_pd(d2, d));
                m4[half] = _mm256_add_pd(m4[half], _mm256_mul_pd(d2, d2));
            }
        }
        [lanes(m2), lanes(m3), lanes(m4)]
    }

    /// Values 4·half … 4·half + 3 of an eight-value chunk.
    #[target_feature(enable = "avx")]
    #[inline]
    fn load(chunk: &[f64], half: usize) -> __m256d {
        let four = &chunk[4 * half..4 * half + 4];
        // SAFETY: `four` holds exactly four values.
        unsafe { _mm256_loadu_pd(four.as_ptr()) }
    }

    #[target_feature(enable = "avx")]
    #[inline]
    fn lanes(halves: [__m256d; 2]) -> [f64; LANES] {
        let mut out = [0.0; LANES];
        // SAFETY: `out` holds exactly eight values.
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), halves[0]);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), halves[1]);
        }
        out
    }
}

/// The moment statistics and the range of a set of values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    /// Mean.
    pub mean: f64,
    /// Population variance `m2`.
    pub var: f64,
    /// Skewness `m3 / m2^1.5`.
    pub skew: f64,
    /// Pearson kurtosis `m4 / m2²`.
    pub kurt: f64,
    /// Smallest value (NaN values skipped).
    pub min: f64,
    /// Largest value (NaN values skipped).
    pub max: f64,
}

impl Moments {
    /// (min, max), if it bounds every value: a NaN (which makes the mean NaN) escapes it.
    pub fn range(&self) -> Option<(f64, f64)> {
        (!self.mean.is_nan()).then_some((self.min, self.max))
    }
}

/// All seven statistics; `scratch` is reused by the percentile selection.
///
/// ```
/// use reflectance_core::features::stats::{STAT_NAMES, summarize};
///
/// let values = [1.0, 2.0, 3.0, 4.0, 5.0];
/// let summary = summarize(&values, &mut Vec::new());
/// assert_eq!(summary.mean, 3.0);
/// assert_eq!(summary.var, 2.0); // population variance
/// assert_eq!(summary.skew, 0.0);
/// assert_eq!(summary.p50, 3.0);
/// assert!((summary.p10 - 1.4).abs() < 1e-12); // numpy's linear percentile
/// assert_eq!(summary.to_array().len(), STAT_NAMES.len());
/// ```
pub fn summarize(values: &[f64], scratch: &mut Vec<u64>) -> Summary {
    assert!(!values.is_empty(), "statistics of an empty set");
    let m = moments(values);
    let [p10, p50, p90] = percentile_ranks(values.len(), [10.0, 50.0, 90.0], |wanted| {
        order_statistics(values, wanted, m.range(), scratch)
    });
    Summary {
        mean: m.mean,
        var: m.var,
        skew: m.skew,
        kurt: m.kurt,
        p10,
        p50,
        p90,
    }
}

/// Percentiles with numpy's default (linear) method.
pub fn percentiles<const K: usize>(values: &[f64], ps: [f64; K]) -> [f64; K] {
    percentiles_with(values, ps, None)
}

/// [`percentiles`], reusing the range of `known` moments of the same values if given.
pub fn percentiles_with<const K: usize>(
    values: &[f64],
    ps: [f64; K],
    known: Option<&Moments>,
) -> [f64; K] {
    let range = match known {
        Some(m) => m.range(),
        None => {
            let (total, min, max) = sum_and_range(values);
            (!total.is_nan()).then_some((min, max))
        }
    };
    percentile_ranks(values.len(), ps, |wanted| {
        order_statistics(values, wanted, range, &mut Vec::new())
    })
}

/// numpy's linear percentiles of `n` values, given a function that returns the order
/// statistics of a sorted list of distinct ranks.
fn percentile_ranks<const K: usize>(
    n: usize,
    ps: [f64; K],
    order_statistics: impl FnOnce(&[usize]) -> Vec<f64>,
) -> [f64; K] {
    let positions = ps.map(|p| {
        let h = (p / 100.0) * (n - 1) as f64;
        let lo = (h.floor() as usize).min(n - 1);
        (lo, (lo + 1).min(n - 1), h - lo as f64)
    });
    let mut wanted: Vec<usize> = positions.iter().flat_map(|&(lo, hi, _)| [lo, hi]).collect();
    wanted.sort_unstable();
    wanted.dedup();
    let found = order_statistics(&wanted);
    let at = |rank: usize| found[wanted.partition_point(|&w| w < rank)];
    positions.map(|(lo, hi, t)| lerp(at(lo), at(hi), t))
}

/// The values at the given (sorted, distinct) ranks. `range` is (min, max) of `values` if
/// known and NaN-free; `keys` is scratch space.
fn order_statistics(
    values: &[f64],
    wanted: &[usize],
    range: Option<(f64, f64)>,
    keys: &mut Vec<u64>,
) -> Vec<f64> {
    match range {
        Some(range) if values.len() > SMALL_SELECT && bucketable(range) => {
            let mut found = Vec::with_capacity(wanted.len());
            bucket_select(values, wanted, range, RECURSION, &mut found);
            found
        }
        _ => introselect(values, wanted, keys),
    }
}

/// Introselect on order keys (integer compares are cheaper than `total_cmp`).
fn introselect(values: &[f64], wanted: &[usize], keys: &mut Vec<u64>) -> Vec<f64> {
    keys.clear();
    keys.extend(values.iter().map(|&v| order_key(v)));
    select_many(keys, wanted, 0);
    wanted.iter().map(|&r| from_order_key(keys[r])).collect()
}

/// Most histogram buckets per bucket pass (two 16 KiB histograms stay in L1); fewer for
/// fewer values, about eight values per bucket, so that scanning the histogram stays cheap.
const MAX_BUCKETS: usize = 1 << 12;
/// Below this many values, introselect beats the bucket passes.
const SMALL_SELECT: usize = 512;
/// Bucket passes at most: each narrows the range 4096-fold; values that still crowd one
/// bucket after that (a range of many decades) finish with introselect.
const RECURSION: u32 = 2;

fn bucketable((min, max): (f64, f64)) -> bool {
    min.is_finite() && max.is_finite() && min < max
}

/// Selection by value buckets: `⌊(v − min)·scale⌋` is monotone in v, so a histogram of it
/// locates each wanted rank in one bucket, and only those few buckets are gathered and
/// searched further. Three light passes over the values (the first vectorizes), against
/// several full partitions for introselect.
fn bucket_select(
    values: &[f64],
    wanted: &[usize],
    (min, max): (f64, f64),
    depth: u32,
    found: &mut Vec<f64>,
) {
    let n_buckets = (values.len() / 8).next_power_of_two().min(MAX_BUCKETS);
    let scale = n_buckets as f64 / (max - min);
    let top = (n_buckets - 1) as f64;
    let buckets: Vec<i32> = values
        .iter()
        .map(|&v| {
            // max/min rather than clamp: clamp's argument check keeps the loop scalar.
            let position = ((v - min) * scale).max(0.0).min(top);
            // SAFETY: v, min and scale are finite, so `position` is a number in
            // [0, top], representable as i32. (The checked `as` does not vectorize.)
            unsafe { position.to_int_unchecked::<i32>() }
        })
        .collect();
    // Two interleaved histograms: runs of equal buckets would otherwise serialize on one
    // counter's load and store.
    let (mut even, mut odd) = (vec![0u32; n_buckets], vec![0u32; n_buckets]);
    let (pairs, tail) = buckets.split_at(buckets.len() & !1);
    for pair in pairs.chunks_exact(2) {
        even[pair[0] as usize] += 1;
        odd[pair[1] as usize] += 1;
    }
    tail.iter().for_each(|&b| even[b as usize] += 1);
    let runs = wanted_buckets(&even, &odd, wanted);
    let mut slot = vec![u8::MAX; n_buckets];
    let mut gathered: Vec<Vec<f64>> = runs
        .iter()
        .enumerate()
        .map(|(i, run)| {
            slot[run.bucket] = i as u8;
            Vec::with_capacity(run.len)
        })
        .collect();
    for (&v, &b) in values.iter().zip(&buckets) {
        let s = slot[b as usize];
        if s != u8::MAX {
            gathered[s as usize].push(v);
        }
    }
    for (run, members) in runs.iter().zip(gathered) {
        let local: Vec<usize> = run.ranks.iter().map(|&r| r - run.first_rank).collect();
        let range = members
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if depth > 1 && members.len() > SMALL_SELECT && bucketable(range) {
            bucket_select(&members, &local, range, depth - 1, found);
        } else {
            found.extend(introselect(&members, &local, &mut Vec::new()));
        }
    }
}

/// One histogram bucket that holds wanted ranks.
struct Run<'a> {
    bucket: usize,
    /// Rank of the bucket's smallest member among all values.
    first_rank: usize,
    len: usize,
    ranks: &'a [usize],
}

/// The buckets of a histogram pair that hold the (sorted) `wanted` ranks, in order.
fn wanted_buckets<'a>(even: &[u32], odd: &[u32], wanted: &'a [usize]) -> Vec<Run<'a>> {
    let mut runs = Vec::new();
    let (mut start, mut next) = (0, 0);
    for (bucket, (a, b)) in even.iter().zip(odd).enumerate() {
        if next == wanted.len() {
            break;
        }
        let len = (a + b) as usize;
        let first = next;
        while next < wanted.len() && wanted[next] < start + len {
            next += 1;
        }
        if next > first {
            runs.push(Run {
                bucket,
                first_rank: start,
                len,
                ranks: &wanted[first..next],
            });
        }
        start += len;
    }
    runs
}

/// A u64 whose unsigned order is the total order of f64.
#[inline]
fn order_key(v: f64) -> u64 {
    let bits = v.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

#[inline]
fn from_order_key(key: u64) -> f64 {
    f64::from_bits(if key >> 63 == 1 {
        key & !(1 << 63)
    } else {
        !key
    })
}

/// numpy's `_lerp`: symmetric form that is exact at both ends.
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    let diff = b - a;
    if t >= 0.5 {
        b - diff * (1.0 - t)
    } else {
        a + diff * t
    }
}

/// Places the order statistics at the (sorted, absolute) indices `wanted` where a full sort
/// would put them; `offset` is the absolute index of `values[0]`.
fn select_many(values: &mut [u64], wanted: &[usize], offset: usize) {
    if wanted.is_empty() || values.is_empty() {
        return;
    }
    let mid = wanted[wanted.len() / 2];
    let k = mid - offset;
    let (left, _, right) = values.select_nth_unstable(k);
    let split = wanted.partition_point(|&w| w < mid);
    select_many(left, &wanted[..split], offset);
    let after = wanted.partition_point(|&w| w <= mid);
    select_many(right, &wanted[after..], mid + 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(values: &[f64]) -> Summary {
        summarize(values, &mut Vec::new())
    }

    #[test]
    fn known_moments() {
        // x = 1..5: mean 3, m2 = 2, m3 = 0, m4 = (16+1+0+1+16)/5 = 6.8, kurt = 1.7.
        let s = summary(&[5.0, 1.0, 4.0, 2.0, 3.0]);
        assert_eq!((s.mean, s.var, s.skew), (3.0, 2.0, 0.0));
        assert!((s.kurt - 1.7).abs() < 1e-15);
        // Skewed: {0, 0, 0, 3}: mean 0.75, m2 = 1.6875, m3 = 2.53125, skew = 2/√3, kurt = 7/3.
        let s = summary(&[0.0, 0.0, 0.0, 3.0]);
        assert!((s.var - 1.6875).abs() < 1e-15);
        assert!((s.skew - 1.154_700_538_379_251_7).abs() < 1e-14);
        assert!((s.kurt - 7.0 / 3.0).abs() < 1e-14);
    }

    #[test]
    fn lane_sum_covers_chunks_and_tail() {
        let values: Vec<f64> = (1..=1001).map(f64::from).collect();
        assert_eq!(sum(&values), 501_501.0);
        assert_eq!(sum(&values[..5]), 15.0);
        assert_eq!(sum(&[]), 0.0);
    }

    #[test]
    fn lane_loops_match_the_portable_ones_bit_for_bit() {
        let mut state = 99u64;
        let values: Vec<f64> = (0..8 * 301)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                if i % 17 == 0 { -0.0 } else { (u - 0.3) * 1e3 }
            })
            .collect();
        let bits = |lanes: [[f64; LANES]; 3]| lanes.map(|lane| lane.map(f64::to_bits));
        assert_eq!(
            bits(lane_sums_and_range(&values)),
            bits(portable_sums_and_range(&values))
        );
        assert_eq!(
            bits(lane_central_sums(&values, 123.456)),
            bits(portable_central_sums(&values, 123.456))
        );
        #[cfg(target_arch = "x86_64")]
        if crate::util::simd_under_test("avx") {
            // SAFETY: the CPU supports AVX.
            let (sums, central) = unsafe {
                (
                    avx::lane_sums_and_range(&values),
                    avx::lane_central_sums(&values, 123.456),
                )
            };
            assert_eq!(bits(sums), bits(portable_sums_and_range(&values)));
            assert_eq!(bits(central), bits(portable_central_sums(&values, 123.456)));
        }
    }

    #[test]
    fn constant_input_has_normal_shape() {
        let s = summary(&[0.25; 17]);
        assert_eq!((s.mean, s.var, s.skew, s.kurt), (0.25, 0.0, 0.0, 3.0));
        assert_eq!((s.p10, s.p50, s.p90), (0.25, 0.25, 0.25));
        // Tiny jitter relative to the magnitude counts as constant too.
        let s = summary(&[1e6, 1e6 + 1e-9, 1e6]);
        assert_eq!((s.skew, s.kurt), (0.0, 3.0));
        let s = summary(&[7.0]);
        assert_eq!(
            (s.var, s.skew, s.kurt, s.p10, s.p90),
            (0.0, 0.0, 3.0, 7.0, 7.0)
        );
    }

    #[test]
    fn percentiles_interpolate_like_numpy() {
        // numpy.percentile([0,1,...,10] shuffled, [10,50,90]) = [1, 5, 9].
        let v = [3.0, 10.0, 0.0, 7.0, 1.0, 9.0, 2.0, 8.0, 4.0, 6.0, 5.0];
        assert_eq!(percentiles(&v, [10.0, 50.0, 90.0]), [1.0, 5.0, 9.0]);
        // Four values 1,2,3,4: h = 0.3, 1.5, 2.7 → 1.3, 2.5, 3.7.
        let p = percentiles(&[4.0, 1.0, 3.0, 2.0], [10.0, 50.0, 90.0]);
        for (got, want) in p.iter().zip([1.3, 2.5, 3.7]) {
            assert!((got - want).abs() < 1e-15, "{got} vs {want}");
        }
        assert_eq!(percentiles(&[2.0, -2.0], [50.0]), [0.0]);
        let signed = [-0.5, 3.0, -7.25, 0.0, 1e-300, -1e-300];
        assert_eq!(percentiles(&signed, [0.0, 100.0]), [-7.25, 3.0]);
    }

    #[test]
    fn order_keys_sort_like_floats() {
        let mut v = [
            3.5,
            -0.0,
            0.0,
            -1e-308,
            1e-308,
            -2.0,
            f64::MAX,
            f64::MIN,
            1.0,
        ];
        let mut keys: Vec<u64> = v.iter().map(|&x| order_key(x)).collect();
        keys.sort_unstable();
        v.sort_by(f64::total_cmp);
        let back: Vec<f64> = keys.iter().map(|&k| from_order_key(k)).collect();
        assert!(
            back.iter().zip(&v).all(|(a, b)| a.to_bits() == b.to_bits()),
            "{back:?}"
        );
    }

    #[test]
    fn selection_matches_sorting() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64) / (1u64 << 53) as f64
        };
        for n in [1usize, 2, 3, 10, 101, 1000, 4097, 30_000] {
            // Ties, both signs, and a heavy tail that squeezes most values into few buckets.
            let values: Vec<f64> = (0..n)
                .map(|i| match i % 3 {
                    0 => (next() * 20.0).floor() - 10.0,
                    1 => next().powi(9) * 1e6,
                    _ => -next() * 1e-3,
                })
                .collect();
            assert_percentiles_sort_like(&values);
        }
    }

    /// Both selection paths (introselect, and buckets from the moments' range) against a
    /// full sort.
    fn assert_percentiles_sort_like(values: &[f64]) {
        let n = values.len();
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let s = summary(values);
        let paths = [
            percentiles(values, [10.0, 50.0, 90.0]),
            [s.p10, s.p50, s.p90],
        ];
        for got in paths {
            for (g, p) in got.iter().zip([10.0, 50.0, 90.0]) {
                let h = p / 100.0 * (n - 1) as f64;
                let lo = h.floor() as usize;
                let hi = (lo + 1).min(n - 1);
                let want = lerp(sorted[lo], sorted[hi], h - lo as f64);
                assert_eq!(g.to_bits(), want.to_bits(), "n={n} p={p}");
            }
        }
    }

    #[test]
    fn bucket_selection_handles_crowded_and_extreme_ranges() {
        let n = 20_000;
        // Everything in one bucket but a far outlier: the bucket pass recurses.
        let mut crowded: Vec<f64> = (0..n).map(|i| ((i * 7919) % n) as f64 * 1e-4).collect();
        crowded[17] = 1e9;
        assert_percentiles_sort_like(&crowded);
        // Six hundred decades: still crowded after two bucket passes, so introselect ends it.
        let decades: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(((i * 7919) % n) as f64 / n as f64 * 600.0 - 300.0))
            .collect();
        assert_percentiles_sort_like(&decades);
        // Signed zeros share a bucket and keep their total order.
        let zeros: Vec<f64> = (0..n)
            .map(|i| match i % 4 {
                0 => -0.0,
                1 => 0.0,
                2 => -1.0,
                _ => 1.0,
            })
            .collect();
        assert_percentiles_sort_like(&zeros);
        // A few ranks land at the very top bucket (v = max).
        let mut ramp: Vec<f64> = (0..n).map(|i| (i % 10) as f64).collect();
        assert_percentiles_sort_like(&ramp);
        // A NaN escapes the range of min and max: introselect, in total order, instead.
        ramp[3] = f64::NAN;
        assert_percentiles_sort_like(&ramp);
    }
}
