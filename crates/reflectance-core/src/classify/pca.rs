//! `pca<N>`: standardize (training mean, population std), eigen-decompose the covariance,
//! keep the N components with the largest eigenvalues and whiten them to unit variance.
//!
//! Conventions: covariance with 1/n (so whitened training scores have population variance
//! exactly 1, like the scaler); eigenvalues sorted descending, ties by eigen-solver order;
//! each component's sign makes its largest-|loading| entry positive (the first such entry
//! on ties). A component whose eigenvalue is ≤ 1e-12 × the largest (the data has fewer
//! dimensions than N) is not scaled: its scores are ~0 and stay so.

use crate::learn::Inconsistent;

use crate::learn::error::LearnError;
use crate::learn::scaler::Scaler;
use nalgebra::{DMatrix, SymmetricEigen};
use ndarray::ArrayView2;
use serde::{Deserialize, Serialize};

const RELATIVE_RANK: f64 = 1e-12;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pca {
    /// Standardization of the input columns.
    pub scaler: Scaler,
    /// N × d loadings (unit vectors), one row per component.
    pub components: Vec<Vec<f64>>,
    /// Eigenvalue of each component (variance of its standardized-data scores).
    pub eigenvalues: Vec<f64>,
    /// Multiplier of each component's score: 1/√eigenvalue (1 for degenerate components).
    pub scale: Vec<f64>,
}

impl Pca {
    pub fn fit(x: ArrayView2<f64>, n_components: usize) -> Result<Pca, LearnError> {
        let (n, d) = x.dim();
        if n_components == 0 || n_components > d {
            return Err(LearnError::InvalidParameter(format!(
                "pca{n_components} needs 1..={d} components"
            )));
        }
        if n < 2 {
            return Err(LearnError::InvalidParameter(
                "PCA needs at least 2 training rows".into(),
            ));
        }
        let scaler = Scaler::fit(x);
        let z = scaler.transform(x);
        let mut cov = DMatrix::<f64>::zeros(d, d);
        for a in 0..d {
            for b in a..d {
                let s: f64 = z
                    .column(a)
                    .iter()
                    .zip(z.column(b))
                    .map(|(u, v)| u * v)
                    .sum();
                let v = s / n as f64;
                cov[(a, b)] = v;
                cov[(b, a)] = v;
            }
        }
        let eig = SymmetricEigen::new(cov);
        let mut order: Vec<usize> = (0..d).collect();
        order.sort_by(|&i, &j| {
            eig.eigenvalues[j]
                .total_cmp(&eig.eigenvalues[i])
                .then(i.cmp(&j))
        });
        let largest = eig.eigenvalues[order[0]].max(0.0);
        let mut components = Vec::with_capacity(n_components);
        let mut eigenvalues = Vec::with_capacity(n_components);
        let mut scale = Vec::with_capacity(n_components);
        for &k in order.iter().take(n_components) {
            let mut v: Vec<f64> = eig.eigenvectors.column(k).iter().copied().collect();
            let mut pivot = 0;
            for (i, x) in v.iter().enumerate() {
                if x.abs() > v[pivot].abs() {
                    pivot = i;
                }
            }
            if v[pivot] < 0.0 {
                v.iter_mut().for_each(|x| *x = -*x);
            }
            let lambda = eig.eigenvalues[k];
            if !lambda.is_finite() || v.iter().any(|x| !x.is_finite()) {
                return Err(LearnError::Numerical("PCA eigen-decomposition".into()));
            }
            components.push(v);
            eigenvalues.push(lambda);
            scale.push(if lambda > RELATIVE_RANK * largest {
                1.0 / lambda.sqrt()
            } else {
                1.0
            });
        }
        Ok(Pca {
            scaler,
            components,
            eigenvalues,
            scale,
        })
    }

    pub fn input_dim(&self) -> usize {
        self.scaler.dim()
    }

    pub fn output_dim(&self) -> usize {
        self.components.len()
    }

    /// Whitened component scores of one input row (`row.len()` = `input_dim()`).
    pub fn transform_row(&self, row: &[f64]) -> Vec<f64> {
        let mut z = row.to_vec();
        self.scaler.apply(&mut z);
        self.components
            .iter()
            .zip(&self.scale)
            .map(|(c, s)| c.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>() * s)
            .collect()
    }

    pub(crate) fn check(&self) -> Result<(), Inconsistent> {
        let d = self.input_dim();
        if self.scaler.std.len() != d
            || self.components.iter().any(|c| c.len() != d)
            || self.scale.len() != self.components.len()
            || self.eigenvalues.len() != self.components.len()
        {
            return Err(Inconsistent("PCA dimensions disagree".into()));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    /// Data with a known covariance: columns a, b = a + e, c independent; after
    /// standardization the correlation matrix has a known spectrum.
    #[test]
    fn recovers_known_components_and_whitens() {
        let mut rng = crate::util::rng::Rng::new(11);
        let n = 4000;
        let mut x = Array2::zeros((n, 3));
        for i in 0..n {
            let g = |r: &mut crate::util::rng::Rng| {
                // Approximately normal (Irwin–Hall, 12 uniforms).
                (0..12).map(|_| r.next_f64()).sum::<f64>() - 6.0
            };
            let a = g(&mut rng);
            x[[i, 0]] = 10.0 + 3.0 * a;
            x[[i, 1]] = -2.0 + 0.5 * (a + 0.5 * g(&mut rng));
            x[[i, 2]] = 7.0 * g(&mut rng);
        }
        let pca = Pca::fit(x.view(), 3).unwrap();
        // The first component: the correlated pair, equal loadings 1/√2, positive.
        let c0 = &pca.components[0];
        assert!((c0[0] - c0[1]).abs() < 0.05 && (c0[0] - 0.5f64.sqrt()).abs() < 0.05);
        assert!(c0[2].abs() < 0.05, "{c0:?}");
        // Correlation ρ of the pair gives eigenvalues 1 + ρ, 1, 1 − ρ (sum = 3 = trace).
        let sum: f64 = pca.eigenvalues.iter().sum();
        assert!((sum - 3.0).abs() < 1e-12);
        let rho = 1.0 / 1.25f64.sqrt();
        assert!(
            (pca.eigenvalues[0] - (1.0 + rho)).abs() < 0.05,
            "{:?}",
            pca.eigenvalues
        );
        assert!(pca.eigenvalues.windows(2).all(|w| w[0] >= w[1]));
        // Whitened scores: zero mean, unit population variance, uncorrelated.
        let scores: Vec<Vec<f64>> = (0..n)
            .map(|i| pca.transform_row(x.row(i).as_slice().unwrap()))
            .collect();
        for a in 0..3 {
            for b in 0..3 {
                let m: f64 = scores.iter().map(|s| s[a] * s[b]).sum::<f64>() / n as f64;
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((m - want).abs() < 1e-9, "cov[{a},{b}] = {m}");
            }
            let mean: f64 = scores.iter().map(|s| s[a]).sum::<f64>() / n as f64;
            assert!(mean.abs() < 1e-12);
        }
        for c in &pca.components {
            let pivot = c
                .iter()
                .copied()
                .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
            assert!(pivot > 0.0);
        }
        assert!(Pca::fit(x.view(), 4).is_err());
        assert!(Pca::fit(x.view(), 0).is_err());
    }
}
