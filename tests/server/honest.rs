//! Honest answers from the shipped `ward6` through the real router: the label is the most
//! probable class, every answer carries a prediction set and a domain verdict, and each
//! kind of input the model does not know is flagged (docs/design.md §3 "Prediction sets",
//! "Domain", "Without white"). The spheres are rendered here under a probe the shipped
//! models never saw (`ict_grace`, not CC0) and captured through the camera model.

use crate::common;

use base64::Engine;
use common::server::{
    Part, TestServer, config, copy_dir, post_json, post_multipart, send, start, temp_dir,
};
use ndarray::Array2;
use reflectance_core::classify::domain::CheckKind;
use reflectance_core::locate::Circle;
use reflectance_core::model::registry::Registry;
use reflectance_core::util::rng::Rng;
use reflectance_render::capture::{self, CaptureSettings, Quantization};
use reflectance_render::envmap::EnvMap;
use reflectance_render::ward::Ward;
use reflectance_render::{self as renderer, Lighting, Quality, View};
use serde_json::{Value, json};
use std::path::Path;

/// A photograph-like capture of a rendered sphere: PNG bytes, its circle and white.
struct Shot {
    png: Vec<u8>,
    circle: Circle,
    white: f64,
}

/// `class` of ward6 rendered under `map` and captured at r = `radius` px as an 8-bit sRGB
/// PNG on a mid-grey background, reported exactly.
fn shot(map: &EnvMap, class: &str, radius: f64) -> Shot {
    let classes = [
        ("black_matte", 0.1, 0.0, 0.0),
        ("black_shiny", 0.1, 0.1, 0.01),
        ("chrome", 0.0, 0.75, 0.0),
        ("gray_shiny", 0.25, 0.05, 0.01),
        ("white_matte", 0.9, 0.0, 0.0),
        ("white_shiny", 0.7, 0.25, 0.01),
    ];
    let &(_, rho_d, rho_s, alpha) = classes.iter().find(|c| c.0 == class).unwrap();
    let material = Ward {
        rho_d,
        rho_s,
        alpha,
    };
    let lighting = Lighting::new(map.clone());
    let view = View::default();
    let size = 200;
    let mut rng = Rng::new(5);
    let rendering = renderer::render(
        &lighting,
        &material,
        size,
        &view,
        &Quality::default(),
        &mut rng,
    );
    let luminance = Array2::from_shape_fn((size, size), |(y, x)| {
        f64::from(rendering.luminance[y * size + x])
    });
    let settings = CaptureSettings {
        quantization: Quantization::Srgb8,
        background: 0.5,
        ..CaptureSettings::ideal(radius)
    };
    let white = lighting.white(&view);
    let taken = capture::capture(
        luminance.view(),
        &rendering.circle,
        white,
        &settings,
        &mut rng,
    )
    .unwrap();
    Shot {
        png: taken.bytes,
        circle: taken.circle,
        white: taken.white,
    }
}

