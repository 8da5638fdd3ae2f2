//! Helpers of the server tests: an in-process server on the real routers, multipart
//! bodies, a tiny rendered dataset and a model trained on it.

use axum::body::Body;
use axum::http::{Request, Response};
use reflectance::ServerConfig as Config;
use reflectance::SharedState;
use reflectance::{admin_router, build_state, data_router, load_models};
use reflectance_core::classify::{ClassifierKind, TrainSpec};
use reflectance_core::dataset::{self, FeatureTable};
use reflectance_core::decode::DecodeOptions;
use reflectance_core::decode::rgbe;
use reflectance_core::features::{Extractor, FeatureConfig};
use reflectance_core::learn::FeatureSet;
use reflectance_core::model::registry::Registry;
use reflectance_core::model::train::{EstimatorData, TrainOptions, train};
use reflectance_render::Quality;
use reflectance_render::batch::{self, Augment, BatchSpec};
use reflectance_render::envmap::EnvMap;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use tower::ServiceExt;

pub const TOKEN: &str = "test-token-0123456789abcdef";

/// A loopback port nobody listens on (right now).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reflectance-srv-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Copy a directory tree.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Four small synthetic light probes (lat-long 64×32): sky gradients, a sun, windows.
pub fn write_probes(dir: &Path) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let maps = [
        EnvMap::from_fn(64, 32, |d| 0.3 + d.y.max(0.0) + 0.2 * (6.0 * d.x).sin()),
        EnvMap::from_fn(64, 32, |d| {
            0.5 + 0.4 * d.x + 0.1 * (9.0 * d.z).cos() + if d.y > 0.9 { 30.0 } else { 0.0 }
        }),
        EnvMap::from_fn(64, 32, |d| {
            0.2 + 0.6 * (0.5 + 0.5 * d.y) + if (d.x * 4.0).sin() > 0.8 { 3.0 } else { 0.0 }
        }),
        EnvMap::from_fn(64, 32, |d| {
            0.4 + 0.3 * (5.0 * d.y).cos().abs() + if d.z > 0.95 { 20.0 } else { 0.0 }
        }),
    ];
    maps.iter()
        .enumerate()
        .map(|(k, map)| {
            let path = dir.join(format!("probe{k}.hdr"));
            std::fs::write(
                &path,
                rgbe::write_flat(map.width, map.height, &map.luminance),
            )
            .unwrap();
            path
        })
        .collect()
}

pub const CLASSES_JSON: &str = r#"{"classes": [
    {"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
    {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
    {"name": "dark", "rho_d": 0.08, "rho_s": 0.0, "alpha": 0.0}]}"#;

/// A rendered dataset: probes 0–2 (training) and probe 3 (held out), 3 classes, 96 px.
pub struct Fixture {
    pub dir: PathBuf,
    /// Registry with `ward6` version 1 trained on probes 0–2.
    pub models: PathBuf,
    /// The held-out renderings: (PFM bytes, class, white).
    pub held_out: Vec<(Vec<u8>, String, f64)>,
}

fn render(dir: &Path, probes: Vec<PathBuf>, out: &str) -> PathBuf {
    let classes_path = dir.join("classes.json");
    std::fs::write(&classes_path, CLASSES_JSON).unwrap();
    let spec = BatchSpec {
        probes,
        classes: reflectance_core::material::load_classes(&classes_path).unwrap(),
        out: dir.join(out),
        size: 96,
        seed: 1,
        quality: Quality::default(),
        augment: Augment::default(),
        shard: None,
    };
    batch::render_dataset(&spec).unwrap().manifest
}

/// Built once per test binary.
pub fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = temp_dir("fixture");
        let probes = write_probes(&dir.join("probes"));
        let train_manifest = render(&dir, probes[..3].to_vec(), "train");
        let test_manifest = render(&dir, probes[3..].to_vec(), "test");
        let extractor = Extractor::new(FeatureConfig::default()).unwrap();
        let manifest = dataset::read_manifest(&train_manifest).unwrap();
        let table: FeatureTable =
            dataset::extract_manifest(&extractor, &manifest, &DecodeOptions::default()).unwrap();
        let classes = reflectance_core::material::load_classes(&dir.join("classes.json")).unwrap();
        let options = TrainOptions {
            name: "ward6".into(),
            spec: TrainSpec::new(FeatureSet::Named("hand6"), ClassifierKind::Svm),
            seed: 1,
            cross_validate: true,
            classes: Some(classes.clone()),
            preprocessing: Default::default(),
            images: Some(manifest.clone()),
            decode: Default::default(),
            // A Ward-parameter estimator beside the classifier (three materials only: it is
            // here for the answer's shape, not its accuracy; the small ridge is the quickest).
            estimator: Some(EstimatorData {
                table: table.clone(),
                label: "train/features.csv".into(),
                materials: classes,
                features: None,
                regression: reflectance_core::estimate::EstimatorOptions {
                    regressor: reflectance_core::estimate::Method::Ridge,
                    ridge_features: 50,
                    ridge_lambda: 1e-2,
                    ridge_gamma: None,
                },
                gamma: Some(1.0 / 6.0),
            }),
            no_white_references_only: false,
        };
        let mut model = train(&table, "train/manifest.csv", &options).unwrap().model;
        let models = dir.join("models");
        Registry::new(&models).publish(&mut model, &[]).unwrap();
        let test = dataset::read_manifest(&test_manifest).unwrap();
        let held_out = test
            .entries
            .iter()
            .map(|e| {
                (
                    std::fs::read(&e.file).unwrap(),
                    e.class.clone().unwrap(),
                    e.white.unwrap(),
                )
            })
            .collect();
        Fixture {
            dir,
            models,
            held_out,
        }
    })
}

