//! The OpenAPI contract: the committed `openapi.yaml` is exactly the document generated
//! from the code (regenerate with `REFLECTANCE_UPDATE_OPENAPI=1 cargo test --release --test
//! server_openapi`), it is what the server serves, and every documented operation is
//! routed by the real routers.

use crate::common;

use axum::body::Body;
use axum::http::{Method, Request};
use common::server::{TOKEN, config, get, models_copy, send, start, temp_dir, with_token};
use serde_json::Value;
use std::path::Path;

fn committed_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("openapi.yaml")
}

#[test]
fn committed_document_matches_the_code() {
    let generated = reflectance::openapi_yaml();
    let path = committed_path();
    if std::env::var_os("REFLECTANCE_UPDATE_OPENAPI").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "openapi.yaml differs from the document generated from the code; regenerate it with\n  \
         REFLECTANCE_UPDATE_OPENAPI=1 cargo test --release --test server openapi"
    );
    assert!(generated.starts_with("openapi: 3.1"));
}

fn document() -> Value {
    let yaml = reflectance::openapi_yaml();
    // The generator also renders JSON; parse that form.
    let _ = yaml;
    serde_json::to_value(<reflectance::ApiDoc as utoipa::OpenApi>::openapi()).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_documented_operation_is_routed_and_served() {
    let data = temp_dir("openapi-data");
    let mut cfg = config(&models_copy("openapi"));
    cfg.admin_token = Some(TOKEN.into());
    cfg.data_dir = data.clone();
    cfg.jobs_dir = data.join("jobs");
    let server = start(cfg);

    // The served document is the committed one.
    let answer = send(
        &server.data,
        Request::get("/openapi.yaml").body(Body::empty()).unwrap(),
    )
    .await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.header("content-type"), Some("application/yaml"));
    assert_eq!(
        String::from_utf8(answer.body).unwrap(),
        reflectance::openapi_yaml()
    );

    // An asset's hashed name, as the page links it.
    let page = send(&server.data, get("/")).await;
    let page = String::from_utf8(page.body).unwrap();
    let asset = page
        .split("\"/assets/")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .expect("the page links an asset");

    let doc = document();
    let paths = doc["paths"].as_object().unwrap();
    let mut operations = 0;
    for (path, item) in paths {
        let concrete = path
            .replace("{name}", "ward6")
            .replace("{version}", "1")
            .replace("{id}", "no-such-job")
            .replace("{file}", asset);
        for method in ["get", "post", "delete", "put", "patch"] {
            let Some(op) = item.get(method) else { continue };
            operations += 1;
            let admin = path.starts_with("/admin/");
            let router = if admin { &server.admin } else { &server.data };
            let mut request = Request::builder()
                .method(Method::from_bytes(method.to_uppercase().as_bytes()).unwrap())
                .uri(&concrete)
                .body(Body::empty())
                .unwrap();
            if admin {
                request = with_token(request, TOKEN);
            }
            let answer = send(router, request).await;
            let documented: Vec<u16> = op["responses"]
                .as_object()
                .unwrap()
                .keys()
                .map(|k| k.parse().unwrap())
                .collect();
            assert!(
                documented.contains(&answer.status) || [408, 413].contains(&answer.status),
                "{method} {concrete}: status {} not documented ({documented:?}): {}",
                answer.status,
                String::from_utf8_lossy(&answer.body)
            );
            if answer.status >= 400 {
                let problem = answer.json();
                assert_ne!(
                    problem["type"], "urn:reflectance:problem:not-found",
                    "{method} {path} is not routed"
                );
                assert_ne!(
                    problem["type"], "urn:reflectance:problem:method-not-allowed",
                    "{method} {path}"
                );
            }
            assert!(op["operationId"].is_string(), "{method} {path}");
        }
    }
    assert_eq!(operations, 35);
}

/// Every property a response carries is in its schema, and every required one is there.
fn check_object(doc: &Value, schema: &Value, value: &Value, at: &str) {
    let schema = resolve(doc, schema);
    if let Some(variants) = schema.get("oneOf").and_then(Value::as_array) {
        // Nullable (`oneOf: [null, X]`).
        if value.is_null() {
            return;
        }
        let inner = variants
            .iter()
            .find(|v| v.get("type") != Some(&Value::from("null")))
            .unwrap();
        return check_object(doc, inner, value, at);
    }
    match value {
        Value::Object(map) => {
            let props = schema["properties"]
                .as_object()
                .unwrap_or_else(|| panic!("{at}: no properties in {schema}"));
            for key in map.keys() {
                assert!(props.contains_key(key), "{at}.{key} is not in the schema");
                check_object(doc, &props[key], &map[key], &format!("{at}.{key}"));
            }
            for required in schema["required"].as_array().into_iter().flatten() {
                assert!(
                    map.contains_key(required.as_str().unwrap()),
                    "{at}: required {required} missing"
                );
            }
        }
        Value::Array(items) => {
            if let Some(item_schema) = schema.get("items") {
                for (i, item) in items.iter().enumerate() {
                    check_object(doc, item_schema, item, &format!("{at}[{i}]"));
                }
            }
        }
        _ => {}
    }
}

fn resolve<'a>(doc: &'a Value, schema: &'a Value) -> &'a Value {
    match schema.get("$ref").and_then(Value::as_str) {
        Some(r) => {
            let name = r.rsplit('/').next().unwrap();
            &doc["components"]["schemas"][name]
        }
        None => schema,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn responses_follow_their_schemas() {
    let server = start(config(&models_copy("openapi-schemas")));
    let doc = document();
    let png = common::sphere_png(200, 90.0);
    let request = common::server::post_multipart(
        "/v1/classify",
        &[
            ("image", common::server::Part::File(&png)),
            ("include", common::server::Part::Text("features,explain")),
        ],
    );
    let answer = send(&server.data, request).await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let schema = &doc["paths"]["/v1/classify"]["post"]["responses"]["200"]["content"]["application/json"]
        ["schema"];
    check_object(&doc, schema, &answer.json(), "classify");
    let problem = send(
        &server.data,
        Request::get("/v1/models/nope").body(Body::empty()).unwrap(),
    )
    .await;
    let schema = &doc["paths"]["/v1/models/{name}"]["get"]["responses"]["404"]["content"]["application/problem+json"]
        ["schema"];
    check_object(&doc, schema, &problem.json(), "problem");
    let detail = send(
        &server.data,
        Request::get("/v1/models/ward6")
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    let schema = &doc["paths"]["/v1/models/{name}"]["get"]["responses"]["200"]["content"]["application/json"]
        ["schema"];
    check_object(&doc, schema, &detail.json(), "model");
}

#[test]
fn the_jobs_feature_set_names_every_named_set() {
    fn features_description(schema: &Value) -> Option<&str> {
        if let Some(text) = schema["properties"]["features"]["description"].as_str() {
            return Some(text);
        }
        let parts = schema["allOf"].as_array()?;
        parts.iter().find_map(features_description)
    }
    let doc = document();
    let text = features_description(&doc["components"]["schemas"]["LearnParams"])
        .expect("LearnParams documents `features`");
    for set in reflectance_core::features::NAMED_SETS {
        assert!(
            text.contains(set),
            "the job's `features` does not name {set}"
        );
    }
}
