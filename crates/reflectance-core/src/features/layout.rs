//! Where each feature sits in the vector. This is the one description of the canonical
//! order (docs/design.md §3 "The 117 features"): the names, the full extraction and the
//! subset extraction all index through it. The optional families sit in [`FAMILIES`] order,
//! each laid out within its place by its own module.

use super::BAND_NAMES;
use super::families::{FAMILIES, Families, Family, ImageOf, InBlock, Kind, OfSphere};
use super::spectrum::ORIENTATIONS;
use super::stats::STAT_NAMES;
use std::ops::Range;

/// Statistics per image or subband: mean, var, skew, kurt, p10, p50, p90.
pub const STATS: usize = STAT_NAMES.len();
/// Radial frequency bands with orientations (`fft.b1` … `fft.b4`).
const RADIAL_BANDS: usize = 4;
/// The oriented band powers, band by band, then `fft.lo.pow`.
const BAND_POWERS: usize = RADIAL_BANDS * ORIENTATIONS.len() + 1;

/// The features of one image (the unwrapped annulus, or its log10), in order: the pixels'
/// statistics, each subband's statistics (level by level, h, v, d), the variance ratios
/// (band by band, finer over coarser), the band powers, then the families inside blocks
/// (the radial changes, ring pair by ring pair; the orientation dependencies, level by level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockLayout {
    /// Pyramid levels (subbands: 3 per level).
    pub levels: usize,
    /// The families (those inside blocks count here).
    pub families: Families,
}

impl BlockLayout {
    /// The first of the pixels' statistics.
    pub const PIXELS: usize = 0;

    /// The first statistic of subband `band` (0 h, 1 v, 2 d) of `level` (0 finest).
    pub fn band(&self, level: usize, band: usize) -> usize {
        STATS * (1 + 3 * level + band)
    }

    fn ratios(&self) -> usize {
        self.band(self.levels, 0)
    }

    /// `ratio.{band}.s{pair+1}_s{pair+2}`.
    pub fn ratio(&self, band: usize, pair: usize) -> usize {
        self.ratios() + band * (self.levels - 1) + pair
    }

    /// `fft.b{1..4}.f{0,45,90,135}.pow` (band, then orientation), then `fft.lo.pow`.
    pub fn band_powers(&self) -> Range<usize> {
        let start = self.ratios() + 3 * (self.levels - 1);
        start..start + BAND_POWERS
    }

    /// The families inside blocks, each with where its features sit in the block (empty
    /// without it), in [`FAMILIES`] order.
    fn inside(
        &self,
    ) -> impl Iterator<Item = (&'static Family, &'static dyn InBlock, Range<usize>)> {
        let mut start = self.band_powers().end;
        FAMILIES.into_iter().filter_map(move |family| {
            let Kind::InBlock(inside) = family.kind else {
                return None;
            };
            let count = match self.families.contains(family) {
                true => inside.count(self.levels),
                false => 0,
            };
            start += count;
            Some((family, inside, start - count..start))
        })
    }

    /// The families inside blocks this block has, each with where its features sit.
    pub(crate) fn families_inside(
        &self,
    ) -> impl Iterator<Item = (&'static dyn InBlock, Range<usize>)> {
        self.inside()
            .filter(|(_, _, at)| !at.is_empty())
            .map(|(_, inside, at)| (inside, at))
    }

    /// Where the features of `family`, a family inside blocks, sit in the block (empty
    /// without it).
    pub fn family(&self, family: &Family) -> Range<usize> {
        let end = self.band_powers().end;
        self.inside()
            .find(|(f, ..)| f.key == family.key)
            .map_or(end..end, |(.., at)| at)
    }

    /// Number of features of the block.
    pub fn count(&self) -> usize {
        self.inside()
            .last()
            .map_or(self.band_powers().end, |(.., at)| at.end)
    }

    /// The names, each written at its index.
    pub fn names(&self) -> Vec<String> {
        let mut names = vec![String::new(); self.band_powers().end];
        for (s, stat) in STAT_NAMES.iter().enumerate() {
            names[Self::PIXELS + s] = format!("pix.{stat}");
        }
        for level in 0..self.levels {
            for (b, band) in BAND_NAMES.iter().enumerate() {
                for (s, stat) in STAT_NAMES.iter().enumerate() {
                    names[self.band(level, b) + s] = format!("wav.s{}.{band}.{stat}", level + 1);
                }
            }
        }
        for (b, band) in BAND_NAMES.iter().enumerate() {
            for pair in 0..self.levels - 1 {
                names[self.ratio(b, pair)] = format!("ratio.{band}.s{}_s{}", pair + 1, pair + 2);
            }
        }
        let powers = self.band_powers();
        for b in 0..RADIAL_BANDS {
            for (o, orientation) in ORIENTATIONS.iter().enumerate() {
                names[powers.start + b * ORIENTATIONS.len() + o] =
                    format!("fft.b{}.{orientation}.pow", b + 1);
            }
        }
        names[powers.end - 1] = "fft.lo.pow".into();
        for (inside, _) in self.families_inside() {
            names.extend(inside.names(self.levels));
        }
        names
    }
}

