//! Feature sets: a named set ([`crate::features::NAMED_SETS`]: `hand6`, `hand2`, `mean1`,
//! `hand6+log`, …), `all`, `auto<N>`, `pca<N>`, or a comma-separated list of feature names. Fixed sets resolve to
//! columns directly; `auto<N>` and `pca<N>` are fitted on training rows only (inside every
//! cross-validation fold).

use super::error::LearnError;
use crate::features::{NAMED_SETS, named_set};
use std::fmt;
use std::str::FromStr;

/// Which features a classifier reads, as specified (`hand6`, `all`, `auto6`, `pca6` or a
/// list of names).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FeatureSet {
    /// One of [`NAMED_SETS`] (the paper's hand-picked sets and our extensions of hand6).
    Named(&'static str),
    /// Every feature of the table.
    All,
    /// Automatic selection of N features (docs/design.md §3 "Automatic selection").
    Auto(usize),
    /// First N principal components of the standardized features, whitened.
    Pca(usize),
    /// Explicit feature names, in the given order.
    List(Vec<String>),
}

fn bad(spec: &str, detail: impl Into<String>) -> LearnError {
    LearnError::BadFeatureSet {
        spec: spec.to_string(),
        detail: detail.into(),
    }
}

fn count(spec: &str, digits: &str) -> Result<usize, LearnError> {
    match digits.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(bad(spec, "N must be a positive integer")),
    }
}

impl FeatureSet {
    /// Parses a specification, checking explicit names against `names` (the table's columns).
    pub fn parse_with(spec: &str, names: &[String]) -> Result<FeatureSet, LearnError> {
        let spec = spec.trim();
        if let Some(&name) = NAMED_SETS.iter().find(|&&n| n == spec) {
            return Ok(FeatureSet::Named(name));
        }
        match spec {
            "all" => return Ok(FeatureSet::All),
            "" => return Err(bad(spec, "empty feature set")),
            _ => {}
        }
        let numbered = |prefix: &str| {
            spec.strip_prefix(prefix)
                .filter(|rest| !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()))
        };
        if let Some(d) = numbered("auto") {
            return Ok(FeatureSet::Auto(count(spec, d)?));
        }
        if let Some(d) = numbered("pca") {
            return Ok(FeatureSet::Pca(count(spec, d)?));
        }
        let list: Vec<String> = spec.split(',').map(|s| s.trim().to_string()).collect();
        if list.iter().any(String::is_empty) {
            return Err(bad(spec, "empty name in the list"));
        }
        let unknown: Vec<String> = list
            .iter()
            .filter(|n| !names.contains(n))
            .cloned()
            .collect();
        if !unknown.is_empty() {
            return Err(LearnError::UnknownFeatures(unknown));
        }
        let mut seen = list.clone();
        seen.sort();
        if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
            return Err(bad(spec, format!("{} is listed twice", w[0])));
        }
        Ok(FeatureSet::List(list))
    }

    /// The names of a fixed set (`None` for the fitted `auto<N>` and `pca<N>`), `all` being
    /// every column of `names`.
    pub fn fixed_names(&self, names: &[String]) -> Option<Vec<String>> {
        match self {
            FeatureSet::Named(set) => Some(named_set(set).unwrap_or_default()),
            FeatureSet::All => Some(names.to_vec()),
            FeatureSet::List(list) => Some(list.clone()),
            FeatureSet::Auto(_) | FeatureSet::Pca(_) => None,
        }
    }

    /// Column indices of a fixed set in a table with columns `names`.
    pub fn resolve(&self, names: &[String]) -> Result<Option<Vec<usize>>, LearnError> {
        let Some(wanted) = self.fixed_names(names) else {
            return Ok(None);
        };
        let mut missing = Vec::new();
        let mut idx = Vec::with_capacity(wanted.len());
        for w in &wanted {
            match names.iter().position(|n| n == w) {
                Some(i) => idx.push(i),
                None => missing.push(w.clone()),
            }
        }
        if missing.is_empty() {
            Ok(Some(idx))
        } else {
            Err(LearnError::UnknownFeatures(missing))
        }
    }
}

impl FromStr for FeatureSet {
    type Err = LearnError;

    /// Parses against the default configuration's names with every family.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        use crate::features::{Families, FeatureConfig, Preprocessing};
        FeatureSet::parse_with(
            s,
            &FeatureConfig::extended(Families::ALL, Preprocessing::default()).names(),
        )
    }
}

