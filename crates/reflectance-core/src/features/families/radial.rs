//! The radial changes (`radial.*`, docs/design.md §8): in each block, how the statistics
//! change from ring to ring of the annulus. The rows of the image and of every subband are cut
//! into [`RADIAL_RINGS`] rings of equal height; each ring is compared with the one inside it:
//! the pixels' mean and log10 variance, and every subband's log10 variance.

use super::{Block, Family, InBlock, Kind};
use crate::features::BAND_NAMES;
use crate::features::observed::kept;
use crate::features::stats::{Moments, log10_floor, moments};
use ndarray::Array2;

/// Prefix of the radial-change features' names (within a block).
pub const RADIAL_PREFIX: &str = "radial.";
/// The radial changes cut the rows of the unwrapped annulus (and of each subband) into this
/// many rings of equal height and compare each with the one inside it.
pub const RADIAL_RINGS: usize = 3;

/// The radial-change family.
pub const RADIAL: Family = Family {
    option: "radial_features",
    help: "Also compute the radial changes (`radial.*`: each of three rings of the annulus minus\n\
           the one inside it, 28 more per block; implied by sets such as hand6+log+radial).",
    key: "radial",
    recorded_when_off: false,
    prefix: RADIAL_PREFIX,
    addition: None,
    kind: Kind::InBlock(&Radial),
};

struct Radial;

/// The changes between two neighbouring rings: the pixels' mean and variance, then the
/// variance of every subband.
fn per_pair(levels: usize) -> usize {
    2 + 3 * levels
}

/// Where change `slot` between ring `pair` + 1 and the one inside it sits among the family's
/// features: slot 0 the pixels' mean, 1 their variance, then [`band_slot`].
fn at(levels: usize, pair: usize, slot: usize) -> usize {
    pair * per_pair(levels) + slot
}

/// The slot of subband (`level`, `band`) within a ring pair's changes.
fn band_slot(level: usize, band: usize) -> usize {
    2 + 3 * level + band
}

impl InBlock for Radial {
    fn count(&self, levels: usize) -> usize {
        (RADIAL_RINGS - 1) * per_pair(levels)
    }

    /// `radial.r{t}_r{t+1}.pix.{mean,var}` and `radial.r{t}_r{t+1}.wav.s{k}.{h,v,d}.var`.
    fn names(&self, levels: usize) -> Vec<String> {
        let mut names = Vec::with_capacity(self.count(levels));
        for pair in 0..RADIAL_RINGS - 1 {
            let prefix = format!("{RADIAL_PREFIX}r{}_r{}.", pair + 1, pair + 2);
            names.push(format!("{prefix}pix.mean"));
            names.push(format!("{prefix}pix.var"));
            for level in 0..levels {
                for band in BAND_NAMES {
                    names.push(format!("{prefix}wav.s{}.{band}.var", level + 1));
                }
            }
        }
        names
    }

    fn deepest(&self, levels: usize, need: &dyn Fn(usize) -> bool) -> Option<usize> {
        (0..levels)
            .rev()
            .find(|&level| (0..3).any(|band| needed(levels, band_slot(level, band), need)))
    }

    fn put(&self, block: &Block<'_>, need: &dyn Fn(usize) -> bool, out: &mut [f64]) {
        let levels = block.levels;
        if needed(levels, 0, need) || needed(levels, 1, need) {
            let changes = ring_changes(block.image, block.pixels());
            for (pair, [mean, var]) in changes.into_iter().enumerate() {
                for (slot, value) in [(0, mean), (1, var)] {
                    let i = at(levels, pair, slot);
                    if need(i) {
                        out[i] = value;
                    }
                }
            }
        }
        for (level, bands) in block.pyramid.iter().enumerate() {
            for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
                let slot = band_slot(level, band);
                if !needed(levels, slot, need) {
                    continue;
                }
                let changes = ring_changes(values, block.band(level, band));
                for (pair, [_, var]) in changes.into_iter().enumerate() {
                    let i = at(levels, pair, slot);
                    if need(i) {
                        out[i] = var;
                    }
                }
            }
        }
    }
}

/// Whether `need` accepts change `slot` of any ring pair.
fn needed(levels: usize, slot: usize, need: &dyn Fn(usize) -> bool) -> bool {
    (0..RADIAL_RINGS - 1).any(|pair| need(at(levels, pair, slot)))
}

/// `[mean, log10 variance]` of each ring of rows minus those of the ring inside it, over
/// the values `keep` keeps ([`kept`]). Ring k (from 0, innermost) holds rows
/// ⌊k·n/R⌋ .. ⌊(k+1)·n/R⌋ of n, R = [`RADIAL_RINGS`].
fn ring_changes(a: &Array2<f64>, keep: Option<&Array2<bool>>) -> [[f64; 2]; RADIAL_RINGS - 1] {
    let rows = a.nrows();
    let ring = |k: usize| {
        let span = ndarray::s![k * rows / RADIAL_RINGS..(k + 1) * rows / RADIAL_RINGS, ..];
        let values = a.slice(span).to_owned();
        let keep = keep.map(|m| m.slice(span).to_owned());
        moments(&kept(&values, keep.as_ref()))
    };
    let rings: [Moments; RADIAL_RINGS] = std::array::from_fn(ring);
    std::array::from_fn(|t| {
        let (inner, outer) = (&rings[t], &rings[t + 1]);
        [
            outer.mean - inner.mean,
            log10_floor(outer.var) - log10_floor(inner.var),
        ]
    })
}