fn probe(name: &str) -> EnvMap {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/probes")
        .join(name);
    EnvMap::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A server on a private copy of the shipped registry (`name` keeps tests that run in
/// parallel out of each other's folders).
fn shipped(name: &str) -> TestServer {
    let models = temp_dir(name).join("models");
    copy_dir(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("models"),
        &models,
    );
    start(config(&models))
}

/// Every model shipped under `models/` is served and classifies the README's sphere
/// with a set and a domain verdict (a model other than the default that fails to load is
/// only logged, so nothing else would notice).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_shipped_model_is_served_and_classifies() {
    let server = shipped("honest-every");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut names: Vec<String> = std::fs::read_dir(root.join("models"))
        .unwrap()
        .map(|entry| entry.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["ward11", "ward6"]);
    let png = std::fs::read(root.join("tests/fixtures/features/sphere_rgb8.png")).unwrap();
    let circle = Circle {
        cx: 96.5,
        cy: 94.25,
        r: 85.0,
    };
    for name in &names {
        assert!(server.state.models.is_served(name), "{name} is not served");
        let path = format!("/v1/models/{name}/classify");
        let doc = classify_at(&server, &path, &png, &circle, Some(0.8), &[]).await;
        assert_eq!(doc["model"]["name"], name.as_str());
        // A metal under both class sets (ward6's chrome, ward11's D or K), in domain, and in
        // its own prediction set.
        let ward = &doc["class"]["ward"];
        assert_eq!(
            (ward["rho_d"].as_f64(), ward["rho_s"].as_f64()),
            (Some(0.0), Some(0.75)),
            "{name}: {doc}"
        );
        assert!(in_domain(&doc), "{name}: {}", doc["domain"]);
        let label = doc["label"].as_str().unwrap().to_string();
        assert!(set(&doc).contains(&label), "{name}: {doc}");
    }
}

/// Classify with the given circle, white (`None`: none) and extra fields.
async fn classify(
    server: &TestServer,
    image: &[u8],
    circle: &Circle,
    white: Option<f64>,
    extra: &[(&str, &str)],
) -> Value {
    classify_at(server, "/v1/classify", image, circle, white, extra).await
}

/// [`classify`] at a given classification path.
async fn classify_at(
    server: &TestServer,
    path: &str,
    image: &[u8],
    circle: &Circle,
    white: Option<f64>,
    extra: &[(&str, &str)],
) -> Value {
    let texts = [circle.cx, circle.cy, circle.r].map(|v| v.to_string());
    let white = white.map(|w| w.to_string());
    let mut fields = vec![
        ("image", Part::File(image)),
        ("cx", Part::Text(&texts[0])),
        ("cy", Part::Text(&texts[1])),
        ("r", Part::Text(&texts[2])),
    ];
    if let Some(w) = &white {
        fields.push(("white", Part::Text(w)));
    }
    fields.extend(extra.iter().map(|&(k, v)| (k, Part::Text(v))));
    let answer = send(&server.data, post_multipart(path, &fields)).await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let doc = answer.json();
    assert_label_rule(&doc);
    doc
}

/// One rule: the label is the most probable class, the first of the probabilities and of
/// the prediction set.
fn assert_label_rule(doc: &Value) {
    let probabilities = doc["probabilities"].as_array().unwrap();
    let label = doc["label"].as_str().unwrap();
    assert_eq!(probabilities[0]["label"], label, "{doc}");
    let p: Vec<f64> = probabilities
        .iter()
        .map(|p| p["p"].as_f64().unwrap())
        .collect();
    assert!(p.windows(2).all(|w| w[0] >= w[1]), "{doc}");
    assert_eq!(doc["prediction_set"]["labels"][0], label, "{doc}");
    assert_eq!(doc["class"]["name"], label);
}

fn in_domain(doc: &Value) -> bool {
    doc["domain"]["in_domain"].as_bool().unwrap()
}

fn set(doc: &Value) -> Vec<String> {
    doc["prediction_set"]["labels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap().to_string())
        .collect()
}

/// The check named `kind` failed (`typicality`, `outline`, `brightness`), by its p-value or
/// its bound.
fn failed(doc: &Value, kind: &str) -> bool {
    let check = doc["domain"]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["check"] == kind);
    check.is_some_and(|c| {
        let value = c["value"].as_f64().unwrap();
        c["p_value"].as_f64().is_some_and(|p| p < 0.01)
            || c["limit"].as_f64().is_some_and(|l| value > l)
    })
}

/// The capture moved onto a canvas with `margin` px of background on every side.
fn padded(png: &[u8], margin: u32) -> Vec<u8> {
    let image = image::load_from_memory(png).unwrap().to_luma8();
    let (w, h) = image.dimensions();
    let background = image.get_pixel(0, 0).0[0];
    let canvas = image::GrayImage::from_fn(w + 2 * margin, h + 2 * margin, |x, y| {
        let inside = (margin..margin + w).contains(&x) && (margin..margin + h).contains(&y);
        match inside {
            true => *image.get_pixel(x - margin, y - margin),
            false => image::Luma([background]),
        }
    });
    let mut out = Vec::new();
    canvas
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn spheres_under_unseen_light_get_sets_and_are_in_domain() {
    let server = shipped("honest-unseen");
    let grace = probe("ict_grace.hdr");
    for class in [
        "black_matte",
        "chrome",
        "gray_shiny",
        "white_matte",
        "white_shiny",
    ] {
        let s = shot(&grace, class, 110.0);
        let doc = classify(&server, &s.png, &s.circle, Some(s.white), &[]).await;
        assert!(in_domain(&doc), "{class}: {}", doc["domain"]);
        assert!(set(&doc).contains(&class.to_string()), "{class}: {doc}");
        // A higher coverage never gives a smaller set; a lower one never a larger.
        let wide = classify(
            &server,
            &s.png,
            &s.circle,
            Some(s.white),
            &[("coverage", "0.999")],
        )
        .await;
        let narrow = classify(
            &server,
            &s.png,
            &s.circle,
            Some(s.white),
            &[("coverage", "0.5")],
        )
        .await;
        assert_eq!(wide["prediction_set"]["coverage"], 0.999);
        assert!(set(&wide).len() >= set(&doc).len() && set(&narrow).len() <= set(&doc).len());
        if class.ends_with("matte") {
            // Without white the exposure hides black from white: both matte classes.
            let doc = classify(&server, &s.png, &s.circle, None, &[]).await;
            let labels = set(&doc);
            assert!(
                labels.contains(&"black_matte".into()) && labels.contains(&"white_matte".into()),
                "{class} without white: {labels:?}"
            );
            assert!(
                doc["warnings"]
                    .to_string()
                    .contains("without a white reference")
            );
        }
    }
    // The coverage is checked like any field.
    let s = shot(&grace, "chrome", 110.0);
    let texts = [s.circle.cx, s.circle.cy, s.circle.r, s.white].map(|v| v.to_string());
    for bad in ["1", "0.2", "lots"] {
        let fields = [
            ("image", Part::File(&s.png)),
            ("cx", Part::Text(&texts[0])),
            ("cy", Part::Text(&texts[1])),
            ("r", Part::Text(&texts[2])),
            ("white", Part::Text(&texts[3])),
            ("coverage", Part::Text(bad)),
        ];
        let answer = send(&server.data, post_multipart("/v1/classify", &fields)).await;
        answer.problem(422, "invalid-field");
    }
}

#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_kind_of_input_the_model_does_not_know_is_flagged() {
    let server = shipped("honest-ood");
    let grace = probe("ict_grace.hdr");
    let flagged = |doc: &Value, what: &str| {
        assert!(!in_domain(doc), "{what}: {}", doc["domain"]);
        let reasons = doc["domain"]["reasons"].as_array().unwrap();
        assert!(!reasons.is_empty(), "{what}: no reason");
        assert!(
            doc["warnings"][0]
                .as_str()
                .unwrap()
                .starts_with("out of domain"),
            "{what}: {}",
            doc["warnings"]
        );
    };
    // Not a sphere: coloured rectangles, with a plausible circle and white.
    let mut rng = Rng::new(3);
    let mut pattern = image::RgbImage::new(300, 300);
    for _ in 0..10 {
        let [x0, y0] = [rng.below(220) as u32, rng.below(220) as u32];
        let colour = [
            rng.below(256) as u8,
            rng.below(256) as u8,
            rng.below(256) as u8,
        ];
        for y in y0..(y0 + 80).min(300) {
            for x in x0..(x0 + 80).min(300) {
                pattern.put_pixel(x, y, image::Rgb(colour));
            }
        }
    }
    let mut png = Vec::new();
    pattern
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let centred = Circle {
        cx: 149.5,
        cy: 149.5,
        r: 120.0,
    };
    let doc = classify(&server, &png, &centred, Some(0.8), &[]).await;
    flagged(&doc, "rectangles");
    assert!(failed(&doc, "outline"), "{}", doc["domain"]);

    // A circle that misses the sphere: moved by 0.6 r, 1.5 times too large, 0.6 times too
    // small.
    let s = shot(&grace, "white_shiny", 110.0);
    let margin = 120;
    let png = padded(&s.png, margin);
    let c = Circle {
        cx: s.circle.cx + f64::from(margin),
        cy: s.circle.cy + f64::from(margin),
        r: s.circle.r,
    };
    let right = classify(&server, &png, &c, Some(s.white), &[]).await;
    assert!(in_domain(&right), "padded: {}", right["domain"]);
    for (what, wrong) in [
        (
            "moved",
            Circle {
                cx: c.cx + 0.6 * c.r,
                ..c
            },
        ),
        ("too large", Circle { r: 1.5 * c.r, ..c }),
        ("too small", Circle { r: 0.6 * c.r, ..c }),
    ] {
        let doc = classify(&server, &png, &wrong, Some(s.white), &[]).await;
        flagged(&doc, what);
        assert!(failed(&doc, "outline"), "{what}: {}", doc["domain"]);
    }

    // A white reference 20 times too small: the sphere brighter than any reflectance.
    let s = shot(&grace, "white_matte", 110.0);
    let doc = classify(&server, &s.png, &s.circle, Some(s.white / 20.0), &[]).await;
    flagged(&doc, "white / 20");
    assert!(failed(&doc, "brightness"), "{}", doc["domain"]);

    // One small light in the dark: a chrome sphere shows a black disc with one highlight.
    let lamp = EnvMap::from_fn(256, 128, |d| {
        let toward = (0.3 * d.x + 0.5 * d.y + 0.81 * d.z) / (0.3f64.hypot(0.5).hypot(0.81));
        if toward > 0.999 { 2000.0 } else { 0.01 }
    });
    let s = shot(&lamp, "chrome", 110.0);
    let doc = classify(&server, &s.png, &s.circle, Some(s.white), &[]).await;
    flagged(&doc, "one lamp in the dark");
    assert!(failed(&doc, "typicality"), "{}", doc["domain"]);

    // A capture outside the envelope of every class: a sphere of 45 px (trained: 60–400).
    let s = shot(&grace, "gray_shiny", 45.0);
    let doc = classify(&server, &s.png, &s.circle, Some(s.white), &[]).await;
    flagged(&doc, "r = 45 px");
    assert!(
        doc["domain"]["reasons"]
            .to_string()
            .contains("radius 45 px"),
        "{}",
        doc["domain"]
    );
}

/// The README's sphere (tests/fixtures/features/sphere_rgb8.png) and its circle.
fn readme_sphere() -> (Vec<u8>, Circle) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let png = std::fs::read(root.join("tests/fixtures/features/sphere_rgb8.png")).unwrap();
    let circle = Circle {
        cx: 96.5,
        cy: 94.25,
        r: 85.0,
    };
    (png, circle)
}