impl fmt::Display for FeatureSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FeatureSet::Named(set) => f.write_str(set),
            FeatureSet::All => f.write_str("all"),
            FeatureSet::Auto(n) => write!(f, "auto{n}"),
            FeatureSet::Pca(n) => write!(f, "pca{n}"),
            FeatureSet::List(list) => f.write_str(&list.join(",")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_round_trips() {
        for spec in [
            "hand6",
            "hand2",
            "mean1",
            "all",
            "auto6",
            "pca12",
            "pix.mean",
            "wav.s2.v.kurt,pix.p10",
            "hand6+log+radial",
            "hand6+log+radial+dep",
            "log.radial.r2_r3.wav.s1.v.var,radial.r1_r2.pix.mean",
            "log.dep.s1.hv,dep.s4.vd",
        ] {
            let set: FeatureSet = spec.parse().unwrap();
            assert_eq!(set.to_string(), spec);
            assert_eq!(set.to_string().parse::<FeatureSet>().unwrap(), set);
        }
        assert_eq!(
            " pix.mean , pix.p10 ".parse::<FeatureSet>().unwrap(),
            FeatureSet::List(vec!["pix.mean".into(), "pix.p10".into()])
        );
        assert_eq!("auto3".parse::<FeatureSet>(), Ok(FeatureSet::Auto(3)));
    }

    #[test]
    fn rejects_bad_specs() {
        assert_eq!(
            "pix.mean,nope,wav.s9.v.var".parse::<FeatureSet>(),
            Err(LearnError::UnknownFeatures(vec![
                "nope".into(),
                "wav.s9.v.var".into()
            ]))
        );
        for bad in [
            "auto0",
            "pca0",
            "",
            "pix.mean,,pix.p10",
            "pix.mean,pix.mean",
        ] {
            assert!(
                matches!(
                    bad.parse::<FeatureSet>(),
                    Err(LearnError::BadFeatureSet { .. })
                ),
                "{bad:?}"
            );
        }
        // Not a number after the prefix: read as a (unknown) feature name.
        assert!(matches!(
            "autox".parse::<FeatureSet>(),
            Err(LearnError::UnknownFeatures(_))
        ));
    }

    #[test]
    fn resolves_columns() {
        let names = crate::features::default_names();
        let idx = FeatureSet::Named("hand6").resolve(names).unwrap().unwrap();
        assert_eq!(idx[0], 0);
        assert_eq!(names[idx[2]], "wav.s1.v.var");
        assert_eq!(FeatureSet::All.resolve(names).unwrap().unwrap().len(), 117);
        assert_eq!(FeatureSet::Auto(3).resolve(names).unwrap(), None);
        // hand6+log needs the log-domain columns.
        assert!(FeatureSet::Named("hand6+log").resolve(names).is_err());
        let extended = crate::features::FeatureConfig::with_log_domain().names();
        let idx = FeatureSet::Named("hand6+log")
            .resolve(&extended)
            .unwrap()
            .unwrap();
        assert_eq!((idx.len(), extended[idx[6]].as_str()), (25, "log.pix.mean"));
        assert_eq!(
            "hand6+log".parse::<FeatureSet>().unwrap().to_string(),
            "hand6+log"
        );
        // hand6+log+radial needs the radial columns of the log-domain block too.
        assert!(
            FeatureSet::Named("hand6+log+radial")
                .resolve(&extended)
                .is_err()
        );
        let every = crate::features::FeatureConfig::extended(
            crate::features::Families::ALL,
            crate::features::Preprocessing::default(),
        )
        .names();
        let idx = FeatureSet::Named("hand6+log+radial")
            .resolve(&every)
            .unwrap()
            .unwrap();
        assert_eq!(
            (idx.len(), every[idx[25]].as_str(), every[idx[52]].as_str()),
            (
                53,
                "log.radial.r1_r2.pix.mean",
                "log.radial.r2_r3.wav.s4.d.var"
            )
        );
        let idx = FeatureSet::Named("hand6+log+radial+dep")
            .resolve(&every)
            .unwrap()
            .unwrap();
        assert_eq!(
            (idx.len(), every[idx[53]].as_str(), every[idx[64]].as_str()),
            (65, "log.dep.s1.hv", "log.dep.s4.vd")
        );
        let short = vec!["pix.mean".to_string()];
        assert!(matches!(
            FeatureSet::Named("hand2").resolve(&short),
            Err(LearnError::UnknownFeatures(m)) if m.len() == 2
        ));
    }
}
