//! The page (`GET /`) and the API reference (`GET /docs`), built into the binary: no CDN,
//! no external fonts. Assets are served under names that carry a hash of their content, so
//! they are cached for good; the two pages themselves are revalidated on every load.

use crate::server::error::{ApiError, Kind};
use axum::extract::Path;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use std::sync::OnceLock;

struct Asset {
    /// The name pages refer to, e.g. `app.js` (served as `app.<hash>.js`).
    name: &'static str,
    bytes: &'static [u8],
    content_type: &'static str,
    /// `bytes` are gzipped (build.rs): served as they are to clients that take gzip.
    gzipped: bool,
}

const JS: &str = "text/javascript; charset=utf-8";
const CSS: &str = "text/css; charset=utf-8";
const TEXT: &str = "text/plain; charset=utf-8";

/// An asset of `web/` (or, with `repository`, another file of the repository), embedded.
macro_rules! asset {
    ($name:literal, $file:literal, $content_type:expr) => {
        asset!($name, repository concat!("web/", $file), $content_type)
    };
    ($name:literal, repository $path:expr, $content_type:expr) => {
        Asset {
            name: $name,
            bytes: include_bytes!(concat!("../../../", $path)),
            content_type: $content_type,
            gzipped: false,
        }
    };
    ($name:literal, gzipped $file:literal, $content_type:expr) => {
        Asset {
            name: $name,
            bytes: include_bytes!(concat!(env!("OUT_DIR"), "/", $file, ".gz")),
            content_type: $content_type,
            gzipped: true,
        }
    };
}

static ASSETS: [Asset; 10] = [
    asset!("app.js", "app.js", JS),
    asset!("app.css", "app.css", CSS),
    asset!("docs.js", "docs.js", JS),
    asset!("swagger-ui-bundle.js", gzipped "swagger-ui-bundle.js", JS),
    asset!("swagger-ui.css", gzipped "swagger-ui.css", CSS),
    asset!("swagger-ui-LICENSE.txt", "vendor/swagger-ui/LICENSE", TEXT),
    asset!("swagger-ui-NOTICE.txt", "vendor/swagger-ui/NOTICE", TEXT),
    asset!(
        "swagger-ui-bundle-LICENSE.txt",
        "vendor/swagger-ui/swagger-ui-bundle.js.LICENSE.txt",
        TEXT
    ),
    // The page's examples: the project's own renders, also its tests' fixtures.
    asset!(
        "example-white-shiny.jpg",
        repository "tests/fixtures/page/phone.jpg",
        "image/jpeg"
    ),
    asset!(
        "example-chrome.png",
        repository "tests/fixtures/features/sphere_rgb8.png",
        "image/png"
    ),
];

const INDEX_HTML: &str = include_str!("../../../web/index.html");
const DOCS_HTML: &str = include_str!("../../../web/docs.html");

/// `app.js` → `app.0123456789.js`: the first 10 hex digits of the content's SHA-256.
fn hashed(asset: &Asset) -> String {
    let digest = Sha256::digest(asset.bytes);
    let hash: String = digest[..5].iter().map(|b| format!("{b:02x}")).collect();
    match asset.name.rsplit_once('.') {
        Some((stem, ext)) => format!("{stem}.{hash}.{ext}"),
        None => format!("{}.{hash}", asset.name),
    }
}

/// Every asset under its hashed name.
fn served() -> &'static [(String, &'static Asset)] {
    static SERVED: OnceLock<Vec<(String, &'static Asset)>> = OnceLock::new();
    SERVED.get_or_init(|| ASSETS.iter().map(|a| (hashed(a), a)).collect())
}

/// A page with each `{{name}}` replaced by the asset's hashed URL.
fn render(template: &str) -> String {
    served()
        .iter()
        .fold(template.to_string(), |page, (hashed, asset)| {
            page.replace(
                &format!("{{{{{}}}}}", asset.name),
                &format!("/assets/{hashed}"),
            )
        })
}

/// Scripts and styles from this server only; pictures also from data: and blob: URLs (the
/// answer's PNGs, the dropped photo). Swagger UI sets inline styles, so /docs allows them.
const PAGE_POLICY: &str = "default-src 'self'; img-src 'self' data: blob:; \
    object-src 'none'; base-uri 'none'; frame-ancestors 'none'; form-action 'none'";
const DOCS_POLICY: &str = "default-src 'self'; img-src 'self' data:; \
    style-src 'self' 'unsafe-inline'; object-src 'none'; base-uri 'none'; \
    frame-ancestors 'none'";

fn page(html: &'static OnceLock<String>, template: &str, policy: &'static str) -> Response {
    let body: &'static str = html.get_or_init(|| render(template));
    let headers = [
        (header::CONTENT_TYPE, "text/html; charset=utf-8"),
        (header::CACHE_CONTROL, "no-cache"),
        (header::CONTENT_SECURITY_POLICY, policy),
        (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        (header::REFERRER_POLICY, "no-referrer"),
    ];
    (headers, body).into_response()
}

/// The page: drop a photograph, check the circle, classify.
#[utoipa::path(
    get,
    operation_id = "page", path = "/",
    tag = "page",
    responses((status = 200, description = "The classification page (HTML)", body = String, content_type = "text/html"))
)]
pub async fn index() -> Response {
    static HTML: OnceLock<String> = OnceLock::new();
    page(&HTML, INDEX_HTML, PAGE_POLICY)
}

