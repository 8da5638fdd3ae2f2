//! A picture of a Ward material: a sphere rendered by this renderer under one of a few
//! built-in illuminations, as an 8-bit sRGB PNG exposed as a camera would: an ideal white
//! surface facing the viewer at [`EXPOSURE`] of full scale, brighter parts clipping. The illuminations are procedural maps with natural-illumination
//! statistics ([`super::synthetic`]): the light probes of the data set stay outside the
//! repository and the image, so none is bundled.

use super::synthetic;
use super::ward::Material;
use super::{Lighting, Quality, View, render};
use crate::image::display;
use crate::util::rng::Rng;
use ndarray::Array2;
use std::sync::OnceLock;

/// Where white lands (as a fraction of full scale), leaving headroom for highlights.
pub const EXPOSURE: f64 = 0.7;

/// The seed of the preview illuminations' family.
const FAMILY: u64 = 0x5052_4556;

/// The illuminations by name: `sky-1` … `sky-4`.
pub const PROBES: [&str; 4] = ["sky-1", "sky-2", "sky-3", "sky-4"];

/// Image sizes a preview may have (a render costs about 3 µs per pixel).
pub const SIZES: std::ops::RangeInclusive<usize> = 72..=384;
/// Broader lobes cost more quadrature; beyond this a preview is refused.
pub const MAX_ALPHA: f64 = 0.5;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PreviewError {
    #[error("unknown probe {0:?} (expected one of {list})", list = PROBES.join(", "))]
    UnknownProbe(String),
    #[error("size {0} must be between {min} and {max}", min = SIZES.start(), max = SIZES.end())]
    Size(usize),
    #[error("alpha {0} must be at most {MAX_ALPHA} for a preview")]
    Alpha(f64),
    #[error(
        "need rho_d ≥ 0, rho_s ≥ 0, rho_d + rho_s ≤ 1 and 0 ≤ alpha, not rho_d {rho_d}, rho_s \
         {rho_s}, alpha {alpha}"
    )]
    Parameters { rho_d: f64, rho_s: f64, alpha: f64 },
}

/// The lighting of a preview probe, built on first use.
fn lighting(probe: &str) -> Result<&'static Lighting, PreviewError> {
    static LIGHTINGS: [OnceLock<Lighting>; PROBES.len()] =
        [const { OnceLock::new() }; PROBES.len()];
    let index = PROBES
        .iter()
        .position(|p| *p == probe)
        .ok_or_else(|| PreviewError::UnknownProbe(probe.to_string()))?;
    Ok(LIGHTINGS[index].get_or_init(|| Lighting::new(synthetic::map(FAMILY, index as u64))))
}

/// Check a request before any rendering.
pub fn check(material: &Material, probe: &str, size: usize) -> Result<(), PreviewError> {
    material.validate().map_err(|_| PreviewError::Parameters {
        rho_d: material.rho_d,
        rho_s: material.rho_s,
        alpha: material.alpha,
    })?;
    if material.alpha > MAX_ALPHA {
        return Err(PreviewError::Alpha(material.alpha));
    }
    if !SIZES.contains(&size) {
        return Err(PreviewError::Size(size));
    }
    PROBES
        .contains(&probe)
        .then_some(())
        .ok_or_else(|| PreviewError::UnknownProbe(probe.to_string()))
}

/// The PNG of `material` under `probe`, `size` × `size` pixels (deterministic).
pub fn png(material: &Material, probe: &str, size: usize) -> Result<Vec<u8>, PreviewError> {
    check(material, probe, size)?;
    let lighting = lighting(probe)?;
    let view = View::default();
    let image = render(
        lighting,
        material,
        size,
        &view,
        &Quality::default(),
        &mut Rng::new(1),
    );
    let white = lighting.white(&view) / EXPOSURE;
    let normalized = Array2::from_shape_fn((size, size), |(y, x)| {
        f64::from(image.luminance[y * size + x]) / white
    });
    Ok(display::luminance_png(normalized.view()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(rho_d: f64, rho_s: f64, alpha: f64) -> Material {
        Material {
            name: "preview".into(),
            rho_d,
            rho_s,
            alpha,
        }
    }

    #[test]
    fn a_white_matte_sphere_is_bright_and_a_black_one_dark() {
        let mean = |m: &Material| {
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
            Err(PreviewError::Parameters { .. })
        ));
    }
}
