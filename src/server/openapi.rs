//! The OpenAPI 3.1 document, generated from the handlers' annotations (utoipa). The
//! committed `openapi.yaml` must equal it: `tests/server/openapi.rs` fails otherwise, and
//! `REFLECTANCE_UPDATE_OPENAPI=1 cargo test --release --test server openapi` rewrites it.

use super::error::Problem;
use super::handlers::{
    admin, classify, datasets, health, input, locate, material, models, preview, v2, web,
};
use super::jobs;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{Object, Schema};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::openapi::server::Server;
use utoipa::{Modify, OpenApi};

struct Extras;

impl Modify for Extras {
    fn modify(&self, doc: &mut utoipa::openapi::OpenApi) {
        let components = doc.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(
                HttpBuilder::new()
                    .scheme(HttpAuthScheme::Bearer)
                    .description(Some(
                        "The admin token (--admin-token-file or REFLECTANCE_ADMIN_TOKEN)",
                    ))
                    .build(),
            ),
        );
        // The admin plane listens on its own address.
        for (path, item) in doc.paths.paths.iter_mut() {
            if path.starts_with("/admin/") {
                item.servers = Some(vec![Server::new("http://127.0.0.1:8081")]);
            }
        }
        // A learning job's training options are keys of its own (`ClassifierOptions`,
        // flattened and inlined).
        if let Some(schema) = components.schemas.get_mut("LearnParams") {
            own_properties(schema);
        }
    }
}

/// utoipa writes each flattened field as an item of an `allOf`, an inlined one as an object
/// of its own; serde reads its keys as the enclosing struct's. Merge the inlined objects
/// into the struct's own object (the last item), after the references of the other
/// flattened types: one object of the keys at that level, as a reader expects them.
fn own_properties(schema: &mut RefOr<Schema>) {
    let RefOr::T(Schema::AllOf(all_of)) = schema else {
        return;
    };
    let (mut objects, mut items): (Vec<Object>, Vec<RefOr<Schema>>) = (Vec::new(), Vec::new());
    for item in std::mem::take(&mut all_of.items) {
        match item {
            RefOr::T(Schema::Object(object)) => objects.push(object),
            other => items.push(other),
        }
    }
    if let Some(mut own) = objects.pop() {
        for inlined in objects {
            own.properties.extend(inlined.properties);
            own.required.extend(inlined.required);
        }
        items.push(RefOr::T(Schema::Object(own)));
    }
    all_of.items = items;
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "reflectance",
        description = "What a sphere is made of, from one photograph under unknown real-world \
            lighting (Dror, Adelson & Willsky 2001).\n\n\
            Every error is `application/problem+json` (RFC 9457) with `type` \
            (`urn:reflectance:problem:<slug>`), `title`, `status`, `detail` and `request_id`. \
            Besides the statuses listed per operation, any request may be answered 404 \
            (`not-found`, unknown route), 405 (`method-not-allowed`), 408 (`timeout`), \
            413 (`body-too-large`, whose detail names the limit and the setting that raises \
            it, --body-limit) or 500 (`internal`). Every response carries `x-request-id` \
            (the client's, when it sends 1–128 visible ASCII characters, else a new one) \
            and `traceresponse` (its W3C trace context: the client's `traceparent` trace, \
            else a new one).\n\n\
            The data plane is the server that serves this document (by default port 8080, \
            `--listen`); the admin plane (`/admin/…`, bearer token) listens on its own \
            address (by default 127.0.0.1:8081, `--admin-listen`).",
        license(name = "MIT OR Apache-2.0", identifier = "MIT OR Apache-2.0")
    ),
    servers((url = "/", description = "data plane (this server)")),
    paths(
        classify::classify_default,
        classify::classify_named,
        locate::locate,
        preview::preview,
        material::gltf,
        models::list,
        models::get,
        health::live,
        health::ready,
        health::metrics,
        serve,
        v2::server_metadata,
        v2::health_live,
        v2::health_ready,
        v2::model_metadata,
        v2::model_ready,
        v2::infer,
        v2::model_version_metadata,
        v2::model_version_ready,
        v2::infer_version,
        admin::submit,
        admin::list,
        admin::get,
        admin::events,
        admin::cancel,
        admin::versions,
        admin::activate,
        admin::delete_version,
        datasets::upload,
        datasets::list,
        datasets::get,
        datasets::delete,
        web::index,
        web::docs,
        web::asset,
    ),
    components(schemas(
        Problem,
        input::RawInput,
        input::JsonInput,
        reflectance_core::inference::ClassifyResponse,
        locate::LocateForm,
        datasets::DatasetForm,
        jobs::JobRequest,
        jobs::JobRecord,
        jobs::JobState,
        jobs::Activate,
    )),
    modifiers(&Extras),
    tags(
        (name = "classification", description = "Classify a sphere"),
        (name = "models", description = "Served models"),
        (name = "health", description = "Health, metrics, this document"),
        (name = "kserve-v2", description = "Open Inference Protocol (KServe V2 REST)"),
        (name = "admin", description = "Admin plane: jobs, datasets and registry (bearer token)"),
        (name = "page", description = "The page for people, and this reference (HTML)"),
    )
)]
pub struct ApiDoc;

/// The document as YAML.
pub fn yaml() -> String {
    ApiDoc::openapi()
        .to_yaml()
        .unwrap_or_else(|e| format!("# cannot render the OpenAPI document: {e}\n"))
}

/// This document.
#[utoipa::path(
    get,
    operation_id = "openapi", path = "/openapi.yaml",
    tag = "health",
    responses((status = 200, description = "The OpenAPI 3.1 document", body = Object, content_type = "application/yaml"))
)]
pub async fn serve() -> Response {
    let mut response = yaml().into_response();
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/yaml"),
    );
    response
}