/// This API reference, rendered from `/openapi.yaml` by Swagger UI (vendored).
#[utoipa::path(
    get,
    operation_id = "docs", path = "/docs",
    tag = "page",
    responses((status = 200, description = "The API reference (HTML)", body = String, content_type = "text/html"))
)]
pub async fn docs() -> Response {
    static HTML: OnceLock<String> = OnceLock::new();
    page(&HTML, DOCS_HTML, DOCS_POLICY)
}

/// A script, style sheet or licence of the pages, by hashed name (cached for a year).
#[utoipa::path(
    get,
    operation_id = "asset", path = "/assets/{file}",
    tag = "page",
    params(("file" = String, Path, description = "Hashed file name, as the pages link it", example = "app.0123456789.js")),
    responses(
        (status = 200, description = "The file", body = String),
        (status = 404, description = "No such asset (`not-found`)", body = crate::server::error::Problem, content_type = "application/problem+json"),
    )
)]
pub async fn asset(
    Path(file): Path<String>,
    request_headers: axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let (hashed, asset) = served()
        .iter()
        .find(|(hashed, _)| *hashed == file)
        .ok_or_else(|| ApiError::new(Kind::NotFound, format!("no asset {file:?}")))?;
    let etag = HeaderValue::from_str(&format!("\"{hashed}\""))
        .unwrap_or_else(|_| HeaderValue::from_static("\"\""));
    let headers = [
        (
            header::CONTENT_TYPE,
            HeaderValue::from_static(asset.content_type),
        ),
        (
            header::CACHE_CONTROL,
            HeaderValue::from_static("public, max-age=31536000, immutable"),
        ),
        (header::ETAG, etag),
        (
            header::X_CONTENT_TYPE_OPTIONS,
            HeaderValue::from_static("nosniff"),
        ),
    ];
    if !asset.gzipped {
        return Ok((headers, asset.bytes).into_response());
    }
    let vary = [(header::VARY, HeaderValue::from_static("accept-encoding"))];
    if takes_gzip(&request_headers) {
        let encoding = [(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"))];
        return Ok((headers, vary, encoding, asset.bytes).into_response());
    }
    let mut plain = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(asset.bytes), &mut plain)
        .map_err(|e| ApiError::internal(format!("asset {file}: {e}")))?;
    Ok((headers, vary, plain).into_response())
}

/// Whether a request's `Accept-Encoding` takes gzip (and does not refuse it with `q=0`).
fn takes_gzip(headers: &axum::http::HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT_ENCODING)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|coding| {
            let mut parts = coding.split(';').map(str::trim);
            let name = parts.next().unwrap_or_default();
            let refused = parts.any(|p| p.replace(' ', "") == "q=0" || p == "q=0.0");
            (name.eq_ignore_ascii_case("gzip") || name == "*") && !refused
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gzip_is_taken_unless_refused() {
        let with = |value: &'static str| {
            let mut headers = axum::http::HeaderMap::new();
            headers.insert(header::ACCEPT_ENCODING, HeaderValue::from_static(value));
            takes_gzip(&headers)
        };
        assert!(with("gzip, deflate, br, zstd") && with("*") && with("GZIP;q=0.5"));
        assert!(!with("identity") && !with("gzip;q=0") && !with("br, gzip; q=0"));
        assert!(!takes_gzip(&axum::http::HeaderMap::new()));
    }

    #[test]
    fn the_pages_link_their_assets_by_hashed_name() {
        let linked = |template: &str, names: &[&str]| {
            let page = render(template);
            assert!(!page.contains("{{"), "unresolved placeholder in {page}");
            for name in names {
                let (hashed, _) = served().iter().find(|(_, a)| a.name == *name).unwrap();
                assert!(page.contains(&format!("\"/assets/{hashed}\"")), "{name}");
            }
        };
        linked(INDEX_HTML, &["app.js", "app.css"]);
        linked(
            DOCS_HTML,
            &[
                "docs.js",
                "swagger-ui-bundle.js",
                "swagger-ui.css",
                "swagger-ui-LICENSE.txt",
            ],
        );
    }

    #[test]
    fn hashed_names_follow_the_content() {
        let a = Asset {
            name: "x.js",
            bytes: b"one",
            content_type: JS,
            gzipped: false,
        };
        let b = Asset { bytes: b"two", ..a };
        let (ha, hb) = (hashed(&a), hashed(&b));
        assert!(ha.starts_with("x.") && ha.ends_with(".js") && ha.len() == "x..js".len() + 10);
        assert_ne!(ha, hb);
        // SHA-256("one") = 7692c3ad…
        assert_eq!(ha, "x.7692c3ad35.js");
    }

    #[test]
    fn the_page_weighs_at_most_200_kb() {
        let own: usize = INDEX_HTML.len()
            + ASSETS
                .iter()
                .filter(|a| a.name.starts_with("app."))
                .map(|a| a.bytes.len())
                .sum::<usize>();
        assert!(own <= 200_000, "{own} bytes");
    }
}
