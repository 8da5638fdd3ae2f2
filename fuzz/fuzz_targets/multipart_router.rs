//! Request parsing through the real data-plane router (shipped `ward6` model): the first
//! byte picks the route and the content type, the rest is the body. Whatever the bytes,
//! the answer is a success or a problem+json client error — never a 5xx, never a panic.
#![no_main]

use axum::body::Body;
use axum::http::Request;
use libfuzzer_sys::fuzz_target;
use reflectance::ServerConfig as Config;
use reflectance::{build_state, data_router, load_models};
use std::sync::OnceLock;
use tower::ServiceExt;

struct Server {
    runtime: tokio::runtime::Runtime,
    router: axum::Router,
}

fn server() -> &'static Server {
    static SERVER: OnceLock<Server> = OnceLock::new();
    SERVER.get_or_init(|| {
        let models = concat!(env!("CARGO_MANIFEST_DIR"), "/../models");
        let mut config = Config::new(models, "ward6");
        config.cpu_threads = 1;
        config.body_limit = 1 << 20;
        config.limits.max_pixels = 1 << 20;
        let state = build_state(config).expect("state");
        load_models(&state).expect("the shipped models load");
        Server {
            runtime: tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("runtime"),
            router: data_router(state),
        }
    })
}

const ROUTES: [&str; 4] = [
    "/v1/classify",
    "/v1/models/ward6/classify",
    "/v1/models/ward6/classify?version=1",
    "/v2/models/ward6/infer",
];

const CONTENT_TYPES: [&str; 4] = [
    "multipart/form-data; boundary=B",
    "multipart/form-data; boundary=\"a b\"",
    "multipart/form-data",
    "application/json",
];

fuzz_target!(|data: &[u8]| {
    let Some((&selector, body)) = data.split_first() else {
        return;
    };
    let server = server();
    let uri = ROUTES[usize::from(selector & 3)];
    let content_type = CONTENT_TYPES[usize::from((selector >> 2) & 3)];
    let request = Request::post(uri)
        .header("content-type", content_type)
        .body(Body::from(body.to_vec()))
        .expect("request");
    let response = server
        .runtime
        .block_on(server.router.clone().oneshot(request))
        .expect("infallible");
    let status = response.status();
    assert!(
        !status.is_server_error(),
        "{uri} {content_type}: {status} for {} body bytes",
        body.len()
    );
    if status.is_client_error() {
        assert_eq!(
            response
                .headers()
                .get("content-type")
                .and_then(|v| v.to_str().ok()),
            Some("application/problem+json")
        );
    }
});
