//! A picture of a Ward material: a sphere rendered by this renderer in one of a few
//! built-in outdoor scenes, in front of the scene itself, as an 8-bit sRGB PNG exposed as a
//! camera would: an ideal white surface facing the viewer at [`EXPOSURE`] of full scale,
//! brighter parts clipping. The scenes are procedural (sky, sun, horizon, ground), so that
//! a reflection reads as the place it reflects: the light probes of the data set stay
//! outside the repository and the image, so none is bundled.

use super::envmap::EnvMap;
use super::ward::Ward;
use super::{Lighting, Quality, Vec3, View, render};
use ndarray::Array2;
use reflectance_core::image::display;
use reflectance_core::material::InvalidWard;
use reflectance_core::util::rng::Rng;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Where white lands (as a fraction of full scale), leaving headroom for highlights.
pub const EXPOSURE: f64 = 0.7;

/// The illuminations by name: `sky-1` (a clear day), `sky-2` (overcast), `sky-3` (a low sun
/// over a tree line), `sky-4` (a sunny square among buildings).
pub const PROBES: [&str; 4] = ["sky-1", "sky-2", "sky-3", "sky-4"];

/// Image sizes a preview may have (a render costs about 3 µs per pixel).
pub const SIZES: std::ops::RangeInclusive<usize> = 72..=384;
/// Broader lobes cost more quadrature; beyond this a preview is refused.
pub const MAX_ALPHA: f64 = 0.5;

/// The backdrop's camera: pitched down a little from the horizontal, this wide (degrees).
const BACKDROP_PITCH: f64 = 8.0;
const BACKDROP_FIELD: f64 = 70.0;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PreviewError {
    #[error("unknown probe {0:?} (expected one of {list})", list = PROBES.join(", "))]
    UnknownProbe(String),
    #[error("size {0} must be between {min} and {max}", min = SIZES.start(), max = SIZES.end())]
    Size(usize),
    #[error("alpha {0} must be at most {MAX_ALPHA} for a preview")]
    Alpha(f64),
    #[error(transparent)]
    Parameters(#[from] InvalidWard),
}

/// How a scene looks: its sun (elevation, azimuth in degrees; no sun when overcast), the
/// sky's brightness at the horizon over the zenith, the ground's brightness, and what
/// stands on the horizon.
struct Scene {
    sun: Option<(f64, f64)>,
    horizon_glow: f64,
    ground: f64,
    skyline: Skyline,
}

enum Skyline {
    Hills,
    Trees,
    Buildings,
}

const SCENES: [Scene; 4] = [
    Scene {
        sun: Some((40.0, 35.0)),
        horizon_glow: 1.5,
        ground: 0.35,
        skyline: Skyline::Hills,
    },
    Scene {
        sun: None,
        horizon_glow: 0.6,
        ground: 0.3,
        skyline: Skyline::Hills,
    },
    Scene {
        sun: Some((9.0, -50.0)),
        horizon_glow: 2.0,
        ground: 0.2,
        skyline: Skyline::Trees,
    },
    Scene {
        sun: Some((55.0, 120.0)),
        horizon_glow: 1.2,
        ground: 0.4,
        skyline: Skyline::Buildings,
    },
];

/// A direction from elevation and azimuth (degrees; azimuth 0 looks along −Z, the map's
/// centre, 90 along +X).
fn toward(elevation: f64, azimuth: f64) -> Vec3 {
    let (e, a) = (elevation.to_radians(), azimuth.to_radians());
    Vec3::new(e.cos() * a.sin(), e.sin(), -e.cos() * a.cos())
}

/// How high the skyline stands at an azimuth (radians of elevation).
fn skyline(kind: &Skyline, azimuth: f64) -> f64 {
    match kind {
        Skyline::Hills => 0.05 + 0.03 * (3.0 * azimuth).sin() + 0.02 * (7.0 * azimuth + 1.0).sin(),
        Skyline::Trees => 0.06 + 0.04 * ((23.0 * azimuth).sin() * (9.0 * azimuth).cos()).abs(),
        Skyline::Buildings => {
            // Blocks of different heights, 24 around the horizon.
            let block = ((azimuth + PI) / (2.0 * PI) * 24.0).floor();
            0.08 + 0.25 * ((block * 12.9898).sin() * 43_758.545).fract().abs()
        }
    }
}

impl Scene {
    /// The scene's luminance seen along `d`.
    fn luminance(&self, d: Vec3) -> f64 {
        let elevation = d.y.clamp(-1.0, 1.0).asin();
        let azimuth = d.x.atan2(-d.z);
        if elevation < 0.0 {
            // Fields in stripes that narrow toward the horizon.
            let stripes = (6.0 * azimuth + 2.0 / (0.05 - elevation)).sin();
            return self.ground * (0.8 + 0.2 * stripes);
        }
        if elevation < skyline(&self.skyline, azimuth) {
            return 0.25 * self.ground;
        }
        let height = d.y.max(0.0);
        let sky = 1.0 + self.horizon_glow * (1.0 - height).powi(4);
        let clouds = 0.3 * ((5.0 * azimuth).sin() * (11.0 * height + azimuth).cos()).max(0.0);
        let sun = self.sun.map_or(0.0, |(e, a)| {
            let cos = d.dot(toward(e, a));
            let angle = cos.clamp(-1.0, 1.0).acos();
            // A disc of 1.5° at 60 × the zenith, in a glow.
            if angle < 1.5f64.to_radians() {
                60.0
            } else {
                2.0 * (-angle / 0.15).exp()
            }
        });
        sky + clouds + sun
    }
}

/// The lighting of a preview probe, built on first use.
fn lighting(probe: &str) -> Result<&'static Lighting, PreviewError> {
    static LIGHTINGS: [OnceLock<Lighting>; PROBES.len()] =
        [const { OnceLock::new() }; PROBES.len()];
    let index = PROBES
        .iter()
        .position(|p| *p == probe)
        .ok_or_else(|| PreviewError::UnknownProbe(probe.to_string()))?;
    let scene = &SCENES[index];
    Ok(LIGHTINGS[index]
        .get_or_init(|| Lighting::new(EnvMap::from_fn(512, 256, |d| scene.luminance(d)))))
}

