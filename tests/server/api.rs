//! The data plane against the real router (in-process): classification of rendered
//! spheres, every error class as problem+json, models, health, metrics, KServe V2.

use crate::common;

use axum::body::Body;
use axum::http::Request;
use base64::Engine;
use common::server::{
    Part, TestServer, config, fixture, get, models_copy, post_json, post_multipart, send, start,
};
use serde_json::{Value, json};

const CX: &str = "47.5";
const R: &str = "43.63636363636363";

fn classify_fields<'a>(image: &'a [u8], white: &'a str) -> Vec<(&'a str, Part<'a>)> {
    vec![
        ("image", Part::File(image)),
        ("white", Part::Text(white)),
        ("cx", Part::Text(CX)),
        ("cy", Part::Text(CX)),
        ("r", Part::Text(R)),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn classifies_held_out_renderings_correctly() {
    let server = start(config(&models_copy("classify")));
    let fx = fixture();
    assert_eq!(fx.held_out.len(), 3);
    for (image, class, white) in &fx.held_out {
        let white = white.to_string();
        let answer = send(
            &server.data,
            post_multipart("/v1/classify", &classify_fields(image, &white)),
        )
        .await;
        assert_eq!(
            answer.status,
            200,
            "{}",
            String::from_utf8_lossy(&answer.body)
        );
        assert_eq!(answer.header("content-type"), Some("application/json"));
        assert_eq!(answer.header("x-model-version"), Some("1"));
        let timing = answer.header("server-timing").unwrap();
        for stage in ["decode;dur=", "features;dur=", "predict;dur=", "total;dur="] {
            assert!(timing.contains(stage), "{timing}");
        }
        let doc = answer.json();
        assert_eq!(doc["label"], class.as_str(), "{doc}");
        // The fixture model estimates the Ward parameters too: values inside their intervals.
        for parameter in ["rho_d", "rho_s", "alpha", "specular_fraction"] {
            let i = &doc["ward"][parameter];
            let [low, value, high] = ["low", "value", "high"].map(|k| i[k].as_f64().unwrap());
            assert!(
                low <= value && value <= high && low >= 0.0,
                "{parameter}: {i}"
            );
        }
        assert!(doc["ward"].get("unknown").is_none(), "{doc}");
        // The estimate never contradicts the class it names: its intervals hold the
        // predicted class's parameters.
        for parameter in ["rho_d", "rho_s", "alpha"] {
            let i = &doc["ward"][parameter];
            let v = doc["class"]["ward"][parameter].as_f64().unwrap();
            let (low, high) = (i["low"].as_f64().unwrap(), i["high"].as_f64().unwrap());
            assert!(low <= v && v <= high, "{parameter}: {v} outside {i}");
        }
        // Without white the total reflectance is unknown: no ρd, ρs; the fraction and α stay.
        let (image, _, _) = &fx.held_out[0];
        let fields = [
            ("image", Part::File(image)),
            ("cx", Part::Text(CX)),
            ("cy", Part::Text(CX)),
            ("r", Part::Text(R)),
        ];
        let unlit = send(&server.data, post_multipart("/v1/classify", &fields))
            .await
            .json();
        let ward = &unlit["ward"];
        assert!(
            ward.get("rho_d").is_none() && ward.get("rho_s").is_none(),
            "{ward}"
        );
        assert!(
            ward["alpha"]["value"].is_number() && ward["specular_fraction"]["high"].is_number()
        );
        assert!(
            ward["unknown"]
                .as_str()
                .unwrap()
                .contains("white reference"),
            "{ward}"
        );
        let described = match class.as_str() {
            "matte" => ("white matte", 0.8, 0.0),
            "chrome" => ("metal: a mirror with sharp reflections", 0.0, 0.75),
            _ => ("black matte", 0.08, 0.0),
        };
        assert_eq!(
            doc["class"],
            json!({"name": class, "description": described.0,
                   "ward": {"rho_d": described.1, "rho_s": described.2, "alpha": 0.0}}),
            "the predicted class in words, with its Ward parameters"
        );
        assert_eq!(doc["model"], json!({"name": "ward6", "version": 1}));
        assert_eq!(
            doc["request_id"].as_str(),
            answer.header("x-request-id"),
            "{doc}"
        );
        let probs = doc["probabilities"].as_array().unwrap();
        assert_eq!(probs.len(), 3);
        let ps: Vec<f64> = probs.iter().map(|p| p["p"].as_f64().unwrap()).collect();
        assert!(ps.windows(2).all(|w| w[0] >= w[1]), "{ps:?}");
        assert!((ps.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert_eq!(
            doc["features"]["names"],
            json!([
                "pix.mean",
                "pix.p10",
                "wav.s1.v.var",
                "wav.s2.v.var",
                "ratio.v.s1_s2",
                "wav.s2.v.kurt"
            ])
        );
        assert_eq!(doc["features"]["values"].as_array().unwrap().len(), 6);
        assert!(doc["features"].get("all").is_none());
        assert_eq!(doc["geometry"]["method"], "given");
        assert_eq!(doc["geometry"]["cx"], 47.5);
        assert_eq!(doc["white"]["method"], "given");
        // r < 80 px: accepted with a warning.
        assert!(
            doc["warnings"][0].as_str().unwrap().contains("below 80"),
            "{doc}"
        );
        for stage in ["decode", "features", "predict", "total"] {
            assert!(doc["timing_ms"][stage].as_f64().unwrap() >= 0.0);
        }
        assert!(doc.get("explain").is_none());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn includes_all_features_and_explanations_and_other_locators() {
    let server = start(config(&models_copy("include")));
    let (image, class, white) = &fixture().held_out[1];
    let white = white.to_string();
    let mut fields = classify_fields(image, &white);
    fields.push(("include", Part::Text("features")));
    fields.push(("include", Part::Text("explain")));
    let answer = send(
        &server.data,
        post_multipart("/v1/models/ward6/classify?version=1", &fields),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let doc = answer.json();
    let all = &doc["features"]["all"];
    assert_eq!(all["names"].as_array().unwrap().len(), 117);
    assert_eq!(all["values"].as_array().unwrap().len(), 117);
    assert_eq!(all["names"][0], "pix.mean");
    // The selected features (extracted alone by default) equal the full extraction's.
    let plain = send(
        &server.data,
        post_multipart("/v1/classify", &classify_fields(image, &white)),
    )
    .await
    .json();
    let names = all["names"].as_array().unwrap();
    for (name, value) in plain["features"]["names"]
        .as_array()
        .unwrap()
        .iter()
        .zip(plain["features"]["values"].as_array().unwrap())
    {
        let i = names.iter().position(|n| n == name).unwrap();
        assert_eq!(&all["values"][i], value, "{name}");
    }
    assert_eq!(plain["probabilities"], doc["probabilities"]);
    let explain = doc["explain"].as_array().unwrap();
    assert_eq!(explain.len(), 3);
    let d: Vec<f64> = explain
        .iter()
        .map(|e| e["distance"].as_f64().unwrap())
        .collect();
    assert!(d.windows(2).all(|w| w[0] <= w[1]));
    assert_eq!(explain[0]["class"], class.as_str(), "{doc}");
    assert!(explain[0]["path"].as_str().unwrap().ends_with(".pfm"));
    assert!(
        explain[0]["illumination"]
            .as_str()
            .unwrap()
            .starts_with("probe")
    );

    // The rendering's mask locates the sphere; so does automatic detection (black
    // background); no white reference gives a warning.
    let mask_path = fixture().dir.join(format!("test/probe3__{class}.mask.png"));
    let mask = std::fs::read(mask_path).unwrap();
    let answer = send(
        &server.data,
        post_multipart(
            "/v1/classify",
            &[
                ("image", Part::File(image)),
                ("white", Part::Text(&white)),
                ("mask", Part::File(&mask)),
            ],
        ),
    )
    .await;
    let doc = answer.json();
    assert_eq!(doc["geometry"]["method"], "mask", "{doc}");
    assert!(
        (doc["geometry"]["r"].as_f64().unwrap() - 43.64).abs() < 1.0,
        "{doc}"
    );
    assert_eq!(doc["label"], class.as_str());
    let answer = send(
        &server.data,
        post_multipart("/v1/classify", &[("image", Part::File(image))]),
    )
    .await;
    let doc = answer.json();
    assert_eq!(doc["geometry"]["method"], "auto", "{doc}");
    assert!(doc["geometry"]["confidence"].as_f64().unwrap() >= 0.9);
    assert_eq!(doc["white"]["method"], "none");
    assert!(
        doc["warnings"].to_string().contains("no white reference"),
        "{doc}"
    );

    // The client's request id is kept.
    let mut request = post_multipart("/v1/classify", &classify_fields(image, &white));
    request
        .headers_mut()
        .insert("x-request-id", "client-id-42".parse().unwrap());
    let answer = send(&server.data, request).await;
    assert_eq!(answer.header("x-request-id"), Some("client-id-42"));
    assert_eq!(answer.json()["request_id"], "client-id-42");
}

/// A mask holds coverage, not light: a mid-grey mask (128 of 255) covers its disc whatever
/// the request's encoding (sRGB would have made it 0.22 and covered nothing).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_grey_mask_is_read_as_stored() {
    let server = start(config(&models_copy("grey-mask")));
    let (image, _, white) = &fixture().held_out[0];
    let white = white.to_string();
    let (cx, cy, r) = (47.5, 47.5, 40.0);
    let samples: Vec<u8> = (0..96 * 96)
        .map(|i| {
            let (x, y) = ((i % 96) as f64, (i / 96) as f64);
            if (x - cx).hypot(y - cy) <= r { 128 } else { 0 }
        })
        .collect();
    let mask = common::png8(96, 96, 1, &samples);
    for encoding in ["srgb", "linear"] {
        let fields = [
            ("image", Part::File(image)),
            ("white", Part::Text(&white)),
            ("mask", Part::File(&mask)),
            ("encoding", Part::Text(encoding)),
        ];
        let doc = send(&server.data, post_multipart("/v1/classify", &fields))
            .await
            .json();
        assert_eq!(doc["geometry"]["method"], "mask", "{encoding}: {doc}");
        let fitted = doc["geometry"]["r"].as_f64().unwrap();
        assert!((fitted - r).abs() < 1.0, "{encoding}: r {fitted}");
    }
}

fn png_sphere() -> Vec<u8> {
    common::sphere_png(200, 90.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_client_mistake_is_a_problem_document() {
    let mut cfg = config(&models_copy("errors"));
    cfg.body_limit = 200_000;
    let server = start(cfg);
    let png = png_sphere();
    let data = &server.data;
    let classify = |fields: &[(&str, Part)]| post_multipart("/v1/classify", fields);
    let circle = |image| {
        vec![
            ("image", Part::File(image)),
            ("cx", Part::Text("99.5")),
            ("cy", Part::Text("99.5")),
            ("r", Part::Text("90")),
        ]
    };

    // Sanity: the PNG sphere classifies.
    assert_eq!(send(data, classify(&circle(&png))).await.status, 200);

    // Corrupt (truncated) PNG, unknown format, too many pixels (crafted header).
    send(data, classify(&circle(&png[..png.len() / 2])))
        .await
        .problem(422, "corrupt-image");
    send(data, classify(&circle(b"hello, not an image")))
        .await
        .problem(415, "unsupported-image-format");
    let huge = common::png_with_header_size(100_000, 100_000);
    send(data, classify(&circle(&huge)))
        .await
        .problem(413, "image-too-large");

    // Bad circles.
    let mut small = circle(&png);
    small[3] = ("r", Part::Text("10"));
    send(data, classify(&small))
        .await
        .problem(422, "bad-geometry");
    let partial = [("image", Part::File(&png)), ("cx", Part::Text("99.5"))];
    send(data, classify(&partial))
        .await
        .problem(422, "bad-geometry");
    let mut outside = circle(&png);
    outside[1] = ("cx", Part::Text("10"));
    send(data, classify(&outside))
        .await
        .problem(422, "bad-geometry");
    let mut nan = circle(&png);
    nan[1] = ("cx", Part::Text("NaN"));
    send(data, classify(&nan))
        .await
        .problem(422, "bad-geometry");
    let mut both = circle(&png);
    both.push(("mask", Part::File(&png)));
    send(data, classify(&both))
        .await
        .problem(422, "bad-geometry");
    // Detection on a noisy background fails cleanly.
    let noise: Vec<u8> = (0..200 * 200u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    let noisy = common::png8(200, 200, 1, &noise);
    let refusal = send(data, classify(&[("image", Part::File(&noisy))]))
        .await
        .problem(422, "bad-geometry");
    // In the service's words: its fields (the command line names its flags).
    assert!(
        refusal["detail"]
            .as_str()
            .unwrap()
            .ends_with("; give cx, cy and r, or a mask"),
        "{refusal}"
    );

    // Bad white references.
    for bad in ["-1", "0", "abc", "inf"] {
        let mut fields = circle(&png);
        fields.push(("white", Part::Text(bad)));
        send(data, classify(&fields))
            .await
            .problem(422, "bad-white");
    }
    let mut two_whites = circle(&png);
    two_whites.push(("white", Part::Text("0.5")));
    two_whites.push(("white_image", Part::File(&png)));
    send(data, classify(&two_whites))
        .await
        .problem(422, "bad-white");
    let black = common::png8(8, 8, 1, &[0; 64]);
    let mut black_card = circle(&png);
    black_card.push(("white_image", Part::File(&black)));
    send(data, classify(&black_card))
        .await
        .problem(422, "bad-white");

    // Unknown model or version.
    send(
        data,
        post_multipart("/v1/models/nope/classify", &circle(&png)),
    )
    .await
    .problem(404, "model-not-found");
    send(
        data,
        post_multipart("/v1/models/ward6/classify?version=9", &circle(&png)),
    )
    .await
    .problem(404, "version-not-found");
    send(
        data,
        post_multipart("/v1/models/ward6/classify?version=x", &circle(&png)),
    )
    .await
    .problem(422, "invalid-field");

    // Missing image, unknown field, bad option values, duplicates.
    send(data, classify(&[("white", Part::Text("0.5"))]))
        .await
        .problem(422, "missing-field");
    let mut extra = circle(&png);
    extra.push(("colour", Part::Text("red")));
    send(data, classify(&extra))
        .await
        .problem(422, "unknown-field");
    let mut include = circle(&png);
    include.push(("include", Part::Text("features,everything")));
    send(data, classify(&include))
        .await
        .problem(422, "invalid-field");
    let mut encoding = circle(&png);
    encoding.push(("encoding", Part::Text("gamma:-2")));
    send(data, classify(&encoding))
        .await
        .problem(422, "invalid-field");
    let mut twice = circle(&png);
    twice.push(("image", Part::File(&png)));
    send(data, classify(&twice))
        .await
        .problem(422, "invalid-field");

    // Wrong content type (JSON has its own problems: tests/server/bodies.rs), malformed
    // multipart.
    send(data, post_json("/v1/classify", &json!({"image": "x"})))
        .await
        .problem(422, "invalid-field");
    send(data, post_json("/v1/locate", &json!({"image": "x"})))
        .await
        .problem(415, "unsupported-media-type");
    let broken = Request::post("/v1/classify")
        .header("content-type", "multipart/form-data; boundary=xyz")
        .body(Body::from(
            "--xyz\r\nContent-Disposition: form-data; name=\"image\"\r\n\r\nabc",
        ))
        .unwrap();
    send(data, broken).await.problem(400, "malformed-request");

    // Body over the limit: declared (Content-Length) and streamed.
    let big = vec![7u8; 300_000];
    let (content_type, body) = common::server::multipart(&[("image", Part::File(&big))]);
    let declared = Request::post("/v1/classify")
        .header("content-type", content_type.clone())
        .header("content-length", body.len())
        .body(Body::from(body.clone()))
        .unwrap();
    send(data, declared).await.problem(413, "body-too-large");
    // Without Content-Length the limit applies while the body is read.
    let streamed = Request::post("/v1/classify")
        .header("content-type", content_type)
        .body(Body::from(body))
        .unwrap();
    send(data, streamed).await.problem(413, "body-too-large");

    // Unknown route, wrong method.
    send(data, get("/v1/nothing"))
        .await
        .problem(404, "not-found");
    let answer = send(data, get("/v1/classify")).await;
    answer.problem(405, "method-not-allowed");
    assert!(answer.header("allow").unwrap().contains("POST"));
    let unknown = send(data, get("/v1/models/nope")).await;
    let problem = unknown.problem(404, "model-not-found");
    let detail = problem["detail"].as_str().unwrap_or_default();
    assert!(
        detail.contains("\"nope\"") && detail.contains("this server serves: ward6"),
        "{detail}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sheds_load_times_out_and_reports_readiness() {
    // Saturated: the one admission slot is taken, the next request is shed at once.
    let mut cfg = config(&models_copy("shed"));
    cfg.max_inflight = 1;
    let server = start(cfg);
    let png = png_sphere();
    let fields = [
        ("image", Part::File(&png)),
        ("cx", Part::Text("99.5")),
        ("cy", Part::Text("99.5")),
        ("r", Part::Text("90")),
    ];
    let permit = server.state.cpu.admit().unwrap();
    let answer = send(&server.data, post_multipart("/v1/classify", &fields)).await;
    answer.problem(429, "overloaded");
    assert_eq!(answer.header("retry-after"), Some("1"));
    drop(permit);
    assert_eq!(
        send(&server.data, post_multipart("/v1/classify", &fields))
            .await
            .status,
        200
    );

    // Readiness: loading, ready, draining.
    let state = reflectance::build_state(config(&models_copy("ready"))).unwrap();
    let router = reflectance::data_router(state.clone());
    let doc = send(&router, get("/health/ready"))
        .await
        .problem(503, "not-ready");
    assert_eq!(doc["detail"], "loading models");
    assert_eq!(send(&router, get("/health/live")).await.status, 200);
    // The Open Inference Protocol answers "false" with a 4xx.
    send(&router, get("/v2/health/ready"))
        .await
        .problem(400, "v2-not-ready");
    send(&router, get("/v2/models/ward6/ready"))
        .await
        .problem(400, "v2-not-ready");
    reflectance::load_models(&state).unwrap();
    assert_eq!(
        send(&router, get("/health/ready")).await.json(),
        json!({"status": "ready"})
    );
    state.readiness.set(reflectance::Phase::Draining);
    let doc = send(&router, get("/health/ready"))
        .await
        .problem(503, "not-ready");
    assert!(doc["detail"].as_str().unwrap().contains("draining"));

    // A per-request time limit far below the work's duration.
    let mut cfg = config(&models_copy("timeout"));
    cfg.request_timeout = std::time::Duration::from_micros(50);
    let server = start(cfg);
    let big = common::sphere_png(1200, 560.0);
    let fields = [("image", Part::File(&big))];
    send(&server.data, post_multipart("/v1/classify", &fields))
        .await
        .problem(408, "timeout");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn models_and_metrics() {
    let server = start(config(&models_copy("models")));
    let list = send(&server.data, get("/v1/models")).await.json();
    assert_eq!(list["default_model"], "ward6");
    assert_eq!(list["models"][0]["name"], "ward6");
    assert_eq!(list["models"][0]["active_version"], 1);
    assert_eq!(list["models"][0]["default"], true);
    let detail = send(&server.data, get("/v1/models/ward6")).await.json();
    assert_eq!(detail["versions"], json!([1]));
    assert_eq!(detail["active_version"], 1);
    assert_eq!(detail["features"]["set"], "hand6");
    assert_eq!(detail["features"]["extracted"], 117);
    assert_eq!(detail["classifier"]["kind"], "svm");
    assert_eq!(detail["classes"].as_array().unwrap().len(), 3);
    let cv = &detail["cv"];
    assert!(cv["accuracy"].as_f64().unwrap() > 0.5, "{detail}");
    assert_eq!(cv["confusion"].as_array().unwrap().len(), 3);
    assert_eq!(detail["sha256"].as_str().unwrap().len(), 64);

    let (image, _, white) = &fixture().held_out[0];
    let white = white.to_string();
    assert_eq!(
        send(
            &server.data,
            post_multipart("/v1/classify", &classify_fields(image, &white))
        )
        .await
        .status,
        200
    );
    send(&server.data, get("/nope"))
        .await
        .problem(404, "not-found");
    let answer = send(&server.data, get("/metrics")).await;
    assert_eq!(answer.status, 200);
    assert!(
        answer
            .header("content-type")
            .unwrap()
            .starts_with("text/plain")
    );
    let text = String::from_utf8(answer.body).unwrap();
    for needle in [
        "reflectance_http_requests_total{route=\"/v1/classify\",method=\"POST\",status=\"200\"}",
        "reflectance_http_requests_total{route=\"unmatched\",method=\"GET\",status=\"404\"}",
        "reflectance_http_request_duration_seconds_bucket{route=\"/v1/models/{name}\",method=\"GET\",status=\"200\",le=",
        "reflectance_stage_duration_seconds_bucket{stage=\"features\",le=",
        "reflectance_stage_duration_seconds_bucket{stage=\"decode\",le=",
        "reflectance_stage_duration_seconds_bucket{stage=\"predict\",le=",
        "reflectance_http_requests_in_flight",
        // The recorder is the process's: tests running beside this one activate other
        // versions of their own `ward6`, so only the gauge's presence is this server's.
        "reflectance_model_active_version{model=\"ward6\"} ",
    ] {
        assert!(text.contains(needle), "{needle} missing from\n{text}");
    }
}

/// `reflectance classify IMAGE --model …` answers exactly as `POST /v1/classify` does
/// (but for the request id and the timings), with a summary for people by default.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_command_line_answers_as_the_service_does() {
    let models = models_copy("cli-classify");
    let server = start(config(&models));
    let (image, class, white) = &fixture().held_out[2];
    let path = models.parent().unwrap().join("sphere.pfm");
    std::fs::write(&path, image).unwrap();
    let white = white.to_string();
    let mut fields = classify_fields(image, &white);
    fields.push(("include", Part::Text("features,explain")));
    let served = send(&server.data, post_multipart("/v1/classify", &fields))
        .await
        .json();
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
            .arg("classify")
            .arg(&path)
            .arg("--model")
            .arg(models.join("ward6"))
            .args(["--white", &white, "--cx", CX, "--cy", CX, "--r", R])
            .args(extra)
            .output()
            .unwrap();
        common::assert_success(&out);
        String::from_utf8(out.stdout).unwrap()
    };
    let mut local: Value =
        serde_json::from_str(&run(&["--json", "--all-features", "--explain"])).unwrap();
    let mut served = served;
    for doc in [&mut local, &mut served] {
        let object = doc.as_object_mut().unwrap();
        object.remove("request_id");
        object.remove("timing_ms");
    }
    assert_eq!(local, served);
    assert_eq!(local["label"], class.as_str());
    let summary = run(&[]);
    assert!(summary.starts_with(&format!("{class}  (p = ")), "{summary}");
    assert!(summary.contains("warning: sphere radius"), "{summary}");
    // Mistakes are one line on stderr and a failure status.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(["classify", "missing.png", "--model"])
        .arg(models.join("ward6"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("reflectance: image missing.png:"),
        "{stderr}"
    );
}

/// A model that records the captures it was trained for says when a photograph lies
/// outside them: too noisy, clipped, or too small a sphere.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn warns_about_photographs_outside_the_captures_of_training() {
    use reflectance_core::decode::{DecodeOptions, decode};
    use reflectance_render::capture::{self, CaptureEnvelope, CaptureRanges, CaptureSettings};
    let models = models_copy("envelope");
    let registry = reflectance_core::model::registry::Registry::new(&models);
    let mut model = registry.load("ward6", 1).unwrap();
    model.capture = Some(CaptureEnvelope {
        ranges: CaptureRanges::default(),
        noise_p99: model
            .classes
            .iter()
            .map(|c| (c.name.clone(), 0.02))
            .collect(),
        clipped_p99: model
            .classes
            .iter()
            .map(|c| (c.name.clone(), 0.01))
            .collect(),
    });
    std::fs::remove_dir_all(models.join("ward6")).unwrap();
    registry.publish(&mut model, &[]).unwrap();
    let server = start(config(&models));
    let (pfm, _, white) = &fixture().held_out[0];
    let render = decode(pfm, &DecodeOptions::default()).unwrap().luminance;
    let circle = reflectance_core::locate::Circle {
        cx: 47.5,
        cy: 47.5,
        r: R.parse().unwrap(),
    };
    let warnings = |settings: CaptureSettings, white: f64| {
        let mut rng = reflectance_core::util::rng::Rng::new(7);
        let shot = capture::capture(render.view(), &circle, white, &settings, &mut rng).unwrap();
        let texts =
            [shot.white, shot.circle.cx, shot.circle.cy, shot.circle.r].map(|v| v.to_string());
        let fields = vec![
            ("image", Part::File(&shot.bytes)),
            ("white", Part::Text(&texts[0])),
            ("cx", Part::Text(&texts[1])),
            ("cy", Part::Text(&texts[2])),
            ("r", Part::Text(&texts[3])),
        ];
        let request = post_multipart("/v1/classify", &fields);
        let data = server.data.clone();
        async move {
            let answer = send(&data, request).await.json();
            answer["warnings"]
                .as_array()
                .unwrap()
                .iter()
                .map(|w| w.as_str().unwrap().to_string())
                .collect::<Vec<_>>()
        }
    };
    let ideal = CaptureSettings {
        quantization: capture::Quantization::Srgb8,
        ..CaptureSettings::ideal(100.0)
    };
    let said = |warnings: &[String], what: &str| warnings.iter().any(|w| w.contains(what));
    let clean = warnings(ideal, *white).await;
    assert!(!said(&clean, "trained"), "{clean:?}");
    let noisy = warnings(
        CaptureSettings {
            noise: 0.08,
            ..ideal
        },
        *white,
    )
    .await;
    assert!(said(&noisy, "noise, estimated at"), "{noisy:?}");
    // White four times above full scale: most of the sphere clips.
    let clipped = warnings(
        CaptureSettings {
            exposure: 1.0,
            ..ideal
        },
        white / 4.0,
    )
    .await;
    assert!(said(&clipped, "clipped"), "{clipped:?}");
    let small = warnings(
        CaptureSettings {
            radius: 40.0,
            ..ideal
        },
        *white,
    )
    .await;
    assert!(said(&small, "radius 40 px"), "{small:?}");
    assert!(
        !said(&small, "noise") && !said(&small, "clipped"),
        "{small:?}"
    );
}

/// The PNG inside a `data:image/png;base64,…` URL, decoded.
fn data_url_png(url: &Value) -> image::DynamicImage {
    let encoded = url
        .as_str()
        .and_then(|u| u.strip_prefix("data:image/png;base64,"))
        .unwrap_or_else(|| panic!("not a PNG data URL: {url}"));
    let png = base64::engine::general_purpose::STANDARD
        .decode(encoded)
        .unwrap();
    image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap()
}

/// Two spheres in one photograph: the more confident is chosen, the other is offered next.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn locate_offers_the_other_circles_it_found() {
    let server = start(config(&models_copy("candidates")));
    let (w, h) = (480u32, 220u32);
    let spheres = [(120.0, 110.0, 80.0), (360.0, 110.0, 60.0)];
    let samples: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = (f64::from(i % w), f64::from(i / w));
            spheres
                .iter()
                .find_map(|&(cx, cy, r)| {
                    let d2 = ((x - cx).powi(2) + (y - cy).powi(2)) / (r * r);
                    (d2 <= 1.0)
                        .then(|| (60.0 + 150.0 * (1.0 - d2).sqrt() + 20.0 * (x / 7.0).sin()) as u8)
                })
                .unwrap_or(20)
        })
        .collect();
    let png = common::png8(w, h, 1, &samples);
    let doc = send(
        &server.data,
        post_multipart("/v1/locate", &[("image", Part::File(&png))]),
    )
    .await
    .json();
    let candidates = doc["candidates"].as_array().unwrap();
    assert!((2..=3).contains(&candidates.len()), "{doc}");
    assert_eq!(candidates[0]["cx"], doc["geometry"]["cx"], "{doc}");
    for (cx, _, r) in spheres {
        let found = candidates.iter().any(|c| {
            (c["cx"].as_f64().unwrap() - cx).abs() < 3.0
                && (c["r"].as_f64().unwrap() - r).abs() < 3.0
        });
        assert!(found, "the sphere at x = {cx} is a candidate: {doc}");
    }
    let confidences: Vec<f64> = candidates
        .iter()
        .map(|c| c["confidence"].as_f64().unwrap())
        .collect();
    assert!(
        confidences.windows(2).all(|p| p[0] >= p[1]),
        "{confidences:?}"
    );
}

/// What the page asks of the service: the circle before classifying, a white card inside
/// the photograph, the pictures of the features' input, thumbnails of the neighbours.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn locates_reads_a_white_card_in_the_photo_and_draws_what_the_features_see() {
    let server = start(config(&models_copy("page-api")));
    let (image, class, white) = &fixture().held_out[0];
    let located = |fields: Vec<(&'static str, Part<'static>)>| {
        send(&server.data, post_multipart("/v1/locate", &fields))
    };
    let image: &'static [u8] = image.clone().leak();
    let doc = located(vec![("image", Part::File(image))]).await.json();
    assert_eq!(
        (doc["width"].as_u64(), doc["height"].as_u64()),
        (Some(96), Some(96))
    );
    let g = &doc["geometry"];
    assert_eq!(g["method"], "auto", "{doc}");
    assert!((g["cx"].as_f64().unwrap() - 47.5).abs() < 1.0, "{doc}");
    assert!((g["r"].as_f64().unwrap() - 43.64).abs() < 1.0, "{doc}");
    let first = &doc["candidates"][0];
    assert_eq!((&first["cx"], &first["r"]), (&g["cx"], &g["r"]), "{doc}");
    assert_eq!(first["rim_visible"], 1.0, "{doc}");
    assert!(doc.get("preview").is_none());
    let doc = located(vec![
        ("image", Part::File(image)),
        ("include", Part::Text("preview")),
    ])
    .await
    .json();
    let preview = data_url_png(&doc["preview"]);
    assert_eq!((preview.width(), preview.height()), (96, 96));
    // Nothing found is an answer, not an error.
    let blank = common::png8(120, 100, 1, &[0; 12_000]).leak();
    let doc = located(vec![("image", Part::File(blank))]).await.json();
    assert_eq!(doc["geometry"], Value::Null, "{doc}");
    assert!(
        doc["warnings"].to_string().contains("no usable sphere"),
        "{doc}"
    );
    for (fields, status, slug) in [
        (
            vec![("image", Part::File(b"not an image" as &[u8]))],
            415,
            "unsupported-image-format",
        ),
        (
            vec![("image", Part::File(image)), ("cx", Part::Text("4"))],
            422,
            "unknown-field",
        ),
        (
            vec![
                ("image", Part::File(image)),
                ("include", Part::Text("explain")),
            ],
            422,
            "invalid-field",
        ),
        (
            vec![("include", Part::Text("preview"))],
            422,
            "missing-field",
        ),
    ] {
        located(fields).await.problem(status, slug);
    }

    // A white card inside the photograph: the median of the pixels the rectangle touches,
    // divided by the card's reflectance.
    let mut samples = vec![40u8; 200 * 200];
    for y in 150..190 {
        for x in 10..60 {
            samples[y * 200 + x] = 200;
        }
    }
    let photo = common::png8(200, 200, 1, &samples);
    let classify = |rect: &'static str, more: Vec<(&'static str, Part<'static>)>| {
        let photo = photo.clone().leak();
        let mut fields = vec![
            ("image", Part::File(&*photo)),
            ("cx", Part::Text("99.5")),
            ("cy", Part::Text("80")),
            ("r", Part::Text("60")),
            ("white_rect", Part::Text(rect)),
        ];
        fields.extend(more);
        send(&server.data, post_multipart("/v1/classify", &fields))
    };
    let doc = classify(
        "12,152,40.5,30",
        vec![("white_reflectance", Part::Text("0.8"))],
    )
    .await
    .json();
    assert_eq!(doc["white"]["method"], "white_rect", "{doc}");
    let card = reflectance_core::decode::srgb_to_linear(200.0 / 255.0);
    assert!(
        (doc["white"]["value"].as_f64().unwrap() - card / 0.8).abs() < 1e-12,
        "{doc}"
    );
    let outside = classify("190,0,20,10", vec![])
        .await
        .problem(422, "bad-white");
    assert!(
        outside["detail"].as_str().unwrap().contains("200 × 200"),
        "{outside}"
    );
    classify("1,2,3", vec![]).await.problem(422, "bad-white");
    classify("1,2,3,4", vec![("white", Part::Text("0.5"))])
        .await
        .problem(422, "bad-white");
    classify("1,2,3,4", vec![("white_reflectance", Part::Text("1.5"))])
        .await
        .problem(422, "bad-white");

    // The annulus and the subbands as pictures, and the neighbours' thumbnails.
    let white = white.to_string();
    let mut fields = classify_fields(image, &white);
    fields.push(("include", Part::Text("images,explain")));
    let doc = send(&server.data, post_multipart("/v1/classify", &fields))
        .await
        .json();
    assert_eq!(doc["label"], class.as_str(), "{doc}");
    let annulus = data_url_png(&doc["images"]["annulus"]);
    assert_eq!((annulus.width(), annulus.height()), (448, 96));
    let subbands = doc["images"]["subbands"].as_array().unwrap();
    assert_eq!(subbands.len(), 12);
    for (k, band) in subbands.iter().enumerate() {
        let scale = k / 3 + 1;
        assert_eq!(band["scale"], scale);
        assert_eq!(band["orientation"], ["h", "v", "d"][k % 3]);
        let picture = data_url_png(&band["image"]);
        assert_eq!(
            (picture.width(), picture.height()),
            (448 >> scale, 96 >> scale)
        );
    }
    for neighbour in doc["explain"].as_array().unwrap() {
        let thumbnail = data_url_png(&neighbour["thumbnail"]);
        assert_eq!(thumbnail.width().max(thumbnail.height()), 48, "{neighbour}");
    }
}

/// The page and the API reference: embedded, linked by content hash, cached accordingly.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serves_the_page_and_the_api_reference_with_their_assets() {
    let server = start(config(&models_copy("page-assets")));
    let page = send(&server.data, get("/")).await;
    assert_eq!(page.status, 200);
    assert_eq!(
        page.header("content-type"),
        Some("text/html; charset=utf-8")
    );
    assert_eq!(page.header("cache-control"), Some("no-cache"));
    let policy = page.header("content-security-policy").unwrap();
    assert!(policy.starts_with("default-src 'self'"), "{policy}");
    let html = String::from_utf8(page.body.clone()).unwrap();
    let linked: Vec<&str> = html
        .split("\"/assets/")
        .skip(1)
        .filter_map(|rest| rest.split('"').next())
        .collect();
    // What the page loads (its script and style); the example photographs only on a click.
    let (assets, examples): (Vec<&str>, Vec<&str>) = linked
        .iter()
        .partition(|a| a.ends_with(".js") || a.ends_with(".css"));
    assert_eq!(assets.len(), 2, "{html}");
    assert_eq!(examples.len(), 2, "{html}");
    for example in &examples {
        let answer = send(&server.data, get(&format!("/assets/{example}"))).await;
        let kind = answer
            .header("content-type")
            .unwrap_or_default()
            .to_string();
        assert!(kind.starts_with("image/"), "{example}: {kind}");
    }
    let mut weight = html.len();
    for asset in &assets {
        let answer = send(&server.data, get(&format!("/assets/{asset}"))).await;
        assert_eq!(answer.status, 200, "{asset}");
        assert_eq!(
            answer.header("cache-control"),
            Some("public, max-age=31536000, immutable")
        );
        assert_eq!(answer.header("etag"), Some(format!("\"{asset}\"").as_str()));
        weight += answer.body.len();
    }
    assert!(weight <= 200_000, "the page weighs {weight} bytes");
    let stale = assets[0].replacen('.', ".0", 1);
    send(&server.data, get(&format!("/assets/{stale}")))
        .await
        .problem(404, "not-found");

    let docs = send(&server.data, get("/docs")).await;
    assert_eq!(docs.status, 200);
    let html = String::from_utf8(docs.body).unwrap();
    for name in [
        "swagger-ui-bundle.",
        "swagger-ui.",
        "docs.",
        "swagger-ui-LICENSE.",
    ] {
        let link = html
            .split("\"/assets/")
            .skip(1)
            .filter_map(|rest| rest.split('"').next())
            .find(|a| a.starts_with(name))
            .unwrap_or_else(|| panic!("{name} not linked"));
        assert_eq!(
            send(&server.data, get(&format!("/assets/{link}")))
                .await
                .status,
            200
        );
    }
    // The viewer's bundle travels gzipped to a client that takes gzip, plain to one that
    // does not: the vendored file either way.
    let bundle = html
        .split("\"/assets/")
        .filter_map(|rest| rest.split('"').next())
        .find(|a| a.starts_with("swagger-ui-bundle."))
        .unwrap();
    let vendored = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("web/vendor/swagger-ui/swagger-ui-bundle.js"),
    )
    .unwrap();
    let asking = |encoding: &'static str| {
        Request::get(format!("/assets/{bundle}"))
            .header("accept-encoding", encoding)
            .body(Body::empty())
            .unwrap()
    };
    let gzipped = send(&server.data, asking("gzip, deflate, br")).await;
    assert_eq!(gzipped.header("content-encoding"), Some("gzip"));
    assert_eq!(gzipped.header("vary"), Some("accept-encoding"));
    assert!(gzipped.body.len() < vendored.len() / 3);
    let mut unzipped = Vec::new();
    std::io::Read::read_to_end(
        &mut flate2::read::GzDecoder::new(&gzipped.body[..]),
        &mut unzipped,
    )
    .unwrap();
    assert!(
        unzipped == vendored,
        "the gzipped bundle is not the vendored file"
    );
    for refusing in ["identity", "gzip;q=0, identity"] {
        let plain = send(&server.data, asking(refusing)).await;
        assert_eq!(plain.header("content-encoding"), None, "{refusing}");
        assert!(plain.body == vendored, "{refusing}");
    }
}

