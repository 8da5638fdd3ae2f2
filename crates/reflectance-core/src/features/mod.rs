//! Features: the unwrapped annulus ([`polar`]), its QMF pyramid ([`pyramid`]), statistics
//! ([`stats`]) and band powers ([`spectrum`]) → the named feature bank (117 features with
//! the default configuration, docs/design.md §3), the optional families (§8: [`families`],
//! each declared once in its own module there) and the named feature sets.
//!
//! [`lighting`] tells a sphere under one lamp in the dark by its shading (a domain check).
//! [`layout`] fixes where every feature sits; [`config`] is what a model file records;
//! [`extract`] computes the vectors, of a photographed sphere or of an object's equivalent
//! sphere, by one path.

pub(crate) mod block;
pub(crate) mod config;
pub(crate) mod extract;
pub mod families;
pub(crate) mod layout;
pub mod lighting;
pub(crate) mod log10;
pub mod observed;
pub(crate) mod polar;
pub mod pyramid;
pub(crate) mod sets;
pub mod spectrum;
pub mod stats;

pub use block::Stages;
pub use config::{ConfigError, FeatureConfig, FeatureOptions, Preprocessing, default_names};
pub use extract::{Extracted, Extractor, Sphere};
pub use families::{
    CAPTURE_NAMES, CENTRE_NAMES, CaptureMeasurements, DOMAIN_NAMES, Families, Family, LOG_PREFIX,
    RADIAL_RINGS,
};
pub use layout::{BlockLayout, Layout};
pub use observed::{MIN_OBSERVED, Observed, ObservedError};
pub use sets::{NAMED_SETS, named_set};

/// Pyramid levels of the default configuration.
pub const LEVELS: usize = 4;
/// Number of features with the default configuration.
pub const FEATURE_COUNT: usize = 117;
/// The subband orientations, in order: h (horizontal structure), v (vertical: radial on
/// the sphere), d.
const BAND_NAMES: [&str; 3] = ["h", "v", "d"];
/// Floor of white-normalized values before their log10: the log-domain features' pixels,
/// the centre features.
pub const LOG_PIXEL_FLOOR: f64 = 1e-4;
