//! The feature-extraction configuration every model file records: the unwrap grid, the
//! pyramid depth, the optional families and the preprocessing.

use super::layout::{BlockLayout, Layout};
use super::polar::UnwrapConfig;
use super::sets::named_set;
use super::{
    CAPTURE_PREFIX, CENTRE_PREFIX, DEPENDENCY_PREFIX, DOMAIN_PREFIX, LEVELS, LOG_PREFIX,
    RADIAL_PREFIX,
};
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// The smallest subband height the 9-tap filters can reflect within.
const MIN_BAND_ROWS: usize = 9;

/// Optional feature families beyond the paper's 117 (docs/design.md §8).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Extensions {
    /// The whole block again on the log10 image (`log.*`).
    pub log_domain: bool,
    /// How the statistics change from ring to ring of the annulus (`radial.*`).
    pub radial: bool,
    /// Correlations of subband magnitudes between orientations at each scale (`dep.*`).
    pub dependencies: bool,
    /// What the camera added, measured on the sphere (`cap.*`: [`crate::features::noise`]), after
    /// every block.
    pub capture: bool,
    /// The sphere's centre against white (`ctr.*`: [`crate::features::centre`]).
    pub centre: bool,
    /// Measurements for the domain check (`dom.*`: [`crate::features::outline`]), last.
    pub domain: bool,
}

impl Extensions {
    /// Every extension.
    pub const ALL: Extensions = Extensions {
        log_domain: true,
        radial: true,
        dependencies: true,
        capture: true,
        centre: true,
        domain: true,
    };

    /// The extensions whose features occur among `names` (a table's columns, a list).
    pub fn of_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Self {
        names.into_iter().fold(Extensions::default(), |seen, name| {
            let in_block = name.strip_prefix(LOG_PREFIX);
            let block_name = in_block.unwrap_or(name);
            Extensions {
                log_domain: seen.log_domain || in_block.is_some(),
                radial: seen.radial || block_name.starts_with(RADIAL_PREFIX),
                dependencies: seen.dependencies || block_name.starts_with(DEPENDENCY_PREFIX),
                capture: seen.capture || name.starts_with(CAPTURE_PREFIX),
                centre: seen.centre || name.starts_with(CENTRE_PREFIX),
                domain: seen.domain || name.starts_with(DOMAIN_PREFIX),
            }
        })
    }

    /// The extensions a feature-set specification reads (a named set or a list of names).
    pub fn of_spec(spec: &str) -> Self {
        let spec = spec.trim();
        match named_set(spec) {
            Some(names) => Self::of_names(names.iter().map(String::as_str)),
            None => Self::of_names(spec.split(',').map(str::trim)),
        }
    }

    /// Both sets of extensions.
    pub fn union(self, other: Extensions) -> Extensions {
        Extensions {
            log_domain: self.log_domain || other.log_domain,
            radial: self.radial || other.radial,
            dependencies: self.dependencies || other.dependencies,
            capture: self.capture || other.capture,
            centre: self.centre || other.centre,
            domain: self.domain || other.domain,
        }
    }
}

/// The extraction options a user chooses: the extensions to compute beyond those a feature
/// set names, and the preprocessing. One definition for the command line (flattened into its
/// arguments, feature `cli`), the service's learning jobs (JSON keys, feature `openapi` for
/// the schema) and any other caller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FeatureOptions {
    /// Also compute the log-domain features (`log.*`, 117 more; implied by feature sets that
    /// name them, such as hand6+log).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub log_features: bool,
    /// Also compute the radial changes (`radial.*`: each of three rings of the annulus minus
    /// the one inside it, 28 more per block; implied by sets such as hand6+log+radial).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub radial_features: bool,
    /// Also compute the orientation dependencies (`dep.*`: correlations of subband
    /// magnitudes between orientations at each scale, 12 more per block; implied by sets
    /// such as hand6+log+radial+dep).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub dependency_features: bool,
    /// Also compute the capture measurements (`cap.noise`: the noise at white estimated on
    /// the sphere, `cap.clipped`: its clipped fraction, `cap.blur`: the blur of its rim).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub capture_features: bool,
    /// Also measure the sphere's centre against white (`ctr.*`: log10 of the disc inside
    /// r/√2 over white, its mean, its inner half's mean and three percentiles), a cue to the
    /// total reflectance that the annulus lacks.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub centre_features: bool,
    /// Also measure how well the circle follows a sphere's outline (`dom.outline`), which a
    /// model's domain check reads (training always measures it).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub domain_features: bool,
    /// Reduce spheres larger than this radius (px, ≥ 32) to it before extraction (area
    /// averaging); a model records it so that serving does the same.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub working_radius: Option<f64>,
    /// Clip the white-normalized sphere at this multiple of white before extraction, as a
    /// camera clips highlights; a model records it so that serving does the same.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub saturation: Option<f64>,
}

