//! The learning view of a feature table: a dense matrix, class and illumination indices.
//!
//! **Augmented rows.** An illumination written `<probe>@<suffix>` (e.g. `grace@rot090`, a
//! rotated or otherwise transformed copy of the `grace` light probe) belongs to the group
//! `<probe>` for cross-validation: when `grace` is held out, every `grace@…` row leaves the
//! training set with it. Augmented rows are used for training only; a held-out fold is
//! evaluated on its un-suffixed rows.

use super::error::LearnError;
use crate::dataset::FeatureTable;
use ndarray::Array2;

/// A feature table as learning reads it: the matrix, each row's class and illumination
/// group, and which rows are augmented copies.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// n × (all feature columns), in the table's column order.
    pub x: Array2<f64>,
    /// Feature column names.
    pub names: Vec<String>,
    /// Class index of every row, into `classes`.
    pub labels: Vec<usize>,
    /// Class names, sorted (byte order).
    pub classes: Vec<String>,
    /// Group (illumination, augmentation suffix removed) index of every row.
    pub groups: Vec<usize>,
    /// Group names, sorted (byte order).
    pub group_names: Vec<String>,
    /// The illumination as written in the table (with any `@suffix`).
    pub illuminations: Vec<String>,
    /// Whether the row is an augmented copy (`<probe>@<suffix>`): training only.
    pub augmented: Vec<bool>,
    /// Each row's image path.
    pub paths: Vec<String>,
}

/// Splits `probe@suffix` into (`probe`, true); a plain name gives (name, false).
pub fn parse_illumination(illumination: &str) -> (&str, bool) {
    match illumination.split_once('@') {
        Some((probe, _)) => (probe, true),
        None => (illumination, false),
    }
}

fn sorted_unique<'a>(items: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut v: Vec<String> = items.map(str::to_string).collect();
    v.sort();
    v.dedup();
    v
}

fn index_of(sorted: &[String], item: &str) -> usize {
    // `item` was collected into `sorted`, so the search always succeeds.
    sorted
        .binary_search_by(|s| s.as_str().cmp(item))
        .unwrap_or(0)
}

impl Dataset {
    /// The dataset of a table: labels not empty, rows as long as the header, values finite.
    pub fn from_table(table: &FeatureTable) -> Result<Dataset, LearnError> {
        let n = table.samples.len();
        if n == 0 {
            return Err(LearnError::NoRows);
        }
        let m = table.names.len();
        let mut x = Array2::zeros((n, m));
        for (row, s) in table.samples.iter().enumerate() {
            let path = || s.path.clone();
            for (what, value) in [("class", &s.class), ("illumination", &s.illumination)] {
                if value.is_empty() {
                    return Err(LearnError::EmptyLabel {
                        row,
                        path: path(),
                        what,
                    });
                }
            }
            if parse_illumination(&s.illumination).0.is_empty() {
                return Err(LearnError::EmptyLabel {
                    row,
                    path: path(),
                    what: "illumination (before '@')",
                });
            }
            if s.values.len() != m {
                return Err(LearnError::RaggedRow {
                    row,
                    path: path(),
                    expected: m,
                    got: s.values.len(),
                });
            }
            for (j, &v) in s.values.iter().enumerate() {
                if !v.is_finite() {
                    return Err(LearnError::NonFinite {
                        row,
                        path: path(),
                        name: table.names[j].clone(),
                        value: v,
                    });
                }
                x[[row, j]] = v;
            }
        }
        let classes = sorted_unique(table.samples.iter().map(|s| s.class.as_str()));
        if classes.len() < 2 {
            return Err(LearnError::TooFewClasses(classes.len()));
        }
        let group_names = sorted_unique(
            table
                .samples
                .iter()
                .map(|s| parse_illumination(&s.illumination).0),
        );
        let labels = table
            .samples
            .iter()
            .map(|s| index_of(&classes, &s.class))
            .collect();
        let mut groups = Vec::with_capacity(n);
        let mut augmented = Vec::with_capacity(n);
        for s in &table.samples {
            let (probe, aug) = parse_illumination(&s.illumination);
            groups.push(index_of(&group_names, probe));
            augmented.push(aug);
        }
        Ok(Dataset {
            x,
            names: table.names.clone(),
            labels,
            classes,
            groups,
            group_names,
            illuminations: table
                .samples
                .iter()
                .map(|s| s.illumination.clone())
                .collect(),
            augmented,
            paths: table.samples.iter().map(|s| s.path.clone()).collect(),
        })
    }

