//! Standardization with the training data's mean and population standard deviation.

use ndarray::{Array2, ArrayView2};
use serde::{Deserialize, Serialize};

/// Per-column standardization: (x − mean) / std, with the training data's statistics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scaler {
    /// Each column's mean.
    pub mean: Vec<f64>,
    /// Population (ddof = 0) standard deviation; 1 for a constant column.
    pub std: Vec<f64>,
}

impl Scaler {
    /// Fits on the rows of `x` (n × d, n ≥ 1). A column whose values are all identical gets
    /// mean = that value and std = 1, so it standardizes to exactly 0.
    pub fn fit(x: ArrayView2<f64>) -> Scaler {
        let n = x.nrows().max(1) as f64;
        let mut mean = Vec::with_capacity(x.ncols());
        let mut std = Vec::with_capacity(x.ncols());
        for col in x.columns() {
            let first = col.iter().next().copied().unwrap_or(0.0);
            if col.iter().all(|&v| v == first) {
                mean.push(first);
                std.push(1.0);
                continue;
            }
            let m = col.iter().sum::<f64>() / n;
            let var = col.iter().map(|&v| (v - m) * (v - m)).sum::<f64>() / n;
            let s = var.sqrt();
            mean.push(m);
            std.push(if s > 0.0 { s } else { 1.0 });
        }
        Scaler { mean, std }
    }

    /// Number of columns.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Standardizes one row in place (`row.len()` = `dim()`).
    pub fn apply(&self, row: &mut [f64]) {
        for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
            *v = (*v - m) / s;
        }
    }

    /// The standardized copy of `x` (n × [`Scaler::dim`]).
    pub fn transform(&self, x: ArrayView2<f64>) -> Array2<f64> {
        let mut out = x.to_owned();
        for mut row in out.rows_mut() {
            for ((v, m), s) in row.iter_mut().zip(&self.mean).zip(&self.std) {
                *v = (*v - m) / s;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

    #[test]
    fn population_std_and_constant_columns() {
        let x = array![[1.0, 5.0, 0.1], [3.0, 5.0, 0.2], [5.0, 5.0, 0.3]];
        let s = Scaler::fit(x.view());
        assert_eq!(s.mean[0], 3.0);
        assert!((s.std[0] - (8.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!((s.mean[1], s.std[1]), (5.0, 1.0));
        let z = s.transform(x.view());
        for j in 0..3 {
            let col = z.column(j);
            let mean = col.sum() / 3.0;
            let var = col.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 3.0;
            assert!(mean.abs() < 1e-15);
            if j == 1 {
                assert!(col.iter().all(|&v| v == 0.0));
            } else {
                assert!((var - 1.0).abs() < 1e-12);
            }
        }
        let mut row = [3.0, 6.0, 0.2];
        s.apply(&mut row);
        assert_eq!(row[..2], [0.0, 1.0]);
    }
}
