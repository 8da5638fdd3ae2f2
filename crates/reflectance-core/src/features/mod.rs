//! Features: the unwrapped annulus ([`polar`]), its QMF pyramid ([`pyramid`]), statistics
//! ([`stats`]) and band powers ([`spectrum`]) → the named feature bank (117 features with
//! the default configuration, docs/design.md §3), the optional families (§8), the capture
//! measurements ([`noise`]), the sphere's centre against white ([`centre`]), the domain
//! measurements ([`outline`]) and the named feature sets.
//!
//! [`layout`] fixes where every feature sits; [`config`] is what a model file records;
//! [`extract`] computes the vectors.

pub(crate) mod centre;
pub(crate) mod config;
pub(crate) mod extract;
pub(crate) mod layout;
pub(crate) mod log10;
pub(crate) mod noise;
pub mod observed;
pub(crate) mod outline;
pub(crate) mod polar;
pub mod pyramid;
pub(crate) mod sets;
pub mod spectrum;
pub mod stats;

pub use config::{
    ConfigError, Extensions, FeatureConfig, FeatureOptions, Preprocessing, default_names,
};
pub use extract::{CaptureMeasurements, Extractor, Stages};
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
/// Floor of the white-normalized unwrapped values before the log of the log-domain features.
pub const LOG_PIXEL_FLOOR: f64 = 1e-4;
/// Prefix of the log-domain features' names.
pub const LOG_PREFIX: &str = "log.";
/// Prefix of the radial-change features' names (within a block).
pub const RADIAL_PREFIX: &str = "radial.";
/// The radial changes cut the rows of the unwrapped annulus (and of each subband) into this
/// many rings of equal height and compare each with the one inside it.
pub const RADIAL_RINGS: usize = 3;
/// Prefix of the orientation-dependency features' names (within a block).
pub const DEPENDENCY_PREFIX: &str = "dep.";
/// Prefix of the capture measurements' names.
pub const CAPTURE_PREFIX: &str = "cap.";
/// The capture measurements: log10 of the noise at white (a fraction of white, floored at
/// 1e-4), the clipped fraction of the annulus, and log10 of the lens blur at the rim as a
/// fraction of the radius (floored at 1e-4): the blur a gloss would have to match, since a
/// lobe's blur grows with the sphere and the lens's does not.
pub const CAPTURE_NAMES: [&str; 3] = ["cap.noise", "cap.clipped", "cap.blur"];
/// Prefix of the centre features' names.
pub const CENTRE_PREFIX: &str = "ctr.";
/// The centre features ([`centre`]): log10 of the disc inside r/√2 against white, its mean, its
/// inner half's mean, its 10th, 50th and 90th percentiles and its cosine-weighted mean.
pub const CENTRE_NAMES: [&str; 6] = [
    "ctr.mean", "ctr.core", "ctr.p10", "ctr.p50", "ctr.p90", "ctr.cos",
];
/// Prefix of the domain measurements' names.
pub const DOMAIN_PREFIX: &str = "dom.";
/// The domain measurements: how well the circle follows a sphere's outline ([`outline`]).
pub const DOMAIN_NAMES: [&str; 1] = ["dom.outline"];
/// The pairs of orientations whose subband magnitudes the dependency features correlate.
const ORIENTATION_PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];
