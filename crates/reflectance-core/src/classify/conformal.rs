//! Prediction sets by split conformal prediction (docs/design.md §3 "Prediction sets").
//!
//! The score of a class for an image is RAPS's (Angelopoulos et al. 2021, "Uncertainty
//! sets for image classifiers using conformal prediction") without its randomization: the
//! probability mass of the classes ranked above it (most probable first, first class on
//! ties), plus λ for every rank beyond `k_reg`. Deterministic, and 0 for the most probable
//! class, so an image the model is sure of gets one class. The calibration scores are those
//! of the true classes of images whose illumination was held out (the classifier's
//! calibration folds): for a new image under light the model never saw, the set of classes
//! whose score is at most the ⌈(n + 1)·c⌉-th smallest calibration score holds the true
//! class with probability ≥ c (if the new image is exchangeable with them; the fold models
//! saw fewer illuminations than the final one, so the sets lean large).

use crate::learn::Inconsistent;

use super::svm::argmax;
use serde::{Deserialize, Serialize};

/// The coverage asked for when a request names none.
pub const DEFAULT_COVERAGE: f64 = 0.95;
/// RAPS's penalty per rank beyond [`K_REG`].
pub const LAMBDA: f64 = 0.01;
/// Ranks free of the penalty.
pub const K_REG: usize = 1;
/// The coverages whose held-out coverage and set size a calibration reports.
pub const MEASURED_COVERAGES: [f64; 3] = [0.9, 0.95, 0.99];

/// A coverage a request may ask for: within [0.5, 0.999].
pub fn check_coverage(coverage: f64) -> Result<f64, crate::learn::LearnError> {
    if coverage.is_finite() && (0.5..=0.999).contains(&coverage) {
        Ok(coverage)
    } else {
        Err(crate::learn::LearnError::BadCoverage(coverage))
    }
}

/// The classes by decreasing probability, the first class first on ties.
fn ranked(p: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..p.len()).collect();
    order.sort_by(|&a, &b| p[b].total_cmp(&p[a]).then(a.cmp(&b)));
    order
}

/// The score of each class, in rank order: (class, score).
fn scores(p: &[f64], lambda: f64, k_reg: usize) -> Vec<(usize, f64)> {
    let mut before = 0.0;
    ranked(p)
        .into_iter()
        .enumerate()
        .map(|(rank, class)| {
            let penalty = lambda * (rank + 1).saturating_sub(k_reg) as f64;
            let score = before + penalty;
            before += p[class];
            (class, score)
        })
        .collect()
}

/// The score of class `y` under probabilities `p`.
pub fn score(p: &[f64], y: usize, lambda: f64, k_reg: usize) -> f64 {
    scores(p, lambda, k_reg)
        .into_iter()
        .find(|&(class, _)| class == y)
        .map_or(f64::INFINITY, |(_, s)| s)
}

/// The classes whose score is at most `threshold`, most probable first (never empty: the
/// most probable class scores 0).
pub fn set(p: &[f64], threshold: f64, lambda: f64, k_reg: usize) -> Vec<usize> {
    let mut out: Vec<usize> = scores(p, lambda, k_reg)
        .into_iter()
        .take_while(|&(_, s)| s <= threshold)
        .map(|(class, _)| class)
        .collect();
    if out.is_empty() && !p.is_empty() {
        out.push(argmax(p));
    }
    out
}

/// The ⌈(n + 1)·c⌉-th smallest of `sorted` (ascending), +∞ when that is beyond n.
fn conformal_quantile(sorted: &[f64], coverage: f64) -> f64 {
    let n = sorted.len();
    let rank = ((n + 1) as f64 * coverage).ceil() as usize;
    match rank {
        0 => f64::NEG_INFINITY,
        r if r > n => f64::INFINITY,
        r => sorted[r - 1],
    }
}

/// What held-out images showed at one coverage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = SetsMeasured))]
pub struct Measured {
    /// The coverage asked for, one of [`MEASURED_COVERAGES`].
    pub coverage: f64,
    /// The fraction of held-out images whose set held the truth, each fold's sets made from
    /// the other folds' scores.
    pub held_out_coverage: f64,
    /// Their mean number of classes.
    pub mean_size: f64,
}

