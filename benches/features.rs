//! Feature extraction speed: a 512×512 8-bit PNG sphere, single thread.
//! Target (issue 2): ≤ 1.0 ms per image excluding decode.

use divan::Bencher;
use ndarray::Array2;
use reflectance_core::analysis::{self, Placement, WhiteSpec};
use reflectance_core::decode::{self, DecodeOptions, LinearImage};
use reflectance_core::features::families::{CENTRE, DOMAIN};
use reflectance_core::features::lighting;
use reflectance_core::features::pyramid::{self, Edge};
use reflectance_core::features::spectrum::SpectrumPlan;
use reflectance_core::features::{Extractor, Families, FeatureConfig, Preprocessing};
use reflectance_core::locate::Circle;

fn main() {
    // As the binary does: see `reflectance_core::util::heap`.
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    divan::main();
}

const SIZE: usize = 512;

/// The sphere as the renderer frames it: centre (N−1)/2, radius N/2.2.
fn circle() -> Circle {
    let c = (SIZE as f64 - 1.0) / 2.0;
    Circle {
        cx: c,
        cy: c,
        r: SIZE as f64 / 2.2,
    }
}

/// An 8-bit grey PNG of a textured, shaded sphere on black.
fn png_bytes() -> Vec<u8> {
    let c = circle();
    let pixels: Vec<u8> = (0..SIZE * SIZE)
        .map(|i| {
            let (x, y) = ((i % SIZE) as f64, (i / SIZE) as f64);
            let (dx, dy) = ((x - c.cx) / c.r, (y - c.cy) / c.r);
            let d2 = dx * dx + dy * dy;
            if d2 > 1.0 {
                return 0;
            }
            let shade = 0.25 + 0.5 * (1.0 - d2).sqrt() + 0.15 * (9.0 * dx).sin() * (7.0 * dy).cos();
            let grain = ((i * 2_654_435_761) % 17) as f64 / 170.0;
            ((shade + grain).clamp(0.0, 1.0) * 255.0) as u8
        })
        .collect();
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    image::ImageEncoder::write_image(
        encoder,
        &pixels,
        SIZE as u32,
        SIZE as u32,
        image::ExtendedColorType::L8,
    )
    .expect("encode png");
    out
}

fn decoded() -> LinearImage {
    decode::decode(&png_bytes(), &DecodeOptions::default()).expect("decode")
}

#[divan::bench]
fn decode_png(bencher: Bencher) {
    let bytes = png_bytes();
    bencher.bench(|| {
        decode::decode(divan::black_box(&bytes), &DecodeOptions::default()).expect("decode")
    });
}

fn bench_extraction(bencher: Bencher, config: FeatureConfig) {
    let image = decoded();
    let extractor = Extractor::new(config).expect("config");
    let c = circle();
    bencher.bench(|| extractor.extract(divan::black_box(image.luminance.view()), &c, 1.0));
}

#[divan::bench]
fn features_excluding_decode(bencher: Bencher) {
    bench_extraction(bencher, FeatureConfig::default());
}

/// The shipped models' configuration: the 117 features plus 117 more of log10 of the
/// unwrapped image.
#[divan::bench]
fn features_with_log_domain(bencher: Bencher) {
    bench_extraction(bencher, FeatureConfig::with_log_domain());
}

/// Every extension: the radial changes and the orientation dependencies too (314 features).
#[divan::bench]
fn features_with_every_extension(bencher: Bencher) {
    bench_extraction(
        bencher,
        FeatureConfig::extended(Families::ALL, Preprocessing::default()),
    );
}

/// What the service does for the shipped default model (`models/ward6`): the features its
/// classifier reads, after reduction to its working radius and with the capture
/// measurements its warnings need. Target (issue 16): ≤ 1.2 ms excluding decode.
#[divan::bench]
fn features_of_the_shipped_model(bencher: Bencher) {
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let registry = reflectance_core::model::registry::Registry::new(&models);
    let file = registry
        .active("ward6")
        .and_then(|version| registry.load("ward6", version))
        .expect("the shipped ward6 model");
    let model = reflectance_core::inference::LoadedModel::new(file).expect("model");
    let image = decoded();
    let locate = Placement::Circle(circle());
    let white = WhiteSpec::Value(1.0);
    let measure = model.file().capture.is_some();
    bencher.bench(|| {
        let wanted = model.needed();
        analysis::analyze_subset(
            model.extractor(),
            divan::black_box(&image),
            &locate,
            &white,
            wanted,
            measure,
        )
        .expect("features")
    });
}

