//! Latitude-longitude environment maps (docs/design.md §3 "Rendering"): row i, column j has
//! θ = π(i+0.5)/H from +Y and φ = 2π(j+0.5)/W − π, direction
//! d = (sin θ sin φ, cos θ, −sin θ cos φ). The rendered quantity is Rec. 709 luminance.

use super::{Vec3, fastmath};
use reflectance_core::decode::{DecodeError, Limits, rgbe};
use std::f64::consts::PI;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct EnvMap {
    pub width: usize,
    pub height: usize,
    /// Luminance, row-major, row 0 at the zenith.
    pub luminance: Vec<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum EnvMapError {
    #[error("{path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Decode { path: String, source: DecodeError },
    #[error("{path}: environment maps must be non-negative and finite")]
    BadValues { path: String },
    #[error("{path}: a lat-long map needs at least 4×2 pixels, not {width}×{height}")]
    TooSmall {
        path: String,
        width: usize,
        height: usize,
    },
}

fn read_picture(path: &Path) -> Result<(rgbe::RgbePicture, String), EnvMapError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| EnvMapError::Read {
        path: name.clone(),
        source,
    })?;
    let picture = rgbe::read(&bytes, &Limits::default()).map_err(|source| EnvMapError::Decode {
        path: name.clone(),
        source,
    })?;
    Ok((picture, name))
}

impl EnvMap {
    /// Load a Radiance `.hdr` lat-long map (its luminance).
    pub fn load(path: &Path) -> Result<EnvMap, EnvMapError> {
        let (picture, name) = read_picture(path)?;
        EnvMap::checked(
            picture.width,
            picture.height,
            picture.luminance().into_raw_vec_and_offset().0,
            name,
        )
    }

    /// Load a Radiance `.hdr` lat-long map's R, G and B as three maps (for colour renders).
    pub fn load_channels(path: &Path) -> Result<[EnvMap; 3], EnvMapError> {
        let (picture, name) = read_picture(path)?;
        let channel = |c: usize| {
            let values = picture.pixels.iter().map(|p| p[c]).collect();
            EnvMap::checked(picture.width, picture.height, values, name.clone())
        };
        Ok([channel(0)?, channel(1)?, channel(2)?])
    }

