//! Tells the tests whether the shared light probes (`../shared/data/probes`) are beside the
//! repository. Tests that read them are marked ignored when they are missing, so that the
//! summary shows them; with `REFLECTANCE_REQUIRE_SHARED` set (as `.ci/run` does) they are
//! never ignored, and fail if the data are missing.

fn main() {
    const PROBES: &str = "../shared/data/probes";
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    println!("cargo::rerun-if-env-changed=REFLECTANCE_REQUIRE_SHARED");
    println!("cargo::rerun-if-changed=build.rs");
    let present = std::path::Path::new(PROBES).is_dir();
    if present {
        // Re-run when the probes change or go (not when they appear: `touch build.rs`).
        println!("cargo::rerun-if-changed={PROBES}");
    }
    if present || std::env::var_os("REFLECTANCE_REQUIRE_SHARED").is_some() {
        println!("cargo::rustc-cfg=shared_data");
    }
}
