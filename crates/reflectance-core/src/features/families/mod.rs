//! The optional feature families beyond the paper's 117 (docs/design.md §8), as data. A family
//! is declared by one [`Family`] in its own module of this folder and listed once in
//! [`FAMILIES`]; everything else reads it from there: the command line's flags and the jobs'
//! keys ([`super::FeatureOptions`]), what a model file records ([`super::FeatureConfig`]),
//! where its features sit ([`super::Layout`]), which a feature set names and what computes
//! them ([`super::Extractor`]).
//!
//! Three kinds, by where the features sit: the whole block again on another image (`log.*`),
//! features within each block (`radial.*`, `dep.*`), and features of the sphere after the
//! blocks (`cap.*`, `ctr.*`, `dom.*`). docs/development.md "Adding a feature family" walks
//! through adding one.

use super::observed::{Observed, Support};
use super::pyramid::Level;
use crate::image::circle::Circle;
use crate::object::normals::EquivalentSphere;
use ndarray::{Array2, ArrayView2, CowArray, Ix2};
use std::cell::OnceCell;

pub(crate) mod capture;
pub(crate) mod centre;
pub(crate) mod dependencies;
pub(crate) mod domain;
pub(crate) mod log;
pub(crate) mod radial;

pub use capture::{CAPTURE, CAPTURE_NAMES, CaptureMeasurements};
pub use centre::{CENTRE, CENTRE_NAMES};
pub use dependencies::DEPENDENCIES;
pub use domain::{DOMAIN, DOMAIN_NAMES};
pub use log::{LOG, LOG_PREFIX};
pub use radial::{RADIAL, RADIAL_RINGS};

/// Every optional family, in the order of their features (the blocks' own families, the
/// blocks again, then the sphere's), of their command-line flags and of their keys.
pub const FAMILIES: [&Family; 6] = [&LOG, &RADIAL, &DEPENDENCIES, &CAPTURE, &CENTRE, &DOMAIN];

/// One optional feature family: how it is asked for, how a model file records it, what its
/// features are named and what computes them.
pub struct Family {
    /// The option that asks for it: its key in learning jobs' JSON (`log_features`); with
    /// dashes, its command-line flag (`--log-features`).
    pub option: &'static str,
    /// What the option does: the OpenAPI description, and the command line's help (its lines
    /// joined and without the final period, as clap writes a doc comment).
    pub help: &'static str,
    /// The key a model file's feature configuration records it by (`log_domain`).
    pub key: &'static str,
    /// Whether a configuration records the key when the family is off (`log_domain`, which
    /// every model file has; the later families are absent from older files).
    pub recorded_when_off: bool,
    /// The prefix of its features' names (within a block, for a family inside the blocks).
    pub prefix: &'static str,
    /// A feature added to the family later, which model files from before it do not compute.
    pub addition: Option<Addition>,
    /// Where its features sit and what computes them.
    pub(crate) kind: Kind,
}

/// A later feature of a family: a model file that has the family but not this key computes
/// the family's first `before` features only, the row it was trained on.
pub struct Addition {
    /// The key a configuration records it by (`centre_cos`).
    pub key: &'static str,
    /// The family's number of features before it.
    pub before: usize,
}

