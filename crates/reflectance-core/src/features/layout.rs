//! Where each feature sits in the vector. This is the one description of the canonical
//! order (docs/design.md §3 "The 117 features"): the names, the full extraction and the
//! subset extraction all index through it, so a new family is added here once.

use super::spectrum::ORIENTATIONS;
use super::stats::STAT_NAMES;
use super::{
    BAND_NAMES, CAPTURE_NAMES, CENTRE_NAMES, DEPENDENCY_PREFIX, DOMAIN_NAMES, LOG_PREFIX,
    ORIENTATION_PAIRS, RADIAL_PREFIX, RADIAL_RINGS,
};
use std::ops::Range;

/// Statistics per image or subband: mean, var, skew, kurt, p10, p50, p90.
pub const STATS: usize = STAT_NAMES.len();
/// Radial frequency bands with orientations (`fft.b1` … `fft.b4`).
const RADIAL_BANDS: usize = 4;
/// The oriented band powers, band by band, then `fft.lo.pow`.
const BAND_POWERS: usize = RADIAL_BANDS * ORIENTATIONS.len() + 1;

/// The features of one image (the unwrapped annulus, or its log10), in order: the pixels'
/// statistics, each subband's statistics (level by level, h, v, d), the variance ratios
/// (band by band, finer over coarser), the band powers, then the optional radial changes
/// (ring pair by ring pair) and orientation dependencies (level by level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockLayout {
    /// Pyramid levels (subbands: 3 per level).
    pub levels: usize,
    /// With the radial changes between rings (`radial.*`).
    pub radial: bool,
    /// With the orientation dependencies of each level.
    pub dependencies: bool,
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

    /// Radial changes between two neighbouring rings: the pixels' mean and variance, and
    /// the variance of every subband.
    fn radial_per_pair(&self) -> usize {
        2 + 3 * self.levels
    }

    fn radial_len(&self) -> usize {
        match self.radial {
            true => (RADIAL_RINGS - 1) * self.radial_per_pair(),
            false => 0,
        }
    }

    /// The radial change `slot` between ring `pair` + 1 and the one inside it: slot 0 the
    /// pixels' mean, 1 their variance, then [`BlockLayout::radial_band_slot`].
    pub fn radial(&self, pair: usize, slot: usize) -> usize {
        self.band_powers().end + pair * self.radial_per_pair() + slot
    }

    /// The slot of subband (`level`, `band`) within a ring pair's radial changes.
    pub fn radial_band_slot(level: usize, band: usize) -> usize {
        2 + 3 * level + band
    }

    /// The correlation of orientation pair `pair` ([`ORIENTATION_PAIRS`]) at `level`.
    pub fn dependency(&self, level: usize, pair: usize) -> usize {
        self.band_powers().end + self.radial_len() + ORIENTATION_PAIRS.len() * level + pair
    }

    /// Number of features of the block.
    pub fn count(&self) -> usize {
        let dependencies = match self.dependencies {
            true => ORIENTATION_PAIRS.len() * self.levels,
            false => 0,
        };
        self.band_powers().end + self.radial_len() + dependencies
    }

    /// The names, each written at its index.
    pub fn names(&self) -> Vec<String> {
        let mut names = vec![String::new(); self.count()];
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
        if self.radial {
            self.name_radial(&mut names);
        }
        if self.dependencies {
            for level in 0..self.levels {
                for (pair, (a, b)) in ORIENTATION_PAIRS.into_iter().enumerate() {
                    names[self.dependency(level, pair)] = format!(
                        "{DEPENDENCY_PREFIX}s{}.{}{}",
                        level + 1,
                        BAND_NAMES[a],
                        BAND_NAMES[b]
                    );
                }
            }
        }
        names
    }

    /// `radial.r{t}_r{t+1}.pix.{mean,var}` and `radial.r{t}_r{t+1}.wav.s{k}.{h,v,d}.var`.
    fn name_radial(&self, names: &mut [String]) {
        for pair in 0..RADIAL_RINGS - 1 {
            let prefix = format!("{RADIAL_PREFIX}r{}_r{}.", pair + 1, pair + 2);
            names[self.radial(pair, 0)] = format!("{prefix}pix.mean");
            names[self.radial(pair, 1)] = format!("{prefix}pix.var");
            for level in 0..self.levels {
                for (b, band) in BAND_NAMES.iter().enumerate() {
                    names[self.radial(pair, Self::radial_band_slot(level, b))] =
                        format!("{prefix}wav.s{}.{band}.var", level + 1);
                }
            }
        }
    }
}

