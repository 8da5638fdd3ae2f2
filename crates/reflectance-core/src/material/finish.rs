//! What a class entry may add to Ward's three parameters (issue #68), for training spheres
//! that look like real materials: a Fresnel term on the specular part (a dielectric's
//! exact one, or a metal's Schlick rise), and a printed disc on the surface. An entry
//! without them is the paper's Ward sphere, rendered bit for bit as before.

use super::gltf::fresnel_dielectric;
use crate::util::rng::Rng;
use serde::{Deserialize, Serialize};

/// How the specular reflectance varies with the angle of incidence.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Fresnel {
    /// Ward's: ρs at every angle (the paper's classes).
    #[default]
    Constant,
    /// A dielectric of index of refraction `ior` > 1: ρs·F(c; n)/F(1; n), F the exact
    /// unpolarized Fresnel reflectance, capped at 1 (so ρs at normal incidence, rising to 1
    /// at grazing angles).
    Dielectric {
        /// The index of refraction.
        ior: f64,
    },
    /// A metal: Schlick's F0 + (1 − F0)(1 − c)⁵ with F0 = ρs.
    Metal,
}

/// A printed disc (a spherical cap) of its own diffuse albedo; the specular coat is the
/// same over it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Disc {
    /// The disc's diffuse albedo, in [0, 1].
    pub albedo: f64,
    /// Its angular radius on the sphere, degrees, in (0, 90].
    pub radius: f64,
}

/// The most a disc's centre is tilted from the view direction, degrees: the whole disc of
/// an 8-ball-like print then stays mostly on the visible half.
pub const DISC_MAX_TILT_DEG: f64 = 60.0;

impl Disc {
    /// The disc's centre, a camera-space unit direction (+Z toward the viewer) drawn
    /// uniformly over the directions within [`DISC_MAX_TILT_DEG`] of the view.
    pub fn draw_centre(rng: &mut Rng) -> [f64; 3] {
        let low = DISC_MAX_TILT_DEG.to_radians().cos();
        let z = 1.0 - rng.next_f64() * (1.0 - low);
        let phi = 2.0 * std::f64::consts::PI * rng.next_f64();
        let s = (1.0 - z * z).max(0.0).sqrt();
        [s * phi.cos(), s * phi.sin(), z]
    }

    /// cos of the disc's angular radius: a surface normal n is on the disc when
    /// n · centre ≥ this.
    pub fn cos_radius(&self) -> f64 {
        self.radius.to_radians().cos()
    }
}

/// What a material adds to its Ward parameters: none of it by default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Finish {
    /// The specular part's dependence on the angle.
    pub fresnel: Fresnel,
    /// A printed disc, if any.
    pub disc: Option<Disc>,
}

impl Finish {
    /// Whether this is the plain Ward material.
    pub fn is_plain(&self) -> bool {
        *self == Finish::default()
    }
}

/// The specular reflectance of a coat of Ward weight `rho_s` as a function of the
/// incidence cosine (n·v for a mirror, v·h for a lobe's half vector), with its constants
/// computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Specular {
    rho_s: f64,
    law: Law,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Law {
    Constant,
    /// ρs / F(1; n), and n.
    Dielectric {
        scale: f64,
        ior: f64,
    },
    Schlick,
}

impl Specular {
    /// The coat of weight `rho_s` under `fresnel`.
    pub fn new(rho_s: f64, fresnel: Fresnel) -> Specular {
        let law = match fresnel {
            Fresnel::Constant => Law::Constant,
            Fresnel::Dielectric { ior } => Law::Dielectric {
                scale: rho_s / fresnel_dielectric(1.0, ior),
                ior,
            },
            Fresnel::Metal => Law::Schlick,
        };
        Specular { rho_s, law }
    }

    /// Whether the reflectance is ρs at every angle (Ward's).
    pub fn is_constant(&self) -> bool {
        self.law == Law::Constant
    }