/// A model's prediction-set calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PredictionSets {
    /// RAPS's λ and k_reg.
    pub lambda: f64,
    /// Ranks free of the penalty.
    pub k_reg: usize,
    /// Calibration scores.
    pub n: usize,
    /// The positive scores, ascending (the other n − len are 0: the truth was the most
    /// probable class).
    pub positive: Vec<f64>,
    /// Folds of whole illuminations that gave the scores (or stratified rows, `false`).
    pub folds: usize,
    /// Whether the folds were whole illuminations.
    pub by_illumination: bool,
    /// What held-out images showed at each of [`MEASURED_COVERAGES`].
    pub measured: Vec<Measured>,
}

impl PredictionSets {
    /// Calibrates on held-out probabilities (class order) with their true classes and the
    /// fold that held each out.
    pub fn calibrate(
        probabilities: &[Vec<f64>],
        truth: &[usize],
        fold: &[usize],
        by_illumination: bool,
    ) -> PredictionSets {
        let all: Vec<f64> = probabilities
            .iter()
            .zip(truth)
            .map(|(p, &y)| score(p, y, LAMBDA, K_REG))
            .collect();
        let folds = fold.iter().max().map_or(0, |&f| f + 1);
        let measured = MEASURED_COVERAGES
            .iter()
            .map(|&coverage| cross_fitted(probabilities, truth, fold, &all, coverage, folds))
            .collect();
        let mut positive: Vec<f64> = all.iter().copied().filter(|&s| s > 0.0).collect();
        positive.sort_by(f64::total_cmp);
        PredictionSets {
            lambda: LAMBDA,
            k_reg: K_REG,
            n: all.len(),
            positive,
            folds,
            by_illumination,
            measured,
        }
    }

    /// The score threshold of sets at `coverage`.
    pub fn threshold(&self, coverage: f64) -> f64 {
        let n = self.n;
        let rank = ((n + 1) as f64 * coverage).ceil() as usize;
        let zeros = n - self.positive.len().min(n);
        match rank {
            0 => f64::NEG_INFINITY,
            r if r > n => f64::INFINITY,
            r if r <= zeros => 0.0,
            r => self.positive[r - zeros - 1],
        }
    }

    /// The prediction set of probabilities `p` at `coverage`, most probable first.
    pub fn set(&self, p: &[f64], coverage: f64) -> Vec<usize> {
        set(p, self.threshold(coverage), self.lambda, self.k_reg)
    }

    /// Checks the stored calibration (after deserializing a model file).
    pub fn validate(&self) -> Result<(), Inconsistent> {
        let ordered = self.positive.windows(2).all(|w| w[0] <= w[1]);
        let finite = self.positive.iter().all(|s| s.is_finite() && *s > 0.0);
        if self.positive.len() > self.n || !ordered || !finite {
            return Err(Inconsistent(
                "prediction-set scores must be positive, ascending and at most n".into(),
            ));
        }
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return Err(Inconsistent(
                "prediction-set λ must be finite and ≥ 0".into(),
            ));
        }
        Ok(())
    }
}