/// Grey noise the size of the README's sphere, 8-bit sRGB values 96–159: nothing like a
/// sphere, yet its noise and exposure are within the capture envelope, so only the domain
/// check (outline and typicality) can flag it.
fn noise_png() -> Vec<u8> {
    let mut rng = Rng::new(3);
    let noise = image::GrayImage::from_fn(196, 191, |_, _| image::Luma([96 + rng.below(64) as u8]));
    let mut png = Vec::new();
    noise
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// A server on a copy of the shipped registry whose `ward6` was changed by `change` (and
/// published again as version 1).
fn shipped_with(
    name: &str,
    change: impl FnOnce(&mut reflectance_core::model::ModelFile),
) -> TestServer {
    let models = temp_dir(name).join("models");
    copy_dir(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("models"),
        &models,
    );
    let registry = Registry::new(&models);
    let mut model = registry.load("ward6", 1).unwrap();
    change(&mut model);
    std::fs::remove_dir_all(models.join("ward6")).unwrap();
    registry.publish(&mut model, &[]).unwrap();
    start(config(&models))
}

/// RAPS as docs/design.md §3 states it, written out here: ranked by probability, a class's
/// score is the mass ranked above it plus λ per rank beyond `k_reg`; the set holds the
/// classes scoring at most the ⌈(n + 1)·c⌉-th smallest calibration score.
fn expected_set(
    doc: &Value,
    sets: &reflectance_core::classify::conformal::PredictionSets,
    coverage: f64,
) -> Vec<String> {
    let n = sets.n;
    let rank = ((n as f64 + 1.0) * coverage).ceil() as usize;
    let zeros = n - sets.positive.len();
    let threshold = if rank <= zeros {
        0.0
    } else {
        sets.positive[rank - zeros - 1]
    };
    let mut above = 0.0;
    let mut out = Vec::new();
    for (i, p) in doc["probabilities"].as_array().unwrap().iter().enumerate() {
        let score = above + sets.lambda * (i + 1).saturating_sub(sets.k_reg) as f64;
        if score > threshold {
            break;
        }
        out.push(p["label"].as_str().unwrap().to_string());
        above += p["p"].as_f64().unwrap();
    }
    out
}

/// Calibrated sets of more than the top label, with a white reference given (so no
/// brightness expansion is involved): the shipped ward11 cannot tell K from J on the
/// README's sphere at 95 % (K's probability 0.825 leaves J's score 0.835 below the 95 %
/// threshold 0.838) and is sure of K at 50 %; a ward6 whose calibration puts the 95 %
/// threshold at 0.9 names chrome and gray_shiny (0.803 + 0.01 ≤ 0.9 < 0.988 + 0.02).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calibrated_sets_name_every_class_the_model_cannot_rule_out() {
    let (png, circle) = readme_sphere();
    let server = shipped("honest-sets");
    let registry = Registry::new(Path::new(env!("CARGO_MANIFEST_DIR")).join("models"));
    let ward11 = registry.load("ward11", 1).unwrap();
    let sets = ward11.prediction_sets.as_ref().unwrap();
    let path = "/v1/models/ward11/classify";
    for (coverage, labels) in [
        ("0.5", vec!["K"]),
        ("0.95", vec!["K", "J"]),
        ("0.99", vec!["K", "J", "I", "A"]),
    ] {
        let doc = classify_at(
            &server,
            path,
            &png,
            &circle,
            Some(0.8),
            &[("coverage", coverage)],
        )
        .await;
        assert_eq!(set(&doc), labels, "ward11 at {coverage}: {doc}");
        assert_eq!(
            set(&doc),
            expected_set(&doc, sets, coverage.parse().unwrap()),
            "{doc}"
        );
        assert!(in_domain(&doc), "{}", doc["domain"]);
        assert_estimate_holds(&doc, &ward11, &labels);
    }
    // V2 names the same set.
    let b64 = base64::engine::general_purpose::STANDARD.encode(&png);
    let number =
        |name: &str, v: f64| json!({"name": name, "datatype": "FP64", "shape": [1], "data": [v]});
    let request = json!({"inputs": [
        {"name": "image", "datatype": "BYTES", "shape": [1], "data": [b64]},
        number("white", 0.8), number("cx", circle.cx), number("cy", circle.cy), number("r", circle.r),
    ]});
    let doc = send(&server.data, post_json("/v2/models/ward11/infer", &request))
        .await
        .json();
    assert_eq!(
        v2_output(&doc, "prediction_set")["data"],
        json!(["K", "J"]),
        "{doc}"
    );

    // A calibration of 20 scores, 15 of them 0, four 0.3 and one 0.9: the 50 % threshold is
    // the 11th smallest, 0; the 95 % one the ⌈21 · 0.95⌉ = 20th, 0.9 (the 19th, 0.3, would
    // leave gray_shiny out).
    let forced = shipped_with("honest-sets-forced", |model| {
        let sets = model.prediction_sets.as_mut().unwrap();
        sets.n = 20;
        sets.positive = vec![0.3, 0.3, 0.3, 0.3, 0.9];
    });
    for (coverage, labels) in [
        ("0.5", vec!["chrome"]),
        ("0.95", vec!["chrome", "gray_shiny"]),
    ] {
        let doc = classify(&forced, &png, &circle, Some(0.8), &[("coverage", coverage)]).await;
        assert_eq!(set(&doc), labels, "forced ward6 at {coverage}: {doc}");
    }
}

