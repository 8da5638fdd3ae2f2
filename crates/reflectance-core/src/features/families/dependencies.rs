//! The orientation dependencies (`dep.*`, docs/design.md §8): in each block, the Pearson
//! correlations of the coefficient magnitudes of each level's orientations (the paper's §7:
//! neighbouring orientations depend on each other at edges, and a blur changes how much).

use super::{Block, Family, InBlock, Kind};
use crate::features::BAND_NAMES;
use crate::features::observed::kept;
use crate::features::pyramid::Level;

/// Prefix of the orientation-dependency features' names (within a block).
pub const DEPENDENCY_PREFIX: &str = "dep.";
/// The pairs of orientations whose subband magnitudes the dependency features correlate.
const ORIENTATION_PAIRS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// The orientation-dependency family.
pub const DEPENDENCIES: Family = Family {
    option: "dependency_features",
    help: "Also compute the orientation dependencies (`dep.*`: correlations of subband\n\
           magnitudes between orientations at each scale, 12 more per block; implied by sets\n\
           such as hand6+log+radial+dep).",
    key: "dependencies",
    recorded_when_off: false,
    prefix: DEPENDENCY_PREFIX,
    addition: None,
    kind: Kind::InBlock(&Dependencies),
};

struct Dependencies;

/// Where the correlation of orientation pair `pair` at `level` sits among the family's features.
fn at(level: usize, pair: usize) -> usize {
    ORIENTATION_PAIRS.len() * level + pair
}

impl InBlock for Dependencies {
    fn count(&self, levels: usize) -> usize {
        ORIENTATION_PAIRS.len() * levels
    }

    /// `dep.s{k}.{hv,hd,vd}`, level by level.
    fn names(&self, levels: usize) -> Vec<String> {
        (0..levels)
            .flat_map(|level| {
                ORIENTATION_PAIRS.map(|(a, b)| {
                    let (a, b) = (BAND_NAMES[a], BAND_NAMES[b]);
                    format!("{DEPENDENCY_PREFIX}s{}.{a}{b}", level + 1)
                })
            })
            .collect()
    }

    fn deepest(&self, levels: usize, need: &dyn Fn(usize) -> bool) -> Option<usize> {
        (0..levels)
            .rev()
            .find(|&level| (0..ORIENTATION_PAIRS.len()).any(|pair| need(at(level, pair))))
    }

    fn put(&self, block: &Block<'_>, need: &dyn Fn(usize) -> bool, out: &mut [f64]) {
        for (level, bands) in block.pyramid.iter().enumerate() {
            if !(0..ORIENTATION_PAIRS.len()).any(|pair| need(at(level, pair))) {
                continue;
            }
            let correlations = orientation_dependencies(bands, block.level(level));
            for (pair, value) in correlations.into_iter().enumerate() {
                if need(at(level, pair)) {
                    out[at(level, pair)] = value;
                }
            }
        }
    }
}

/// Pearson correlations of the coefficient magnitudes of a level's orientations, in
/// [`ORIENTATION_PAIRS`] order. 0 where a band is constant.
fn orientation_dependencies(level: &Level, support: Option<&Level<bool>>) -> [f64; 3] {
    // Over the coefficients supported in all three bands.
    let alike = |s: &&Level<bool>| s.h.dim() == s.v.dim() && s.h.dim() == s.d.dim();
    let both = support.filter(alike).map(|s| {
        ndarray::Zip::from(&s.h)
            .and(&s.v)
            .and(&s.d)
            .map_collect(|&h, &v, &d| h && v && d)
    });
    let bands = [&level.h, &level.v, &level.d].map(|b| kept(b, both.as_ref()));
    let n = bands[0].len().max(1) as f64;
    let means = bands
        .each_ref()
        .map(|band| band.iter().map(|v| v.abs()).sum::<f64>() / n);
    // Two passes in f64: the means, then the centred products of every pair and square.
    let (mut products, mut squares) = ([0.0; 3], [0.0; 3]);
    for ((h, v), d) in bands[0].iter().zip(bands[1].iter()).zip(bands[2].iter()) {
        let c = [h.abs() - means[0], v.abs() - means[1], d.abs() - means[2]];
        for (k, (a, b)) in ORIENTATION_PAIRS.into_iter().enumerate() {
            products[k] += c[a] * c[b];
            squares[k] += c[k] * c[k];
        }
    }
    std::array::from_fn(|k| {
        let (a, b) = ORIENTATION_PAIRS[k];
        if squares[a] > 0.0 && squares[b] > 0.0 {
            products[k] / (squares[a] * squares[b]).sqrt()
        } else {
            0.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    #[test]
    fn orientation_dependencies_correlate_subband_magnitudes() {
        let pattern = Array2::from_shape_fn((8, 16), |(i, j)| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        let level = Level {
            v: pattern.mapv(|x| -3.0 * x),
            d: Array2::from_elem((8, 16), 0.5),
            h: pattern,
        };
        // |v| = 3|h| exactly; d is constant, so it correlates with nothing.
        let [hv, hd, vd] = orientation_dependencies(&level, None);
        assert!((hv - 1.0).abs() < 1e-12, "{hv}");
        assert_eq!((hd, vd), (0.0, 0.0));
        let opposite = Array2::from_shape_fn((8, 16), |(i, _)| if i < 4 { 1.0 } else { 2.0 });
        let level = Level {
            h: opposite.clone(),
            v: opposite.mapv(|x| 3.0 - x),
            d: opposite,
        };
        let [hv, hd, _] = orientation_dependencies(&level, None);
        assert!(
            (hv + 1.0).abs() < 1e-12 && (hd - 1.0).abs() < 1e-12,
            "{hv} {hd}"
        );
    }
}
