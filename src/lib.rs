//! `reflectance`: what a sphere is made of, from one photograph under unknown real-world
//! lighting (Dror, Adelson & Willsky 2001). `docs/design.md` is the specification and
//! `docs/architecture.md` the map. This crate is the binary's: the command line, the
//! service and the reports, on `reflectance-core` (the pipeline, without HTTP) and
//! `reflectance-render` (training data), which it names by their own names.

mod archive;
mod cli;
mod heap;
mod progress;
mod report;
mod server;

// The entry points for embedding: a photograph in, a classification out.
pub use reflectance_core::{
    ClassifyResponse, DecodeOptions, Extractor, FeatureConfig, Input, LoadedModel, ModelFile,
    Registry, classify, decode, decode_file,
};

/// The command line, `reflectance --help`: what the binary runs.
pub use cli::main as command_line;
/// The allocator's thresholds for this workload (the binary and the benches set them).
pub use heap::tune as tune_heap;

// The service, for embedding it and for the tests that drive its router.
pub use server::config::Config as ServerConfig;
pub use server::listener::serve_plane;
pub use server::metrics::render as metrics_text;
pub use server::openapi::{ApiDoc, yaml as openapi_yaml};
pub use server::router::{admin_router, data_router};
pub use server::state::{Phase, SharedState};
pub use server::trace::one_request_encoded as trace_one_request;
pub use server::{StartError, build_state, load_models};

// Dataset archives (`reflectance dataset pack`, `POST /admin/v1/datasets`).
pub use archive::{ArchiveLimits, pack as pack_archive, unpack as unpack_archive};
