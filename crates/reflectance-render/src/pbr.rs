//! A sphere under a light probe for the Ward BRDF and for glTF's metallic-roughness BRDF,
//! by the same Monte Carlo estimator with the same samples: what measures how far the glTF
//! export ([`reflectance_core::material::gltf`]) is from the Ward material it maps
//! (`examples/gltf_mapping.rs`, docs/accuracy.md). Not a training renderer: no pixel
//! supersampling and no bright-source treatment, but both BRDFs see exactly the same light.

use crate::envmap::EnvMap;
use crate::ward::{Ward, WardBrdf};
use crate::{Camera, Vec3, View};
use reflectance_core::material::gltf::{Pbr, fresnel_dielectric};
use reflectance_core::util::rng::Rng;
use std::f64::consts::PI;

/// A BRDF split as the estimator needs it: a diffuse part summed over the whole (reduced)
/// probe, a specular lobe sampled around the mirror direction, or an ideal mirror.
pub trait Brdf: Sync {
    /// The part summed over every direction of the reduced probe.
    fn diffuse(&self, n: Vec3, v: Vec3, l: Vec3) -> f64;
    /// The glossy part (0 for an ideal mirror).
    fn specular(&self, n: Vec3, v: Vec3, l: Vec3) -> f64;
    /// An ideal mirror's weight at cos θ = n·v, or None for a glossy lobe.
    fn mirror(&self, cos: f64) -> Option<f64>;
}

impl Brdf for Ward {
    fn diffuse(&self, _: Vec3, _: Vec3, _: Vec3) -> f64 {
        self.rho_d / PI
    }
    fn specular(&self, n: Vec3, v: Vec3, l: Vec3) -> f64 {
        self.specular_brdf(n, v, l)
    }
    fn mirror(&self, _: f64) -> Option<f64> {
        (self.alpha == 0.0).then_some(self.rho_s)
    }
}

/// Which renderer's reading of glTF's BRDF: both GGX with height-correlated Smith
/// visibility and the dielectric's diffuse weighted by 1 − F; they differ in the Fresnel
/// term of a dielectric.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reading {
    /// The Khronos glTF sample viewer (what real-time viewers implement): Schlick's
    /// F0 + (1 − F0)(1 − v·h)⁵ with F0 = ((ior − 1)/(ior + 1))², scaled by `specularFactor`.
    Viewer,
    /// Blender's Cycles: the exact Fresnel term of the index; `specularFactor` 0 is no
    /// reflection.
    Cycles,
}

/// glTF 2.0's BRDF (its specification's Appendix B, with `KHR_materials_ior` and
/// `KHR_materials_specular`) for grey materials, as a renderer reads it.
#[derive(Clone, Copy, Debug)]
pub struct Gltf {
    pub pbr: Pbr,
    pub reading: Reading,
}

impl Gltf {
    /// (dielectric, metal) Fresnel terms at v·h.
    fn fresnel(&self, v_dot_h: f64) -> (f64, f64) {
        let p = &self.pbr;
        let c = v_dot_h.abs().min(1.0);
        let weight = (1.0 - c).powi(5);
        let dielectric = match self.reading {
            Reading::Viewer => {
                let f0 = ((p.ior - 1.0) / (p.ior + 1.0)).powi(2).min(1.0);
                p.specular * (f0 + (1.0 - f0) * weight)
            }
            Reading::Cycles if p.specular == 0.0 => 0.0,
            Reading::Cycles => fresnel_dielectric(c, p.ior),
        };
        let metal = p.base_color + (1.0 - p.base_color) * weight;
        (dielectric, metal)
    }

    /// GGX's distribution times the height-correlated Smith visibility.
    fn ggx(&self, n: Vec3, v: Vec3, l: Vec3) -> f64 {
        let a2 = self.pbr.roughness.powi(4);
        let (nl, nv) = (n.dot(l), n.dot(v));
        if nl <= 0.0 || nv <= 0.0 {
            return 0.0;
        }
        let h = (l + v).normalized();
        let nh = n.dot(h);
        let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
        let visibility = 0.5
            / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
        d * visibility
    }
}

impl Brdf for Gltf {
    fn diffuse(&self, _: Vec3, v: Vec3, l: Vec3) -> f64 {
        let h = (l + v).normalized();
        let (dielectric, _) = self.fresnel(v.dot(h));
        (1.0 - self.pbr.metallic) * (1.0 - dielectric) * self.pbr.base_color / PI
    }
    fn specular(&self, n: Vec3, v: Vec3, l: Vec3) -> f64 {
        let h = (l + v).normalized();
        let (dielectric, metal) = self.fresnel(v.dot(h));
        let m = self.pbr.metallic;
        ((1.0 - m) * dielectric + m * metal) * self.ggx(n, v, l)
    }
    fn mirror(&self, cos: f64) -> Option<f64> {
        let (dielectric, metal) = self.fresnel(cos);
        let m = self.pbr.metallic;
        (self.pbr.roughness == 0.0).then_some((1.0 - m) * dielectric + m * metal)
    }
}

