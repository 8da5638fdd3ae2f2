//! Phone photographs (issues 46 and 63): colour JPEGs (quality 90, 4:2:0) of 4 and 12 MP with
//! a small and a large shaded ball, and of 48 MP with a small one, on a wood-grain table,
//! single thread: libjpeg-turbo's `djpeg` decoding the file in full (the floor every request
//! pays, measured in the same run), the photograph decoded whole and for location, and a
//! classification by the shipped ward6 model located automatically and given the circle,
//! through `inference::classify` (what `POST /v1/classify` runs on its CPU pool). The dev
//! photograph `chrome_arhangoyal_grainger125_full.jpg` (4096 × 3072) is measured too when
//! `../shared/data/photos/dev/` holds it.
//!
//! `taskset -c 0 cargo bench --bench phone` (docs/performance.md, "Phone photographs").

use bytes::Bytes;
use divan::Bencher;
use reflectance_core::analysis::{LOCATING_SIDE, Placement, WhiteSpec};
use reflectance_core::decode::{self, DecodeOptions};
use reflectance_core::inference::{self, Answer, Input, LoadedModel};
use reflectance_core::locate::Circle;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex, OnceLock};

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

/// The shipped ward6 model (its latest version).
fn model() -> Arc<LoadedModel> {
    static MODEL: OnceLock<Arc<LoadedModel>> = OnceLock::new();
    MODEL
        .get_or_init(|| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ward6");
            let file = reflectance_core::model::registry::load_path(&path).expect("models/ward6");
            Arc::new(LoadedModel::new(file).expect("its extractor"))
        })
        .clone()
}

/// A request's CPU work: decode what it needs, locate, white, features, classify.
fn classify(bytes: &Bytes, locate: Placement<Bytes, Bytes>) -> inference::Classified {
    let input = Input::new(
        bytes.clone(),
        WhiteSpec::Value(1.0),
        locate,
        None,
        Answer::default(),
    )
    .expect("input");
    inference::classify(model(), input, decode::Limits::default()).expect("classified")
}

/// The file on disk for `djpeg` (written once per photograph).
fn file_of(name: &str, bytes: &[u8]) -> PathBuf {
    let path = std::env::temp_dir().join(format!("reflectance-bench-{name}.jpg"));
    if !path.exists() {
        std::fs::write(&path, bytes).expect("write the bench's JPEG");
    }
    path
}

/// libjpeg-turbo's `djpeg` decoding the file in full, when it is installed
/// (`libjpeg-turbo-progs`): the floor the targets are set against.
fn djpeg(bencher: Bencher, path: &Path) {
    let run = || {
        Command::new("djpeg")
            .args(["-outfile", "/dev/null"])
            .arg(path)
            .stdout(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if !run() {
        eprintln!("djpeg is not installed: no baseline");
        return;
    }
    bencher.bench(run);
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn djpeg_full(bencher: Bencher, photo: &Photo) {
    djpeg(
        bencher,
        &file_of(&photo.to_string().replace(' ', "_"), &jpeg(photo)),
    );
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn decode_full(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let options = DecodeOptions::default();
    bencher.bench(|| {
        let photo = decode::Photo::open(divan::black_box(&bytes), &options).expect("open");
        photo.whole(1).map(|copy| copy.image.width())
    });
}

/// The located copy: the largest DCT-domain reduction that keeps [`LOCATING_SIDE`].
#[divan::bench(args = PHOTOS, sample_count = 10)]
fn decode_for_location(bencher: Bencher, photo: &Photo) {
    let bytes = jpeg(photo);
    let options = DecodeOptions::default();
    let d = decode::denominator_for(photo.width, photo.height, LOCATING_SIDE);
    bencher.bench(|| {
        let photo = decode::Photo::open(divan::black_box(&bytes), &options).expect("open");
        photo.whole(d).map(|copy| copy.image.width())
    });
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn located(bencher: Bencher, photo: &Photo) {
    let bytes = Bytes::from(jpeg(photo));
    let found = classify(&bytes, Placement::Auto).analysis.geometry.circle();
    let truth = photo.circle();
    assert!(
        (found.cx - truth.cx).hypot(found.cy - truth.cy) < 0.04 * truth.r,
        "{photo}: found {found:?}"
    );
    bencher.bench(|| classify(divan::black_box(&bytes), Placement::Auto));
}

#[divan::bench(args = PHOTOS, sample_count = 10)]
fn circle_given(bencher: Bencher, photo: &Photo) {
    let bytes = Bytes::from(jpeg(photo));
    let circle = photo.circle();
    bencher.bench(|| classify(divan::black_box(&bytes), Placement::Circle(circle)));
}

/// The dev photograph, when present: 4096 × 3072, a ball of radius 201 px.
fn dev_photo() -> Option<(PathBuf, Bytes)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/photos/dev/chrome_arhangoyal_grainger125_full.jpg");
    let bytes = std::fs::read(&path).ok()?;
    Some((path, Bytes::from(bytes)))
}

#[divan::bench(sample_count = 10)]
fn dev_photo_djpeg_full(bencher: Bencher) {
    let Some((path, _)) = dev_photo() else { return };
    djpeg(bencher, &path);
}

#[divan::bench(sample_count = 10)]
fn dev_photo_located(bencher: Bencher) {
    let Some((_, bytes)) = dev_photo() else {
        return;
    };
    bencher.bench(|| {
        let input = Input::new(
            bytes.clone(),
            WhiteSpec::Value(1.0),
            Placement::Auto,
            None,
            Answer::default(),
        )
        .expect("input");
        inference::classify(model(), input, decode::Limits::default()).ok()
    });
}

#[divan::bench(sample_count = 10)]
fn dev_photo_circle_given(bencher: Bencher) {
    let Some((_, bytes)) = dev_photo() else {
        return;
    };
    let circle = Circle {
        cx: 2348.6,
        cy: 2252.6,
        r: 201.4,
    };
    bencher.bench(|| classify(divan::black_box(&bytes), Placement::Circle(circle)));
}
