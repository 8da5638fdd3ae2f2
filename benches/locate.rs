//! Finding the sphere in a phone-sized photograph, single thread: a 4000 × 3000 (12 MP)
//! JPEG of a shaded ball (r = 400 px) on a wood-grain table with a box beside it.
//! Target (issue 28): ≤ 300 ms to locate a 12 MP JPEG, decode included.

use divan::Bencher;
use ndarray::Array2;
use reflectance_core::decode::{self, DecodeOptions};
use reflectance_core::locate;

fn main() {
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    divan::main();
}

const WIDTH: usize = 4000;
const HEIGHT: usize = 3000;

/// The picture's sRGB codes: grain, a box, and a ball lit from the top left.
fn codes() -> Vec<u8> {
    let (cx, cy, r) = (2300.0, 1400.0, 400.0);
    (0..WIDTH * HEIGHT)
        .map(|i| {
            let (x, y) = ((i % WIDTH) as f64, (i / WIDTH) as f64);
            let (dx, dy) = ((x - cx) / r, (y - cy) / r);
            let d2 = dx * dx + dy * dy;
            let value = if d2 <= 1.0 {
                0.1 + 0.7 * (0.5 * (-dx - dy) + 0.7 * (1.0 - d2).sqrt()).max(0.0)
            } else if (600.0..1400.0).contains(&x) && (900.0..1500.0).contains(&y) {
                0.8
            } else {
                0.35 + 0.08 * (0.012 * x + 3.0 * (0.002 * y).sin()).sin()
            };
            let grain = ((i * 2_654_435_761) % 13) as f64 / 400.0;
            ((value + grain).clamp(0.0, 1.0) * 255.0) as u8
        })
        .collect()
}

fn jpeg_bytes() -> Vec<u8> {
    let mut out = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90),
        &codes(),
        WIDTH as u32,
        HEIGHT as u32,
        image::ExtendedColorType::L8,
    )
    .expect("encode jpeg");
    out
}

#[divan::bench(sample_count = 10)]
fn locate_12mp_jpeg(bencher: Bencher) {
    let bytes = jpeg_bytes();
    bencher.bench(|| {
        let image =
            decode::decode(divan::black_box(&bytes), &DecodeOptions::default()).expect("decode");
        locate::detect(image.luminance.view()).expect("the ball")
    });
}

#[divan::bench(sample_count = 10)]
fn detect_12mp_excluding_decode(bencher: Bencher) {
    let image = decode::decode(&jpeg_bytes(), &DecodeOptions::default()).expect("decode");
    let luminance: Array2<f64> = image.luminance;
    bencher.bench(|| locate::detect(divan::black_box(luminance.view())).expect("the ball"));
}

/// Dev photographs (when `../shared/data/photos/dev/` holds them), decoded once: location
/// alone, whatever it finds or refuses.
#[divan::bench(sample_count = 10, args = ["chrome_boeyli_0200.jpg", "chrome_arhangoyal_grainger125_full.jpg", "other_husky_tennis0.jpg"])]
fn detect_dev_photograph_excluding_decode(bencher: Bencher, name: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/photos/dev")
        .join(name);
    let Ok(bytes) = std::fs::read(&path) else {
        return;
    };
    let image = decode::decode(&bytes, &DecodeOptions::default()).expect("decode");
    let luminance: Array2<f64> = image.luminance;
    bencher.bench(|| locate::detect(divan::black_box(luminance.view())).is_ok());
}

/// The copy a request would locate on with a located side of about 1200 px (issue 63): the
/// photograph decoded at ½ in libjpeg-turbo's DCT domain (2000 × 1500 here).
fn half_copy(bytes: &[u8]) -> Array2<f64> {
    let photo = decode::Photo::open(bytes, &DecodeOptions::default()).expect("open");
    let (width, height) = photo.size();
    let d = decode::denominator_for(width, height, 1200);
    let copy = photo.whole(d).expect("the reduced copy");
    copy.image.luminance.clone()
}

/// Detection alone on the ½-scale copy of the 12 MP JPEG (target, issue 63: ≤ ~30 ms).
#[divan::bench(sample_count = 10)]
fn detect_12mp_half_copy_excluding_decode(bencher: Bencher) {
    let luminance = half_copy(&jpeg_bytes());
    bencher.bench(|| locate::detect(divan::black_box(luminance.view())).expect("the ball"));
}

/// Dev photographs on the copy a located side of 1200 px gives (4096 px → ½, 1280 px → 1):
/// detection alone, whatever it finds or refuses.
#[divan::bench(sample_count = 10, args = ["chrome_arhangoyal_grainger125_full.jpg", "chrome_bglogowski_scene_1-4.jpg", "other_husky_tennis0.jpg"])]
fn detect_dev_photograph_half_copy_excluding_decode(bencher: Bencher, name: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/photos/dev")
        .join(name);
    let Ok(bytes) = std::fs::read(&path) else {
        return;
    };
    let luminance = half_copy(&bytes);
    bencher.bench(|| locate::detect(divan::black_box(luminance.view())).is_ok());
}
