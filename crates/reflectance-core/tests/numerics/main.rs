//! The core's numbers against independent references: golden features (numpy, pyrtools),
//! the learning layer (scikit-learn), resolution independence, sphere detection on
//! photograph-like composites and on the development photographs, and typed errors for
//! every corrupt input. `cargo test -p reflectance-core` runs them.

#[path = "../../../../tests/common/images.rs"]
mod common;

mod decode_errors;
mod detection;
mod golden;
mod learn_reference;
mod real_photos;
mod resolution;
