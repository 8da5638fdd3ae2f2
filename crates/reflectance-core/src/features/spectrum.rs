//! Oriented band powers of the unwrapped image, docs/design.md §3 "Band powers".
//!
//! `P = |FFT2(U − mean U)|² / (H·W)²`, so the non-DC powers sum to the variance of U.
//! Bins are classified exactly as numpy would from `fftfreq` values (Nyquist frequencies are
//! negative), and the real FFT's implicit conjugate half is accumulated into the class of
//! the mirrored bin, which at the Nyquist row can differ from the stored bin's class.

use ndarray::ArrayView2;
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Radial bands b1 (finest) … b4: lower bounds on ρ² = fx² + fy² (b1 has no upper bound).
const BAND_LOWER_RHO2: [f64; 4] = [1.0 / 16.0, 1.0 / 64.0, 1.0 / 256.0, 1.0 / 1024.0];
/// Orientation names, in feature order.
pub const ORIENTATIONS: [&str; 4] = ["f0", "f45", "f90", "f135"];
/// Radial bands with orientations (`fft.b1` … `fft.b4`).
pub const BANDS: usize = 4;
/// Class index of the `lo` band (0 < ρ < 1/32); 0..16 are band·4 + orientation.
const LO_CLASS: u8 = 16;
const NO_CLASS: u8 = u8::MAX;

/// Powers per band × orientation, then the `lo` band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandPowers {
    /// `oriented[band][orientation]`: band b1 (finest) first, orientations in [`ORIENTATIONS`]
    /// order.
    pub oriented: [[f64; 4]; BANDS],
    /// The `lo` band (0 < ρ < 1/32).
    pub lo: f64,
}

impl BandPowers {
    /// Sum of every band: the variance of the image (Parseval).
    pub fn total(&self) -> f64 {
        self.oriented.iter().flatten().sum::<f64>() + self.lo
    }

    /// Every band multiplied by `factor`.
    pub fn scaled(&self, factor: f64) -> BandPowers {
        BandPowers {
            oriented: self.oriented.map(|band| band.map(|p| p * factor)),
            lo: self.lo * factor,
        }
    }
}

/// FFT plans and the bin classification for one grid size; build once, share freely.
pub struct SpectrumPlan {
    rows: usize,
    cols: usize,
    row_fft: Arc<dyn RealToComplex<f64>>,
    col_fft: Arc<dyn Fft<f64>>,
    /// For each class, the half-spectrum bins (column-major `kx·rows + ky`) whose power it
    /// receives: once for the stored bin, once more for its implicit conjugate.
    class_bins: Vec<Vec<u32>>,
}

impl std::fmt::Debug for SpectrumPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SpectrumPlan({}×{})", self.rows, self.cols)
    }
}

/// numpy `fftfreq(n)[k]`.
fn fftfreq(k: usize, n: usize) -> f64 {
    let positive = (n - 1) / 2 + 1;
    let signed = if k < positive {
        k as f64
    } else {
        k as f64 - n as f64
    };
    signed * (1.0 / n as f64)
}

/// The class of full-spectrum bin (ky, kx).
fn classify(ky: usize, kx: usize, rows: usize, cols: usize) -> u8 {
    let (fy, fx) = (fftfreq(ky, rows), fftfreq(kx, cols));
    let rho2 = fx * fx + fy * fy;
    if rho2 == 0.0 {
        return NO_CLASS;
    }
    let Some(band) = BAND_LOWER_RHO2.iter().position(|&lower| rho2 >= lower) else {
        return LO_CLASS;
    };
    let angle = fy.atan2(fx).to_degrees().rem_euclid(180.0);
    let orientation = match angle {
        a if !(22.5..157.5).contains(&a) => 0,
        a if a < 67.5 => 1,
        a if a < 112.5 => 2,
        _ => 3,
    };
    (band * 4 + orientation) as u8
}

impl SpectrumPlan {
    /// The FFT plans and frequency-bin classes of a `rows` × `cols` image.
    pub fn new(rows: usize, cols: usize) -> Self {
        let row_fft = RealFftPlanner::<f64>::new().plan_fft_forward(cols);
        let col_fft = FftPlanner::<f64>::new().plan_fft_forward(rows);
        let half = cols / 2 + 1;
        let mut class_bins = vec![Vec::new(); LO_CLASS as usize + 1];
        for kx in 0..half {
            let mirrored = kx != 0 && 2 * kx != cols;
            for ky in 0..rows {
                let bin = (kx * rows + ky) as u32;
                let own = classify(ky, kx, rows, cols);
                let twin = if mirrored {
                    classify((rows - ky) % rows, cols - kx, rows, cols)
                } else {
                    NO_CLASS
                };
                for class in [own, twin].into_iter().filter(|&c| c != NO_CLASS) {
                    class_bins[class as usize].push(bin);
                }
            }
        }
        SpectrumPlan {
            rows,
            cols,
            row_fft,
            col_fft,
            class_bins,
        }
    }

    /// Band powers of `image` (rows × cols, the plan's size).
    pub fn band_powers(&self, image: ArrayView2<f64>) -> BandPowers {
        assert_eq!(
            image.dim(),
            (self.rows, self.cols),
            "image size does not match the plan"
        );
        let powers: Vec<f64> = self.spectrum(image).iter().map(|f| f.norm_sqr()).collect();
        let norm = 1.0 / ((self.rows * self.cols) as f64).powi(2);
        let sums: Vec<f64> = self
            .class_bins
            .iter()
            .map(|bins| sum_powers(&powers, bins) * norm)
            .collect();
        let mut oriented = [[0.0; 4]; BANDS];
        for (i, slot) in oriented.iter_mut().flatten().enumerate() {
            *slot = sums[i];
        }
        BandPowers {
            oriented,
            lo: sums[LO_CLASS as usize],
        }
    }

