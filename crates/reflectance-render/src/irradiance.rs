//! Cosine-weighted irradiance E(n) = ∫ L(ω) max(0, n·ω) dω of an environment map, for the
//! diffuse term and the white reference.
//!
//! Bright pixels (small, intense sources such as the sun) are kept as a list and summed
//! exactly for every normal, so shadow terminators stay sharp; the rest of the map, which is
//! smooth after the cosine filter, is precomputed on a lat-long grid of normals and
//! interpolated bilinearly. `tests::grid_error_is_small` measures the error against direct
//! summation on every probe shipped with the project.

use super::Vec3;
use super::envmap::EnvMap;
use std::f64::consts::PI;

/// Normals grid (lat-long, same convention as the maps).
const GRID_W: usize = 128;
const GRID_H: usize = 64;
/// A pixel is a "bright source" if it carries at least this fraction of the map's power…
const BRIGHT_FRACTION: f64 = 1e-3;
/// …up to this many pixels (the brightest ones).
const MAX_BRIGHT: usize = 96;

#[derive(Clone, Debug)]
pub struct Irradiance {
    /// E of the smooth remainder at the grid normals, row-major.
    smooth: Vec<f64>,
    /// Bright pixels: direction and L·dω.
    bright: Vec<(Vec3, f64)>,
}

/// A pixel of the map reduced to a direction and its power L·dω.
struct Source {
    direction: Vec3,
    power: f64,
}

impl Irradiance {
    pub fn new(map: &EnvMap) -> Irradiance {
        let mut sources: Vec<Source> = Vec::with_capacity(map.width * map.height);
        for i in 0..map.height {
            let d_omega = map.solid_angle(i);
            for j in 0..map.width {
                sources.push(Source {
                    direction: map.direction(i as f64 + 0.5, j as f64 + 0.5),
                    power: map.luminance[i * map.width + j] * d_omega,
                });
            }
        }
        let total: f64 = sources.iter().map(|s| s.power).sum();
        let mut order: Vec<usize> = (0..sources.len()).collect();
        order.sort_by(|&a, &b| {
            sources[b]
                .power
                .total_cmp(&sources[a].power)
                .then(a.cmp(&b))
        });
        let bright: Vec<(Vec3, f64)> = order
            .iter()
            .take(MAX_BRIGHT)
            .take_while(|&&k| sources[k].power >= BRIGHT_FRACTION * total && sources[k].power > 0.0)
            .map(|&k| (sources[k].direction, sources[k].power))
            .collect();
        for &k in order.iter().take(bright.len()) {
            sources[k].power = 0.0;
        }
        let smooth = smooth_grid(&merge_2x2(map, &sources));
        Irradiance { smooth, bright }
    }

    /// E(n) for a unit normal in map coordinates.
    #[inline]
    pub fn at(&self, n: Vec3) -> f64 {
        let exact: f64 = self
            .bright
            .iter()
            .map(|(d, p)| p * n.dot(*d).max(0.0))
            .sum();
        exact + self.smooth_at(n)
    }

    fn smooth_at(&self, n: Vec3) -> f64 {
        let theta = n.y.clamp(-1.0, 1.0).acos();
        let phi = n.x.atan2(-n.z);
        let u = (phi + PI) / (2.0 * PI) * GRID_W as f64 - 0.5;
        let v = theta / PI * GRID_H as f64 - 0.5;
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let xa = (x0 as isize).rem_euclid(GRID_W as isize) as usize;
        let xb = (xa + 1) % GRID_W;
        let ya = (y0 as isize).clamp(0, GRID_H as isize - 1) as usize * GRID_W;
        let yb = (y0 as isize + 1).clamp(0, GRID_H as isize - 1) as usize * GRID_W;
        let g = &self.smooth;
        (1.0 - fy) * ((1.0 - fx) * g[ya + xa] + fx * g[ya + xb])
            + fy * ((1.0 - fx) * g[yb + xa] + fx * g[yb + xb])
    }
}

/// Merge 2×2 blocks of pixels into single sources at their power-weighted mean direction
/// (the cosine kernel is smooth at that scale), for a 4× cheaper grid computation.
fn merge_2x2(map: &EnvMap, sources: &[Source]) -> Vec<Source> {
    let (w, h) = (map.width, map.height);
    let mut merged = Vec::with_capacity(w.div_ceil(2) * h.div_ceil(2));
    for bi in (0..h).step_by(2) {
        for bj in (0..w).step_by(2) {
            let mut power = 0.0;
            let mut direction = Vec3::new(0.0, 0.0, 0.0);
            let mut plain = Vec3::new(0.0, 0.0, 0.0);
            for i in bi..(bi + 2).min(h) {
                for j in bj..(bj + 2).min(w) {
                    let s = &sources[i * w + j];
                    power += s.power;
                    direction = direction + s.direction * s.power;
                    plain = plain + s.direction;
                }
            }
            let direction = if power > 0.0 {
                direction.normalized()
            } else {
                plain.normalized()
            };
            merged.push(Source { direction, power });
        }
    }
    merged
}