    /// Number of rows.
    pub fn n_rows(&self) -> usize {
        self.labels.len()
    }

    /// Number of classes.
    pub fn n_classes(&self) -> usize {
        self.classes.len()
    }

    /// Rows per class over `rows`.
    pub fn class_counts(&self, rows: &[usize]) -> Vec<usize> {
        let mut counts = vec![0; self.n_classes()];
        for &r in rows {
            counts[self.labels[r]] += 1;
        }
        counts
    }

    /// The training rows (every row not in `group`) and evaluation rows (the un-augmented
    /// rows of `group`) of a leave-one-group-out fold, restricted to `within`.
    pub fn split_group(&self, within: &[usize], group: usize) -> (Vec<usize>, Vec<usize>) {
        let train = within
            .iter()
            .copied()
            .filter(|&r| self.groups[r] != group)
            .collect();
        let test = within
            .iter()
            .copied()
            .filter(|&r| self.groups[r] == group && !self.augmented[r])
            .collect();
        (train, test)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Sample;

    pub(crate) fn table(rows: &[(&str, &str, &str, Vec<f64>)]) -> FeatureTable {
        FeatureTable {
            names: (0..rows[0].3.len()).map(|i| format!("f{i}")).collect(),
            samples: rows
                .iter()
                .map(|(p, c, i, v)| Sample {
                    path: p.to_string(),
                    class: c.to_string(),
                    illumination: i.to_string(),
                    values: v.clone(),
                })
                .collect(),
        }
    }

    #[test]
    fn builds_sorted_indices_and_groups() {
        let t = table(&[
            ("a.png", "white", "grace", vec![1.0, 2.0]),
            ("b.png", "chrome", "beach", vec![3.0, 4.0]),
            ("c.png", "white", "grace@rot090", vec![5.0, 6.0]),
            ("d.png", "black", "beach", vec![7.0, 8.0]),
        ]);
        let d = Dataset::from_table(&t).unwrap();
        assert_eq!(d.classes, ["black", "chrome", "white"]);
        assert_eq!(d.labels, [2, 1, 2, 0]);
        assert_eq!(d.group_names, ["beach", "grace"]);
        assert_eq!(d.groups, [1, 0, 1, 0]);
        assert_eq!(d.augmented, [false, false, true, false]);
        assert_eq!(d.x[[2, 1]], 6.0);
        let all: Vec<usize> = (0..4).collect();
        assert_eq!(d.split_group(&all, 1), (vec![1, 3], vec![0]));
        assert_eq!(d.class_counts(&all), [1, 1, 2]);
    }

    #[test]
    fn rejects_bad_tables() {
        let empty = FeatureTable {
            names: vec!["f0".into()],
            samples: vec![],
        };
        assert_eq!(Dataset::from_table(&empty), Err(LearnError::NoRows));
        let one_class = table(&[("a", "x", "g", vec![1.0]), ("b", "x", "h", vec![2.0])]);
        assert_eq!(
            Dataset::from_table(&one_class),
            Err(LearnError::TooFewClasses(1))
        );
        let no_class = table(&[("a", "", "g", vec![1.0]), ("b", "x", "h", vec![2.0])]);
        assert!(matches!(
            Dataset::from_table(&no_class),
            Err(LearnError::EmptyLabel {
                row: 0,
                what: "class",
                ..
            })
        ));
        let no_illum = table(&[("a", "y", "g", vec![1.0]), ("b", "x", "@r", vec![2.0])]);
        assert!(matches!(
            Dataset::from_table(&no_illum),
            Err(LearnError::EmptyLabel { row: 1, .. })
        ));
        let nan = table(&[("a", "y", "g", vec![1.0]), ("b", "x", "h", vec![f64::NAN])]);
        assert!(matches!(
            Dataset::from_table(&nan),
            Err(LearnError::NonFinite { row: 1, .. })
        ));
    }
}