    /// Half spectrum of the mean-removed image, column-major: `[kx][ky]`, kx ≤ cols/2.
    fn spectrum(&self, image: ArrayView2<f64>) -> Vec<Complex<f64>> {
        let (rows, half) = (self.rows, self.cols / 2 + 1);
        let image = image.as_standard_layout();
        let pixels = image.as_slice().expect("standard layout");
        let mean = crate::features::stats::sum(pixels) / pixels.len() as f64;
        let mut row_in = self.row_fft.make_input_vec();
        let mut row_out = self.row_fft.make_output_vec();
        let mut scratch = self.row_fft.make_scratch_vec();
        let mut columns = vec![Complex::new(0.0, 0.0); half * rows];
        for (ky, row) in pixels.chunks_exact(self.cols).enumerate() {
            row_in.iter_mut().zip(row).for_each(|(d, &s)| *d = s - mean);
            self.row_fft
                .process_with_scratch(&mut row_in, &mut row_out, &mut scratch)
                .expect("buffer sizes come from the plan");
            for (kx, value) in row_out.iter().enumerate() {
                columns[kx * rows + ky] = *value;
            }
        }
        self.col_fft.process(&mut columns);
        columns
    }
}

/// Σ powers over `bins`, with independent accumulators (the order is fixed: deterministic).
fn sum_powers(powers: &[f64], bins: &[u32]) -> f64 {
    let mut acc = [0.0f64; 4];
    let chunks = bins.chunks_exact(4);
    let tail = chunks.remainder();
    for chunk in chunks {
        for k in 0..4 {
            acc[k] += powers[chunk[k] as usize];
        }
    }
    let tail_sum: f64 = tail.iter().map(|&b| powers[b as usize]).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail_sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn noise(rows: usize, cols: usize, seed: u64) -> Array2<f64> {
        let mut state = seed;
        Array2::from_shape_fn((rows, cols), |_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        })
    }

    fn variance(img: &Array2<f64>) -> f64 {
        let mean = img.mean().unwrap();
        img.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / img.len() as f64
    }

    #[test]
    fn fftfreq_matches_numpy() {
        let f: Vec<f64> = (0..6).map(|k| fftfreq(k, 6)).collect();
        assert_eq!(
            f,
            [
                0.0,
                1.0 / 6.0,
                2.0 / 6.0,
                -3.0 / 6.0,
                -2.0 / 6.0,
                -1.0 / 6.0
            ]
        );
        let f: Vec<f64> = (0..5).map(|k| fftfreq(k, 5)).collect();
        assert_eq!(f, [0.0, 0.2, 0.4, -0.4, -0.2]);
    }

    #[test]
    fn powers_sum_to_the_variance() {
        for (rows, cols) in [(96, 448), (24, 40), (9, 15)] {
            let img = noise(rows, cols, 7);
            let plan = SpectrumPlan::new(rows, cols);
            let p = plan.band_powers(img.view());
            let var = variance(&img);
            assert!((p.total() - var).abs() < 1e-12 * var, "{rows}×{cols}");
        }
    }

    #[test]
    fn pure_orientations_land_in_their_bands() {
        // A horizontal wave (varying along x only, fy = 0) is orientation f0; one varying
        // along y only is f90; a diagonal wave along (x + y) at equal frequency is f45 or f135.
        let (rows, cols) = (96, 448);
        let plan = SpectrumPlan::new(rows, cols);
        let wave = |fy: f64, fx: f64| {
            Array2::from_shape_fn((rows, cols), |(y, x)| {
                (2.0 * std::f64::consts::PI * (fy * y as f64 + fx * x as f64)).cos()
            })
        };
        let along_x = plan.band_powers(wave(0.0, 112.0 / 448.0).view());
        assert!((along_x.oriented[0][0] - 0.5).abs() < 1e-12, "{along_x:?}");
        let along_y = plan.band_powers(wave(6.0 / 96.0, 0.0).view());
        // fy = 1/16: ρ² = 1/256 → band b3, orientation 90°.
        assert!((along_y.oriented[2][2] - 0.5).abs() < 1e-12, "{along_y:?}");
        let diagonal = plan.band_powers(wave(3.0 / 96.0, 14.0 / 448.0).view());
        // fx = fy = 1/32: ρ² = 1/512 → b4; the bin at +45° and its conjugate at −135°≡45°.
        assert!(
            (diagonal.oriented[3][1] - 0.5).abs() < 1e-12,
            "{diagonal:?}"
        );
        let low = plan.band_powers(wave(1.0 / 96.0, 0.0).view());
        assert!((low.lo - 0.5).abs() < 1e-12, "{low:?}");
    }

    #[test]
    fn nyquist_row_bins_split_between_orientations() {
        // At fy = −1/2 the stored bin (kx) and its conjugate (W − kx) have angles on either
        // side of 90°: classify both like numpy does on the full spectrum.
        let (rows, cols) = (8, 8);
        let a = classify(4, 3, rows, cols);
        let b = classify(4, 5, rows, cols);
        assert_ne!(a, b);
        let img = noise(rows, cols, 3);
        let p = SpectrumPlan::new(rows, cols).band_powers(img.view());
        assert!((p.total() - variance(&img)).abs() < 1e-12);
    }
}