/// Where a family's features sit, and what computes them.
pub(crate) enum Kind {
    /// The whole block again (with the families inside it), on an image made from the
    /// white-normalized annulus; named as the block with the family's prefix.
    Block(ImageOf),
    /// Features inside each block, after the band powers.
    InBlock(&'static dyn InBlock),
    /// Features of the sphere, after the blocks.
    OfSphere(&'static dyn OfSphere),
}

/// The image a family of blocks makes of the white-normalized annulus.
pub(crate) type ImageOf = fn(&Array2<f64>) -> Array2<f64>;

/// What computes a family inside each block.
pub(crate) trait InBlock: Sync {
    /// Number of its features in a block of `levels` pyramid levels.
    fn count(&self, levels: usize) -> usize;
    /// Their names, in order.
    fn names(&self, levels: usize) -> Vec<String>;
    /// The deepest pyramid level (0: the finest) the features that `need` accepts read
    /// (`None`: no level).
    fn deepest(&self, levels: usize, need: &dyn Fn(usize) -> bool) -> Option<usize>;
    /// The features that `need` accepts (indices into its own), into `out` (its features).
    fn put(&self, block: &Block<'_>, need: &dyn Fn(usize) -> bool, out: &mut [f64]);
}

/// One block's image as the families inside blocks read it.
pub(crate) struct Block<'a> {
    /// The image (rows: radius, columns: angle).
    pub image: &'a Array2<f64>,
    /// Its pyramid's levels, finest first: all of them, or those down to the deepest a subset
    /// of the features needs.
    pub pyramid: &'a [Level],
    /// The configuration's pyramid levels.
    pub levels: usize,
    /// The observed part statistics read (`None`: everything).
    pub support: Option<&'a Support<'a>>,
}

impl Block<'_> {
    /// The observed cells of the image (`None`: all).
    pub fn pixels(&self) -> Option<&Array2<bool>> {
        self.support.map(|s| s.pixels)
    }

    /// The supported coefficients of subband `band` (0 h, 1 v, 2 d) of `level` (`None`: all).
    pub fn band(&self, level: usize, band: usize) -> Option<&Array2<bool>> {
        let level = self.support.and_then(|s| s.levels.get(level))?;
        Some([&level.h, &level.v, &level.d][band])
    }

    /// The supported coefficients of `level` (`None`: all).
    pub fn level(&self, level: usize) -> Option<&Level<bool>> {
        self.support.and_then(|s| s.levels.get(level))
    }
}

/// What computes a family of the sphere.
pub(crate) trait OfSphere: Sync {
    /// Its features' names, in order.
    fn names(&self) -> &'static [&'static str];
    /// Its features of `sphere`: every one that `wanted` accepts (by index into its own);
    /// the others may be NaN.
    fn extract(&self, sphere: &Seen<'_>, wanted: &dyn Fn(usize) -> bool) -> Vec<f64>;
}

/// A sphere as the families of the sphere read it: a photographed sphere, or an object's
/// equivalent sphere. A photographed sphere is the object whose observed part is everything.
pub(crate) struct Seen<'a> {
    /// The image as given (an object's: its equivalent sphere, missing cells filled).
    pub given: CowArray<'a, f64, Ix2>,
    /// The sphere in it.
    pub circle: Circle,
    /// The image reduced to the working radius, and the sphere in it, when the configuration
    /// has one and the sphere is larger (an object's equivalent sphere is built at it).
    pub reduced: Option<(Array2<f64>, Circle)>,
    /// White, in the image's units.
    pub white: f64,
    /// The value the image's samples clip at (`None`: they do not, as in floating point).
    pub full_scale: Option<f64>,
    /// Whether the rim's blur is read as the features see the sphere ([`Seen::seen`]).
    pub blur_as_seen: bool,
    /// The white-normalized annulus the blocks read (rows: radius, columns: angle).
    pub annulus: Array2<f64>,
    /// Which of its cells are observed (`None`: all).
    pub observed: Option<Observed>,
    /// An object's equivalent sphere (`None`: a photographed sphere).
    pub equivalent: Option<&'a EquivalentSphere>,
    /// The capture measurements, once measured (the `cap.*` features and the capture
    /// envelope both read them).
    pub capture: OnceCell<CaptureMeasurements>,
}

impl Seen<'_> {
    /// The image as the features see it, and the sphere in it: reduced to the working
    /// radius, if it was.
    pub fn seen(&self) -> (ArrayView2<'_, f64>, &Circle) {
        match &self.reduced {
            Some((image, circle)) => (image.view(), circle),
            None => (self.given.view(), &self.circle),
        }
    }
}

/// A set of the optional families: those a user asks for, those a feature set names, those
/// a configuration computes. A family in a set has its [`Addition`] too, unless the set was
/// read from a model file from before it.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Families {
    /// One bit per family, in [`FAMILIES`] order.
    on: u16,
    /// One bit per family whose addition is recorded.
    additions: u16,
}

/// The position of `family` in [`FAMILIES`].
const fn index(family: &Family) -> usize {
    let mut i = 0;
    while i < FAMILIES.len() {
        if same(FAMILIES[i].key, family.key) {
            return i;
        }
        i += 1;
    }
    panic!("a family missing from FAMILIES")
}

/// `a == b`, in a const fn.
const fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

impl Families {
    /// No family.
    pub const NONE: Families = Families {
        on: 0,
        additions: 0,
    };

