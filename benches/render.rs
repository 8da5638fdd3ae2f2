//! Rendering speed: one 256×256 sphere per class type under a real probe (when
//! ../shared/data/probes is present; a synthetic sunny map otherwise), single thread.
//! Target (issue 3): ≤ 0.3 s per image on one core.

use divan::Bencher;
use reflectance_core::util::rng::Rng;
use reflectance_render::envmap::EnvMap;
use reflectance_render::ward::Ward;
use reflectance_render::{Lighting, Quality, View, render};
use std::sync::OnceLock;

fn main() {
    // As the binary does: see `reflectance_core::util::heap`.
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    divan::main();
}

fn lighting() -> &'static Lighting {
    static LIGHTING: OnceLock<Lighting> = OnceLock::new();
    LIGHTING.get_or_init(|| {
        let probe = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/probes/polyhaven_noon_grass.hdr");
        let map = EnvMap::load(&probe).unwrap_or_else(|_| {
            let mut map = EnvMap::from_fn(512, 256, |d| {
                0.3 + 0.8 * d.y.max(0.0) + 0.1 * (10.0 * d.x).sin()
            });
            map.luminance[30 * 512 + 200] = 5e4;
            map
        });
        Lighting::new(map)
    })
}

fn ward(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
    Ward {
        rho_d,
        rho_s,
        alpha,
    }
}

/// One 256×256 image of `material`.
fn bench_class(bencher: Bencher, material: Ward) {
    bencher.bench(|| {
        render(
            lighting(),
            &material,
            256,
            &View::default(),
            &Quality::default(),
            &mut Rng::new(1),
        )
    });
}

#[divan::bench(sample_count = 10)]
fn matte(bencher: Bencher) {
    bench_class(bencher, ward(0.9, 0.0, 0.0));
}

#[divan::bench(sample_count = 10)]
fn mirror(bencher: Bencher) {
    bench_class(bencher, ward(0.0, 0.75, 0.0));
}

#[divan::bench(sample_count = 10)]
fn shiny(bencher: Bencher) {
    bench_class(bencher, ward(0.7, 0.25, 0.01));
}

/// Per-probe precomputation (irradiance grid, bright sources), shared by all classes.
#[divan::bench(sample_count = 5)]
fn lighting_setup(bencher: Bencher) {
    let map = lighting().map.clone();
    bencher.bench(|| Lighting::new(map.clone()));
}
