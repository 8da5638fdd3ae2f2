//! A vectorizable log10 for the log-domain features (`hand6+log`, the shipped models): the
//! logarithm of every unwrapped pixel was a third of that extraction's time as libm calls.
//!
//! fdlibm's `log` (error < 1 ulp) in straight-line IEEE arithmetic, times 1/ln 10: within
//! 2 ulp of the correctly rounded log10, identical on every platform, and the compiler
//! turns the slice loop into SIMD code.

// fdlibm's constants, by their bits: ln 2 split in a high part with trailing zeros and the
// rest; the minimax coefficients of (log(1+f) − f + f²/2)/s in s² (s = f/(2+f)).
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
const LG: [f64; 7] = [
    f64::from_bits(0x3fe5_5555_5555_5593),
    f64::from_bits(0x3fd9_9999_9997_fa04),
    f64::from_bits(0x3fd2_4924_9422_9359),
    f64::from_bits(0x3fcc_71c5_1d8e_78af),
    f64::from_bits(0x3fc7_4664_96cb_03de),
    f64::from_bits(0x3fc3_9a09_d078_c69f),
    f64::from_bits(0x3fc2_f112_df3e_5244),
];

/// log10(x) for a positive normal finite x (the caller's guarantee; anything else gives a
/// meaningless number, not an error).
#[inline(always)]
fn log10_normal(x: f64) -> f64 {
    let bits = x.to_bits();
    let high = (bits >> 32) as u32;
    let mut k = (high >> 20) as i32 - 1023;
    // Scale the mantissa into [√2/2, √2) so that f = m − 1 is small.
    let mantissa = high & 0x000f_ffff;
    let up = (mantissa + 0x95f64) & 0x10_0000;
    k += (up >> 20) as i32;
    let m = f64::from_bits(u64::from(mantissa | (up ^ 0x3ff0_0000)) << 32 | (bits & 0xffff_ffff));
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let (z, dk) = (s * s, f64::from(k));
    let w = z * z;
    let t1 = w * (LG[1] + w * (LG[3] + w * LG[5]));
    let t2 = z * (LG[0] + w * (LG[2] + w * (LG[4] + w * LG[6])));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    let ln = dk * LN2_HI - ((hfsq - (s * (hfsq + r) + dk * LN2_LO)) - f);
    ln * std::f64::consts::LOG10_E
}

/// `log10(max(v, floor))` of every value; `floor` must be a positive normal number.
pub fn log10_floored(values: &[f64], floor: f64) -> Vec<f64> {
    assert!(
        floor.is_normal() && floor > 0.0,
        "floor must be positive and normal"
    );
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2.
        return unsafe { log10_floored_avx2(values, floor) };
    }
    log10_floored_portable(values, floor)
}

/// The same IEEE operations in the same order (Rust never fuses them into FMAs), compiled
/// with 256-bit integer and float instructions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn log10_floored_avx2(values: &[f64], floor: f64) -> Vec<f64> {
    log10_floored_portable(values, floor)
}

/// A plain loop over slices, not `map().collect()`: the iterator's `fold` is a function of
/// its own that the AVX2 build does not inline, and it ran two lanes wide.
#[inline(always)]
fn log10_floored_portable(values: &[f64], floor: f64) -> Vec<f64> {
    let mut out = vec![0.0; values.len()];
    for (o, &v) in out.iter_mut().zip(values) {
        // max() maps NaN and −∞ to the floor; +∞ stays, and keeps its logarithm.
        let x = v.max(floor);
        let finite = log10_normal(x);
        *o = if x == f64::INFINITY { x } else { finite };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    #[test]
    fn within_two_ulp_of_libm_across_the_pixel_range() {
        // 1e-4 (the features' floor) to 1e6, densely, plus the points where the mantissa
        // scaling switches and exact powers of ten and two.
        let mut xs: Vec<f64> = (0..200_000)
            .map(|i| 1e-4 * 10f64.powf(10.0 * i as f64 / 200_000.0))
            .collect();
        for e in -13..20 {
            let two = 2f64.powi(e);
            xs.extend([
                two,
                two * std::f64::consts::SQRT_2,
                two * std::f64::consts::SQRT_2.next_down(),
                10f64.powi(e / 3),
            ]);
            xs.extend([two.next_up(), two.next_down(), 1.0 + 1e-12, 1.0 - 1e-12]);
        }
        let got = log10_floored(&xs, 1e-300);
        for (x, g) in xs.iter().zip(&got) {
            let want = x.log10();
            assert!(
                ulps(*g, want) <= 2 || (g - want).abs() < 1e-300,
                "log10({x}) = {g}, libm {want}"
            );
        }
        assert_eq!(log10_floored(&[1.0, 10.0, 1000.0], 1e-4), [0.0, 1.0, 3.0]);
    }

    #[test]
    fn floor_nan_and_infinity() {
        let got = log10_floored(
            &[0.0, -5.0, f64::NAN, f64::NEG_INFINITY, f64::INFINITY],
            1e-4,
        );
        let floor = 1e-4f64.log10();
        assert!(got[..4].iter().all(|&g| ulps(g, floor) <= 2), "{got:?}");
        assert_eq!(got[4], f64::INFINITY);
    }

    #[test]
    fn simd_and_portable_builds_agree_bit_for_bit() {
        let xs: Vec<f64> = (0..10_000).map(|i| 1e-4 + i as f64 * 0.013_7).collect();
        let b = log10_floored_portable(&xs, 1e-4);
        let same = |a: Vec<f64>| assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        same(log10_floored(&xs, 1e-4));
        #[cfg(target_arch = "x86_64")]
        if crate::util::simd_under_test("avx2") {
            // SAFETY: the CPU supports AVX2.
            same(unsafe { log10_floored_avx2(&xs, 1e-4) });
        }
    }
}