    /// Every family.
    pub const ALL: Families = {
        let mut all = Families::NONE;
        let mut i = 0;
        while i < FAMILIES.len() {
            all = all.with(FAMILIES[i]);
            i += 1;
        }
        all
    };

    /// These and `family`, with its addition.
    pub const fn with(self, family: &Family) -> Families {
        let bit = 1 << index(family);
        Families {
            on: self.on | bit,
            additions: match family.addition {
                Some(_) => self.additions | bit,
                None => self.additions,
            },
        }
    }

    /// These with `family` recorded as on or off, and its addition as recorded or not (as
    /// a model file says).
    pub(crate) fn recorded(self, family: &Family, on: bool, addition: bool) -> Families {
        let bit = 1 << index(family);
        let set = |bits: u16, to: bool| if to { bits | bit } else { bits & !bit };
        Families {
            on: set(self.on, on),
            additions: set(self.additions, addition && family.addition.is_some()),
        }
    }

    /// Whether `family` is in the set.
    pub fn contains(&self, family: &Family) -> bool {
        self.on & (1 << index(family)) != 0
    }

    /// Whether the set records `family`'s addition (see [`Addition`]).
    pub fn has_addition(&self, family: &Family) -> bool {
        self.additions & (1 << index(family)) != 0
    }

    /// Both sets.
    pub fn union(self, other: Families) -> Families {
        Families {
            on: self.on | other.on,
            additions: self.additions | other.additions,
        }
    }

    /// The same families, each with its addition.
    pub fn completed(self) -> Families {
        self.iter().fold(Families::NONE, Families::with)
    }

    /// The families in the set, in [`FAMILIES`] order.
    pub fn iter(self) -> impl Iterator<Item = &'static Family> {
        FAMILIES.into_iter().filter(move |f| self.contains(f))
    }

    /// The families whose features occur among `names` (a table's columns, a list).
    pub fn of_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Families {
        names.into_iter().fold(Families::NONE, |seen, name| {
            // Inside the blocks of a family of blocks, a name is the block's.
            let blocks = FAMILIES
                .into_iter()
                .filter(|f| matches!(f.kind, Kind::Block(_)));
            let in_block = blocks
                .clone()
                .find_map(|f| name.strip_prefix(f.prefix))
                .unwrap_or(name);
            let named = |f: &&Family| match f.kind {
                Kind::InBlock(_) => in_block.starts_with(f.prefix),
                Kind::Block(_) | Kind::OfSphere(_) => name.starts_with(f.prefix),
            };
            FAMILIES
                .into_iter()
                .filter(named)
                .fold(seen, Families::with)
        })
    }
}

impl std::fmt::Debug for Families {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut set = f.debug_set();
        for family in FAMILIES {
            match (self.contains(family), &family.addition) {
                (true, Some(a)) if !self.has_addition(family) => {
                    set.entry(&format_args!("{} (without {})", family.key, a.key))
                }
                (true, _) => set.entry(&format_args!("{}", family.key)),
                (false, _) => &mut set,
            };
        }
        set.finish()
    }
}

impl FromIterator<&'static Family> for Families {
    fn from_iter<I: IntoIterator<Item = &'static Family>>(families: I) -> Self {
        families.into_iter().fold(Families::NONE, Families::with)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_has_its_own_option_key_and_prefix() {
        for (i, a) in FAMILIES.iter().enumerate() {
            assert_eq!(index(a), i);
            for b in &FAMILIES[i + 1..] {
                assert!(a.option != b.option && a.key != b.key && a.prefix != b.prefix);
            }
            assert!(a.option.ends_with("_features"), "{}", a.option);
        }
        assert_eq!(FAMILIES.len(), Families::ALL.iter().count());
    }

    #[test]
    fn a_set_records_additions_apart_from_families() {
        let centre = Families::NONE.with(&CENTRE);
        assert!(centre.contains(&CENTRE) && centre.has_addition(&CENTRE));
        let old = Families::NONE.recorded(&CENTRE, true, false);
        assert!(old.contains(&CENTRE) && !old.has_addition(&CENTRE));
        assert_eq!(old.completed(), centre);
        assert_eq!(format!("{old:?}"), "{centre (without centre_cos)}");
        // A family without an addition records none.
        assert_eq!(
            Families::NONE.recorded(&LOG, true, true),
            Families::NONE.with(&LOG)
        );
    }
}
