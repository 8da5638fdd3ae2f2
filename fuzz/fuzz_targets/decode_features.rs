//! Image decoding + feature extraction on arbitrary bytes: every input is either refused
//! with a typed error or yields finite, non-negative luminance (decoded in full, and reduced
//! by the scaled JPEG decode) whose analysis (automatic location, and a given circle when the
//! image is large enough) never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reflectance_core::analysis::{self, Placement, WhiteSpec};
use reflectance_core::features::{Extractor, FeatureConfig};
use reflectance_core::decode::{DecodeOptions, Limits, Photo, decode};
use reflectance_core::locate::Circle;
use std::sync::OnceLock;

fn extractor() -> &'static Extractor {
    static EXTRACTOR: OnceLock<Extractor> = OnceLock::new();
    EXTRACTOR.get_or_init(|| Extractor::new(FeatureConfig::default()).expect("default config"))
}

fuzz_target!(|data: &[u8]| {
    // Smaller limits than the server's, so that each execution stays fast.
    let options = DecodeOptions {
        encoding: None,
        limits: Limits {
            max_width: 1024,
            max_height: 1024,
            max_pixels: 1 << 20,
        },
        // The colour copy is decoded too, so that its path is fuzzed with the rest.
        colour: true,
    };
    // The photograph decoded at a reduction the input picks, whole and as a region: an
    // error, or an image of the reduced size with usable luminance.
    let denominator = 1 << (data.len() % 4);
    if let Ok(photo) = Photo::open(data, &options) {
        let (w, h) = photo.size();
        for region in [[0, 0, w, h], [w / 4, h / 3, w / 2 + 1, h / 2 + 1]] {
            if let Ok(copy) = photo.region(region, denominator) {
                let (d, lum) = (copy.denominator, &copy.image.luminance);
                assert!([1, 2, 4, 8].contains(&d) && d <= denominator);
                assert!(lum.nrows() <= h.div_ceil(d) + 1 && lum.ncols() <= w.div_ceil(d) + 4);
                assert!(lum.iter().all(|v| v.is_finite() && *v >= 0.0));
            }
        }
    }
    let Ok(image) = decode(data, &options) else {
        return;
    };
    assert!(image.width() > 0 && image.height() > 0);
    assert!(
        image.luminance.iter().all(|v| v.is_finite() && *v >= 0.0),
        "decoded luminance must be finite and non-negative"
    );
    if let Some(mask) = &image.alpha_mask {
        assert_eq!(mask.dim(), image.luminance.dim());
    }
    let extractor = extractor();
    if let Ok(a) = analysis::analyze(extractor, &image, &Placement::Auto, &WhiteSpec::Missing) {
        assert_eq!(a.values.len(), extractor.config().names().len());
    }
    let (w, h) = (image.width() as f64, image.height() as f64);
    let r = w.min(h) / 2.0 - 1.0;
    if r >= 32.0 {
        let circle = Circle {
            cx: (w - 1.0) / 2.0,
            cy: (h - 1.0) / 2.0,
            r,
        };
        let _ = analysis::analyze(
            extractor,
            &image,
            &Placement::Circle(circle),
            &WhiteSpec::Value(0.5),
        );
    }
});
