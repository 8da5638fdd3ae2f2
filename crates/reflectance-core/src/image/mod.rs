//! From bytes to a located, white-normalized sphere: decoding, the circle (given, fitted to a
//! mask, or detected), the white reference, and the resampling to the working radius.

pub(crate) mod blocks;
pub mod blur;
pub(crate) mod circle;
pub mod colour;
pub mod decode;
pub(crate) mod detect;
pub mod display;
pub mod footprint;
pub mod geometry;
pub mod normals;
pub(crate) mod occlusion;
pub mod resample;
pub mod white;
