//! Phone photographs (issue 46): colour JPEGs (quality 90, 4:2:0) of 4 and 12 MP with a small
//! and a large shaded ball, and of 48 MP with a small one, on a wood-grain table, single
//! thread; decoded in full and for the location's working copy (DCT-domain scaling,
//! [`decode::decode_reduced`]), located automatically and given the circle, through the
//! shipped ward6 model's extraction (decode → white → locate → features: what
//! `POST /v1/classify` does before the classifier, which takes under a millisecond). The dev photograph
//! `chrome_arhangoyal_grainger125_full.jpg` (4096 × 3072) is measured too when
//! `../shared/data/photos/dev/` holds it.
//!
//! `taskset -c 0 cargo bench --bench phone` (one core: `jpeg-decoder` decodes a large
//! image's colour components on threads of its own).

use divan::Bencher;
use reflectance_core::analysis::{self, Placement, WhiteSpec};
use reflectance_core::decode::{self, DecodeOptions};
use reflectance_core::features::Extractor;
use reflectance_core::locate::{self, Circle};
use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

/// The location's working copy is at most this many pixels across (`image::detect`).
const WORK_SIZE: usize = 640;

fn main() {
    assert!(reflectance::tune_heap(), "heap thresholds refused");
    divan::main();
}

/// A synthetic photograph: its size and its ball.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Photo {
    width: usize,
    height: usize,
    /// The ball's radius (px).
    r: usize,
}

impl Photo {
    fn circle(&self) -> Circle {
        Circle {
            cx: 0.58 * self.width as f64,
            cy: 0.47 * self.height as f64,
            r: self.r as f64,
        }
    }
}

impl fmt::Display for Photo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mp = (self.width * self.height) as f64 / 1e6;
        write!(f, "{mp:.0}MP r{}", self.r)
    }
}

const PHOTOS: &[Photo] = &[
    Photo {
        width: 2304,
        height: 1728,
        r: 200,
    },
    Photo {
        width: 2304,
        height: 1728,
        r: 600,
    },
    Photo {
        width: 4000,
        height: 3000,
        r: 200,
    },
    Photo {
        width: 4000,
        height: 3000,
        r: 1000,
    },
    Photo {
        width: 8000,
        height: 6000,
        r: 400,
    },
];

/// The picture's sRGB codes: grain, a box, and a warm ball lit from the top left.
fn encode(photo: &Photo) -> Vec<u8> {
    let Photo { width, height, .. } = *photo;
    let Circle { cx, cy, r } = photo.circle();
    let scale = width as f64 / 4000.0;
    let mut rgb = Vec::with_capacity(3 * width * height);
    for i in 0..width * height {
        let (x, y) = ((i % width) as f64, (i / width) as f64);
        let (dx, dy) = ((x - cx) / r, (y - cy) / r);
        let d2 = dx * dx + dy * dy;
        let (sx, sy) = (x / scale, y / scale);
        let value = if d2 <= 1.0 {
            0.1 + 0.7 * (0.5 * (-dx - dy) + 0.7 * (1.0 - d2).sqrt()).max(0.0)
        } else if (300.0..1100.0).contains(&sx) && (500.0..1100.0).contains(&sy) {
            0.8
        } else {
            0.35 + 0.08 * (0.012 * sx + 3.0 * (0.002 * sy).sin()).sin()
        };
        let grain = ((i * 2_654_435_761) % 13) as f64 / 400.0;
        let v = (value + grain).clamp(0.0, 1.0);
        for tint in [1.0, 0.9, 0.75] {
            rgb.push((v * tint * 255.0) as u8);
        }
    }
    let mut out = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90),
        &rgb,
        width as u32,
        height as u32,
        image::ExtendedColorType::Rgb8,
    )
    .expect("encode jpeg");
    out
}

/// Each photograph's JPEG, encoded once.
fn jpeg(photo: &Photo) -> Vec<u8> {
    static CACHE: OnceLock<Mutex<HashMap<Photo, Vec<u8>>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    let mut cache = cache.lock().expect("cache");
    cache.entry(*photo).or_insert_with(|| encode(photo)).clone()
}

