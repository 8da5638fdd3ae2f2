//! Resolution independence: the same sphere rendered at r = 100, 200 and 400 px.
//!
//! Measured (docs/accuracy.md, "Resolution and the working radius"): hand6's pixel statistics (mean, p10) agree within 0.005
//! at any size, but the finest-scale features drift (up to 1.4 in log10 variance for a
//! chrome sphere between r = 100 and 200; p90 of highlights by 3 %) because the canonical
//! grid is finer than the pixels of small spheres. With a working radius, larger spheres are
//! reduced first: scale-2 features then agree within 0.05, every hand6 feature within 0.15.

use ndarray::Array2;
use reflectance_core::features::{
    Extractor, Families, FeatureConfig, Preprocessing, default_names, named_set,
};
use reflectance_core::util::rng::Rng;
use reflectance_render::envmap::EnvMap;
use reflectance_render::ward::{Material, Ward};
use reflectance_render::{Lighting, Quality, View, render};

/// The shared ict_grace probe: texture, and a small bright source.
fn lighting() -> Lighting {
    let probe = crate::common::shared().join("data/probes/ict_grace.hdr");
    let map = EnvMap::load(&probe).unwrap_or_else(|e| panic!("{}: {e}", probe.display()));
    Lighting::new(map)
}

fn hand6() -> Vec<usize> {
    let names = default_names();
    named_set("hand6")
        .unwrap()
        .iter()
        .map(|n| names.iter().position(|m| m == n).unwrap())
        .collect()
}

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
fn sizes_agree_within_the_measured_tolerances() {
    let lighting = lighting();
    let white = lighting.white(&View::default());
    let plain = Extractor::new(FeatureConfig::default()).unwrap();
    let reduced = Extractor::new(FeatureConfig::extended(
        Families::NONE,
        Preprocessing::at_radius(100.0),
    ))
    .unwrap();
    let names = default_names();
    let set = hand6();
    let at = |name: &str| names.iter().position(|n| n == name).unwrap();
    for material in [
        Material::new(
            "chrome",
            Ward {
                rho_d: 0.0,
                rho_s: 0.75,
                alpha: 0.0,
            },
        ),
        Material::new(
            "white_matte",
            Ward {
                rho_d: 0.9,
                rho_s: 0.0,
                alpha: 0.0,
            },
        ),
    ] {
        let features = |radius: f64, extractor: &Extractor| {
            let size = (radius * 2.2).round() as usize;
            let img = render(
                &lighting,
                &material.ward,
                size,
                &View::default(),
                &Quality::default(),
                &mut Rng::new(1),
            );
            let lum = Array2::from_shape_vec(
                (size, size),
                img.luminance.iter().map(|&v| f64::from(v)).collect(),
            )
            .unwrap();
            extractor.extract(lum.view(), &img.circle, white)
        };
        let base = features(100.0, &plain);
        for radius in [200.0, 400.0] {
            let raw = features(radius, &plain);
            let with_working_radius = features(radius, &reduced);
            let delta = |v: &[f64], name: &str| (v[at(name)] - base[at(name)]).abs();
            // hand6's pixel statistics do not depend on the size.
            for name in ["pix.mean", "pix.p10"] {
                assert!(
                    delta(&raw, name) < 0.005,
                    "{} r={radius} {name}",
                    material.name
                );
            }
            // With the working radius every hand6 feature agrees within 0.15 (scale 1 keeps
            // ~0.1 of pixel-phase variation: at r = 100 the grid is at the pixel limit).
            for &i in &set {
                let d = (with_working_radius[i] - base[i]).abs();
                assert!(d < 0.15, "{} r={radius} {}: Δ {d}", material.name, names[i]);
            }
            // Scale 2 drifts by > 0.2 for a mirror without reduction, < 0.05 with it.
            if material.name == "chrome" {
                assert!(delta(&raw, "wav.s2.v.var") > 0.2);
                assert!(delta(&with_working_radius, "wav.s2.v.var") < 0.05);
            }
        }
    }
}