    fn checked(
        width: usize,
        height: usize,
        luminance: Vec<f64>,
        name: String,
    ) -> Result<EnvMap, EnvMapError> {
        if width < 4 || height < 2 {
            return Err(EnvMapError::TooSmall {
                path: name,
                width,
                height,
            });
        }
        if luminance.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(EnvMapError::BadValues { path: name });
        }
        Ok(EnvMap {
            width,
            height,
            luminance,
        })
    }

    /// A map from a function of direction, sampled at pixel centres (tests, synthetic maps).
    pub fn from_fn(width: usize, height: usize, f: impl Fn(Vec3) -> f64) -> EnvMap {
        let mut map = EnvMap {
            width,
            height,
            luminance: vec![0.0; width * height],
        };
        for i in 0..height {
            for j in 0..width {
                map.luminance[i * width + j] = f(map.direction(i as f64 + 0.5, j as f64 + 0.5));
            }
        }
        map
    }

    /// Direction of continuous map coordinates (row, column), centres at +0.5.
    pub fn direction(&self, row: f64, col: f64) -> Vec3 {
        let theta = PI * row / self.height as f64;
        let phi = 2.0 * PI * col / self.width as f64 - PI;
        Vec3::new(
            theta.sin() * phi.sin(),
            theta.cos(),
            -theta.sin() * phi.cos(),
        )
    }

    /// Exact solid angle of a pixel of row `i`: (2π/W)(cos θ_top − cos θ_bottom).
    pub fn solid_angle(&self, i: usize) -> f64 {
        let h = self.height as f64;
        let top = PI * i as f64 / h;
        let bottom = PI * (i + 1) as f64 / h;
        2.0 * PI / self.width as f64 * (top.cos() - bottom.cos())
    }

    /// ∫ v dω of per-pixel values `v` on this map's grid (of the luminance: the map's power).
    pub fn integral(&self, values: &[f64]) -> f64 {
        values
            .chunks_exact(self.width)
            .enumerate()
            .map(|(i, row)| self.solid_angle(i) * row.iter().sum::<f64>())
            .sum()
    }

    /// Bilinear lookup in direction `d` (unit), wrapping in φ and clamping in θ.
    #[inline]
    pub fn lookup(&self, d: Vec3) -> f64 {
        let theta = fastmath::atan2((d.x * d.x + d.z * d.z).sqrt(), d.y);
        let phi = fastmath::atan2(d.x, -d.z);
        let u = (phi + PI) / (2.0 * PI) * self.width as f64 - 0.5;
        let v = theta / PI * self.height as f64 - 0.5;
        let (x0, fx) = fastmath::floor_split(u);
        let (y0, fy) = fastmath::floor_split(v);
        let w = self.width as isize;
        let xa = if x0 < 0 { x0 + w } else { x0 } as usize % self.width;
        let xb = (xa + 1) % self.width;
        let max_row = self.height as isize - 1;
        let ya = y0.clamp(0, max_row) as usize * self.width;
        let yb = (y0 + 1).clamp(0, max_row) as usize * self.width;
        let l = &self.luminance;
        let top = (1.0 - fx) * l[ya + xa] + fx * l[ya + xb];
        let bottom = (1.0 - fx) * l[yb + xa] + fx * l[yb + xb];
        (1.0 - fy) * top + fy * bottom
    }

    /// The map with its luminance raised to the power `k`, rescaled to the same
    /// solid-angle-weighted mean: a different dynamic range of the same scene.
    pub fn with_contrast(&self, k: f64) -> EnvMap {
        let powered: Vec<f64> = self.luminance.iter().map(|v| v.powf(k)).collect();
        let scale = self.integral(&self.luminance) / self.integral(&powered).max(f64::MIN_POSITIVE);
        EnvMap {
            width: self.width,
            height: self.height,
            luminance: powered.into_iter().map(|v| v * scale).collect(),
        }
    }

    /// The map as through a capture `factor` times coarser, interpolated back to its size:
    /// blocks of `factor` × `factor` pixels averaged by solid angle, then looked up
    /// bilinearly. Light probes come at different resolutions, and a mirror under a blurred
    /// map must not be new to a classifier.
    pub fn reduced(&self, factor: usize) -> EnvMap {
        let small = self.block_averaged(factor);
        EnvMap::from_fn(self.width, self.height, |d| small.lookup(d))
    }

    /// The map `factor` times coarser: blocks of `factor` × `factor` pixels averaged by solid
    /// angle (partial blocks at the edges averaged over what they hold).
    pub fn block_averaged(&self, factor: usize) -> EnvMap {
        let factor = factor.max(1);
        let (width, height) = (self.width.div_ceil(factor), self.height.div_ceil(factor));
        let mut small = EnvMap {
            width,
            height,
            luminance: vec![0.0; width * height],
        };
        for i in 0..height {
            let rows = i * factor..((i + 1) * factor).min(self.height);
            let weight: f64 = rows.clone().map(|r| self.solid_angle(r)).sum();
            for j in 0..width {
                let cols = j * factor..((j + 1) * factor).min(self.width);
                let power: f64 = rows
                    .clone()
                    .map(|r| {
                        let row = &self.luminance[r * self.width..][cols.clone()];
                        self.solid_angle(r) * row.iter().sum::<f64>()
                    })
                    .sum();
                small.luminance[i * width + j] = power / (cols.len() as f64 * weight);
            }
        }
        small
    }

    /// The map with its columns rolled right by `k` (a rotation about +Y by 2πk/W).
    pub fn rolled(&self, k: usize) -> EnvMap {
        let mut luminance = self.luminance.clone();
        for row in luminance.chunks_exact_mut(self.width) {
            row.rotate_right(k % self.width);
        }
        EnvMap {
            width: self.width,
            height: self.height,
            luminance,
        }
    }

    /// Irradiance on a surface of normal `n`, by direct summation over every pixel:
    /// E(n) = Σ L(ω) max(0, n·ω) dω. O(W·H) per call: a reference, not a renderer path.
    pub fn irradiance_exact(&self, n: Vec3) -> f64 {
        let mut total = 0.0;
        for i in 0..self.height {
            let d_omega = self.solid_angle(i);
            let row = &self.luminance[i * self.width..(i + 1) * self.width];
            for (j, &l) in row.iter().enumerate() {
                let cos = n.dot(self.direction(i as f64 + 0.5, j as f64 + 0.5));
                if cos > 0.0 {
                    total += l * cos * d_omega;
                }
            }
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direction_convention() {
        let map = EnvMap::from_fn(512, 256, |_| 1.0);
        // Row 0 is the zenith side; the map centre looks along −Z; three quarters across is +X.
        let centre = map.direction(128.0, 256.0);
        assert!((centre.z + 1.0).abs() < 1e-12, "{centre:?}");
        let right = map.direction(128.0, 384.0);
        assert!((right.x - 1.0).abs() < 1e-12, "{right:?}");
        assert!(map.direction(0.0, 0.0).y > 0.999);
    }

    #[test]
    fn solid_angles_cover_the_sphere() {
        let map = EnvMap::from_fn(64, 32, |_| 1.0);
        let total: f64 = (0..32).map(|i| map.solid_angle(i) * 64.0).sum();
        assert!((total - 4.0 * PI).abs() < 1e-12);
    }

    #[test]
    fn lookup_hits_pixel_centres_and_wraps() {
        let map = EnvMap::from_fn(8, 4, |d| d.x + 2.0 * d.y + 3.0);
        for (i, j) in [(0, 0), (1, 3), (2, 7), (3, 5)] {
            let d = map.direction(i as f64 + 0.5, j as f64 + 0.5);
            // The fast atan2 is within 1e-8 rad: a 1e-8 fraction of a pixel.
            assert!(
                (map.lookup(d) - map.luminance[i * 8 + j]).abs() < 1e-6,
                "({i},{j})"
            );
        }
        // Halfway between the last and the first column interpolates across the seam.
        let seam = map.direction(1.5, 8.0);
        let expected = 0.5 * (map.luminance[8 + 7] + map.luminance[8]);
        assert!((map.lookup(seam) - expected).abs() < 1e-6);
    }

    #[test]
    fn contrast_keeps_the_mean_and_changes_the_range() {
        let map = EnvMap::from_fn(64, 32, |d| 0.5 + 2.0 * d.y.max(0.0).powi(8) + 0.1 * d.x);
        let total = |m: &EnvMap| m.integral(&m.luminance);
        let range = |m: &EnvMap| {
            m.luminance.iter().fold(0.0f64, |a, &b| a.max(b))
                / m.luminance.iter().fold(f64::INFINITY, |a, &b| a.min(b))
        };
        for k in [0.7, 1.5] {
            let c = map.with_contrast(k);
            assert!((total(&c) - total(&map)).abs() < 1e-12 * total(&map));
            assert!((range(&c).ln() - k * range(&map).ln()).abs() < 1e-9, "{k}");
        }
    }

    #[test]
    fn a_reduced_map_keeps_its_light_and_loses_its_finest_detail() {
        let (w, h) = (128, 64);
        let mut sharp = EnvMap::from_fn(w, h, |d| 1.0 + d.y.max(0.0));
        sharp.luminance[20 * w + 70] += 1e3;
        let flux = |m: &EnvMap| m.integral(&m.luminance);
        let peak = |m: &EnvMap| m.luminance.iter().fold(0.0f64, |a, &b| a.max(b));
        let mut previous = peak(&sharp);
        for factor in [2, 4] {
            let soft = sharp.reduced(factor);
            assert_eq!((soft.width, soft.height), (w, h));
            assert!((flux(&soft) / flux(&sharp) - 1.0).abs() < 0.01, "{factor}");
            assert!(previous > 2.5 * peak(&soft), "{factor}");
            previous = peak(&soft);
        }
        // Sizes the factor does not divide: partial blocks at the edges, still a mean.
        let odd = EnvMap::from_fn(30, 15, |_| 2.0).reduced(4);
        assert_eq!((odd.width, odd.height), (30, 15));
        assert!(odd.luminance.iter().all(|v| (v - 2.0).abs() < 1e-12));
    }

    #[test]
    fn uniform_map_irradiance_is_pi() {
        let map = EnvMap::from_fn(512, 256, |_| 1.0);
        for n in [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.5f64.sqrt(), 0.5f64.sqrt()),
            Vec3::new(0.6, 0.0, 0.8),
        ] {
            assert!((map.irradiance_exact(n) / PI - 1.0).abs() < 2e-5, "{n:?}");
        }
    }
}
