//! `cfg(shared_data)` for the tests that read the shared light probes and photographs
//! (`../shared` beside the repository): ignored without them, unless
//! `REFLECTANCE_REQUIRE_SHARED` is set (CI), when they run and fail naming what is missing.

include!("../../build-support/shared_data.rs");

fn main() {
    shared_data("../../../shared/data/probes");
}