impl FeatureOptions {
    /// The extensions asked for.
    pub fn extensions(&self) -> Extensions {
        Extensions {
            log_domain: self.log_features,
            radial: self.radial_features,
            dependencies: self.dependency_features,
            capture: self.capture_features,
            centre: self.centre_features,
            domain: self.domain_features,
        }
    }

    /// The preprocessing asked for.
    pub fn preprocessing(&self) -> Preprocessing {
        Preprocessing {
            working_radius: self.working_radius,
            saturation: self.saturation,
        }
    }

    /// The configuration that extracts what the feature-set `spec` reads with these options
    /// (see [`FeatureConfig::for_spec`]); validated.
    pub fn config(&self, spec: &str) -> Result<FeatureConfig, ConfigError> {
        FeatureConfig::for_spec(self.extensions(), spec, self.preprocessing())
    }

    /// The keys of these options in JSON, sorted (for callers that refuse unknown keys).
    pub fn keys() -> Vec<String> {
        crate::util::json_keys::<Self>()
    }
}

/// Everything that determines the feature values: stored in every model file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureConfig {
    /// The annulus and the grid it is unwrapped to (docs/design.md §3 "Canonical unwrap").
    pub unwrap: UnwrapConfig,
    /// Pyramid levels, 2 to 8 ([`super::LEVELS`] by default).
    pub levels: usize,
    /// Also compute every feature on log10(max(U, 1e-4)) of the unwrapped, white-normalized
    /// image U, named with the `log.` prefix (an extension of the paper; docs/design.md §8).
    #[serde(default)]
    pub log_domain: bool,
    /// Also compute, in each block, how the statistics change from ring to ring of the
    /// annulus (`radial.*`; an extension, docs/design.md §8). Absent in older model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub radial: bool,
    /// Also compute, in each block, the correlations of subband magnitudes between
    /// orientations at each scale (`dep.*`; an extension, docs/design.md §8). Absent in older
    /// model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub dependencies: bool,
    /// Also compute the capture measurements `cap.noise`, `cap.clipped` and `cap.blur` (after every
    /// block; an extension, docs/design.md §8). Absent in older model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub capture: bool,
    /// Also compute the sphere's centre against white, `ctr.*` (last; an extension,
    /// docs/design.md §8). Absent in older model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub centre: bool,
    /// With `centre`: the family ends with the cosine-weighted mean `ctr.cos`. Absent (so
    /// false) in model files from before it existed, whose centre family is the first five
    /// values: they keep extracting exactly the row they were trained on.
    #[serde(default, skip_serializing_if = "is_false")]
    pub centre_cos: bool,
    /// Also compute the domain measurements, `dom.*` (last; an extension, docs/design.md
    /// §8). Absent in older model files.
    #[serde(default, skip_serializing_if = "is_false")]
    pub domain: bool,
    /// Spheres larger than this radius (px) are first area-downsampled to it, so a model
    /// sees the same effective resolution as in training (see `resample`). None: no
    /// resampling (the paper's definition).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub working_radius: Option<f64>,
    /// Unwrapped values (in units of white) above this are clipped to it, so that
    /// highlights look the same whether the camera clipped them or not. None: no ceiling
    /// (the paper's definition). See `Preprocessing`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturation: Option<f64>,
}

