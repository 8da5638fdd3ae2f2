//! The feature-extraction configuration every model file records: the unwrap grid, the
//! pyramid depth, the optional families and the preprocessing; and the options a user
//! chooses it by.

use super::LEVELS;
#[cfg(doc)]
use super::families::Addition;
use super::families::{FAMILIES, Families, Family, LOG};
use super::layout::Layout;
use super::polar::UnwrapConfig;
use super::sets::families_of;
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// The smallest subband height the 9-tap filters can reflect within.
const MIN_BAND_ROWS: usize = 9;

/// The preprocessing a user chooses and a model records, so that serving repeats it (none
/// changes the feature names): options of the command line (flattened into its arguments,
/// feature `cli`) and of the service's learning jobs (JSON keys) as part of [`FeatureOptions`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Preprocessing {
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
    /// Measure the rim's blur (`cap.blur`) on the sphere reduced to the working radius, where
    /// the other features read it, rather than on the image as given; a model records it so
    /// that serving does the same.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub blur_at_working_radius: bool,
}

impl Preprocessing {
    /// Reduction to a working radius, nothing else.
    pub fn at_radius(working_radius: f64) -> Self {
        Preprocessing {
            working_radius: Some(working_radius),
            ..Preprocessing::default()
        }
    }
}

/// The description of [`FeatureOptions`], in its documentation and its OpenAPI schema.
macro_rules! feature_options_doc {
    () => {
        "The extraction options a user chooses: the extensions to compute beyond those a feature\n\
         set names, and the preprocessing. One definition for the command line (flattened into its\n\
         arguments, feature `cli`), the service's learning jobs (JSON keys, feature `openapi` for\n\
         the schema) and any other caller."
    };
}

#[doc = feature_options_doc!()]
///
/// The families' options are theirs ([`Family::option`], [`Family::help`]): `--log-features`
/// on the command line is `log_features` in a job.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FeatureOptions {
    /// The families to compute beyond those the feature set names (each implied by the sets
    /// that name its features, such as hand6+log).
    #[serde(flatten, with = "asked")]
    #[cfg_attr(feature = "cli", command(flatten))]
    pub families: Families,
    /// The preprocessing.
    #[serde(flatten)]
    #[cfg_attr(feature = "cli", command(flatten))]
    pub preprocessing: Preprocessing,
}

impl FeatureOptions {
    /// The configuration that extracts what the feature-set `spec` reads with these options
    /// (see [`FeatureConfig::for_spec`]); validated.
    pub fn config(&self, spec: &str) -> Result<FeatureConfig, ConfigError> {
        FeatureConfig::for_spec(self.families, spec, self.preprocessing)
    }

    /// The keys of these options in JSON, sorted (for callers that refuse unknown keys).
    pub fn keys() -> Vec<String> {
        crate::util::json_keys::<Self>()
    }
}

/// The families as options: one boolean per family, by its [`Family::option`] (JSON keys).
mod asked {
    use super::{FAMILIES, Families};
    use serde::de::{self, Deserializer, IgnoredAny, MapAccess, Visitor};
    use serde::ser::{SerializeMap, Serializer};

    pub fn serialize<S: Serializer>(families: &Families, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(FAMILIES.len()))?;
        for family in FAMILIES {
            map.serialize_entry(family.option, &families.contains(family))?;
        }
        map.end()
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Families, D::Error> {
        deserializer.deserialize_map(Options)
    }

    struct Options;

    impl<'de> Visitor<'de> for Options {
        type Value = Families;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("the feature families' options")
        }

        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Families, A::Error> {
            let mut seen = [false; FAMILIES.len()];
            let mut families = Families::NONE;
            while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
                let Some(i) = FAMILIES.iter().position(|f| f.option == key) else {
                    map.next_value::<IgnoredAny>()?;
                    continue;
                };
                if std::mem::replace(&mut seen[i], true) {
                    return Err(de::Error::duplicate_field(FAMILIES[i].option));
                }
                let on = map.next_value::<bool>()?;
                families = families.recorded(FAMILIES[i], on, on);
            }
            Ok(families)
        }
    }
}

/// The families as a model file records them: each family's [`Family::key`] (written when
/// on, or always for those [`Family::recorded_when_off`]), and its addition's key when the
/// configuration computes it; a key that is absent is off.
mod recorded {
    use super::{FAMILIES, Families};
    use serde::de::{self, Deserializer, IgnoredAny, MapAccess, Visitor};
    use serde::ser::{SerializeMap, Serializer};

