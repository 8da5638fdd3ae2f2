//! Trained models: the file format, the versioned registry with hot swap, and training
//! from a feature table to a verified model file.

mod file;
pub mod publish;
pub mod registry;
pub mod train;

pub use file::*;