/// What extraction does to a sphere before the features, beyond the spec: settings a
/// model records so that serving repeats them (none changes the feature names).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Preprocessing {
    /// See [`FeatureConfig::working_radius`].
    pub working_radius: Option<f64>,
    /// See [`FeatureConfig::saturation`]. A camera whose exposure puts white at e of full
    /// scale clips at 1/e of white; a ceiling at the lowest such point makes every capture
    /// in range, and an unclipped render, look alike.
    pub saturation: Option<f64>,
}

impl Preprocessing {
    /// Reduction to a working radius, nothing else.
    pub fn at_radius(working_radius: f64) -> Self {
        Preprocessing {
            working_radius: Some(working_radius),
            saturation: None,
        }
    }
}

impl Default for FeatureConfig {
    fn default() -> Self {
        FeatureConfig {
            unwrap: UnwrapConfig::default(),
            levels: LEVELS,
            log_domain: false,
            radial: false,
            dependencies: false,
            capture: false,
            centre: false,
            centre_cos: false,
            domain: false,
            working_radius: None,
            saturation: None,
        }
    }
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// A feature configuration that cannot be extracted (a model file's, or one built by hand).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    /// The unwrapped width cannot be halved `levels` times.
    #[error("unwrap width {cols} is not divisible by 2^{levels}")]
    WidthNotDivisible {
        /// Unwrapped columns.
        cols: usize,
        /// Pyramid levels.
        levels: usize,
    },
    /// A level's subbands would have fewer than 9 rows.
    #[error(
        "unwrap height {rows} is too small for {levels} levels (level {level} would have {band_rows} < 9 rows)"
    )]
    HeightTooSmall {
        /// Unwrapped rows.
        rows: usize,
        /// Pyramid levels.
        levels: usize,
        /// The first level too small (0: the finest).
        level: usize,
        /// Its subbands' rows.
        band_rows: usize,
    },
    /// The annulus is not 0 ≤ inner < outer ≤ 1, or r0 ≤ 0.
    #[error("invalid annulus [{inner}, {outer}]·r (need 0 ≤ inner < outer ≤ 1) or r0 {r0} ≤ 0")]
    BadAnnulus {
        /// Inner radius, a fraction of r.
        inner: f64,
        /// Outer radius, a fraction of r.
        outer: f64,
        /// Radius (px) up to which one sample per cell is taken.
        r0: f64,
    },
    /// Pyramid levels outside 2–8.
    #[error("levels must be between 2 and 8, not {0}")]
    BadLevels(usize),
    /// A working radius that is not a finite number ≥ 32 px.
    #[error("working radius {0} must be a finite number of pixels ≥ 32")]
    BadWorkingRadius(f64),
    /// A saturation that is not a finite multiple of white > 0.
    #[error("saturation {0} must be a finite multiple of white > 0")]
    BadSaturation(f64),
}

