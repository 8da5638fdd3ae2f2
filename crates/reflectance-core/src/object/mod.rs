//! Objects of any shape, read as their equivalent sphere (docs/design.md §9): normal maps,
//! the footprint of a normal on the sphere, self-shadowing, and block reductions.

pub(crate) mod blocks;
pub mod footprint;
pub mod normals;
pub(crate) mod occlusion;