    pub fn serialize<S: Serializer>(families: &Families, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(None)?;
        for family in FAMILIES {
            let on = families.contains(family);
            if on || family.recorded_when_off {
                map.serialize_entry(family.key, &on)?;
            }
            if let Some(addition) = &family.addition
                && families.has_addition(family)
            {
                map.serialize_entry(addition.key, &true)?;
            }
        }
        map.end()
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Families, D::Error> {
        deserializer.deserialize_map(Recorded)
    }

    struct Recorded;

    impl<'de> Visitor<'de> for Recorded {
        type Value = Families;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("the feature families of a configuration")
        }

        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Families, A::Error> {
            // Per family: whether it is on, whether its addition is (`None`: not yet read).
            let mut read = [(None, None); FAMILIES.len()];
            while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
                let found = FAMILIES.iter().enumerate().find_map(|(i, f)| {
                    let addition = f.addition.as_ref().map(|a| a.key);
                    match (f.key == key, addition == Some(&*key)) {
                        (true, _) => Some((i, f.key, false)),
                        (false, true) => addition.map(|k| (i, k, true)),
                        (false, false) => None,
                    }
                });
                let Some((i, name, is_addition)) = found else {
                    map.next_value::<IgnoredAny>()?;
                    continue;
                };
                let slot = match is_addition {
                    false => &mut read[i].0,
                    true => &mut read[i].1,
                };
                if slot.is_some() {
                    return Err(de::Error::duplicate_field(name));
                }
                *slot = Some(map.next_value::<bool>()?);
            }
            let families = FAMILIES.iter().zip(read).fold(
                Families::NONE,
                |families, (family, (on, addition))| {
                    families.recorded(family, on.unwrap_or(false), addition.unwrap_or(false))
                },
            );
            Ok(families)
        }
    }
}

#[cfg(feature = "cli")]
impl clap::FromArgMatches for Families {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut families = Families::NONE;
        families.update_from_arg_matches(matches)?;
        Ok(families)
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        for family in FAMILIES {
            if matches.contains_id(family.option) {
                let on = matches.get_flag(family.option);
                *self = self.recorded(family, on, on);
            }
        }
        Ok(())
    }
}

/// The families' options on the command line: `--log-features`, … with their help (lines
/// joined, without the final period: as clap writes a doc comment).
#[cfg(feature = "cli")]
impl clap::Args for Families {
    fn augment_args(command: clap::Command) -> clap::Command {
        static FLAGS: OnceLock<Vec<(String, String)>> = OnceLock::new();
        let flags = FLAGS.get_or_init(|| {
            let help = |text: &str| {
                let line = text.lines().map(str::trim).collect::<Vec<_>>().join(" ");
                match line.strip_suffix('.') {
                    Some(cut) if !line.ends_with("..") => cut.to_string(),
                    _ => line,
                }
            };
            let flag = |option: &str| option.replace('_', "-");
            FAMILIES.map(|f| (flag(f.option), help(f.help))).to_vec()
        });
        FAMILIES
            .into_iter()
            .zip(flags)
            .fold(command, |command, (family, (flag, help))| {
                command.arg(
                    clap::Arg::new(family.option)
                        .long(flag.as_str())
                        .action(clap::ArgAction::SetTrue)
                        .help(help.as_str()),
                )
            })
    }

    fn augment_args_for_update(command: clap::Command) -> clap::Command {
        Self::augment_args(command)
    }
}

/// The options' schema: the families' options (booleans, described by their help) and the
/// preprocessing.
#[cfg(feature = "openapi")]
impl utoipa::PartialSchema for FeatureOptions {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        use utoipa::openapi::RefOr;
        use utoipa::openapi::schema::{ObjectBuilder, Schema, SchemaType, Type};
        let RefOr::T(Schema::Object(mut object)) =
            <Preprocessing as utoipa::PartialSchema>::schema()
        else {
            unreachable!("the preprocessing is an object");
        };
        object.description = Some(feature_options_doc!().into());
        for family in FAMILIES {
            let option = ObjectBuilder::new()
                .schema_type(SchemaType::new(Type::Boolean))
                .description(Some(family.help));
            object.properties.insert(
                family.option.into(),
                RefOr::T(Schema::Object(option.build())),
            );
        }
        RefOr::T(Schema::Object(object))
    }
}