/// A registry copied from the fixture's, private to one test.
pub fn models_copy(name: &str) -> PathBuf {
    let dir = temp_dir(name).join("models");
    copy_dir(&fixture().models, &dir);
    dir
}

pub struct TestServer {
    pub state: SharedState,
    pub data: axum::Router,
    pub admin: axum::Router,
}

pub fn config(models: &Path) -> Config {
    let mut config = Config::new(models, "ward6");
    config.cpu_threads = 2;
    config
}

/// A server on `config` with its models loaded.
pub fn start(config: Config) -> TestServer {
    let state = build_state(config).unwrap();
    load_models(&state).unwrap();
    TestServer {
        data: data_router(state.clone()),
        admin: admin_router(state.clone()),
        state,
    }
}

/// A multipart part.
pub enum Part<'a> {
    Text(&'a str),
    File(&'a [u8]),
}

pub fn multipart(fields: &[(&str, Part)]) -> (String, Vec<u8>) {
    let boundary = "----reflectance-test-boundary-7d93";
    let mut body = Vec::new();
    for (name, part) in fields {
        body.extend(format!("--{boundary}\r\n").as_bytes());
        match part {
            Part::Text(t) => {
                body.extend(
                    format!("Content-Disposition: form-data; name=\"{name}\"\r\n\r\n{t}\r\n")
                        .as_bytes(),
                );
            }
            Part::File(bytes) => {
                body.extend(
                    format!(
                        "Content-Disposition: form-data; name=\"{name}\"; filename=\"{name}.bin\"\r\n\
                         Content-Type: application/octet-stream\r\n\r\n"
                    )
                    .as_bytes(),
                );
                body.extend(*bytes);
                body.extend(b"\r\n");
            }
        }
    }
    body.extend(format!("--{boundary}--\r\n").as_bytes());
    (format!("multipart/form-data; boundary={boundary}"), body)
}

pub fn post_multipart(uri: &str, fields: &[(&str, Part)]) -> Request<Body> {
    let (content_type, body) = multipart(fields);
    Request::post(uri)
        .header("content-type", content_type)
        .body(Body::from(body))
        .unwrap()
}

pub fn get(uri: &str) -> Request<Body> {
    Request::get(uri).body(Body::empty()).unwrap()
}

pub fn with_token(mut request: Request<Body>, token: &str) -> Request<Body> {
    request
        .headers_mut()
        .insert("authorization", format!("Bearer {token}").parse().unwrap());
    request
}

pub fn post_json(uri: &str, body: &Value) -> Request<Body> {
    Request::post(uri)
        .header("content-type", "application/json")
        .body(Body::from(serde_json::to_vec(body).unwrap()))
        .unwrap()
}

pub struct Answer {
    pub status: u16,
    pub headers: axum::http::HeaderMap,
    pub body: Vec<u8>,
}

impl Answer {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.body)
            .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&self.body)))
    }

    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.get(name).and_then(|v| v.to_str().ok())
    }

    /// Assert the answer's `status` (its body the message when not); returns its JSON.
    pub fn json_of(&self, status: u16) -> Value {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        self.json()
    }

    /// Assert a problem+json answer of `status` and type slug; returns the document.
    pub fn problem(&self, status: u16, slug: &str) -> Value {
        assert_eq!(
            self.status,
            status,
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        assert_eq!(
            self.header("content-type"),
            Some("application/problem+json"),
            "{}",
            String::from_utf8_lossy(&self.body)
        );
        let doc = self.json();
        assert_eq!(
            doc["type"],
            format!("urn:reflectance:problem:{slug}"),
            "{doc}"
        );
        assert_eq!(doc["status"], status);
        assert!(doc["title"].as_str().is_some_and(|t| !t.is_empty()));
        assert!(doc["detail"].as_str().is_some_and(|t| !t.is_empty()));
        let id = doc["request_id"].as_str().unwrap();
        assert!(!id.is_empty());
        assert_eq!(self.header("x-request-id"), Some(id));
        doc
    }
}

pub async fn send(router: &axum::Router, request: Request<Body>) -> Answer {
    let response: Response<Body> = router.clone().oneshot(request).await.unwrap();
    let status = response.status().as_u16();
    let headers = response.headers().clone();
    let body = axum::body::to_bytes(response.into_body(), usize::MAX)
        .await
        .unwrap()
        .to_vec();
    Answer {
        status,
        headers,
        body,
    }
}