    /// The reflectance at incidence cosine `cos` (clamped to [0, 1]).
    #[inline]
    pub fn at(&self, cos: f64) -> f64 {
        match self.law {
            Law::Constant => self.rho_s,
            Law::Dielectric { scale, ior } => (scale * fresnel_dielectric(cos, ior)).min(1.0),
            Law::Schlick => {
                let w = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
                self.rho_s + (1.0 - self.rho_s) * w
            }
        }
    }

    /// The share of light left to the diffuse part under the coat, seen at view cosine
    /// `cos`: 1 for Ward's constant coat (the paper's ρd/π), else 1 − [`Self::at`].
    #[inline]
    pub fn diffuse_weight(&self, cos: f64) -> f64 {
        match self.law {
            Law::Constant => 1.0,
            _ => 1.0 - self.at(cos),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dielectric_of_index_1_5_reflects_rho_s_at_normal_incidence() {
        for rho_s in [0.04, 0.045, 0.1, 0.25] {
            let coat = Specular::new(rho_s, Fresnel::Dielectric { ior: 1.5 });
            assert!((coat.at(1.0) - rho_s).abs() < 1e-15, "{rho_s}");
            assert!((coat.diffuse_weight(1.0) - (1.0 - rho_s)).abs() < 1e-15);
            // Rising monotonically to 1 (capped) at grazing incidence.
            let values: Vec<f64> = (0..=100).map(|i| coat.at(1.0 - i as f64 / 100.0)).collect();
            assert!(values.windows(2).all(|w| w[1] >= w[0]), "{values:?}");
            assert!((coat.at(0.0) - 1.0).abs() < 1e-12, "{}", coat.at(0.0));
        }
        // The exact term, as Cycles has it: 0.04 at index 1.5, F(60°) = 0.0892.
        let coat = Specular::new(0.04, Fresnel::Dielectric { ior: 1.5 });
        assert!((coat.at(0.5) - fresnel_dielectric(0.5, 1.5)).abs() < 1e-15);
        // A coat brighter than its index's F0 is capped at 1.
        let bright = Specular::new(0.5, Fresnel::Dielectric { ior: 1.5 });
        assert_eq!(bright.at(0.05), 1.0);
    }

    #[test]
    fn a_metal_follows_schlick_and_ward_is_constant() {
        let metal = Specular::new(0.65, Fresnel::Metal);
        assert_eq!(metal.at(1.0), 0.65);
        assert_eq!(metal.at(0.0), 1.0);
        assert!((metal.at(0.5) - (0.65 + 0.35 / 32.0)).abs() < 1e-15);
        let ward = Specular::new(0.1, Fresnel::Constant);
        assert!(ward.is_constant() && !metal.is_constant());
        assert_eq!((ward.at(0.0), ward.at(1.0)), (0.1, 0.1));
        assert_eq!(ward.diffuse_weight(0.3), 1.0);
        assert!(Finish::default().is_plain());
    }

    #[test]
    fn disc_centres_lie_within_60_degrees_of_the_view_and_fill_the_cap() {
        let mut rng = Rng::new(7);
        let low = DISC_MAX_TILT_DEG.to_radians().cos();
        let centres: Vec<[f64; 3]> = (0..4000).map(|_| Disc::draw_centre(&mut rng)).collect();
        for c in &centres {
            let norm = c.iter().map(|v| v * v).sum::<f64>();
            assert!((norm - 1.0).abs() < 1e-12 && c[2] >= low, "{c:?}");
        }
        // Uniform over the cap: z uniform on [cos 60°, 1], so its mean is 0.75.
        let mean_z = centres.iter().map(|c| c[2]).sum::<f64>() / centres.len() as f64;
        assert!((mean_z - 0.75).abs() < 0.01, "{mean_z}");
        let disc = Disc {
            albedo: 0.85,
            radius: 60.0,
        };
        assert!((disc.cos_radius() - 0.5).abs() < 1e-15);
    }
}
