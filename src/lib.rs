//! `reflectance`: what a sphere is made of, from one photograph under unknown real-world
//! lighting (Dror, Adelson & Willsky 2001). `docs/design.md` is the specification and
//! `docs/architecture.md` the map. The modules follow the pipeline:
//! image (decode, locate, white) → features → learn → model → inference → server / cli,
//! with render (training data) and report (tables and plots) beside it.

pub mod cli;
pub mod dataset;
pub mod features;
pub mod image;
pub mod inference;
pub mod learn;
pub mod model;
pub mod render;
pub mod report;
pub mod server;
pub mod util;