fn smooth_grid(sources: &[Source]) -> Vec<f64> {
    let grid = EnvMap::from_fn(GRID_W, GRID_H, |_| 0.0);
    let live: Vec<&Source> = sources.iter().filter(|s| s.power > 0.0).collect();
    let (dx, dy, dz, p): (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) = live.iter().fold(
        (Vec::new(), Vec::new(), Vec::new(), Vec::new()),
        |(mut x, mut y, mut z, mut p), s| {
            x.push(s.direction.x);
            y.push(s.direction.y);
            z.push(s.direction.z);
            p.push(s.power);
            (x, y, z, p)
        },
    );
    const LANES: usize = 8;
    let mut out = Vec::with_capacity(GRID_W * GRID_H);
    for a in 0..GRID_H {
        for b in 0..GRID_W {
            let n = grid.direction(a as f64 + 0.5, b as f64 + 0.5);
            // Independent lanes so the loop vectorizes; the summation order is fixed.
            let mut lanes = [0.0f64; LANES];
            let whole = p.len() / LANES * LANES;
            for base in (0..whole).step_by(LANES) {
                for (l, lane) in lanes.iter_mut().enumerate() {
                    let k = base + l;
                    let cos = n.x * dx[k] + n.y * dy[k] + n.z * dz[k];
                    *lane += p[k] * if cos > 0.0 { cos } else { 0.0 };
                }
            }
            let tail: f64 = (whole..p.len())
                .map(|k| p[k] * (n.x * dx[k] + n.y * dy[k] + n.z * dz[k]).max(0.0))
                .sum();
            out.push(lanes.iter().sum::<f64>() + tail);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::shared_probe;

    fn normals(count: usize) -> Vec<Vec3> {
        let mut rng = reflectance_core::util::rng::Rng::new(11);
        (0..count)
            .map(|_| {
                let z = 2.0 * rng.next_f64() - 1.0;
                let a = 2.0 * PI * rng.next_f64();
                let s = (1.0 - z * z).sqrt();
                Vec3::new(s * a.cos(), s * a.sin(), z)
            })
            .collect()
    }

    #[test]
    fn uniform_map_gives_pi() {
        let irr = Irradiance::new(&EnvMap::from_fn(512, 256, |_| 1.0));
        for n in normals(50) {
            assert!((irr.at(n) / PI - 1.0).abs() < 1e-3, "{n:?}: {}", irr.at(n));
        }
    }

    #[test]
    fn a_point_light_is_summed_exactly() {
        // One very bright pixel on a black map: E(n) = P·max(0, n·s) with no grid blur.
        let mut map = EnvMap::from_fn(512, 256, |_| 0.0);
        map.luminance[60 * 512 + 300] = 5e4;
        let irr = Irradiance::new(&map);
        for n in normals(200) {
            let exact = map.irradiance_exact(n);
            assert!((irr.at(n) - exact).abs() <= 1e-9 * exact.max(1.0), "{n:?}");
        }
    }

    /// The accepted error of the grid: on the real probes, relative to the mean irradiance
    /// of the map, at random normals.
    #[test]
    #[cfg_attr(
        not(shared_data),
        ignore = "needs ../shared/data/probes beside the repository"
    )]
    fn grid_error_is_small_on_real_probes() {
        for name in [
            "polyhaven_noon_grass.hdr",
            "ict_grace.hdr",
            "polyhaven_studio_small_03.hdr",
        ] {
            let map = shared_probe(name);
            let irr = Irradiance::new(&map);
            let ns = normals(40);
            let exact: Vec<f64> = ns.iter().map(|&n| map.irradiance_exact(n)).collect();
            let scale = exact.iter().sum::<f64>() / exact.len() as f64;
            let worst = ns
                .iter()
                .zip(&exact)
                .map(|(&n, e)| (irr.at(n) - e).abs() / scale)
                .fold(0.0, f64::max);
            assert!(worst < 5e-3, "{name}: worst relative error {worst}");
        }
    }
}