/// How a sphere is drawn: `size` × `size` pixels over the unit disc, `samples` lobe
/// samples per pixel, the lobe sampled with Ward's α (`lobe_alpha`).
#[derive(Clone, Copy, Debug)]
pub struct Drawing {
    pub size: usize,
    pub samples: usize,
    pub lobe_alpha: f64,
    pub seed: u64,
}

/// A direction of the lobe's sampling mixture: half Beckmann half-vectors of width α around
/// n, half cosine-weighted directions (for the tails); with the mixture's density.
fn sample(n: Vec3, v: Vec3, alpha: f64, frame: (Vec3, Vec3), rng: &mut Rng) -> Option<(Vec3, f64)> {
    let (t, b) = frame;
    let (u1, u2) = (rng.next_f64(), rng.next_f64());
    let local = |cos: f64, phi: f64| {
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        (t * (sin * phi.cos()) + b * (sin * phi.sin()) + n * cos).normalized()
    };
    let l = if rng.next_f64() < 0.5 {
        let tan2 = -alpha * alpha * (1.0 - u1).ln();
        let h = local(1.0 / (1.0 + tan2).sqrt(), 2.0 * PI * u2);
        h * (2.0 * v.dot(h)) - v
    } else {
        local(u1.sqrt(), 2.0 * PI * u2)
    };
    let nl = n.dot(l);
    if nl <= 0.0 {
        return None;
    }
    let h = (l + v).normalized();
    let nh = n.dot(h);
    let tan2 = (1.0 - nh * nh) / (nh * nh);
    let beckmann = (-tan2 / (alpha * alpha)).exp() / (PI * alpha * alpha * nh.powi(4));
    let pdf = 0.5 * beckmann * nh / (4.0 * l.dot(h).abs()) + 0.5 * nl / PI;
    Some((l, pdf))
}

/// Two unit vectors completing `n` to an orthonormal frame.
fn frame_of(n: Vec3) -> (Vec3, Vec3) {
    let other = if n.x.abs() < 0.9 {
        Vec3::new(1.0, 0.0, 0.0)
    } else {
        Vec3::new(0.0, 1.0, 0.0)
    };
    let t = (other - n * n.dot(other)).normalized();
    let b = Vec3::new(
        n.y * t.z - n.z * t.y,
        n.z * t.x - n.x * t.z,
        n.x * t.y - n.y * t.x,
    );
    (t, b)
}