/// `GET /v1/preview`: a rendered sphere of given Ward parameters, the same every time.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn previews_a_material_as_a_png() {
    let server = start(config(&models_copy("preview")));
    let uri = "/v1/preview?rho_d=0.7&rho_s=0.25&alpha=0.01&probe=sky-2&size=80";
    let first = send(&server.data, get(uri)).await;
    assert_eq!(
        first.status,
        200,
        "{}",
        String::from_utf8_lossy(&first.body)
    );
    assert_eq!(first.header("content-type"), Some("image/png"));
    assert_eq!(first.header("cache-control"), Some("public, max-age=86400"));
    let picture = image::load_from_memory(&first.body).unwrap().to_luma8();
    assert_eq!(picture.dimensions(), (80, 80));
    // The sphere stands in front of its scene: sky above the horizon, brighter than the
    // ground below it, and the lit sphere between.
    let (sky, ground) = (picture.get_pixel(0, 0).0[0], picture.get_pixel(0, 79).0[0]);
    assert!(sky > ground && ground > 0, "sky {sky}, ground {ground}");
    assert!(picture.get_pixel(40, 40).0[0] > 0);
    let again = send(&server.data, get(uri)).await;
    assert_eq!(again.body, first.body);
    let default = send(&server.data, get("/v1/preview?rho_d=0.7&rho_s=0&alpha=0")).await;
    let picture = image::load_from_memory(&default.body).unwrap();
    assert_eq!((picture.width(), picture.height()), (192, 192));
    let refused = [
        ("rho_s=0.1&alpha=0", "rho_d"),
        ("rho_d=0.8&rho_s=0.5&alpha=0", "rho_d + rho_s"),
        ("rho_d=0.1&rho_s=0.1&alpha=0.9", "alpha 0.9"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&probe=studio", "sky-1, sky-2"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&size=1000", "size 1000"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&colour=red", "colour"),
        ("rho_d=x&rho_s=0.1&alpha=0", "rho_d"),
    ];
    refuses_queries(&server, "/v1/preview", &refused).await;
}