/// Coverage and mean size at `coverage` when each fold's sets come from the other folds'
/// scores.
fn cross_fitted(
    probabilities: &[Vec<f64>],
    truth: &[usize],
    fold: &[usize],
    scores: &[f64],
    coverage: f64,
    folds: usize,
) -> Measured {
    let (mut covered, mut size, mut n) = (0usize, 0usize, 0usize);
    for f in 0..folds {
        let mut others: Vec<f64> = (0..scores.len())
            .filter(|&i| fold[i] != f)
            .map(|i| scores[i])
            .collect();
        others.sort_by(f64::total_cmp);
        let threshold = conformal_quantile(&others, coverage);
        for i in (0..scores.len()).filter(|&i| fold[i] == f) {
            let members = set(&probabilities[i], threshold, LAMBDA, K_REG);
            covered += usize::from(members.contains(&truth[i]));
            size += members.len();
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    Measured {
        coverage,
        held_out_coverage: covered as f64 / n,
        mean_size: size as f64 / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::rng::Rng;

    #[test]
    fn scores_are_the_mass_ranked_above_plus_the_rank_penalty() {
        let p = [0.1, 0.6, 0.3];
        assert_eq!(score(&p, 1, 0.0, 1), 0.0);
        assert_eq!(score(&p, 2, 0.0, 1), 0.6);
        assert!((score(&p, 0, 0.0, 1) - 0.9).abs() < 1e-15);
        assert!((score(&p, 2, 0.01, 1) - 0.61).abs() < 1e-15);
        assert!((score(&p, 0, 0.01, 1) - 0.92).abs() < 1e-15);
        // Ties: the first class ranks first.
        assert_eq!(score(&[0.5, 0.5], 0, 0.0, 1), 0.0);
        assert_eq!(score(&[0.5, 0.5], 1, 0.0, 1), 0.5);
        assert_eq!(set(&p, 0.0, 0.0, 1), [1]);
        assert_eq!(set(&p, 0.6, 0.0, 1), [1, 2]);
        assert_eq!(set(&p, 0.95, 0.0, 1), [1, 2, 0]);
        assert_eq!(set(&p, f64::NEG_INFINITY, 0.0, 1), [1]);
    }

    /// Held-out probabilities of a classifier right 80 % of the time: the truth gets a high
    /// probability when right, else the second rank.
    fn synthetic(n: usize, seed: u64) -> (Vec<Vec<f64>>, Vec<usize>) {
        let mut rng = Rng::new(seed);
        let (mut probabilities, mut truth) = (Vec::new(), Vec::new());
        for _ in 0..n {
            let y = rng.below(4) as usize;
            let top = if rng.next_f64() < 0.8 {
                y
            } else {
                (y + 1 + rng.below(3) as usize) % 4
            };
            let confidence = 0.5 + 0.5 * rng.next_f64();
            let mut p = vec![(1.0 - confidence) / 3.0; 4];
            p[top] = confidence;
            probabilities.push(p);
            truth.push(y);
        }
        (probabilities, truth)
    }

    #[test]
    fn sets_cover_new_images_at_the_asked_rate() {
        let (p, y) = synthetic(4000, 1);
        let fold: Vec<usize> = (0..p.len()).map(|i| i % 5).collect();
        let sets = PredictionSets::calibrate(&p, &y, &fold, true);
        sets.validate().unwrap();
        assert_eq!(sets.n, 4000);
        let (test_p, test_y) = synthetic(20_000, 2);
        for coverage in [0.8, 0.9, 0.95] {
            let covered = test_p
                .iter()
                .zip(&test_y)
                .filter(|(p, y)| sets.set(p, coverage).contains(y))
                .count() as f64
                / test_p.len() as f64;
            // Conformal: at least the coverage, and not much more (n = 4000).
            assert!(
                covered >= coverage - 0.01 && covered <= coverage + 0.03,
                "{coverage}: {covered}"
            );
        }
        // Sure and right: one class. Higher coverage: never smaller sets.
        assert_eq!(sets.set(&[0.97, 0.01, 0.01, 0.01], 0.9), [0]);
        let p = [0.55, 0.25, 0.15, 0.05];
        assert!(sets.set(&p, 0.95).len() >= sets.set(&p, 0.9).len());
        // The held-out measurement agrees with the rate asked for.
        let at95 = &sets.measured[1];
        assert_eq!(at95.coverage, 0.95);
        assert!((at95.held_out_coverage - 0.95).abs() < 0.02, "{at95:?}");
        assert!(at95.mean_size > 1.0 && at95.mean_size < 4.0);
    }

    #[test]
    fn the_threshold_is_the_conformal_quantile() {
        let sets = PredictionSets {
            lambda: 0.0,
            k_reg: 1,
            n: 9,
            positive: vec![0.2, 0.5, 0.7],
            folds: 1,
            by_illumination: false,
            measured: vec![],
        };
        // ⌈10·c⌉-th smallest of [0 × 6, 0.2, 0.5, 0.7].
        assert_eq!(sets.threshold(0.6), 0.0);
        assert_eq!(sets.threshold(0.7), 0.2);
        assert_eq!(sets.threshold(0.9), 0.7);
        assert_eq!(sets.threshold(0.95), f64::INFINITY);
        assert!(check_coverage(0.95).is_ok());
        assert!(check_coverage(1.0).is_err() && check_coverage(f64::NAN).is_err());
        let mut bad = sets.clone();
        bad.positive = vec![0.5, 0.2];
        assert!(bad.validate().is_err());
    }
}
