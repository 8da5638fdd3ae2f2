//! Small, intense parts of a map (the sun, lamps) as explicit area sources for specular
//! reflection.
//!
//! A sphere's features are dominated by the highlights of such sources, so Monte-Carlo
//! lobe samples that only sometimes hit them make the features noisy. Instead, every bright
//! pixel is integrated deterministically: split into sub-pixel points (spacing ≤ α/2) whose
//! BRDF-weighted radiance is summed exactly; the Ward lobe is importance-sampled only on the
//! remaining `dim` map (bright pixels set to 0), so no energy is counted twice.

use super::Vec3;
use super::envmap::EnvMap;
use std::f64::consts::PI;

/// A pixel is bright if its luminance is at least this many times the map's mean…
const BRIGHT_RATIO: f64 = 50.0;
/// …keeping the brightest ones up to this count.
const MAX_BRIGHT: usize = 512;

#[derive(Clone, Debug)]
pub struct BrightTexel {
    pub row: usize,
    pub col: usize,
    pub center: Vec3,
    pub luminance: f64,
}

#[derive(Clone, Debug)]
pub struct BrightSources {
    pub texels: Vec<BrightTexel>,
    /// The map without the bright pixels.
    pub dim: EnvMap,
    /// Angular radius (rad) that bounds every map pixel around its centre.
    pub texel_radius: f64,
}

/// A point of a bright pixel: direction and luminance × its share of the solid angle.
#[derive(Clone, Copy, Debug)]
pub struct SourcePoint {
    pub direction: Vec3,
    pub power: f64,
}

impl BrightSources {
    pub fn new(map: &EnvMap) -> BrightSources {
        let (w, h) = (map.width, map.height);
        let total_solid: f64 = (0..h).map(|i| map.solid_angle(i) * w as f64).sum();
        let mean = map.integral(&map.luminance) / total_solid;
        let mut candidates: Vec<usize> = (0..w * h)
            .filter(|&k| map.luminance[k] >= BRIGHT_RATIO * mean && map.luminance[k] > 0.0)
            .collect();
        candidates.sort_by(|&a, &b| {
            map.luminance[b]
                .total_cmp(&map.luminance[a])
                .then(a.cmp(&b))
        });
        candidates.truncate(MAX_BRIGHT);
        let mut dim = map.clone();
        let texels = candidates
            .iter()
            .map(|&k| {
                dim.luminance[k] = 0.0;
                let (row, col) = (k / w, k % w);
                BrightTexel {
                    row,
                    col,
                    center: map.direction(row as f64 + 0.5, col as f64 + 0.5),
                    luminance: map.luminance[k],
                }
            })
            .collect();
        // Half the diagonal of the largest pixel (at the equator), in radians.
        let texel_radius = 0.5 * (2.0 * PI / w as f64).hypot(PI / h as f64);
        BrightSources {
            texels,
            dim,
            texel_radius,
        }
    }

    /// Indices of the bright pixels within `angle` (rad) of direction `d`.
    pub fn near(&self, d: Vec3, angle: f64, out: &mut Vec<usize>) {
        out.clear();
        let cos_limit = angle.min(PI).cos();
        out.extend(
            self.texels
                .iter()
                .enumerate()
                .filter(|(_, t)| t.center.dot(d) >= cos_limit)
                .map(|(i, _)| i),
        );
    }

    /// `per_side²` points of bright pixel `index`, at the centres of equal sub-rectangles in
    /// (θ, φ), each carrying luminance × its exact solid angle.
    pub fn points(
        &self,
        map_width: usize,
        map_height: usize,
        index: usize,
        per_side: usize,
    ) -> Vec<SourcePoint> {
        let t = &self.texels[index];
        let (w, h, n) = (map_width as f64, map_height as f64, per_side as f64);
        let mut out = Vec::with_capacity(per_side * per_side);
        for a in 0..per_side {
            let top = PI * (t.row as f64 + a as f64 / n) / h;
            let bottom = PI * (t.row as f64 + (a + 1) as f64 / n) / h;
            let d_omega = 2.0 * PI / (w * n) * (top.cos() - bottom.cos());
            for b in 0..per_side {
                let row = t.row as f64 + (a as f64 + 0.5) / n;
                let col = t.col as f64 + (b as f64 + 0.5) / n;
                let theta = PI * row / h;
                let phi = 2.0 * PI * col / w - PI;
                out.push(SourcePoint {
                    direction: Vec3::new(
                        theta.sin() * phi.sin(),
                        theta.cos(),
                        -theta.sin() * phi.cos(),
                    ),
                    power: t.luminance * d_omega,
                });
            }
        }
        out
    }
}

/// Sub-points per pixel side so that their spacing is at most α/2 (1 for mirrors).
pub fn points_per_side(map_height: usize, alpha: f64) -> usize {
    if alpha <= 0.0 {
        return 1;
    }
    let pixel = PI / map_height as f64;
    ((pixel / (0.5 * alpha)).ceil() as usize).clamp(1, 8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_conserve_each_pixels_power() {
        let mut map = EnvMap::from_fn(64, 32, |_| 0.1);
        map.luminance[10 * 64 + 20] = 500.0;
        map.luminance[3 * 64 + 5] = 80.0;
        let bright = BrightSources::new(&map);
        assert_eq!(bright.texels.len(), 2);
        assert_eq!((bright.texels[0].row, bright.texels[0].col), (10, 20));
        assert_eq!(bright.dim.luminance[10 * 64 + 20], 0.0);
        for index in 0..2 {
            let t = &bright.texels[index];
            let want = t.luminance * map.solid_angle(t.row);
            for per_side in [1, 3, 5] {
                let got: f64 = bright
                    .points(64, 32, index, per_side)
                    .iter()
                    .map(|p| p.power)
                    .sum();
                assert!((got - want).abs() < 1e-12 * want, "{per_side}");
            }
        }
        let mut near = Vec::new();
        bright.near(bright.texels[1].center, 0.01, &mut near);
        assert_eq!(near, [1]);
    }

    #[test]
    fn spacing_follows_alpha() {
        assert_eq!(points_per_side(256, 0.0), 1);
        assert_eq!(points_per_side(256, 0.01), 3);
        assert_eq!(points_per_side(256, 0.02), 2);
        assert_eq!(points_per_side(256, 0.5), 1);
    }
}
