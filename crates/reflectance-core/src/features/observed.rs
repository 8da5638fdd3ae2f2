//! Features over the observed part of an annulus (docs/design.md §9, issue #44): an
//! object's equivalent sphere shows only the normals the object turns towards the camera,
//! so its unwrapped annulus has missing cells. Every statistic reads observed data only:
//!
//! - pixel statistics and radial changes: over the observed cells;
//! - subband statistics, variance ratios and orientation dependencies: over the
//!   coefficients whose whole support is observed ([`pyramid::supported`]), so what fills
//!   the missing cells cannot change them;
//! - band powers: of the annulus with its missing cells set to the observed mean, divided
//!   by the observed fraction (a gappy periodogram: a zero-mean field masked to a fraction
//!   f keeps f of its power in expectation, and the bands still sum to the observed
//!   variance).
//!
//! A subband or ring with fewer than [`MIN_SUPPORTED`] such values (a coarse level over a
//! patchy sphere) is read whole, over the mean-filled annulus.

use super::pyramid::{self, Edge, Level};
use ndarray::Array2;
use std::borrow::Cow;

/// The least fraction of the annulus's cells an object must show for its features to be
/// read: below it, statistics of a few patches say little about the material.
pub const MIN_OBSERVED: f64 = 0.2;

/// Fewest values a statistic reads over the observed part before it reads the whole grid.
pub const MIN_SUPPORTED: usize = 16;

/// An unwrapped cell is observed when this share of its samples fell on observed cells of
/// the equivalent sphere (all of them, up to rounding).
const SEEN: f64 = 0.999;

/// Which cells of an unwrapped annulus the object showed.
#[derive(Clone, Debug, PartialEq)]
pub struct Observed {
    /// Observed cells (rows: radius, columns: angle), the unwrapped grid's shape.
    pub mask: Array2<bool>,
    /// The fraction of the grid's cells observed, in [0, 1].
    pub fraction: f64,
}

/// Why an object's annulus gives no features.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ObservedError {
    /// Too little of the equivalent sphere's annulus is observed.
    #[error(
        "the object shows {:.0} % of the sphere's annulus and the features need at least \
         {:.0} %: photograph a part of it that turns through more directions (a flat face or \
         a cylinder seen side-on shows too few), or check that the normals match the image",
        fraction * 100.0,
        needed * 100.0
    )]
    TooLittle {
        /// The fraction observed.
        fraction: f64,
        /// [`MIN_OBSERVED`].
        needed: f64,
    },
}

impl Observed {
    /// The observed cells of an unwrapped coverage (each cell the share of its samples that
    /// fell on observed cells), when there are enough of them.
    pub fn from_coverage(coverage: &Array2<f64>) -> Result<Observed, ObservedError> {
        let mask = coverage.mapv(|c| c >= SEEN);
        let seen = mask.iter().filter(|&&m| m).count();
        let fraction = seen as f64 / mask.len().max(1) as f64;
        if fraction < MIN_OBSERVED {
            return Err(ObservedError::TooLittle {
                fraction,
                needed: MIN_OBSERVED,
            });
        }
        Ok(Observed { mask, fraction })
    }

    /// `unwrapped` with its missing cells set to the mean of the observed ones.
    pub fn filled(&self, unwrapped: &Array2<f64>) -> Array2<f64> {
        let (sum, count) =
            ndarray::Zip::from(unwrapped)
                .and(&self.mask)
                .fold((0.0, 0usize), |(s, n), &v, &m| match m {
                    true => (s + v, n + 1),
                    false => (s, n),
                });
        let mean = sum / count.max(1) as f64;
        ndarray::Zip::from(unwrapped)
            .and(&self.mask)
            .map_collect(|&v, &m| if m { v } else { mean })
    }

    /// Where the statistics of each block read: the cells, and the coefficients of each of
    /// `levels` pyramid levels whose support is observed.
    pub(crate) fn support(&self, levels: usize) -> Support<'_> {
        Support {
            pixels: &self.mask,
            levels: pyramid::supported(self.mask.view(), levels, Edge::Periodic),
            fraction: self.fraction,
        }
    }
}

/// What a block's statistics read over an annulus with missing cells.
pub(crate) struct Support<'a> {
    /// The observed cells.
    pub pixels: &'a Array2<bool>,
    /// The supported coefficients, finest level first.
    pub levels: Vec<Level<bool>>,
    /// The observed fraction: the band powers' divisor.
    pub fraction: f64,
}

/// The values of `values` where `keep` is set (row-major), or all of them where fewer than
/// [`MIN_SUPPORTED`] are (or `keep` is `None`, or not of their shape).
pub(crate) fn kept<'a>(values: &'a Array2<f64>, keep: Option<&Array2<bool>>) -> Cow<'a, [f64]> {
    let all = || match values.as_slice() {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(values.iter().copied().collect()),
    };
    let Some(keep) = keep.filter(|k| k.dim() == values.dim()) else {
        return all();
    };
    let chosen: Vec<f64> = values
        .iter()
        .zip(keep.iter())
        .filter_map(|(&v, &k)| k.then_some(v))
        .collect();
    if chosen.len() < MIN_SUPPORTED {
        return all();
    }
    Cow::Owned(chosen)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn too_little_coverage_is_refused_with_its_fraction() {
        let coverage = Array2::from_shape_fn((10, 10), |(r, _)| if r < 1 { 1.0 } else { 0.5 });
        let err = Observed::from_coverage(&coverage).unwrap_err();
        assert_eq!(
            err,
            ObservedError::TooLittle {
                fraction: 0.1,
                needed: MIN_OBSERVED
            }
        );
        assert!(err.to_string().contains("10 %"), "{err}");
    }

    #[test]
    fn filling_keeps_observed_cells_and_sets_the_rest_to_their_mean() {
        let coverage = Array2::from_shape_fn((4, 8), |(_, c)| if c < 4 { 1.0 } else { 0.0 });
        let observed = Observed::from_coverage(&coverage).unwrap();
        assert_eq!(observed.fraction, 0.5);
        let values = Array2::from_shape_fn((4, 8), |(r, c)| (r * 8 + c) as f64);
        let filled = observed.filled(&values);
        let mean = (0..4)
            .flat_map(|r| (0..4).map(move |c| (r * 8 + c) as f64))
            .sum::<f64>()
            / 16.0;
        for ((r, c), &v) in filled.indexed_iter() {
            let want = if c < 4 { values[(r, c)] } else { mean };
            assert_eq!(v, want, "({r}, {c})");
        }
    }

    #[test]
    fn kept_values_fall_back_to_all_when_too_few_are_kept() {
        let values = Array2::from_shape_fn((8, 8), |(r, c)| (r * 8 + c) as f64);
        let half = Array2::from_shape_fn((8, 8), |(r, _)| r < 4);
        assert_eq!(kept(&values, Some(&half)).len(), 32);
        let few = Array2::from_shape_fn((8, 8), |(r, c)| r == 0 && c < 3);
        assert_eq!(kept(&values, Some(&few)).len(), 64);
        assert_eq!(kept(&values, None).len(), 64);
    }
}
