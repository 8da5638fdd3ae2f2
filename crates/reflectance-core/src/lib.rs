//! `reflectance-core`: what a sphere is made of, from one photograph under unknown
//! real-world lighting (Dror, Adelson & Willsky 2001), without HTTP, an async runtime or
//! metrics. `docs/design.md` is the specification and `docs/architecture.md` the map. The
//! modules follow the pipeline: image (decode, locate, white) → features → learn → model →
//! inference, with material (Ward classes, capture envelopes) and dataset beside them.
//! The `openapi` feature derives the answer types' OpenAPI schemas.

#![deny(missing_docs)]

pub mod dataset;
pub mod features;
pub mod image;
pub mod inference;
pub mod learn;
pub mod material;
pub mod model;
pub mod util;

// The entry points for embedding: a photograph in, a classification out.
pub use features::{Extractor, FeatureConfig};
pub use image::decode::{DecodeOptions, decode, decode_file};
pub use inference::{ClassifyResponse, Input, LoadedModel, classify};
pub use model::ModelFile;
pub use model::registry::Registry;