/// The whole vector: the block of the unwrapped image, the block of its log10 (with the
/// log-domain extension, names prefixed `log.`), then the capture measurements, the
/// centre features and the domain measurements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The block of one image.
    pub block: BlockLayout,
    /// With the log10 block (`log.*`, the log-domain extension).
    pub log_domain: bool,
    /// With the capture measurements (`cap.*`).
    pub capture: bool,
    /// With the centre features (`ctr.*`).
    pub centre: bool,
    /// Whether the centre family ends with `ctr.cos` (see `FeatureConfig::centre_cos`).
    pub centre_cos: bool,
    /// With the domain measurements (`dom.*`).
    pub domain: bool,
}

impl Layout {
    /// The blocks' features: one image's, or two with the log-domain extension.
    pub fn blocks(&self) -> Range<usize> {
        let blocks = if self.log_domain { 2 } else { 1 };
        0..blocks * self.block.count()
    }

    /// The capture measurements (empty without the extension).
    pub fn capture(&self) -> Range<usize> {
        let start = self.blocks().end;
        match self.capture {
            true => start..start + CAPTURE_NAMES.len(),
            false => start..start,
        }
    }

    /// The centre features (empty without the extension).
    pub fn centre(&self) -> Range<usize> {
        let start = self.capture().end;
        match self.centre {
            true => start..start + CENTRE_NAMES.len() - usize::from(!self.centre_cos),
            false => start..start,
        }
    }

    /// The domain measurements (empty without the extension).
    pub fn domain(&self) -> Range<usize> {
        let start = self.centre().end;
        match self.domain {
            true => start..start + DOMAIN_NAMES.len(),
            false => start..start,
        }
    }

    /// Number of features (117 with the default configuration).
    pub fn count(&self) -> usize {
        self.domain().end
    }

    /// The feature names, in canonical order (see [`super::FeatureConfig::names`]).
    pub fn names(&self) -> Vec<String> {
        let block = self.block.names();
        let log = block
            .iter()
            .filter(|_| self.log_domain)
            .map(|n| format!("{LOG_PREFIX}{n}"))
            .collect::<Vec<_>>();
        let capture = CAPTURE_NAMES
            .iter()
            .filter(|_| self.capture)
            .map(|n| n.to_string());
        let centre = CENTRE_NAMES
            .iter()
            .take(self.centre().len())
            .map(|n| n.to_string());
        let domain = DOMAIN_NAMES
            .iter()
            .filter(|_| self.domain)
            .map(|n| n.to_string());
        block
            .into_iter()
            .chain(log)
            .chain(capture)
            .chain(centre)
            .chain(domain)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::features::{Extensions, FeatureConfig};
    use std::collections::HashSet;

    #[test]
    fn every_index_has_exactly_one_name_in_every_configuration() {
        for bits in 0..64u8 {
            let extensions = Extensions {
                log_domain: bits & 1 != 0,
                radial: bits & 2 != 0,
                dependencies: bits & 4 != 0,
                capture: bits & 8 != 0,
                centre: bits & 16 != 0,
                domain: bits & 32 != 0,
            };
            for levels in [2, 4, 5] {
                let config = FeatureConfig {
                    levels,
                    ..FeatureConfig::extended(extensions, Default::default())
                };
                let layout = config.layout();
                let names = layout.names();
                assert_eq!(names.len(), layout.count());
                assert!(
                    names.iter().all(|n| !n.is_empty()),
                    "{extensions:?}: a hole"
                );
                let unique: HashSet<_> = names.iter().collect();
                assert_eq!(unique.len(), names.len(), "{extensions:?}: a name twice");
            }
        }
    }
}