/// The whole vector: the block of the unwrapped image, the block again for each family of
/// blocks (the log10 image's, names prefixed `log.`), then the families of the sphere (the
/// capture measurements, the centre features, the domain measurements).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The block of one image.
    pub block: BlockLayout,
    /// The families.
    pub families: Families,
}

impl Layout {
    /// The layout of `levels` pyramid levels and the `families`.
    pub fn new(levels: usize, families: Families) -> Layout {
        Layout {
            block: BlockLayout { levels, families },
            families,
        }
    }

    /// The blocks' features: one image's, and one more per family of blocks.
    pub fn blocks(&self) -> Range<usize> {
        let repeats = self.blocks_again().count();
        0..(1 + repeats) * self.block.count()
    }

    /// The families of blocks this layout has, each with the image its block reads and
    /// where the block sits.
    pub(crate) fn blocks_again(&self) -> impl Iterator<Item = (ImageOf, Range<usize>)> {
        let n = self.block.count();
        self.families
            .iter()
            .filter_map(|family| match family.kind {
                Kind::Block(image) => Some(image),
                Kind::InBlock(_) | Kind::OfSphere(_) => None,
            })
            .enumerate()
            .map(move |(k, image)| (image, (k + 1) * n..(k + 2) * n))
    }

    /// The families of the sphere, each with where its features sit (empty without it), in
    /// [`FAMILIES`] order.
    fn of_sphere(
        &self,
    ) -> impl Iterator<Item = (&'static Family, &'static dyn OfSphere, Range<usize>)> {
        let mut start = self.blocks().end;
        FAMILIES.into_iter().filter_map(move |family| {
            let Kind::OfSphere(of) = family.kind else {
                return None;
            };
            let count = match (self.families.contains(family), &family.addition) {
                (false, _) => 0,
                (true, Some(a)) if !self.families.has_addition(family) => a.before,
                (true, _) => of.names().len(),
            };
            start += count;
            Some((family, of, start - count..start))
        })
    }

    /// The families of the sphere this layout has, each with where its features sit.
    pub(crate) fn families_of_sphere(
        &self,
    ) -> impl Iterator<Item = (&'static dyn OfSphere, Range<usize>)> {
        self.of_sphere()
            .filter(|(_, _, at)| !at.is_empty())
            .map(|(_, of, at)| (of, at))
    }

    /// Where the features of `family` sit: a family of the sphere's (empty without it, where
    /// they would sit), the block of a family of blocks, or a family inside blocks' in the
    /// first block.
    pub fn family(&self, family: &Family) -> Range<usize> {
        let end = self.blocks().end;
        match family.kind {
            Kind::InBlock(_) => self.block.family(family),
            Kind::Block(_) => {
                let mut blocks = self
                    .families
                    .iter()
                    .filter(|f| matches!(f.kind, Kind::Block(_)));
                match blocks.position(|f| f.key == family.key) {
                    Some(k) => {
                        let n = self.block.count();
                        (k + 1) * n..(k + 2) * n
                    }
                    None => end..end,
                }
            }
            Kind::OfSphere(_) => self
                .of_sphere()
                .find(|(f, ..)| f.key == family.key)
                .map_or(end..end, |(.., at)| at),
        }
    }

    /// Number of features (117 with the default configuration).
    pub fn count(&self) -> usize {
        self.of_sphere()
            .last()
            .map_or(self.blocks().end, |(.., at)| at.end)
    }

    /// The feature names, in canonical order (see [`super::FeatureConfig::names`]).
    pub fn names(&self) -> Vec<String> {
        let block = self.block.names();
        let mut names = block.clone();
        for family in self.families.iter() {
            if let Kind::Block(_) = family.kind {
                names.extend(block.iter().map(|n| format!("{}{n}", family.prefix)));
            }
        }
        for (of, at) in self.families_of_sphere() {
            names.extend(of.names()[..at.len()].iter().map(|n| n.to_string()));
        }
        names
    }
}

#[cfg(test)]
mod tests {
    use crate::features::FeatureConfig;
    use crate::features::families::{FAMILIES, Families};
    use std::collections::HashSet;

    #[test]
    fn every_index_has_exactly_one_name_in_every_configuration() {
        for bits in 0..1u32 << FAMILIES.len() {
            let families: Families = (FAMILIES.into_iter().enumerate())
                .filter(|(i, _)| bits & 1 << i != 0)
                .map(|(_, family)| family)
                .collect();
            for levels in [2, 4, 5] {
                let config = FeatureConfig {
                    levels,
                    ..FeatureConfig::extended(families, Default::default())
                };
                let layout = config.layout();
                let names = layout.names();
                assert_eq!(names.len(), layout.count());
                assert!(names.iter().all(|n| !n.is_empty()), "{families:?}: a hole");
                let unique: HashSet<_> = names.iter().collect();
                assert_eq!(unique.len(), names.len(), "{families:?}: a name twice");
            }
        }
    }
}