/// `pix.mean` of a 512² image, without and with the domain check's outline measurement
/// (`dom.outline`: 48 rays of up to 96 samples): the difference is its cost.
#[divan::bench(args = [false, true])]
fn features_with_outline(bencher: Bencher, outline: bool) {
    let config = FeatureConfig::default().with(&DOMAIN);
    let extractor = Extractor::new(config).expect("config");
    let image = decoded();
    let wanted = match outline {
        true => vec![0, extractor.feature_count() - 1],
        false => vec![0],
    };
    bencher.bench(|| {
        let luminance = divan::black_box(image.luminance.view());
        extractor.extract_subset(luminance, &circle(), 1.0, &wanted)
    });
}

/// What `reflectance.features(array, cx=…, cy=…, r=…, white=…)` asks of the core for the
/// 512 × 512 sphere handed over as linear luminance: the array taken over (a copy: Python
/// keeps its own), checked, and its 117 features. `python/bench.py` times the same call from
/// Python; the difference is the binding's cost.
#[divan::bench]
fn features_of_an_array(bencher: Bencher) {
    let luminance = decoded().luminance;
    let extractor = Extractor::new(FeatureConfig::default()).expect("config");
    let locate = Placement::Circle(circle());
    let white = WhiteSpec::Value(1.0);
    bencher.bench(|| {
        let image =
            decode::from_luminance(divan::black_box(&luminance).clone(), &Default::default())
                .expect("valid luminance");
        analysis::analyze(&extractor, &image, &locate, &white).expect("features")
    });
}

#[divan::bench]
fn features_including_decode(bencher: Bencher) {
    let bytes = png_bytes();
    let extractor = Extractor::new(FeatureConfig::default()).expect("config");
    let c = circle();
    bencher.bench(|| {
        let image =
            decode::decode(divan::black_box(&bytes), &DecodeOptions::default()).expect("decode");
        extractor.extract(image.luminance.view(), &c, 1.0)
    });
}

#[divan::bench]
fn stage_unwrap(bencher: Bencher) {
    let image = decoded();
    let extractor = Extractor::new(FeatureConfig::default()).expect("config");
    let c = circle();
    bencher.bench(|| extractor.unwrap(divan::black_box(image.luminance.view()), &c, 1.0));
}

/// [`stage_unwrap`] after reduction to the shipped models' working radius (the sphere's
/// radius 233 to 116): the difference is the reduction's cost.
#[divan::bench]
fn stage_reduce_and_unwrap(bencher: Bencher) {
    let image = decoded();
    let config = FeatureConfig {
        working_radius: Some(116.363_636_363_636_36),
        ..FeatureConfig::default()
    };
    let extractor = Extractor::new(config).expect("config");
    let c = circle();
    bencher.bench(|| extractor.unwrap(divan::black_box(image.luminance.view()), &c, 1.0));
}

/// The lighting check's fit of the shading and its highlight, on the sphere as a request
/// fits it: at the shipped models' working radius (every other pixel of the 512² sphere,
/// radius 116), and as given (radius 233, four times the pixels).
#[divan::bench(args = [116, 233])]
fn stage_lighting_fit(bencher: Bencher, radius: usize) {
    let image = decoded();
    let c = circle();
    let (sphere, c) = match radius {
        116 => (
            image.luminance.slice(ndarray::s![..;2, ..;2]).to_owned(),
            Circle {
                cx: c.cx / 2.0,
                cy: c.cy / 2.0,
                r: c.r / 2.0,
            },
        ),
        _ => (image.luminance.clone(), c),
    };
    bencher.bench(|| lighting::shading(divan::black_box(sphere.view()), &c));
}

fn unwrapped() -> Array2<f64> {
    let extractor = Extractor::new(FeatureConfig::default()).expect("config");
    extractor.unwrap(decoded().luminance.view(), &circle(), 1.0)
}

#[divan::bench]
fn stage_pyramid(bencher: Bencher) {
    let u = unwrapped();
    bencher.bench(|| pyramid::build(divan::black_box(u.view()), 4, Edge::Periodic));
}

#[divan::bench]
fn stage_band_powers(bencher: Bencher) {
    let u = unwrapped();
    let plan = SpectrumPlan::new(96, 448);
    bencher.bench(|| plan.band_powers(divan::black_box(u.view())));
}

#[divan::bench]
fn stage_statistics(bencher: Bencher) {
    let extractor = Extractor::new(FeatureConfig::default()).expect("config");
    let stages = extractor.stages_of_unwrapped(unwrapped());
    bencher.bench(|| extractor.features_of(divan::black_box(&stages)));
}

/// The centre features' cost (the Ward-parameter estimators read them): the 117 features at
/// the shipped working radius, without and with `ctr.*`.
#[divan::bench(args = [false, true])]
fn features_with_centre(bencher: Bencher, centre: bool) {
    let families = match centre {
        true => Families::NONE.with(&CENTRE),
        false => Families::NONE,
    };
    let config = FeatureConfig::extended(families, Preprocessing::at_radius(116.36));
    bench_extraction(bencher, config);
}
