//! The Open Inference Protocol (KServe V2 REST) against the real router: metadata,
//! health, versions, inference with JSON tensors and with the binary tensor data
//! extension, the outputs filter, compressed bodies, and errors in the protocol's shape.
//! (tests/clients/ runs the protocol's reference client against the real binary.)

use crate::common;

use axum::body::Body;
use axum::http::Request;
use base64::Engine;
use common::server::{Answer, config, fixture, get, models_copy, post_json, send, start};
use reflectance_core::model::registry::Registry;
use serde_json::{Value, json};
use std::io::Write;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kserve_v2_protocol() {
    let server = start(config(&models_copy("v2")));
    let data = &server.data;
    let meta = send(data, get("/v2")).await.json();
    assert_eq!(meta["name"], "reflectance");
    assert_eq!(
        send(data, get("/v2/health/live")).await.json(),
        json!({"live": true})
    );
    assert_eq!(
        send(data, get("/v2/health/ready")).await.json(),
        json!({"ready": true})
    );
    let model = send(data, get("/v2/models/ward6")).await.json();
    assert_eq!(model["versions"], json!(["1"]));
    assert_eq!(
        model["outputs"][1],
        json!({"name": "probabilities", "datatype": "FP64", "shape": [3]})
    );
    // The fixture model estimates the Ward parameters: its outputs say so.
    let names: Vec<&str> = model["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "label",
            "probabilities",
            "classes",
            "prediction_set",
            "in_domain",
            "ward",
            "specular_fraction",
            "colour"
        ]
    );
    assert_eq!(
        send(data, get("/v2/models/ward6/ready")).await.json(),
        json!({"name": "ward6", "ready": true})
    );
    send(data, get("/v2/models/nope"))
        .await
        .problem(404, "model-not-found");
    send(data, get("/v2/models/nope/ready"))
        .await
        .problem(404, "model-not-found");

    for (image, class, white) in &fixture().held_out {
        let b64 = base64::engine::general_purpose::STANDARD.encode(image);
        let number = |name: &str, v: f64| json!({"name": name, "datatype": "FP64", "shape": [1], "data": [v]});
        let request = json!({
            "id": "req-1",
            "inputs": [
                {"name": "image", "datatype": "BYTES", "shape": [1], "data": [b64]},
                number("white", *white), number("cx", 47.5), number("cy", 47.5),
                number("r", 43.63636363636363),
            ]
        });
        let answer = send(data, post_json("/v2/models/ward6/infer", &request)).await;
        assert_eq!(
            answer.status,
            200,
            "{}",
            String::from_utf8_lossy(&answer.body)
        );
        assert_eq!(answer.header("x-model-version"), Some("1"));
        let doc = answer.json();
        assert_eq!(doc["model_name"], "ward6");
        assert_eq!(doc["model_version"], "1");
        assert_eq!(doc["id"], "req-1");
        assert_eq!(doc["outputs"][0]["name"], "label");
        assert_eq!(doc["outputs"][0]["data"][0], class.as_str(), "{doc}");
        let p: Vec<f64> = doc["outputs"][1]["data"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(p.len(), 3);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert_eq!(doc["outputs"][2]["data"].as_array().unwrap().len(), 3);
        // The prediction set (the label first) and the domain verdict.
        let set = &doc["outputs"][3];
        assert_eq!(set["name"], "prediction_set");
        assert_eq!(set["data"][0], class.as_str(), "{doc}");
        assert_eq!(set["shape"], json!([set["data"].as_array().unwrap().len()]));
        let domain = &doc["outputs"][4];
        assert_eq!(
            (&domain["name"], &domain["datatype"]),
            (&json!("in_domain"), &json!("BOOL"))
        );
        assert!(domain["data"][0].is_boolean(), "{doc}");
        // The estimate: rows ρd, ρs, α of (value, low, high).
        let ward = &doc["outputs"][5];
        assert_eq!(
            (&ward["name"], &ward["shape"]),
            (&json!("ward"), &json!([3, 3]))
        );
        let w: Vec<f64> = ward["data"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        for row in w.chunks(3) {
            assert!(row[1] <= row[0] && row[0] <= row[2], "{ward}");
        }
        let fraction = &doc["outputs"][6];
        assert_eq!(
            (&fraction["name"], &fraction["shape"]),
            (&json!("specular_fraction"), &json!([3]))
        );
    }
    let bad = |inputs: Value| post_json("/v2/models/ward6/infer", &json!({"inputs": inputs}));
    send(
        data,
        bad(json!([{"name": "image", "datatype": "BYTES", "shape": [1], "data": ["***"]}])),
    )
    .await
    .problem(422, "invalid-field");
    send(
        data,
        bad(json!([{"name": "image", "datatype": "FP32", "shape": [1], "data": [1.0]}])),
    )
    .await
    .problem(422, "invalid-field");
    send(
        data,
        bad(json!([{"name": "white", "datatype": "FP64", "shape": [1], "data": [0.5]}])),
    )
    .await
    .problem(422, "missing-field");
    send(
        data,
        bad(json!([{"name": "colour", "datatype": "FP64", "shape": [1], "data": [0.5]}])),
    )
    .await
    .problem(422, "unknown-field");
    let garbage = base64::engine::general_purpose::STANDARD.encode(b"not an image");
    send(
        data,
        bad(json!([{"name": "image", "datatype": "BYTES", "shape": [1], "data": [garbage]}])),
    )
    .await
    .problem(415, "unsupported-image-format");
    send(
        data,
        post_json("/v2/models/ward6/infer", &json!({"inputs": "x"})),
    )
    .await
    .problem(422, "invalid-field");
    let not_json = Request::post("/v2/models/ward6/infer")
        .header("content-type", "application/json")
        .body(Body::from("{nope"))
        .unwrap();
    send(data, not_json).await.problem(400, "malformed-request");
    // tritonclient sends no content type: the body is read as the protocol's JSON.
    let untyped = Request::post("/v2/models/ward6/infer")
        .body(Body::from("{}"))
        .unwrap();
    let doc = send(data, untyped).await.problem(422, "invalid-field");
    assert!(doc["detail"].as_str().unwrap().contains("inputs"), "{doc}");
    let text = Request::post("/v2/models/ward6/infer")
        .header("content-type", "text/plain")
        .body(Body::from("{}"))
        .unwrap();
    send(data, text)
        .await
        .problem(415, "unsupported-media-type");
}

/// The binary tensor data extension's framing: a BYTES element is its 4-byte
/// little-endian length, then its bytes.
pub(crate) fn framed(element: &[u8]) -> Vec<u8> {
    let mut out = (element.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(element);
    out
}

/// A request of JSON and binary data, as tritonclient sends it (no content type).
pub(crate) fn binary_request(uri: &str, head: &Value, binary: &[u8]) -> Request<Body> {
    let mut body = serde_json::to_vec(head).unwrap();
    let length = body.len();
    body.extend_from_slice(binary);
    Request::post(uri)
        .header("inference-header-content-length", length.to_string())
        .body(Body::from(body))
        .unwrap()
}

/// (JSON part, binary part) of an answer that used the binary extension.
fn split_answer(answer: &Answer) -> (Value, Vec<u8>) {
    let length: usize = answer
        .header("inference-header-content-length")
        .expect("a binary answer announces its JSON's length")
        .parse()
        .unwrap();
    (
        serde_json::from_slice(&answer.body[..length]).unwrap(),
        answer.body[length..].to_vec(),
    )
}

fn fp64(name: &str, value: f64) -> Value {
    json!({"name": name, "datatype": "FP64", "shape": [1], "data": [value]})
}

/// Inputs with the image as binary data, the numbers in binary (white) and in JSON.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn binary_tensor_data_in_and_out() {
    let server = start(config(&models_copy("v2-binary")));
    let data = &server.data;
    let (image, class, white) = &fixture().held_out[0];
    let image_part = framed(image);
    let white_part = white.to_le_bytes();
    let head = json!({
        "inputs": [
            {"name": "image", "datatype": "BYTES", "shape": [1],
             "parameters": {"binary_data_size": image_part.len()}},
            {"name": "white", "datatype": "FP64", "shape": [1],
             "parameters": {"binary_data_size": 8}},
            fp64("cx", 47.5), fp64("cy", 47.5), fp64("r", 43.63636363636363),
        ],
        "outputs": [
            {"name": "label", "parameters": {"binary_data": true}},
            {"name": "probabilities", "parameters": {"binary_data": true}},
            {"name": "in_domain"},
        ],
    });
    let binary = [image_part.as_slice(), &white_part].concat();
    let answer = send(
        data,
        binary_request("/v2/models/ward6/infer", &head, &binary),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let (doc, raw) = split_answer(&answer);
    let outputs = doc["outputs"].as_array().unwrap();
    // Exactly what was asked for, in its order.
    let names: Vec<&str> = outputs
        .iter()
        .map(|o| o["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["label", "probabilities", "in_domain"]);
    let label_size = outputs[0]["parameters"]["binary_data_size"]
        .as_u64()
        .unwrap() as usize;
    assert_eq!(&raw[..label_size], framed(class.as_bytes()).as_slice());
    assert!(outputs[0].get("data").is_none());
    let p: Vec<f64> = raw[label_size..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(outputs[1]["parameters"]["binary_data_size"], 8 * p.len());
    assert_eq!(p.len(), 3);
    assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{p:?}");
    assert_eq!(raw.len(), label_size + 24);
    // Not asked as binary: JSON data.
    assert!(outputs[2]["data"][0].is_boolean(), "{doc}");

    // The request's binary_data_output: every output binary, BOOL as one byte.
    let mut all = head.clone();
    all["outputs"] = json!([{"name": "in_domain"}, {"name": "prediction_set"}]);
    all["parameters"] = json!({"binary_data_output": true});
    let answer = send(
        data,
        binary_request("/v2/models/ward6/infer", &all, &binary),
    )
    .await;
    let (doc, raw) = split_answer(&answer);
    assert_eq!(doc["outputs"][0]["parameters"]["binary_data_size"], 1);
    assert!(raw[0] <= 1);
    assert_eq!(&raw[1..5], &((class.len() as u32).to_le_bytes()));
    assert_eq!(
        &raw[5..5 + class.len()],
        class.as_bytes(),
        "the label heads its set"
    );

    // Binary data that does not add up is a malformed request, said in `error`.
    let short = send(
        data,
        binary_request("/v2/models/ward6/infer", &head, &binary[..100]),
    )
    .await;
    let problem = short.problem(400, "malformed-request");
    assert_eq!(problem["error"], problem["detail"]);
    assert!(
        problem["error"]
            .as_str()
            .unwrap()
            .contains("binary_data_size")
    );
    let extra = [binary.as_slice(), b"xx"].concat();
    send(
        data,
        binary_request("/v2/models/ward6/infer", &head, &extra),
    )
    .await
    .problem(400, "malformed-request");
    let lying = Request::post("/v2/models/ward6/infer")
        .header("inference-header-content-length", "99999")
        .body(Body::from("{}"))
        .unwrap();
    send(data, lying).await.problem(400, "malformed-request");
}

/// JSON data nested by the shape, integer and FP32 numbers, a gzip body, and the outputs
/// filter: the same answer as the flat request.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nested_data_other_number_types_and_compressed_bodies() {
    let server = start(config(&models_copy("v2-shapes")));
    let data = &server.data;
    let (image, class, white) = &fixture().held_out[1];
    let b64 = base64::engine::general_purpose::STANDARD.encode(image);
    let request = json!({
        "inputs": [
            {"name": "image", "datatype": "BYTES", "shape": [1, 1], "data": [[b64]]},
            {"name": "white", "datatype": "FP32", "shape": [1, 1], "data": [[*white as f32]]},
            {"name": "cx", "datatype": "INT32", "shape": [1], "data": [47]},
            fp64("cy", 47.5), fp64("r", 43.63636363636363),
        ],
        "outputs": [{"name": "label"}],
    });
    let answer = send(data, post_json("/v2/models/ward6/infer", &request)).await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    assert_eq!(answer.header("content-type"), Some("application/json"));
    let doc = answer.json();
    assert_eq!(doc["outputs"].as_array().unwrap().len(), 1, "{doc}");
    assert_eq!(doc["outputs"][0]["data"], json!([class]));

    for (encoding, body) in [
        ("gzip", {
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(&serde_json::to_vec(&request).unwrap()).unwrap();
            e.finish().unwrap()
        }),
        ("deflate", {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(&serde_json::to_vec(&request).unwrap()).unwrap();
            e.finish().unwrap()
        }),
    ] {
        let compressed = Request::post("/v2/models/ward6/infer")
            .header("content-encoding", encoding)
            .body(Body::from(body))
            .unwrap();
        let doc = send(data, compressed).await.json();
        assert_eq!(doc["outputs"][0]["data"], json!([class]), "{encoding}");
    }
    let not_gzip = Request::post("/v2/models/ward6/infer")
        .header("content-encoding", "gzip")
        .body(Body::from("{}"))
        .unwrap();
    send(data, not_gzip).await.problem(400, "malformed-request");

    // Shapes must hold their elements; outputs must exist; BYTES must be strings.
    let mut bad = request.clone();
    bad["inputs"][3]["shape"] = json!([2]);
    let doc = send(data, post_json("/v2/models/ward6/infer", &bad))
        .await
        .problem(422, "invalid-field");
    assert!(doc["error"].as_str().unwrap().contains("shape"), "{doc}");
    let mut bad = request.clone();
    bad["outputs"] = json!([{"name": "hue"}]);
    send(data, post_json("/v2/models/ward6/infer", &bad))
        .await
        .problem(422, "unknown-field");
    let mut bad = request.clone();
    bad["inputs"][0]["data"] = json!([[1]]);
    send(data, post_json("/v2/models/ward6/infer", &bad))
        .await
        .problem(422, "invalid-field");
}

/// Every version the registry holds has its routes; the active one answers the plain ones.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_version_has_its_routes() {
    let models = models_copy("v2-versions");
    let registry = Registry::new(&models);
    let mut second = registry.load("ward6", 1).unwrap();
    registry.publish(&mut second, &[]).unwrap();
    registry.set_active("ward6", 1).unwrap();
    let server = start(config(&models));
    let data = &server.data;
    let meta = send(data, get("/v2/models/ward6")).await.json();
    assert_eq!(meta["versions"], json!(["1", "2"]));
    for version in ["1", "2"] {
        let meta = send(data, get(&format!("/v2/models/ward6/versions/{version}")))
            .await
            .json();
        assert_eq!(meta["name"], "ward6");
        assert_eq!(
            send(
                data,
                get(&format!("/v2/models/ward6/versions/{version}/ready"))
            )
            .await
            .json(),
            json!({"name": "ward6", "ready": true})
        );
    }
    let (image, class, white) = &fixture().held_out[0];
    let b64 = base64::engine::general_purpose::STANDARD.encode(image);
    let request = json!({"inputs": [
        {"name": "image", "datatype": "BYTES", "shape": [1], "data": [b64]},
        fp64("white", *white), fp64("cx", 47.5), fp64("cy", 47.5), fp64("r", 43.63636363636363),
    ]});
    for (uri, version) in [
        ("/v2/models/ward6/infer", "1"),
        ("/v2/models/ward6/versions/2/infer", "2"),
        ("/v2/models/ward6/versions/1/infer", "1"),
    ] {
        let answer = send(data, post_json(uri, &request)).await;
        let doc = answer.json();
        assert_eq!(doc["model_version"], version, "{uri}");
        assert_eq!(answer.header("x-model-version"), Some(version));
        assert_eq!(doc["outputs"][0]["data"], json!([class]));
    }
    for missing in ["3", "0", "x", "01x"] {
        let doc = send(
            data,
            get(&format!("/v2/models/ward6/versions/{missing}/ready")),
        )
        .await
        .problem(404, "version-not-found");
        assert_eq!(doc["error"], doc["detail"]);
        send(
            data,
            post_json(
                &format!("/v2/models/ward6/versions/{missing}/infer"),
                &request,
            ),
        )
        .await
        .problem(404, "version-not-found");
    }
    send(data, get("/v2/models/nope/versions/1"))
        .await
        .problem(404, "model-not-found");
    // Off the protocol's routes, problems keep their own shape.
    let doc = send(data, get("/v1/models/nope"))
        .await
        .problem(404, "model-not-found");
    assert!(doc.get("error").is_none(), "{doc}");
}

/// The elements of output `name` of an answer, with its shape.
fn output<'a>(doc: &'a Value, name: &str) -> (&'a Value, &'a Vec<Value>) {
    let output = doc["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["name"] == name)
        .unwrap_or_else(|| panic!("no output {name} in {doc}"));
    (&output["shape"], output["data"].as_array().unwrap())
}

/// A batch (an image input of shape [N]) answers what N single requests answer, in order,
/// every output led by N; per-image inputs hold one value each or one for all; one bad
/// image fails the batch with a 400 that names it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn batches_answer_each_image_in_order() {
    let server = start(config(&models_copy("v2-batch")));
    let data = &server.data;
    let meta = send(data, get("/v2/models/ward6")).await.json();
    assert!(meta["max_batch_size"].as_u64().unwrap() >= 8, "{meta}");
    let held_out = &fixture().held_out;
    let n = held_out.len().min(6);
    assert!(
        n >= 3,
        "the fixture holds {} held-out images",
        held_out.len()
    );
    let b64 = |image: &[u8]| base64::engine::general_purpose::STANDARD.encode(image);
    let images: Vec<String> = held_out[..n].iter().map(|(i, ..)| b64(i)).collect();
    let whites: Vec<f64> = held_out[..n].iter().map(|(_, _, w)| *w).collect();
    let circle = [
        fp64("cx", 47.5),
        fp64("cy", 47.5),
        fp64("r", 43.63636363636363),
    ];
    let infer = |images: &[String], whites: &[f64]| {
        let mut inputs = vec![
            json!({"name": "image", "datatype": "BYTES", "shape": [images.len()], "data": images}),
            json!({"name": "white", "datatype": "FP64", "shape": [whites.len()], "data": whites}),
        ];
        inputs.extend(circle.iter().cloned());
        post_json("/v2/models/ward6/infer", &json!({ "inputs": inputs }))
    };

    let batch = send(data, infer(&images, &whites)).await.json_of(200);
    let (shape, labels) = output(&batch, "label");
    assert_eq!(shape, &json!([n, 1]));
    let (shape, p) = output(&batch, "probabilities");
    assert_eq!(shape, &json!([n, 3]));
    let (shape, _) = output(&batch, "ward");
    assert_eq!(shape, &json!([n, 3, 3]));
    let (set_shape, sets) = output(&batch, "prediction_set");
    let width = set_shape[1].as_u64().unwrap() as usize;
    for i in 0..n {
        let single = send(data, infer(&images[i..=i], &whites[i..=i]))
            .await
            .json_of(200);
        assert_eq!(labels[i], output(&single, "label").1[0], "image {i}");
        assert_eq!(
            &p[3 * i..3 * i + 3],
            output(&single, "probabilities").1.as_slice()
        );
        // Sets padded with empty names to the longest.
        let set = output(&single, "prediction_set").1;
        assert_eq!(&sets[width * i..width * i + set.len()], set.as_slice());
        assert!(
            sets[width * i + set.len()..width * (i + 1)]
                .iter()
                .all(|s| s == "")
        );
    }

    // One white for all images.
    let one_white = send(data, infer(&images, &whites[..1])).await.json_of(200);
    assert_eq!(output(&one_white, "label").1.len(), n);
    // Neither one per image nor one for all.
    let doc = send(data, infer(&images, &whites[..2]))
        .await
        .problem(422, "invalid-field");
    assert!(
        doc["detail"].as_str().unwrap().contains("\"white\""),
        "{doc}"
    );
    // One bad image: the batch fails, naming it.
    let mut bad = images.clone();
    bad[2] = b64(b"not an image");
    let doc = send(data, infer(&bad, &whites))
        .await
        .problem(400, "batch-item");
    let detail = doc["detail"].as_str().unwrap();
    assert!(
        detail.starts_with(&format!("image 2 of the batch of {n}")),
        "{doc}"
    );
    assert!(detail.contains("unsupported-image-format"), "{doc}");
    // More than the largest batch.
    let many = vec![images[0].clone(); meta["max_batch_size"].as_u64().unwrap() as usize + 1];
    send(data, infer(&many, &whites[..1]))
        .await
        .problem(422, "invalid-field");
}
