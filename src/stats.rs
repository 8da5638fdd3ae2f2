//! Population moments (two passes, f64) and numpy-style linear-interpolation percentiles.

/// The seven statistics of one set of values, in canonical feature order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub mean: f64,
    pub var: f64,
    pub skew: f64,
    pub kurt: f64,
    pub p10: f64,
    pub p50: f64,
    pub p90: f64,
}

/// Statistic names in the order [`Summary::to_array`] returns them.
pub const STAT_NAMES: [&str; 7] = ["mean", "var", "skew", "kurt", "p10", "p50", "p90"];

impl Summary {
    pub fn to_array(&self) -> [f64; 7] {
        [
            self.mean, self.var, self.skew, self.kurt, self.p10, self.p50, self.p90,
        ]
    }
}

/// Mean, variance `m2`, skewness `m3/m2^1.5` and Pearson kurtosis `m4/m2²`.
/// A numerically constant input (min == max, or m2 ≤ (1e-12·max|x|)²) has skew 0, kurt 3.
pub fn moments(values: &[f64]) -> (f64, f64, f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let (mut m2, mut m3, mut m4) = (0.0, 0.0, 0.0);
    let (mut min, mut max, mut max_abs) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for &x in values {
        let d = x - mean;
        let d2 = d * d;
        m2 += d2;
        m3 += d2 * d;
        m4 += d2 * d2;
        min = min.min(x);
        max = max.max(x);
        max_abs = max_abs.max(x.abs());
    }
    let (m2, m3, m4) = (m2 / n, m3 / n, m4 / n);
    let scale = 1e-12 * max_abs;
    if min == max || m2 <= scale * scale {
        return (mean, m2, 0.0, 3.0);
    }
    (mean, m2, m3 / m2.powf(1.5), m4 / (m2 * m2))
}

/// All seven statistics; `scratch` is reused for the percentile selection.
pub fn summarize(values: &[f64], scratch: &mut Vec<f64>) -> Summary {
    assert!(!values.is_empty(), "statistics of an empty set");
    let (mean, var, skew, kurt) = moments(values);
    scratch.clear();
    scratch.extend_from_slice(values);
    let [p10, p50, p90] = percentiles(scratch, [10.0, 50.0, 90.0]);
    Summary {
        mean,
        var,
        skew,
        kurt,
        p10,
        p50,
        p90,
    }
}

/// Percentiles with numpy's default (linear) method; reorders `values`.
pub fn percentiles<const K: usize>(values: &mut [f64], ps: [f64; K]) -> [f64; K] {
    let n = values.len();
    let positions = ps.map(|p| {
        let h = (p / 100.0) * (n - 1) as f64;
        let lo = (h.floor() as usize).min(n - 1);
        (lo, (lo + 1).min(n - 1), h - lo as f64)
    });
    let mut wanted: Vec<usize> = positions.iter().flat_map(|&(lo, hi, _)| [lo, hi]).collect();
    wanted.sort_unstable();
    wanted.dedup();
    select_many(values, &wanted, 0);
    positions.map(|(lo, hi, t)| lerp(values[lo], values[hi], t))
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
fn select_many(values: &mut [f64], wanted: &[usize], offset: usize) {
    if wanted.is_empty() || values.is_empty() {
        return;
    }
    let mid = wanted[wanted.len() / 2];
    let k = mid - offset;
    let (left, _, right) = values.select_nth_unstable_by(k, f64::total_cmp);
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
        let mut v = vec![3.0, 10.0, 0.0, 7.0, 1.0, 9.0, 2.0, 8.0, 4.0, 6.0, 5.0];
        assert_eq!(percentiles(&mut v, [10.0, 50.0, 90.0]), [1.0, 5.0, 9.0]);
        // Four values 1,2,3,4: h = 0.3, 1.5, 2.7 → 1.3, 2.5, 3.7.
        let mut v = vec![4.0, 1.0, 3.0, 2.0];
        let p = percentiles(&mut v, [10.0, 50.0, 90.0]);
        for (got, want) in p.iter().zip([1.3, 2.5, 3.7]) {
            assert!((got - want).abs() < 1e-15, "{got} vs {want}");
        }
        let mut two = vec![2.0, -2.0];
        assert_eq!(percentiles(&mut two, [50.0]), [0.0]);
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
        for n in [1usize, 2, 3, 10, 101, 1000, 4097] {
            let values: Vec<f64> = (0..n).map(|_| (next() * 20.0).floor()).collect();
            let mut sorted = values.clone();
            sorted.sort_by(f64::total_cmp);
            let mut work = values.clone();
            let got = percentiles(&mut work, [10.0, 50.0, 90.0]);
            for (g, p) in got.iter().zip([10.0, 50.0, 90.0]) {
                let h = p / 100.0 * (n - 1) as f64;
                let lo = h.floor() as usize;
                let hi = (lo + 1).min(n - 1);
                let want = lerp(sorted[lo], sorted[hi], h - lo as f64);
                assert_eq!(*g, want, "n={n} p={p}");
            }
        }
    }
}