/// Check a request before any rendering.
pub fn check(ward: &Ward, probe: &str, size: usize) -> Result<(), PreviewError> {
    ward.validate()?;
    if ward.alpha > MAX_ALPHA {
        return Err(PreviewError::Alpha(ward.alpha));
    }
    if !SIZES.contains(&size) {
        return Err(PreviewError::Size(size));
    }
    PROBES
        .contains(&probe)
        .then_some(())
        .ok_or_else(|| PreviewError::UnknownProbe(probe.to_string()))
}

/// The scene behind the sphere, as a perspective camera sees it at `(x, y)` (−1 … 1 across
/// the image, y up).
fn backdrop(map: &EnvMap, x: f64, y: f64) -> f64 {
    let half = (BACKDROP_FIELD / 2.0).to_radians().tan();
    let (s, c) = BACKDROP_PITCH.to_radians().sin_cos();
    // Forward (along −Z, pitched down), right (+X) and up, combined and normalized.
    let (fx, fy, fz) = (x * half, c * y * half - s, -c - s * y * half);
    let norm = (fx * fx + fy * fy + fz * fz).sqrt();
    map.lookup(Vec3::new(fx / norm, fy / norm, fz / norm))
}

/// The PNG of `ward` under `probe`, `size` × `size` pixels (deterministic).
pub fn png(ward: &Ward, probe: &str, size: usize) -> Result<Vec<u8>, PreviewError> {
    check(ward, probe, size)?;
    let lighting = lighting(probe)?;
    let view = View::default();
    let image = render(
        lighting,
        ward,
        size,
        &view,
        &Quality::default(),
        &mut Rng::new(1),
    );
    let white = lighting.white(&view) / EXPOSURE;
    let n = size as f64;
    let normalized = Array2::from_shape_fn((size, size), |(y, x)| {
        let k = y * size + x;
        let cover = f64::from(image.coverage[k]);
        let (u, v) = (
            (2.0 * x as f64 + 1.0) / n - 1.0,
            1.0 - (2.0 * y as f64 + 1.0) / n,
        );
        let behind = backdrop(&lighting.map, u, v);
        // The render is the sphere's light over a black background, weighted by coverage.
        (f64::from(image.luminance[k]) + (1.0 - cover) * behind) / white
    });
    Ok(display::luminance_png(normalized.view()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
        Ward {
            rho_d,
            rho_s,
            alpha,
        }
    }

    #[test]
    fn a_white_matte_sphere_is_bright_and_a_black_one_dark() {
        let mean = |m: &Ward| {
            let png = png(m, "sky-1", 72).unwrap();
            let picture = image::load_from_memory(&png).unwrap().to_luma8();
            assert_eq!(picture.dimensions(), (72, 72));
            // The centre 20 × 20 pixels: inside the sphere.
            let (mut sum, mut n) = (0u32, 0u32);
            for y in 26..46 {
                for x in 26..46 {
                    sum += u32::from(picture.get_pixel(x, y).0[0]);
                    n += 1;
                }
            }
            f64::from(sum) / f64::from(n)
        };
        let (white, black) = (
            mean(&material(0.9, 0.0, 0.0)),
            mean(&material(0.05, 0.0, 0.0)),
        );
        assert!(white > 2.0 * black, "white {white}, black {black}");
        assert!(white > 100.0, "white {white}");
    }

    #[test]
    fn previews_are_deterministic_and_checked() {
        let m = material(0.3, 0.2, 0.02);
        assert_eq!(png(&m, "sky-2", 72).unwrap(), png(&m, "sky-2", 72).unwrap());
        assert_eq!(
            png(&m, "studio", 72),
            Err(PreviewError::UnknownProbe("studio".into()))
        );
        assert_eq!(png(&m, "sky-1", 71), Err(PreviewError::Size(71)));
        assert_eq!(
            png(&material(0.3, 0.2, 0.6), "sky-1", 72),
            Err(PreviewError::Alpha(0.6))
        );
        assert!(matches!(
            png(&material(0.8, 0.5, 0.0), "sky-1", 72),
            Err(PreviewError::Parameters(_))
        ));
    }
}