/// Radiance leaving each pixel of the sphere (row-major, None outside the disc) under
/// `map`, seen from `view`'s elevation (orthographic); `reduced` is the map the diffuse
/// part sums over. Every BRDF drawn with the same `drawing` sees the same samples.
pub fn draw(
    map: &EnvMap,
    reduced: &EnvMap,
    brdf: &dyn Brdf,
    view: &View,
    drawing: &Drawing,
) -> Vec<Option<f64>> {
    let Camera { v, up, right, .. } = Camera::new(view);
    let texels: Vec<(Vec3, f64)> = (0..reduced.height)
        .flat_map(|i| {
            (0..reduced.width).map(move |j| {
                let d = reduced.direction(i as f64 + 0.5, j as f64 + 0.5);
                (
                    d,
                    reduced.luminance[i * reduced.width + j] * reduced.solid_angle(i),
                )
            })
        })
        .collect();
    let size = drawing.size;
    (0..size * size)
        .map(|p| {
            let x = 2.0 * ((p % size) as f64 + 0.5) / size as f64 - 1.0;
            let yy = 1.0 - 2.0 * ((p / size) as f64 + 0.5) / size as f64;
            let z2 = 1.0 - x * x - yy * yy;
            if z2 <= 0.0 {
                return None;
            }
            let n = right * x + up * yy + v * z2.sqrt();
            let nv = n.dot(v);
            let diffuse: f64 = texels
                .iter()
                .filter(|(l, _)| n.dot(*l) > 0.0)
                .map(|&(l, power)| power * n.dot(l) * brdf.diffuse(n, v, l))
                .sum();
            let specular = match brdf.mirror(nv) {
                Some(weight) => weight * map.lookup(n * (2.0 * nv) - v),
                None => {
                    let mut rng = Rng::fork(drawing.seed, p as u64);
                    let frame = frame_of(n);
                    let total: f64 = (0..drawing.samples)
                        .filter_map(|_| sample(n, v, drawing.lobe_alpha, frame, &mut rng))
                        .map(|(l, pdf)| map.lookup(l) * brdf.specular(n, v, l) * n.dot(l) / pdf)
                        .sum();
                    total / drawing.samples as f64
                }
            };
            Some(diffuse + specular)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use reflectance_core::material::gltf::pbr_of;

    fn uniform() -> EnvMap {
        EnvMap::from_fn(64, 32, |_| 1.0)
    }

    fn mean(pixels: &[Option<f64>]) -> f64 {
        let inside: Vec<f64> = pixels.iter().flatten().copied().collect();
        inside.iter().sum::<f64>() / inside.len() as f64
    }

    const DRAWING: Drawing = Drawing {
        size: 24,
        samples: 256,
        lobe_alpha: 0.05,
        seed: 1,
    };

    /// Under light of 1 from everywhere, a Lambertian surface of albedo ρd leaves ρd, and
    /// Ward's (nearly normalized) narrow lobe about ρs.
    #[test]
    fn a_white_furnace_gives_back_the_albedos() {
        let map = uniform();
        let view = View::default();
        let matte = Ward {
            rho_d: 0.5,
            rho_s: 0.0,
            alpha: 0.0,
        };
        let pixels = draw(&map, &map, &matte, &view, &DRAWING);
        assert!(
            pixels.iter().flatten().all(|p| (p - 0.5).abs() < 0.01),
            "{pixels:?}"
        );
        let glossy = Ward {
            rho_d: 0.0,
            rho_s: 0.5,
            alpha: 0.05,
        };
        let centre = draw(&map, &map, &glossy, &view, &DRAWING)[12 * 24 + 12].unwrap();
        assert!((centre - 0.5).abs() < 0.03, "{centre}");
    }

    /// The mapping's defining property: over the disc, under uniform light, a mirror's glTF
    /// metal reflects on average what Ward's ρs does.
    #[test]
    fn the_exported_mirror_reflects_rho_s_over_the_disc() {
        let map = uniform();
        let view = View::default();
        let drawing = Drawing {
            size: 200,
            ..DRAWING
        };
        let ward = Ward {
            rho_d: 0.0,
            rho_s: 0.75,
            alpha: 0.0,
        };
        let w = mean(&draw(&map, &map, &ward, &view, &drawing));
        assert!((w - 0.75).abs() < 1e-9, "ward {w}");
        for reading in [Reading::Viewer, Reading::Cycles] {
            let gltf = Gltf {
                pbr: pbr_of(&ward),
                reading,
            };
            let g = mean(&draw(&map, &map, &gltf, &view, &drawing));
            assert!((g - 0.75).abs() < 2e-3, "{reading:?}: gltf {g}");
        }
    }

    /// A dielectric mirror under uniform light, as each renderer reads it: its disc's mean
    /// is the disc mean of its Fresnel term, the exact one for Cycles (the core's quadrature
    /// of it, which the mapping solves with) and Schlick's for the viewer.
    #[test]
    fn dielectric_mirrors_reflect_their_fresnel_term() {
        use reflectance_core::material::gltf::{DISC_EDGE, disc_fresnel, ior_of_f0};
        let map = uniform();
        let view = View::default();
        let size = 240;
        let drawing = Drawing { size, ..DRAWING };
        for f0 in [0.03, 0.24] {
            let pbr = Pbr {
                base_color: 0.0,
                metallic: 0.0,
                roughness: 0.0,
                ior: ior_of_f0(f0),
                specular: 1.0,
            };
            for (reading, expected) in [
                (Reading::Cycles, disc_fresnel(f0)),
                (Reading::Viewer, {
                    // (1 − cos θ)⁵ over the disc to DISC_EDGE, cos θ = √(1 − u), u = ρ².
                    let n = 100_000;
                    let e2 = DISC_EDGE * DISC_EDGE;
                    let w: f64 = (0..n)
                        .map(|i| (1.0 - (1.0 - e2 * (i as f64 + 0.5) / n as f64).sqrt()).powi(5))
                        .sum::<f64>()
                        / n as f64;
                    f0 + (1.0 - f0) * w
                }),
            ] {
                let pixels = draw(&map, &map, &Gltf { pbr, reading }, &view, &drawing);
                let (mut sum, mut count) = (0.0, 0);
                for (p, value) in pixels.iter().enumerate() {
                    let x = 2.0 * ((p % size) as f64 + 0.5) / size as f64 - 1.0;
                    let y = 1.0 - 2.0 * ((p / size) as f64 + 0.5) / size as f64;
                    if let Some(v) = value.filter(|_| x * x + y * y <= DISC_EDGE * DISC_EDGE) {
                        sum += v;
                        count += 1;
                    }
                }
                let mean = sum / count as f64;
                assert!(
                    (mean - expected).abs() < 0.01 * expected,
                    "{reading:?} F0 {f0}: {mean} vs {expected}"
                );
            }
        }
    }
}
