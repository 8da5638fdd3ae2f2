//! Tells the tests whether the shared light probes (`../shared/data/probes`) are beside the
//! repository, and whether a browser is installed for the page's test. Tests that need
//! either are marked ignored when it is missing, so that the summary shows them; with
//! `REFLECTANCE_REQUIRE_SHARED` or `REFLECTANCE_REQUIRE_BROWSER` set (as `.ci/run` does) they
//! are never ignored, and fail if it is missing. (Installing the browser is noticed; after
//! putting `../shared` in place, `touch build.rs`.)

include!("build-support/shared_data.rs");

fn main() {
    shared_data("../shared/data/probes");
    browser();
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
