//! What a request's body may be, against the real router: the classification form as JSON
//! with base64 files (the same answer as the form), every other body refused with a
//! problem+json that says what to send, a 413 that names the limit and the setting that
//! raises it, WebP read, and formats not read named with what to do (issue 65, 8 and 9).

use crate::common;

use axum::body::Body;
use axum::http::Request;
use base64::Engine;
use common::server::{
    Part, config, fixture, models_copy, multipart, post_json, post_multipart, send, start,
};
use serde_json::{Value, json};

const CX: &str = "47.5";
const R: &str = "43.63636363636363";

fn b64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn post_raw(uri: &str, content_type: Option<&str>, body: Vec<u8>) -> Request<Body> {
    let mut request = Request::post(uri);
    if let Some(t) = content_type {
        request = request.header("content-type", t);
    }
    request.body(Body::from(body)).unwrap()
}

/// An answer without what differs between two requests (their ids and timings).
fn comparable(mut doc: Value) -> Value {
    let object = doc.as_object_mut().unwrap();
    object.remove("request_id");
    object.remove("timing_ms");
    doc
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_with_base64_files_answers_as_the_form_does() {
    let server = start(config(&models_copy("json-body")));
    let data = &server.data;
    let fx = fixture();
    for (image, class, white) in &fx.held_out {
        let white_text = white.to_string();
        let form = [
            ("image", Part::File(image)),
            ("white", Part::Text(&white_text)),
            ("cx", Part::Text(CX)),
            ("cy", Part::Text(CX)),
            ("r", Part::Text(R)),
            ("include", Part::Text("features")),
        ];
        let by_form = send(data, post_multipart("/v1/classify", &form))
            .await
            .json_of(200);
        assert_eq!(by_form["label"], class.as_str(), "{by_form}");
        let as_json = json!({
            "image": b64(image), "white": white, "cx": 47.5, "cy": 47.5,
            "r": 43.63636363636363, "include": ["features"],
        });
        let answer = send(data, post_json("/v1/classify", &as_json)).await;
        assert_eq!(answer.header("x-model-version"), Some("1"));
        let by_json = answer.json_of(200);
        assert_eq!(comparable(by_json), comparable(by_form.clone()));
        // The named route; numbers as the form's text, a data: URL, the URL-safe alphabet
        // without padding, line breaks as `base64` writes them: the same answer.
        let url_safe = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(image);
        let wrapped: Vec<String> = b64(image)
            .as_bytes()
            .chunks(76)
            .map(|c| String::from_utf8(c.to_vec()).unwrap())
            .collect();
        for image in [
            format!("data:application/octet-stream;base64,{}", b64(image)),
            url_safe,
            wrapped.join("\n"),
        ] {
            let as_text = json!({
                "image": image, "white": white_text, "cx": CX, "cy": CX, "r": R,
                "include": "features", "white_image": null,
            });
            let doc = send(data, post_json("/v1/models/ward6/classify", &as_text))
                .await
                .json_of(200);
            assert_eq!(comparable(doc), comparable(by_form.clone()));
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_body_not_read_is_answered_with_what_to_send() {
    let server = start(config(&models_copy("wrong-bodies")));
    let data = &server.data;
    let png = common::sphere_png(200, 90.0);
    // What the classification routes take: the form, JSON with base64, the V2 route.
    let takes_both = |detail: &str| {
        for words in [
            "multipart/form-data",
            "-F image=@photo.jpg",
            "application/json",
            "base64",
            "/v2/models/{name}/infer",
        ] {
            assert!(detail.contains(words), "{words:?} not in {detail}");
        }
    };
    for uri in ["/v1/classify", "/v1/models/ward6/classify"] {
        // An empty POST (curl -X POST).
        let doc = send(data, post_raw(uri, None, Vec::new()))
            .await
            .problem(415, "unsupported-media-type");
        let detail = doc["detail"].as_str().unwrap();
        assert!(detail.starts_with("the request has no body"), "{detail}");
        takes_both(detail);
        // The photograph's bytes as the body.
        for content_type in ["image/png", "application/octet-stream"] {
            let doc = send(data, post_raw(uri, Some(content_type), png.clone()))
                .await
                .problem(415, "unsupported-media-type");
            let detail = doc["detail"].as_str().unwrap();
            assert!(
                detail.contains(&format!("raw bytes ({content_type})")),
                "{detail}"
            );
            takes_both(detail);
        }
        // curl --data-binary @photo.png.
        let doc = send(
            data,
            post_raw(uri, Some("application/x-www-form-urlencoded"), png.clone()),
        )
        .await
        .problem(415, "unsupported-media-type");
        let detail = doc["detail"].as_str().unwrap();
        assert!(detail.contains("--data-binary"), "{detail}");
        takes_both(detail);
        for (content_type, said) in [
            (None, "the body has no Content-Type"),
            (Some("text/plain"), "the body is text/plain"),
            (
                Some("multipart/form-data"),
                "the body is multipart/form-data without a boundary",
            ),
        ] {
            let doc = send(data, post_raw(uri, content_type, png.clone()))
                .await
                .problem(415, "unsupported-media-type");
            let detail = doc["detail"].as_str().unwrap();
            assert!(detail.starts_with(said), "{detail}");
            takes_both(detail);
        }
    }
    // JSON that is not the request: each says what is wrong and what to send.
    let json_body = |body: &[u8]| post_raw("/v1/classify", Some("application/json"), body.to_vec());
    let cases: Vec<(Request<Body>, u16, &str, &[&str])> = vec![
        (
            json_body(b""),
            400,
            "malformed-request",
            &["empty", "{\"image\": \"<base64"],
        ),
        (
            json_body(b"{\"image\": "),
            400,
            "malformed-request",
            &["not valid JSON", "\"image\""],
        ),
        (
            json_body(b"[1, 2]"),
            422,
            "invalid-field",
            &["an array, not an object", "\"image\""],
        ),
        (
            post_json("/v1/classify", &json!({"image": "photo.jpg"})),
            422,
            "invalid-field",
            &["image is not base64", "base64 -w0 photo.jpg", "not a path"],
        ),
        (
            post_json("/v1/classify", &json!({"image": "%%%%"})),
            422,
            "invalid-field",
            &["image is not base64"],
        ),
        (
            post_json("/v1/classify", &json!({"image": ""})),
            422,
            "invalid-field",
            &["image is empty"],
        ),
        (
            post_json("/v1/classify", &json!({"image": 42})),
            422,
            "invalid-field",
            &["image must be a string", "base64"],
        ),
        (
            post_json("/v1/classify", &json!({"image": "data:image/png,rawtext"})),
            422,
            "invalid-field",
            &["data: URL must hold base64"],
        ),
        (
            post_json("/v1/classify", &json!({"white": 0.8})),
            422,
            "missing-field",
            &["image field is required"],
        ),
        (
            post_json("/v1/classify", &json!({"inputs": b64(&png)})),
            422,
            "unknown-field",
            &["unknown field \"inputs\"", "expected image, white"],
        ),
        (
            post_json("/v1/classify", &json!({"image": b64(&png), "white": true})),
            422,
            "invalid-field",
            &["white must be a number, not a boolean"],
        ),
        (
            post_json(
                "/v1/classify",
                &json!({"image": b64(&png), "white": "bright"}),
            ),
            422,
            "bad-white",
            &["white must be a finite number"],
        ),
        (
            post_json(
                "/v1/classify",
                &json!({"image": b64(&png), "white_rect": [1, 2, 3]}),
            ),
            422,
            "invalid-field",
            &["white_rect must be [x, y, w, h]"],
        ),
        (
            post_json("/v1/classify", &json!({"image": b64(&png), "include": [1]})),
            422,
            "invalid-field",
            &["include must be a list of strings"],
        ),
        (
            post_json(
                "/v1/classify",
                &json!({"image": b64(b"hello, not an image")}),
            ),
            415,
            "unsupported-image-format",
            &["not an image format known here", "expected PNG, JPEG, WebP"],
        ),
        // Locating takes the form only, and says where JSON goes.
        (
            post_json("/v1/locate", &json!({"image": b64(&png)})),
            415,
            "unsupported-media-type",
            &[
                "the body is JSON",
                "multipart/form-data",
                "-F image=@photo.jpg",
                "POST /v1/classify",
            ],
        ),
        (
            post_raw("/v1/locate", None, Vec::new()),
            415,
            "unsupported-media-type",
            &["the request has no body", "multipart/form-data"],
        ),
    ];
    for (request, status, slug, words) in cases {
        let doc = send(data, request).await.problem(status, slug);
        let detail = doc["detail"].as_str().unwrap();
        for word in words {
            assert!(detail.contains(word), "{word:?} not in {detail}");
        }
    }
    // A JSON white rectangle, as numbers or as the form's text, is the form's.
    let circle = json!({"cx": 99.5, "cy": 99.5, "r": 90});
    let with = |extra: Value| {
        let mut body = json!({"image": b64(&png)});
        for source in [&circle, &extra] {
            for (k, v) in source.as_object().unwrap() {
                body[k] = v.clone();
            }
        }
        post_json("/v1/classify", &body)
    };
    let by_numbers = send(data, with(json!({"white_rect": [90, 90, 20, 20]})))
        .await
        .json_of(200);
    let by_text = send(data, with(json!({"white_rect": "90,90,20,20"})))
        .await
        .json_of(200);
    assert_eq!(by_numbers["white"]["method"], "white_rect", "{by_numbers}");
    assert_eq!(comparable(by_numbers), comparable(by_text));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_the_body_limit_the_answer_names_the_limit_and_its_setting() {
    let mut cfg = config(&models_copy("body-limit"));
    cfg.body_limit = 200_000;
    let server = start(cfg);
    let data = &server.data;
    let big = vec![7u8; 300_000];
    let (form_type, form) = multipart(&[("image", Part::File(&big))]);
    let json = serde_json::to_vec(&json!({"image": b64(&big)})).unwrap();
    let declared = |uri: &str, content_type: &str, body: &[u8]| {
        Request::post(uri)
            .header("content-type", content_type)
            .header("content-length", body.len())
            .body(Body::from(body.to_vec()))
            .unwrap()
    };
    let requests = [
        declared("/v1/classify", &form_type, &form),
        post_raw("/v1/classify", Some(&form_type), form.clone()),
        declared("/v1/classify", "application/json", &json),
        post_raw("/v1/classify", Some("application/json"), json.clone()),
        post_raw("/v1/locate", Some(&form_type), form.clone()),
        post_raw(
            "/v2/models/ward6/infer",
            Some("application/json"),
            json.clone(),
        ),
    ];
    for request in requests {
        let what = format!("{} {:?}", request.uri(), request.headers());
        let doc = send(data, request).await.problem(413, "body-too-large");
        let detail = doc["detail"].as_str().unwrap();
        for words in [
            "195.3 KiB",
            "200000 bytes",
            "--body-limit",
            "REFLECTANCE_BODY_LIMIT",
        ] {
            assert!(detail.contains(words), "{what}: {words:?} not in {detail}");
        }
    }
}

/// The same label, and the same probabilities to 1e-9.
fn same_answer(a: &Value, b: &Value) {
    assert_eq!(a["label"], b["label"], "{a}");
    let p = |doc: &Value| -> Vec<(String, f64)> {
        let list = doc["probabilities"].as_array().unwrap();
        list.iter()
            .map(|p| (p["label"].to_string(), p["p"].as_f64().unwrap()))
            .collect()
    };
    let (pa, pb) = (p(a), p(b));
    assert_eq!(pa.len(), pb.len());
    for ((la, va), (lb, vb)) in pa.iter().zip(&pb) {
        assert!(la == lb && (va - vb).abs() < 1e-9, "{pa:?} against {pb:?}");
    }
}

/// The sphere of [`common::sphere_png`] as a lossless WebP (the same 8-bit samples).
fn webp_of(png: &[u8]) -> Vec<u8> {
    let image = image::load_from_memory(png).unwrap().to_luma8();
    let mut out = Vec::new();
    image::codecs::webp::WebPEncoder::new_lossless(&mut out)
        .encode(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::L8,
        )
        .unwrap();
    assert!(out.starts_with(b"RIFF") && &out[8..12] == b"WEBP");
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn webp_is_read_and_formats_not_read_are_named() {
    let server = start(config(&models_copy("formats")));
    let data = &server.data;
    let png = common::sphere_png(200, 90.0);
    let webp = webp_of(&png);
    let circle = |image| {
        vec![
            ("image", Part::File(image)),
            ("white", Part::Text("0.8")),
            ("cx", Part::Text("99.5")),
            ("cy", Part::Text("99.5")),
            ("r", Part::Text("90")),
        ]
    };
    // WebP: the same pixels answer as the PNG does, by the form and by JSON; located too.
    let by_png = send(data, post_multipart("/v1/classify", &circle(&png)))
        .await
        .json_of(200);
    let by_webp = send(data, post_multipart("/v1/classify", &circle(&webp)))
        .await
        .json_of(200);
    // WebP holds colour: the grey samples come back as R = G = B, whose luminance is the
    // grey level to the last bits of a double.
    same_answer(&by_webp, &by_png);
    let as_json = json!({"image": b64(&webp), "white": 0.8, "cx": 99.5, "cy": 99.5, "r": 90});
    let by_json = send(data, post_json("/v1/classify", &as_json))
        .await
        .json_of(200);
    same_answer(&by_json, &by_png);
    let located = send(
        data,
        post_multipart("/v1/locate", &[("image", Part::File(&webp))]),
    )
    .await
    .json_of(200);
    assert_eq!(
        (located["width"].clone(), located["height"].clone()),
        (json!(200), json!(200))
    );

    // Formats recognized but not read: named, with the formats read and what to do.
    let gif: &[u8] = b"GIF89a\x01\0\x01\0\x80\0\0\xff\xff\xff\0\0\0!\xf9\x04\x01\0\0\0\0,\0\0\0\0\x01\0\x01\0\0\x02\x02D\x01\0;";
    let mut bmp = b"BM".to_vec();
    for v in [58u32, 0, 54, 40, 1, 1] {
        bmp.extend(v.to_le_bytes());
    }
    bmp.extend([1, 0, 24, 0]);
    bmp.extend([0u8; 24]);
    bmp.extend([255, 255, 255, 0]);
    let heic = b"\0\0\0\x18ftypheic\0\0\0\0mif1heic\0\0\0\x0cmeta";
    let base64_text = b64(&png).into_bytes();
    let cases: [(&[u8], &[&str]); 4] = [
        (gif, &["a GIF image", "convert it to PNG or JPEG"]),
        (&bmp, &["a BMP image", "convert it to PNG or JPEG"]),
        (
            heic,
            &[
                "a HEIC/HEIF image",
                "heif-convert photo.heic photo.jpg",
                "as JPEG",
            ],
        ),
        (&base64_text, &["base64 text of a PNG image", "JSON body"]),
    ];
    for (bytes, words) in cases {
        let by_form = send(data, post_multipart("/v1/classify", &circle(bytes))).await;
        let by_json = send(
            data,
            post_json("/v1/classify", &json!({"image": b64(bytes), "white": 0.8})),
        )
        .await;
        let located = send(
            data,
            post_multipart("/v1/locate", &[("image", Part::File(bytes))]),
        )
        .await;
        for answer in [by_form, by_json, located] {
            let doc = answer.problem(415, "unsupported-image-format");
            let detail = doc["detail"].as_str().unwrap();
            let expected = "expected PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM or OpenEXR";
            for word in words.iter().chain([&expected]) {
                assert!(detail.contains(word), "{word:?} not in {detail}");
            }
        }
    }
}
