//! A fast `atan2` for environment-map lookups: maximum error ≈ 1e-8 rad (a map pixel is
//! ≈ 1e-2 rad), pure arithmetic, identical on every platform.

use std::f64::consts::{FRAC_PI_2, PI};

/// atan(x) for |x| ≤ 1 (odd minimax polynomial, Abramowitz & Stegun 4.4.49 form).
#[inline]
fn atan_unit(x: f64) -> f64 {
    const C: [f64; 8] = [
        0.999_999_332_9,
        -0.333_298_560_5,
        0.199_465_359_9,
        -0.139_085_335_1,
        0.096_420_044_1,
        -0.055_909_886_1,
        0.021_861_228_8,
        -0.004_054_058_0,
    ];
    let x2 = x * x;
    let mut p = C[7];
    for &c in C[..7].iter().rev() {
        p = p * x2 + c;
    }
    x * p
}

/// atan2(y, x) in (−π, π].
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    if ax == 0.0 && ay == 0.0 {
        return 0.0;
    }
    let a = if ay <= ax {
        atan_unit(ay / ax)
    } else {
        FRAC_PI_2 - atan_unit(ax / ay)
    };
    let a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 { -a } else { a }
}

/// `(floor(x), x − floor(x))` as an integer and a fraction, without a libm call.
#[inline]
pub fn floor_split(x: f64) -> (isize, f64) {
    let t = x as isize;
    let t = if (t as f64) > x { t - 1 } else { t };
    (t, x - t as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan2_is_accurate_everywhere() {
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let a = -PI + 2.0 * PI * (i as f64 + 0.37) / 2000.0;
            for r in [1e-3, 1.0, 7.5] {
                let (y, x) = (r * a.sin(), r * a.cos());
                worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst < 5e-8, "max error {worst}");
        assert_eq!(atan2(0.0, 1.0), 0.0);
        assert!((atan2(1.0, 0.0) - FRAC_PI_2).abs() < 1e-12);
        assert!((atan2(0.0, -1.0) - PI).abs() < 1e-12);
    }
}