impl FeatureConfig {
    /// Check that the configuration can be extracted: levels in 2–8, a working radius ≥ 32
    /// px, a positive saturation, a valid annulus and a grid every level can halve.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let u = &self.unwrap;
        if !(2..=8).contains(&self.levels) {
            return Err(ConfigError::BadLevels(self.levels));
        }
        if let Some(r) = self
            .working_radius
            .filter(|r| !(r.is_finite() && *r >= crate::locate::MIN_RADIUS))
        {
            return Err(ConfigError::BadWorkingRadius(r));
        }
        if let Some(s) = self.saturation.filter(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(ConfigError::BadSaturation(s));
        }
        if !(0.0 <= u.inner && u.inner < u.outer && u.outer <= 1.0 && u.r0 > 0.0) {
            return Err(ConfigError::BadAnnulus {
                inner: u.inner,
                outer: u.outer,
                r0: u.r0,
            });
        }
        if !u.cols.is_multiple_of(1 << self.levels) {
            return Err(ConfigError::WidthNotDivisible {
                cols: u.cols,
                levels: self.levels,
            });
        }
        for level in 0..self.levels {
            let band_rows = u.rows >> level;
            if band_rows < MIN_BAND_ROWS {
                return Err(ConfigError::HeightTooSmall {
                    rows: u.rows,
                    levels: self.levels,
                    level,
                    band_rows,
                });
            }
        }
        Ok(())
    }

    /// The default configuration with the given extensions and preprocessing.
    pub fn extended(extensions: Extensions, preprocessing: Preprocessing) -> Self {
        FeatureConfig {
            log_domain: extensions.log_domain,
            radial: extensions.radial,
            dependencies: extensions.dependencies,
            capture: extensions.capture,
            centre: extensions.centre,
            centre_cos: extensions.centre,
            domain: extensions.domain,
            working_radius: preprocessing.working_radius,
            saturation: preprocessing.saturation,
            ..FeatureConfig::default()
        }
    }

    /// The configuration that extracts what a feature-set specification reads: the
    /// extensions `asked` for, those the specification names (e.g. `hand6+log`), and the
    /// preprocessing; validated.
    pub fn for_spec(
        asked: Extensions,
        spec: &str,
        preprocessing: Preprocessing,
    ) -> Result<Self, ConfigError> {
        let config = FeatureConfig::extended(asked.union(Extensions::of_spec(spec)), preprocessing);
        config.validate()?;
        Ok(config)
    }

    /// This configuration with the families the feature-set `spec` names computed too (an
    /// estimator's features beside a classifier's, e.g. the centre for hand6+log+cap+ctr).
    pub fn with_families_of(&self, spec: &str) -> FeatureConfig {
        let extensions = self.extensions().union(Extensions::of_spec(spec));
        FeatureConfig::extended(extensions, self.preprocessing())
    }

    /// The preprocessing this configuration does.
    pub fn preprocessing(&self) -> Preprocessing {
        Preprocessing {
            working_radius: self.working_radius,
            saturation: self.saturation,
        }
    }

    /// The default configuration with the log-domain features.
    pub fn with_log_domain() -> Self {
        let log_domain = Extensions {
            log_domain: true,
            ..Extensions::default()
        };
        FeatureConfig::extended(log_domain, Preprocessing::default())
    }

    /// The extensions this configuration computes.
    pub fn extensions(&self) -> Extensions {
        Extensions {
            log_domain: self.log_domain,
            radial: self.radial,
            dependencies: self.dependencies,
            capture: self.capture,
            centre: self.centre,
            domain: self.domain,
        }
    }

    /// Where each feature of this configuration sits.
    pub fn layout(&self) -> Layout {
        Layout {
            block: BlockLayout {
                levels: self.levels,
                radial: self.radial,
                dependencies: self.dependencies,
            },
            log_domain: self.log_domain,
            capture: self.capture,
            centre: self.centre,
            centre_cos: self.centre_cos,
            domain: self.domain,
        }
    }

    /// Canonical feature names for this configuration.
    ///
    /// ```
    /// use reflectance_core::FeatureConfig;
    /// use reflectance_core::features::{Extensions, Preprocessing};
    ///
    /// let names = FeatureConfig::default().names();
    /// assert_eq!(names.len(), 117);
    /// assert_eq!(names[..3], ["pix.mean", "pix.var", "pix.skew"]);
    /// assert!(names.iter().any(|n| n == "wav.s1.h.var"));
    /// assert!(names.iter().any(|n| n == "fft.b2.f45.pow"));
    ///
    /// // An extension appends its family: the capture measurements come last here.
    /// let extensions = Extensions { capture: true, ..Extensions::default() };
    /// let extended = FeatureConfig::extended(extensions, Preprocessing::default()).names();
    /// assert_eq!(extended[..117], names[..]);
    /// assert_eq!(extended[117..], ["cap.noise", "cap.clipped", "cap.blur"]);
    /// ```
    pub fn names(&self) -> Vec<String> {
        self.layout().names()
    }
}

/// The default configuration's names, computed once.
pub fn default_names() -> &'static [String] {
    static NAMES: OnceLock<Vec<String>> = OnceLock::new();
    NAMES.get_or_init(|| FeatureConfig::default().names())
}
