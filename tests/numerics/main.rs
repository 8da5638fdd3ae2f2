//! Numbers against independent references and physics: golden features (numpy, pyrtools),
//! the learning layer (scikit-learn), the renderer's known answers, resolution
//! independence, and sphere detection on photograph-like composites.

mod detection;
mod golden;
mod learn_reference;
mod render_physics;
mod resolution;
