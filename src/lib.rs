//! `reflectance`: what a sphere is made of, from one photograph under unknown real-world
//! lighting (Dror, Adelson & Willsky 2001). `docs/design.md` is the specification and
//! `docs/architecture.md` the map. This crate is the binary's: the command line, the
//! service and the reports, on `reflectance-core` (the pipeline, without HTTP) and
//! `reflectance-render` (training data), whose modules it re-exports under their names.

pub mod archive;
pub mod cli;
pub mod heap;
pub(crate) mod report;
pub mod server;

pub use reflectance_core::{dataset, features, image, inference, learn, material, model, util};
pub use reflectance_render as render;

// The entry points for embedding: a photograph in, a classification out.
pub use reflectance_core::{
    ClassifyResponse, DecodeOptions, Extractor, FeatureConfig, Input, LoadedModel, ModelFile,
    Registry, classify, decode, decode_file,
};
