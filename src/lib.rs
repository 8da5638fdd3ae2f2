//! `reflectance`: what a sphere is made of, from one photograph under unknown real-world
//! lighting (Dror, Adelson & Willsky 2001). DESIGN.md has the conventions; the modules
//! follow the pipeline: decode → geometry → white → unwrap → pyramid → stats → spectrum →
//! features → learn → model/registry → server.

pub mod analysis;
pub mod capture;
pub mod cli;
pub mod dataset;
pub mod detect;
pub mod features;
pub mod fsutil;
pub mod geometry;
pub mod heap;
pub mod image_io;
pub mod inference;
pub mod learn;
pub mod log10;
pub mod model;
pub mod noise;
pub mod progress;
pub mod pyramid;
pub mod registry;
pub mod render;
pub mod report;
pub mod resample;
pub mod rng;
pub mod server;
pub mod spectrum;
pub mod stats;
pub mod train;
pub mod unwrap;
pub mod white;
