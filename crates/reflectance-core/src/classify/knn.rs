//! Baselines: k-nearest neighbours (1-NN, 5-NN) and chance.
//!
//! k-NN: Euclidean distance in the standardized selected-feature space. Neighbours are
//! ordered by (distance, training index); the k first vote. The prediction is the class
//! with the most votes; a tie goes to the tied class whose nearest voting member is the
//! closest, then to the first in class order. Probabilities are the vote fractions.
//!
//! Chance: predicts the most frequent training class (the first in class order on ties);
//! its probabilities are the training class frequencies. The expected accuracy of guessing
//! uniformly at random, 1/K, is reported separately by cross-validation.

use crate::learn::Inconsistent;

use super::svm::squared_distance;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KnnModel {
    pub k: usize,
    pub n_classes: usize,
    /// Standardized training rows.
    pub train: Vec<Vec<f64>>,
    pub labels: Vec<usize>,
}

/// A vote: predicted class and vote fractions.
#[derive(Clone, Debug, PartialEq)]
pub struct Vote {
    pub class: usize,
    pub fractions: Vec<f64>,
}

impl KnnModel {
    /// The k nearest training rows: (squared distance, training index), ordered.
    pub fn neighbours(&self, z: &[f64]) -> Vec<(f64, usize)> {
        let mut d: Vec<(f64, usize)> = self
            .train
            .iter()
            .enumerate()
            .map(|(i, t)| (squared_distance(t, z), i))
            .collect();
        let k = self.k.min(d.len());
        let order = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        if k < d.len() {
            d.select_nth_unstable_by(k, order);
            d.truncate(k);
        }
        d.sort_by(order);
        d
    }

    pub fn vote(&self, z: &[f64]) -> Vote {
        let nb = self.neighbours(z);
        let mut votes = vec![0usize; self.n_classes];
        let mut nearest = vec![f64::INFINITY; self.n_classes];
        for &(d, i) in &nb {
            let c = self.labels.get(i).copied().unwrap_or(usize::MAX);
            if let (Some(v), Some(n)) = (votes.get_mut(c), nearest.get_mut(c)) {
                *v += 1;
                *n = n.min(d);
            }
        }
        let top = votes.iter().copied().max().unwrap_or(0);
        let mut class = 0;
        let mut best = (false, f64::INFINITY);
        for c in 0..self.n_classes {
            if votes[c] == top && top > 0 && (!best.0 || nearest[c] < best.1) {
                best = (true, nearest[c]);
                class = c;
            }
        }
        let total = nb.len().max(1) as f64;
        Vote {
            class,
            fractions: votes.iter().map(|&v| v as f64 / total).collect(),
        }
    }

    pub(crate) fn check(&self, dim: usize) -> Result<(), Inconsistent> {
        if self.k == 0 || self.train.is_empty() || self.train.len() != self.labels.len() {
            return Err(Inconsistent(
                "k-NN training data is empty or inconsistent".into(),
            ));
        }
        if self.train.iter().any(|t| t.len() != dim)
            || self.labels.iter().any(|&l| l >= self.n_classes)
        {
            return Err(Inconsistent("k-NN dimensions disagree".into()));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChanceModel {
    /// Training class frequencies.
    pub frequencies: Vec<f64>,
}

impl ChanceModel {
    pub fn fit(labels: &[usize], n_classes: usize) -> ChanceModel {
        let mut counts = vec![0usize; n_classes];
        for &l in labels {
            counts[l] += 1;
        }
        let n = labels.len().max(1) as f64;
        ChanceModel {
            frequencies: counts.iter().map(|&c| c as f64 / n).collect(),
        }
    }

    pub fn class(&self) -> usize {
        super::svm::argmax(&self.frequencies)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(k: usize, train: &[(f64, usize)]) -> KnnModel {
        KnnModel {
            k,
            n_classes: 3,
            train: train.iter().map(|&(x, _)| vec![x]).collect(),
            labels: train.iter().map(|&(_, l)| l).collect(),
        }
    }

    #[test]
    fn nearest_neighbour_and_distance_ties() {
        let m = model(1, &[(0.0, 2), (2.0, 1), (-2.0, 0), (5.0, 0)]);
        assert_eq!(m.vote(&[0.4]).class, 2);
        assert_eq!(m.vote(&[4.0]).class, 0);
        // Equidistant from index 1 (class 1) and index 2 (class 0)? No: 0.0 is nearest.
        // Exactly between 2.0 (index 1) and 5.0 (index 3): lower index wins.
        let v = m.vote(&[3.5]);
        assert_eq!(v.class, 1);
        assert_eq!(v.fractions, [0.0, 1.0, 0.0]);
        assert_eq!(m.neighbours(&[3.5]), vec![(2.25, 1)]);
    }

    #[test]
    fn five_nn_votes_and_vote_ties() {
        // Votes 2-2-1: the tied class with the closer member wins.
        let m = model(
            5,
            &[(0.0, 0), (0.5, 1), (1.0, 0), (1.2, 1), (3.0, 2), (9.0, 2)],
        );
        let v = m.vote(&[0.6]);
        assert_eq!(v.fractions, [0.4, 0.4, 0.2]);
        assert_eq!(v.class, 1);
        let v = m.vote(&[0.1]);
        assert_eq!(v.class, 0);
        // Tied votes and tied nearest distances: class order decides.
        let m = model(2, &[(1.0, 2), (-1.0, 1)]);
        assert_eq!(m.vote(&[0.0]).class, 1);
        // Majority beats proximity.
        let m = model(3, &[(0.0, 2), (1.0, 1), (1.1, 1)]);
        assert_eq!(m.vote(&[0.0]).class, 1);
        // k larger than the training set uses all of it.
        let m = model(5, &[(0.0, 2), (1.0, 1)]);
        assert_eq!(m.vote(&[0.0]).fractions, [0.0, 0.5, 0.5]);
    }

    #[test]
    fn chance_is_most_frequent_class() {
        let c = ChanceModel::fit(&[1, 2, 2, 1, 0], 3);
        assert_eq!(c.frequencies, [0.2, 0.4, 0.4]);
        assert_eq!(c.class(), 1);
    }
}