/// The Ward estimate's intervals hold the parameters of every class of the set (docs/design.md:
/// the estimate never contradicts the classes the answer names); at 95 % on the README's
/// sphere that widens ρs to K's 0.75, far above the regression's own estimate.
fn assert_estimate_holds(doc: &Value, model: &reflectance_core::model::ModelFile, labels: &[&str]) {
    for label in labels {
        let class = model.classes.iter().find(|c| c.name == *label).unwrap();
        let ward = class.ward.as_ref().unwrap();
        for (name, value) in [
            ("rho_d", ward.rho_d),
            ("rho_s", ward.rho_s),
            ("alpha", ward.alpha),
        ] {
            let interval = &doc["ward"][name];
            let (low, high) = (
                interval["low"].as_f64().unwrap(),
                interval["high"].as_f64().unwrap(),
            );
            assert!(
                low <= value + 1e-12 && value <= high + 1e-12,
                "{label}'s {name} {value} outside the estimate's [{low}, {high}]: {}",
                doc["ward"]
            );
        }
    }
}

/// The output of a V2 answer named `name`.
fn v2_output<'a>(doc: &'a Value, name: &str) -> &'a Value {
    doc["outputs"]
        .as_array()
        .unwrap_or_else(|| panic!("{doc}"))
        .iter()
        .find(|o| o["name"] == name)
        .unwrap_or_else(|| panic!("no {name}: {doc}"))
}

