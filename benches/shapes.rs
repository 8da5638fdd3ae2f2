//! The equivalent sphere of an object of known shape (issue #44): a 4000 × 3000 (12 MP)
//! photograph and its normal map (a torus-like blob covering a third of the frame) mapped to
//! a sphere of the working radius, and then unwrapped as the features read it, single thread.
//! Target: ≤ 20 ms for the mapping (docs/performance.md has the figures).

use ndarray::Array2;
use reflectance::{Extractor, FeatureConfig};
use reflectance_core::object::normals::{NormalMap, equivalent_sphere};

fn main() {
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    divan::main();
}

const WIDTH: usize = 4000;
const HEIGHT: usize = 3000;

/// A bumpy dome: normals that turn across the object, background outside it.
fn inputs() -> (Array2<f64>, NormalMap) {
    let (cx, cy, r) = (2000.0, 1500.0, 1300.0);
    let normals = Array2::from_shape_fn((HEIGHT, WIDTH), |(row, col)| {
        let (x, y) = ((col as f64 - cx) / r, (cy - row as f64) / r);
        let d2 = x * x + y * y;
        if d2 >= 0.95 {
            return [0.0f32; 3];
        }
        let bump = 0.15 * (9.0 * x).sin() * (7.0 * y).cos();
        let n = [x + bump, y - bump, (1.0 - d2).sqrt()];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        n.map(|c| (c / len) as f32)
    });
    let luminance = normals.mapv(|n| f64::from(0.2 + 0.6 * n[2].max(0.0)));
    (
        luminance,
        NormalMap::from_vectors(normals).expect("unit normals"),
    )
}

#[divan::bench(sample_count = 10)]
fn map_12_mp(bencher: divan::Bencher) {
    let (luminance, normals) = inputs();
    bencher.bench_local(|| {
        let sphere = equivalent_sphere(&luminance, &normals, None, 116.0).expect("a sphere");
        divan::black_box(sphere.fraction)
    });
}

#[divan::bench(sample_count = 10)]
fn map_and_unwrap_12_mp(bencher: divan::Bencher) {
    let (luminance, normals) = inputs();
    let config = FeatureConfig {
        working_radius: Some(116.0),
        ..FeatureConfig::default()
    };
    let extractor = Extractor::new(config).expect("the default features");
    bencher.bench_local(|| {
        let sphere = equivalent_sphere(&luminance, &normals, None, 116.0).expect("a sphere");
        let annulus = extractor.unwrap_equivalent(&sphere, 1.0).expect("observed");
        divan::black_box(annulus.1.fraction)
    });
}
