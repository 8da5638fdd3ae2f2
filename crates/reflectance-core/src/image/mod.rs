//! Pixel primitives the stages share: Gaussian blur, area-weighted resampling, colour, and
//! pictures for people.

pub mod blur;
pub mod circle;
pub mod colour;
pub mod display;
pub mod plane;
pub mod regions;
pub mod resample;