/// A picture of nothing is out of domain on /v1 and V2 for both shipped models, for the
/// reasons the domain check gives and no other (the capture envelope holds it).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_picture_of_nothing_is_out_of_domain_on_v1_and_v2() {
    let server = shipped("honest-nothing");
    let (_, circle) = readme_sphere();
    let png = noise_png();
    let b64 = base64::engine::general_purpose::STANDARD.encode(&png);
    for name in ["ward6", "ward11"] {
        let path = format!("/v1/models/{name}/classify");
        let doc = classify_at(&server, &path, &png, &circle, Some(0.8), &[]).await;
        assert_eq!(
            doc["domain"]["in_domain"], false,
            "{name}: {}",
            doc["domain"]
        );
        assert_eq!(
            doc["domain"]["reasons"],
            json!([CheckKind::Outline.reason(), CheckKind::Typicality.reason()]),
            "{name}"
        );
        assert!(
            failed(&doc, "outline") && failed(&doc, "typicality"),
            "{}",
            doc["domain"]
        );
        assert!(
            doc["warnings"][0]
                .as_str()
                .unwrap()
                .starts_with("out of domain")
        );
        let number = |name: &str, v: f64| json!({"name": name, "datatype": "FP64", "shape": [1], "data": [v]});
        let request = json!({"inputs": [
            {"name": "image", "datatype": "BYTES", "shape": [1], "data": [b64]},
            number("white", 0.8), number("cx", circle.cx), number("cy", circle.cy), number("r", circle.r),
        ]});
        let answer = send(
            &server.data,
            post_json(&format!("/v2/models/{name}/infer"), &request),
        )
        .await;
        assert_eq!(
            answer.status,
            200,
            "{}",
            String::from_utf8_lossy(&answer.body)
        );
        let doc = answer.json();
        assert_eq!(
            v2_output(&doc, "in_domain")["data"],
            json!([false]),
            "{name}: {doc}"
        );
    }
    // The README's sphere itself is in domain on both.
    let (sphere, _) = readme_sphere();
    let doc = classify(&server, &sphere, &circle, Some(0.8), &[]).await;
    assert_eq!(doc["domain"]["in_domain"], true, "{}", doc["domain"]);
}

