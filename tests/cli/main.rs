//! The command line through the real binary: features, render, report, train → predict,
//! model files and the registry, and decoding errors.

#[path = "../common/mod.rs"]
mod common;

mod decode_errors;
mod features;
mod models;
mod render;
mod report;
