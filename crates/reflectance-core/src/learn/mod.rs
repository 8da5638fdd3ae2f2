//! What the classifier and the estimator share: a feature table as a dense matrix
//! ([`Dataset`]), feature-set specifications ([`FeatureSet`]), standardization, the normal
//! distribution, and the learning layer's error type.
//!
//! Everything is deterministic for a fixed seed and independent of the number of threads:
//! randomness comes only from [`crate::util::rng::Rng`] streams forked per task, and parallel
//! loops collect their results in a fixed order.

pub(crate) mod error;
pub(crate) mod feature_set;
pub mod matrix;
pub(crate) mod normal;
pub mod scaler;

pub use error::{Inconsistent, LearnError};
pub use feature_set::FeatureSet;
pub use matrix::Dataset;

#[cfg(test)]
pub(crate) mod testutil {
    use crate::dataset::{FeatureTable, Sample};
    use crate::util::rng::Rng;

    /// A small synthetic table: `classes` × `groups` × `per_cell` rows of `features`
    /// columns `f0…`, class centres plus an illumination shift plus uniform noise.
    pub fn table(
        seed: u64,
        classes: usize,
        groups: usize,
        per_cell: usize,
        features: usize,
        noise: f64,
    ) -> FeatureTable {
        let mut rng = Rng::new(seed);
        let mut centre = vec![vec![0.0; features]; classes];
        for c in centre.iter_mut() {
            for v in c.iter_mut() {
                *v = rng.next_f64() * 4.0 - 2.0;
            }
        }
        let shift: Vec<Vec<f64>> = (0..groups)
            .map(|_| (0..features).map(|_| rng.next_f64() - 0.5).collect())
            .collect();
        let mut samples = Vec::new();
        for (g, shift) in shift.iter().enumerate() {
            for (c, centre) in centre.iter().enumerate() {
                for v in 0..per_cell {
                    let values = (0..features)
                        .map(|j| centre[j] + shift[j] + noise * (rng.next_f64() * 2.0 - 1.0))
                        .collect();
                    samples.push(Sample {
                        path: format!("g{g}/c{c}_{v}.png"),
                        class: format!("c{c}"),
                        illumination: format!("g{g}"),
                        values,
                    });
                }
            }
        }
        FeatureTable {
            names: (0..features).map(|j| format!("f{j}")).collect(),
            samples,
        }
    }
}