/// A white reference 20 times too small breaks the brightness bound (log10 of the centre
/// over white 0.94 > 0.59). With the shipped ward6 the typicality check flags it too (its
/// classifier reads the brightness); a ward6 whose statistical checks never flag (threshold
/// raised to 1e300) shows the bound alone makes the answer out of domain, with exactly its
/// reason.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_white_twenty_times_too_small_breaks_the_brightness_bound_alone() {
    let (png, circle) = readme_sphere();
    let server = shipped("honest-bright");
    let doc = classify(&server, &png, &circle, Some(0.8 / 20.0), &[]).await;
    assert_eq!(doc["domain"]["in_domain"], false, "{}", doc["domain"]);
    assert!(failed(&doc, "brightness"), "{}", doc["domain"]);
    let bound_only = shipped_with("honest-bright-bound", |model| {
        model.domain.as_mut().unwrap().threshold = 1e300;
    });
    let doc = classify(&bound_only, &png, &circle, Some(0.8 / 20.0), &[]).await;
    assert_eq!(doc["domain"]["in_domain"], false, "{}", doc["domain"]);
    assert_eq!(
        doc["domain"]["reasons"],
        json!([CheckKind::Brightness.reason()]),
        "{}",
        doc["domain"]
    );
    assert!(
        failed(&doc, "brightness") && !failed(&doc, "outline"),
        "{}",
        doc["domain"]
    );
    // The right white: in domain.
    let doc = classify(&bound_only, &png, &circle, Some(0.8), &[]).await;
    assert_eq!(doc["domain"]["in_domain"], true, "{}", doc["domain"]);
}
