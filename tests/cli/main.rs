//! The command line through the real binary: features, render, report, train → predict,
//! model files and the registry, sharded runs and their merge.

#[path = "../common/mod.rs"]
mod common;

mod dataset;
mod features;
mod gltf;
mod honest;
mod models;
mod render;
mod report;
mod shard;
