// Included by the build scripts of the packages whose tests read the shared light probes
// (`../shared/data/probes` beside the repository): `cfg(shared_data)` when they are there.
// Tests that need them are marked ignored when they are missing, so that the summary shows
// them; with `REFLECTANCE_REQUIRE_SHARED` set (as `.ci/run` does) they are never ignored,
// and fail if the probes are missing. (`touch build.rs` after they appear.)

/// `probes`: the probes' folder relative to the package's directory.
fn shared_data(probes: &str) {
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    println!("cargo::rerun-if-env-changed=REFLECTANCE_REQUIRE_SHARED");
    println!("cargo::rerun-if-changed=build.rs");
    let present = std::path::Path::new(probes).is_dir();
    if present {
        // Re-run when the probes change or go (not when they appear: `touch build.rs`).
        println!("cargo::rerun-if-changed={probes}");
    }
    if present || std::env::var_os("REFLECTANCE_REQUIRE_SHARED").is_some() {
        println!("cargo::rustc-cfg=shared_data");
    }
}
