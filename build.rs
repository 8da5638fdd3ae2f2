//! Tells the tests whether the shared light probes (`../shared/data/probes`) are beside the
//! repository, and whether a browser is installed for the page's test. Tests that need
//! either are marked ignored when it is missing, so that the summary shows them; with
//! `REFLECTANCE_REQUIRE_SHARED` or `REFLECTANCE_REQUIRE_BROWSER` set (as `.ci/run` does) they
//! are never ignored, and fail if it is missing. (Installing the browser is noticed; after
//! putting `../shared` in place, `touch build.rs`.)

//!
//! It also gzips the vendored API viewer (Swagger UI, 1.9 MB of text) for the binary, which
//! serves it compressed (`server/handlers/web.rs`).

include!("build-support/shared_data.rs");

fn main() {
    shared_data("../shared/data/probes");
    browser();
    gzip_vendored();
}

/// `OUT_DIR/<name>.gz` of each large vendored asset (deterministic: no name, no time).
fn gzip_vendored() {
    use std::io::Write;
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    for name in ["swagger-ui-bundle.js", "swagger-ui.css"] {
        let path = format!("web/vendor/swagger-ui/{name}");
        println!("cargo::rerun-if-changed={path}");
        let bytes = std::fs::read(&path).expect("the vendored viewer is in the repository");
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(&bytes).expect("gzip in memory");
        let gz = encoder.finish().expect("gzip in memory");
        std::fs::write(out.join(format!("{name}.gz")), gz).expect("OUT_DIR is writable");
    }
}

/// `cfg(browser)`: Chromium and ChromeDriver where the page's test looks for them.
fn browser() {
    println!("cargo::rustc-check-cfg=cfg(browser)");
    let mut found = true;
    for (variable, default) in [
        ("REFLECTANCE_CHROMIUM", "/usr/bin/chromium"),
        ("REFLECTANCE_CHROMEDRIVER", "/usr/bin/chromedriver"),
    ] {
        println!("cargo::rerun-if-env-changed={variable}");
        let path = std::env::var(variable).unwrap_or_else(|_| default.to_string());
        let path = std::path::Path::new(&path);
        found &= path.is_file();
        // Installing the browser changes its folder: the test is then built to run, with no
        // `touch build.rs`. (A missing file itself would make every build rerun.)
        if let Some(folder) = path.parent().filter(|f| f.is_dir()) {
            println!("cargo::rerun-if-changed={}", folder.display());
        }
    }
    println!("cargo::rerun-if-env-changed=REFLECTANCE_REQUIRE_BROWSER");
    if found || std::env::var_os("REFLECTANCE_REQUIRE_BROWSER").is_some() {
        println!("cargo::rustc-cfg=browser");
    }
}