/// Each query of `path` is `422 invalid-field` with a detail holding its words.
async fn refuses_queries(server: &TestServer, path: &str, cases: &[(&str, &str)]) {
    for (query, words) in cases {
        let problem = send(&server.data, get(&format!("{path}?{query}")))
            .await
            .problem(422, "invalid-field");
        let detail = problem["detail"].as_str().unwrap();
        assert!(detail.contains(words), "{query}: {detail}");
    }
}

/// `GET /v1/material.gltf`: the glTF asset `reflectance gltf` writes, as a download.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn exports_a_material_as_gltf() {
    let server = start(config(&models_copy("gltf")));
    let answer = send(
        &server.data,
        get("/v1/material.gltf?rho_d=0.25&rho_s=0.1&alpha=0.02&name=j"),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    assert_eq!(answer.header("content-type"), Some("model/gltf+json"));
    assert_eq!(
        answer.header("content-disposition"),
        Some("attachment; filename=\"j.gltf\"")
    );
    // Known values of the mapping (docs/design.md §8), solved independently in numpy:
    // ρs 0.1 → F0 0.07993, ior 1.7883; baseColor ρd / (1 − F0); GGX roughness √(0.7 α).
    let doc = answer.json();
    assert_eq!(
        doc["extras"]["ward"],
        json!({"rho_d": 0.25, "rho_s": 0.1, "alpha": 0.02})
    );
    let material = &doc["materials"][0];
    assert_eq!(material["name"], "j");
    let pbr = &material["pbrMetallicRoughness"];
    let roughness = pbr["roughnessFactor"].as_f64().unwrap();
    assert!(
        (roughness * roughness - 0.7 * 0.02).abs() < 1e-12,
        "{roughness}"
    );
    assert_eq!(pbr["metallicFactor"], 0.0);
    let ior = material["extensions"]["KHR_materials_ior"]["ior"]
        .as_f64()
        .unwrap();
    assert!((ior - 1.7883).abs() < 2e-3, "{ior}");
    let base = pbr["baseColorFactor"][0].as_f64().unwrap();
    assert!((base - 0.25 / (1.0 - 0.07993)).abs() < 1e-3, "{base}");
    assert!(
        material["extensions"]
            .get("KHR_materials_specular")
            .is_none()
    );

    // Binary glTF, and a colour: the same material, tinted, in the binary container.
    let glb = send(
        &server.data,
        get("/v1/material.gltf?rho_d=0.25&rho_s=0.1&alpha=0.02&name=j&format=glb&colour=0.6,0.3,0.2"),
    )
    .await;
    assert_eq!(glb.status, 200, "{}", String::from_utf8_lossy(&glb.body));
    assert_eq!(glb.header("content-type"), Some("model/gltf-binary"));
    assert_eq!(
        glb.header("content-disposition"),
        Some("attachment; filename=\"j.glb\"")
    );
    assert_eq!(&glb.body[0..4], b"glTF");
    let length = u32::from_le_bytes(glb.body[12..16].try_into().unwrap()) as usize;
    let inside: Value = serde_json::from_slice(&glb.body[20..20 + length]).unwrap();
    let tinted: Vec<f64> = inside["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let y = 0.2126 * tinted[0] + 0.7152 * tinted[1] + 0.0722 * tinted[2];
    assert!(
        (y - base).abs() < 1e-9,
        "the tint keeps the grey value's luminance: {tinted:?}"
    );
    assert!(
        (tinted[0] / tinted[1] - 2.0).abs() < 1e-9 && (tinted[1] / tinted[2] - 1.5).abs() < 1e-9
    );
    let refused = [
        ("rho_s=0.1&alpha=0", "rho_d"),
        ("rho_d=0.8&rho_s=0.5&alpha=0", "rho_d + rho_s"),
        ("rho_d=0.1&rho_s=0.1&alpha=2", "alpha"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&name=../x", "invalid name"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&size=3", "size"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&name=", "invalid name"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&colour=1,2", "colour"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&colour=0,0,0", "colour"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&colour=-1,1,1", "colour"),
        ("rho_d=0.1&rho_s=0.1&alpha=0&format=obj", "format"),
    ];
    refuses_queries(&server, "/v1/material.gltf", &refused).await;
}

/// A model file from before prediction sets and the domain check still loads and answers:
/// without a set, with a warning that says so, and with a domain verdict that rests on the
/// capture envelope alone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_model_without_the_calibrations_answers_without_a_set_and_says_so() {
    let models = models_copy("uncalibrated");
    let registry = reflectance_core::model::registry::Registry::new(&models);
    let mut model = registry.load("ward6", 1).unwrap();
    assert!(model.prediction_sets.is_some() && model.domain.is_some());
    model.prediction_sets = None;
    model.domain = None;
    model.no_white = None;
    model.self_test.no_white_probabilities = None;
    std::fs::remove_dir_all(models.join("ward6")).unwrap();
    registry.publish(&mut model, &[]).unwrap();
    let server = start(config(&models));
    let (image, class, white) = &fixture().held_out[0];
    let white = white.to_string();
    let doc = send(
        &server.data,
        post_multipart("/v1/classify", &classify_fields(image, &white)),
    )
    .await
    .json();
    assert_eq!(doc["label"], class.as_str(), "{doc}");
    assert!(doc.get("prediction_set").is_none(), "{doc}");
    assert!(
        doc["warnings"]
            .to_string()
            .contains("no prediction-set calibration"),
        "{doc}"
    );
    assert_eq!(doc["domain"]["in_domain"], true, "{doc}");
    assert!(doc["domain"].get("score").is_none(), "{doc}");
    let detail = send(&server.data, get("/v1/models/ward6")).await.json();
    assert_eq!(detail["calibration"], json!({"with_white": {}}), "{detail}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_shipped_version_2_shows_its_classifier_for_objects_and_answers_spheres_with_the_first()
{
    let models = common::server::temp_dir("shipped-objects").join("models");
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ward6/2");
    common::server::copy_dir(&shipped, &models.join("ward6/2"));
    let server = start(config(&models));
    let detail = send(&server.data, get("/v1/models/ward6")).await.json();
    let calibration = &detail["calibration"];
    assert_eq!(calibration["objects"]["prediction_sets"]["images"], 11340);
    assert!(calibration["objects"]["domain"]["images"].as_u64().unwrap() > 0);
    assert_ne!(calibration["objects"], calibration["with_white"]);
    let sphere = std::fs::read(common::fixtures().join("features/sphere_rgb8.png")).unwrap();
    let circle = [("cx", "96.5"), ("cy", "94.25"), ("r", "85")];
    let mut fields: Vec<(&str, Part)> = vec![("image", Part::File(&sphere))];
    fields.extend(circle.map(|(k, v)| (k, Part::Text(v))));
    let without = send(&server.data, post_multipart("/v1/classify", &fields)).await;
    assert_eq!(without.json()["classifier"], "without_white");
    fields.push(("white", Part::Text("0.8")));
    let with = send(&server.data, post_multipart("/v1/classify", &fields)).await;
    assert_eq!(with.json()["classifier"], "with_white");
    assert_eq!(with.json()["model"]["version"], 2);
}
