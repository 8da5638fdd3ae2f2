//! `cfg(shared_data)` for the tests that render under the shared light probes.

include!("../../build-support/shared_data.rs");

fn main() {
    shared_data("../../../shared/data/probes");
}
