//! Numbers against independent references and physics: golden features (numpy, pyrtools),
//! the learning layer (scikit-learn), the renderer's known answers, resolution
//! independence, sphere detection on photograph-like composites, and typed errors for
//! every corrupt input.

#[path = "../common/mod.rs"]
mod common;

mod decode_errors;
mod detection;
mod golden;
mod learn_reference;
mod real_photos;
mod render_physics;
mod resolution;
