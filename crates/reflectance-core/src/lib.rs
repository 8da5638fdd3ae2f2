//! `reflectance-core`: what a sphere is made of, from one photograph under unknown
//! real-world lighting (Dror, Adelson & Willsky 2001), without HTTP, an async runtime or
//! metrics. `docs/design.md` is the specification and `docs/architecture.md` the map. The
//! modules follow the pipeline: image (decode, locate, white) → features → learn → model →
//! inference, with material (Ward classes, capture envelopes) and dataset beside them.
//! The `openapi` feature derives the answer types' OpenAPI schemas.

#![deny(missing_docs)]

// In pipeline order: each module uses only those above it.
pub mod analysis;
pub mod classify;
pub mod dataset;
pub mod decode;
pub mod estimate;
pub mod features;
pub mod image;
pub mod inference;
pub mod learn;
pub mod locate;
pub mod material;
pub mod model;
pub mod object;
pub mod util;
pub mod white;

// The entry points for embedding: a photograph in, a classification out.
pub use decode::{DecodeOptions, decode, decode_file};
pub use features::{Extractor, FeatureConfig};
pub use inference::{ClassifyResponse, Input, LoadedModel, classify};
pub use model::ModelFile;
pub use model::registry::Registry;
