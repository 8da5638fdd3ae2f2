//! Objects of any shape (issue #44): a photograph and its normal map through the real
//! router, classified as their equivalent sphere.

use crate::common;

use common::server::{
    CLASSES_JSON, Part, config, fixture, models_copy, post_multipart, send, start, temp_dir,
    write_probes,
};
use reflectance_render::Quality;
use reflectance_render::batch::{self, Augment, BatchSpec};
use reflectance_render::shapes::ShapeSpec;

/// An object's image and normals, its class and white.
type Rendered = (Vec<u8>, Vec<u8>, String, f64);

/// Tori rendered under the fixture's held-out probe: (image, normals, class, white) each.
/// Rendered once per test process: the tests that read them run in parallel, and each
/// rendering into the same directory would remove the files another is reading.
pub(crate) fn held_out_tori() -> Vec<Rendered> {
    static TORI: std::sync::OnceLock<Vec<Rendered>> = std::sync::OnceLock::new();
    TORI.get_or_init(render_tori).clone()
}

fn render_tori() -> Vec<Rendered> {
    let dir = temp_dir("tori");
    let probes = write_probes(&dir.join("probes"));
    let classes = dir.join("classes.json");
    std::fs::write(&classes, CLASSES_JSON).unwrap();
    let spec = BatchSpec {
        probes: probes[3..].to_vec(),
        classes: reflectance_core::material::load_classes(&classes).unwrap(),
        out: dir.join("tori"),
        size: 128,
        seed: 1,
        quality: Quality::default(),
        augment: Augment {
            shape: ShapeSpec::Torus,
            ..Augment::default()
        },
        shard: None,
    };
    let manifest = batch::render_dataset(&spec).unwrap().manifest;
    let manifest = reflectance_core::dataset::read_manifest(&manifest).unwrap();
    manifest
        .entries
        .iter()
        .map(|e| {
            let normals = &e.normals.as_ref().unwrap().file;
            (
                std::fs::read(&e.file).unwrap(),
                std::fs::read(normals).unwrap(),
                e.class.clone().unwrap(),
                e.white.unwrap(),
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_object_and_its_normals_are_classified_as_their_equivalent_sphere() {
    let server = start(config(&models_copy("shapes")));
    let _ = fixture();
    for (image, normals, class, white) in held_out_tori() {
        let white = white.to_string();
        let answer = send(
            &server.data,
            post_multipart(
                "/v1/classify",
                &[
                    ("image", Part::File(&image)),
                    ("white", Part::Text(&white)),
                    ("normals", Part::File(&normals)),
                    ("include", Part::Text("images")),
                ],
            ),
        )
        .await;
        let doc = answer.json_of(200);
        assert_eq!(doc["label"], class.as_str(), "{doc}");
        assert_eq!(doc["geometry"]["method"], "normals", "{doc}");
        let observed = doc["observed_fraction"].as_f64().unwrap();
        assert!((0.9..=1.0).contains(&observed), "{observed}");
        // The hole's saddles are left out and said to be; the set is the 99.9 % one.
        let hollow = doc["not_convex_fraction"].as_f64().unwrap();
        assert!((0.1..0.35).contains(&hollow), "{hollow}");
        // Seen straight on, its convex outside is in no shadow of its own.
        let shadowed = doc["shadowed_fraction"].as_f64().unwrap();
        assert!(shadowed < 0.02, "{shadowed}");
        assert_eq!(doc["prediction_set"]["coverage"], 0.999, "{doc}");
        let sphere = doc["images"]["equivalent_sphere"].as_str().unwrap();
        assert!(sphere.starts_with("data:image/png;base64,"), "{sphere}");
    }
}

/// A mask of the columns `columns` of a 128² image, as a PNG.
fn columns_mask(columns: std::ops::Range<u32>) -> Vec<u8> {
    let mask = image::GrayImage::from_fn(128, 128, |x, _| match columns.contains(&x) {
        true => image::Luma([255]),
        false => image::Luma([0]),
    });
    let mut png = Vec::new();
    mask.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// A request that must be refused: its photograph, its other fields, and what the refusal
/// must say.
type Refusal<'a> = (&'a [u8], Vec<(&'a str, Part<'a>)>, &'a str);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_normals_are_refused_with_what_to_fix() {
    let server = start(config(&models_copy("shapes-bad")));
    let tori = held_out_tori();
    let (image, normals, _, white) = &tori[0];
    let white = white.to_string();
    let (garbage, small, sliver) = (
        b"not a normal map".to_vec(),
        common::sphere_png(96, 40.0),
        columns_mask(62..66),
    );
    let cases: [Refusal; 4] = [
        (
            image,
            vec![
                ("normals", Part::File(normals)),
                ("cx", Part::Text("64")),
                ("cy", Part::Text("64")),
                ("r", Part::Text("50")),
            ],
            "not both",
        ),
        (
            image,
            vec![("normals", Part::File(&garbage))],
            "PNG or an OpenEXR",
        ),
        (
            &small,
            vec![("normals", Part::File(normals))],
            "128×128 but the photograph is 96×96",
        ),
        (
            image,
            vec![
                ("normals", Part::File(normals)),
                ("mask", Part::File(&sliver)),
            ],
            "the features need at least 20 %",
        ),
    ];
    for (photo, extra, wanted) in cases {
        let mut fields = vec![("image", Part::File(photo)), ("white", Part::Text(&white))];
        fields.extend(extra);
        let doc = send(&server.data, post_multipart("/v1/classify", &fields))
            .await
            .problem(422, "bad-geometry");
        let detail = doc["detail"].as_str().unwrap();
        assert!(detail.contains(wanted), "{wanted}: {doc}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_open_inference_protocol_takes_normals_as_an_input() {
    use super::v2::{binary_request, framed};
    let server = start(config(&models_copy("shapes-v2")));
    let metadata = send(&server.data, common::server::get("/v2/models/ward6")).await;
    let inputs = metadata.json()["inputs"].clone();
    assert!(
        inputs
            .as_array()
            .unwrap()
            .iter()
            .any(|i| i["name"] == "normals" && i["datatype"] == "BYTES"),
        "{inputs}"
    );
    let tori = held_out_tori();
    let (image, normals, class, white) = &tori[0];
    let (image, normals) = (framed(image), framed(normals));
    let head = serde_json::json!({
        "inputs": [
            {"name": "image", "datatype": "BYTES", "shape": [1],
             "parameters": {"binary_data_size": image.len()}},
            {"name": "normals", "datatype": "BYTES", "shape": [1],
             "parameters": {"binary_data_size": normals.len()}},
            {"name": "white", "datatype": "FP64", "shape": [1], "data": [white]},
        ],
        "outputs": [{"name": "label"}, {"name": "in_domain"}],
    });
    let binary = [image.as_slice(), normals.as_slice()].concat();
    let answer = send(
        &server.data,
        binary_request("/v2/models/ward6/infer", &head, &binary),
    )
    .await;
    let doc = answer.json_of(200);
    assert_eq!(doc["outputs"][0]["data"][0], class.as_str(), "{doc}");
}