#[cfg(feature = "openapi")]
impl utoipa::ToSchema for FeatureOptions {}

/// Everything that determines the feature values: stored in every model file.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureConfig {
    /// The annulus and the grid it is unwrapped to (docs/design.md §3 "Canonical unwrap").
    pub unwrap: UnwrapConfig,
    /// Pyramid levels, 2 to 8 ([`super::LEVELS`] by default).
    pub levels: usize,
    /// The optional families it computes (extensions of the paper, docs/design.md §8), each
    /// recorded by its [`Family::key`] (`log_domain`, `radial`, …; the later families are
    /// absent from older model files) and with its [`Addition`] unless the file is older than
    /// that (`centre_cos`: without it, the centre family is the first five values, the row
    /// such a model was trained on).
    #[serde(flatten, with = "recorded")]
    pub families: Families,
    /// Spheres larger than this radius (px) are first area-downsampled to it, so a model
    /// sees the same effective resolution as in training (see `resample`). None: no
    /// resampling (the paper's definition).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub working_radius: Option<f64>,
    /// Unwrapped values (in units of white) above this are clipped to it, so that
    /// highlights look the same whether the camera clipped them or not. None: no ceiling
    /// (the paper's definition). A camera whose exposure puts white at e of full scale clips
    /// at 1/e of white; a ceiling at the lowest such point makes every capture in range, and
    /// an unclipped render, look alike.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturation: Option<f64>,
    /// Whether `cap.blur` is measured on the sphere at the working radius (where a sharp
    /// ball reads as sharp whatever its size in the photograph) rather than as given, where
    /// the rim of a large sharp ball reads below anything a model trained on smaller renders
    /// saw (docs/accuracy.md, "Accuracy per input radius"). Absent (false) in model files
    /// from before it.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub blur_at_working_radius: bool,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        FeatureConfig {
            unwrap: UnwrapConfig::default(),
            levels: LEVELS,
            families: Families::NONE,
            working_radius: None,
            saturation: None,
            blur_at_working_radius: false,
        }
    }
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

    /// The default configuration with the given families (each with its addition) and
    /// preprocessing.
    pub fn extended(families: Families, preprocessing: Preprocessing) -> Self {
        FeatureConfig {
            families: families.completed(),
            working_radius: preprocessing.working_radius,
            saturation: preprocessing.saturation,
            blur_at_working_radius: preprocessing.blur_at_working_radius,
            ..FeatureConfig::default()
        }
    }

    /// The configuration that extracts what a feature-set specification reads: the
    /// families `asked` for, those the specification names (e.g. `hand6+log`), and the
    /// preprocessing; validated.
    pub fn for_spec(
        asked: Families,
        spec: &str,
        preprocessing: Preprocessing,
    ) -> Result<Self, ConfigError> {
        let config = FeatureConfig::extended(asked.union(families_of(spec)), preprocessing);
        config.validate()?;
        Ok(config)
    }

    /// This configuration with the families the feature-set `spec` names computed too (an
    /// estimator's features beside a classifier's, e.g. the centre for hand6+log+cap+ctr).
    pub fn with_families_of(&self, spec: &str) -> FeatureConfig {
        let families = self.families.union(families_of(spec));
        FeatureConfig::extended(families, self.preprocessing())
    }

    /// This configuration with `family` computed too (with its addition).
    pub fn with(self, family: &Family) -> FeatureConfig {
        FeatureConfig {
            families: self.families.with(family),
            ..self
        }
    }

    /// The preprocessing this configuration does.
    pub fn preprocessing(&self) -> Preprocessing {
        Preprocessing {
            working_radius: self.working_radius,
            saturation: self.saturation,
            blur_at_working_radius: self.blur_at_working_radius,
        }
    }

    /// The default configuration with the log-domain features.
    pub fn with_log_domain() -> Self {
        FeatureConfig::default().with(&LOG)
    }

    /// Where each feature of this configuration sits.
    pub fn layout(&self) -> Layout {
        Layout::new(self.levels, self.families)
    }

    /// Canonical feature names for this configuration.
    ///
    /// ```
    /// use reflectance_core::FeatureConfig;
    /// use reflectance_core::features::families::CAPTURE;
    ///
    /// let names = FeatureConfig::default().names();
    /// assert_eq!(names.len(), 117);
    /// assert_eq!(names[..3], ["pix.mean", "pix.var", "pix.skew"]);
    /// assert!(names.iter().any(|n| n == "wav.s1.h.var"));
    /// assert!(names.iter().any(|n| n == "fft.b2.f45.pow"));
    ///
    /// // An optional family appends its features: the capture measurements come last here.
    /// let extended = FeatureConfig::default().with(&CAPTURE).names();
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::families::{CAPTURE, CENTRE, DEPENDENCIES, DOMAIN, RADIAL};

    const GRID: &str =
        r#""unwrap":{"inner":0.2,"outer":0.9,"rows":96,"cols":448,"r0":80.0},"levels":4"#;

    fn json(config: &FeatureConfig) -> String {
        serde_json::to_string(config).unwrap()
    }

    #[test]
    fn a_configuration_is_stored_as_model_files_store_it() {
        assert_eq!(
            json(&FeatureConfig::default()),
            format!(r#"{{{GRID},"log_domain":false}}"#)
        );
        // The shipped models'.
        let shipped = FeatureConfig {
            working_radius: Some(116.36363636363636),
            saturation: Some(1.25),
            ..FeatureConfig::with_log_domain()
                .with(&CAPTURE)
                .with(&CENTRE)
                .with(&DOMAIN)
        };
        let stored = format!(
            r#"{{{GRID},"log_domain":true,"capture":true,"centre":true,"centre_cos":true,"domain":true,"working_radius":116.36363636363636,"saturation":1.25}}"#
        );
        assert_eq!(json(&shipped), stored);
        let read: FeatureConfig = serde_json::from_str(&stored).unwrap();
        assert_eq!(read, shipped);
        let six = [&LOG, &RADIAL, &DEPENDENCIES, &CAPTURE, &CENTRE, &DOMAIN];
        let every = FeatureConfig::extended(six.into_iter().collect(), Preprocessing::default());
        assert_eq!(
            json(&every),
            format!(
                r#"{{{GRID},"log_domain":true,"radial":true,"dependencies":true,"capture":true,"centre":true,"centre_cos":true,"domain":true}}"#
            )
        );
    }

    #[test]
    fn older_configurations_read_and_write_as_they_were() {
        // From before `ctr.cos`, from before every family but the log domain's, and older.
        for old in [
            format!(r#"{{{GRID},"log_domain":false,"centre":true}}"#),
            format!(r#"{{{GRID},"log_domain":true}}"#),
            format!(r#"{{{GRID}}}"#),
        ] {
            let config: FeatureConfig = serde_json::from_str(&old).unwrap();
            let expected = old.replace(
                &format!("{GRID}}}"),
                &format!("{GRID},\"log_domain\":false}}"),
            );
            assert_eq!(json(&config), expected);
        }
        // As a model file is read: from its JSON value.
        let value = serde_json::json!({"unwrap": {"inner": 0.2, "outer": 0.9, "rows": 96,
            "cols": 448, "r0": 80.0}, "levels": 4, "radial": "yes"});
        let error = serde_json::from_value::<FeatureConfig>(value).unwrap_err();
        assert_eq!(
            error.to_string(),
            "invalid type: string \"yes\", expected a boolean"
        );
    }

    #[test]
    fn options_are_one_key_per_family_and_the_preprocessing() {
        let options = FeatureOptions {
            families: Families::NONE.with(&CENTRE),
            preprocessing: Preprocessing::at_radius(64.0),
        };
        let text = serde_json::to_string(&options).unwrap();
        // The families' options in their order (a family added later adds its own before the
        // preprocessing), then the preprocessing.
        let families = r#"{"log_features":false,"radial_features":false,"dependency_features":false,"capture_features":false,"centre_features":true,"domain_features":false,"#;
        assert!(text.starts_with(families), "{text}");
        let preprocessing =
            r#","working_radius":64.0,"saturation":null,"blur_at_working_radius":false}"#;
        assert!(text.ends_with(preprocessing), "{text}");
        let read: FeatureOptions = serde_json::from_str(&text).unwrap();
        assert_eq!(read, options);
        let partial: FeatureOptions =
            serde_json::from_str(r#"{"domain_features":true,"other":1}"#).unwrap();
        assert_eq!(partial.families, Families::NONE.with(&DOMAIN));
        assert_eq!(FeatureOptions::keys().len(), FAMILIES.len() + 3);
    }
}