/// The shipped ward6 model's extractor.
fn extractor() -> &'static Extractor {
    static EXTRACTOR: OnceLock<Extractor> = OnceLock::new();
    EXTRACTOR.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ward6/1");
        let file = reflectance_core::model::registry::load_path(&path).expect("models/ward6");
        Extractor::new(file.features.config).expect("its extractor")
    })
}

/// Decode, then white, locate and extract as a request does.
fn classify_front(bytes: &[u8], locate: &Placement) -> analysis::Analysis {
    let image = decode::decode(bytes, &DecodeOptions::default()).expect("decode");
    analysis::analyze(extractor(), &image, locate, &WhiteSpec::Value(1.0)).expect("analysis")
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn decode_full(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    bencher.bench(|| decode::decode(divan::black_box(&bytes), &DecodeOptions::default()));
}

/// The location's working copy: the largest DCT-domain reduction that keeps
/// [`WORK_SIZE`] across.
#[divan::bench(args = PHOTOS, sample_count = 10)]
fn decode_for_location(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let d = decode::denominator_for(photo.width, photo.height, WORK_SIZE);
    bencher
        .bench(|| decode::decode_reduced(divan::black_box(&bytes), &DecodeOptions::default(), d));
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn located(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let found = classify_front(&bytes, &Placement::Auto).geometry.circle();
    let truth = photo.circle();
    assert!(
        (found.cx - truth.cx).hypot(found.cy - truth.cy) < 0.04 * truth.r,
        "{photo}: found {found:?}"
    );
    bencher.bench(|| classify_front(divan::black_box(&bytes), &Placement::Auto));
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn circle_given(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let locate = Placement::Circle(photo.circle());
    bencher.bench(|| classify_front(divan::black_box(&bytes), &locate));
}

/// Detection alone on the reduced copy (its candidates and its sub-pixel fit at the reduced
/// scale): what location would cost if the full image were not needed for the fit.
#[divan::bench(args = PHOTOS, sample_count = 10)]
fn detect_on_reduced_copy(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let d = decode::denominator_for(photo.width, photo.height, WORK_SIZE);
    let reduced = decode::decode_reduced(&bytes, &DecodeOptions::default(), d).expect("decode");
    bencher.bench(|| locate::detect(divan::black_box(reduced.image.luminance.view())).ok());
}

/// The dev photograph, when present: 4096 × 3072, a ball of radius 201 px.
fn dev_photo() -> Option<Vec<u8>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/photos/dev/chrome_arhangoyal_grainger125_full.jpg");
    std::fs::read(path).ok()
}

#[divan::bench(sample_count = 10)]
fn dev_photo_decode_full(bencher: Bencher) {
    let Some(bytes) = dev_photo() else { return };
    bencher.bench(|| decode::decode(divan::black_box(&bytes), &DecodeOptions::default()));
}

#[divan::bench(sample_count = 10)]
fn dev_photo_decode_for_location(bencher: Bencher) {
    let Some(bytes) = dev_photo() else { return };
    let d = decode::denominator_for(4096, 3072, WORK_SIZE);
    bencher
        .bench(|| decode::decode_reduced(divan::black_box(&bytes), &DecodeOptions::default(), d));
}

#[divan::bench(sample_count = 10)]
fn dev_photo_located(bencher: Bencher) {
    let Some(bytes) = dev_photo() else { return };
    // Refused today (issue 46's detection part): located, then not confident enough.
    bencher.bench(|| {
        let image =
            decode::decode(divan::black_box(&bytes), &DecodeOptions::default()).expect("decode");
        analysis::analyze(
            extractor(),
            &image,
            &Placement::Auto,
            &WhiteSpec::Value(1.0),
        )
        .ok()
    });
}

#[divan::bench(sample_count = 10)]
fn dev_photo_circle_given(bencher: Bencher) {
    let Some(bytes) = dev_photo() else { return };
    let locate = Placement::Circle(Circle {
        cx: 2348.6,
        cy: 2252.6,
        r: 201.4,
    });
    bencher.bench(|| classify_front(divan::black_box(&bytes), &locate));
}
