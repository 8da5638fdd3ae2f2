//! The named feature sets: the paper's hand-picked ones and hand6 with our extensions.

use super::families::{CAPTURE_NAMES, CENTRE_NAMES, DEPENDENCIES, Families, LOG_PREFIX, RADIAL};
use super::layout::BlockLayout;
use super::stats::STAT_NAMES;
use super::{BAND_NAMES, LEVELS};

/// The families whose features a feature-set specification names (a named set or a list of
/// names).
pub(crate) fn families_of(spec: &str) -> Families {
    let spec = spec.trim();
    match named_set(spec) {
        Some(names) => Families::of_names(names.iter().map(String::as_str)),
        None => Families::of_names(spec.split(',').map(str::trim)),
    }
}

/// The named feature sets: the paper's hand-picked ones, the trivial one, and hand6 with
/// our extensions ([`named_set`] lists their features).
pub const NAMED_SETS: [&str; 12] = [
    "hand6",
    "hand2",
    "mean1",
    "hand6+log",
    "hand6+log+radial",
    "hand6+log+radial+dep",
    "hand6+cap",
    "hand6+log+cap",
    "hand6+log+ctr",
    "hand6+log+cap+ctr",
    "estimator",
    "scale_free",
];

/// The paper's hand-picked sets (§6.3, Fig. 7), the trivial one, hand6 extended with the
/// log-domain pixel statistics and subband variances (`hand6+log`), and that with the
/// log-domain radial changes (`hand6+log+radial`; docs/design.md §8), and hand6 and hand6+log with
/// the capture measurements (`hand6+cap`, `hand6+log+cap`), hand6+log with the centre features
/// (`hand6+log+ctr`, the shipped ward6 since version 3: the centre shows the reflectance head
/// on, where a dielectric's Fresnel term is least), and hand6+log+cap with them
/// (`hand6+log+cap+ctr`), and `estimator`, the shipped Ward-parameter estimators'
/// inputs: hand6+log+cap+ctr without `cap.blur`, so that a model whose classifier does not read
/// the rim's blur need not measure it, and with the log-domain variance ratios and subband
/// kurtoses, which tell α better (docs/design.md §8, docs/accuracy.md), and `scale_free`, the features of
/// hand6+log that do not change when the image is multiplied by a constant (the classifier a
/// model uses without a white reference: docs/design.md §3 "Without white").
pub fn named_set(name: &str) -> Option<Vec<String>> {
    const HAND6: [&str; 6] = [
        "pix.mean",
        "pix.p10",
        "wav.s1.v.var",
        "wav.s2.v.var",
        "ratio.v.s1_s2",
        "wav.s2.v.kurt",
    ];
    let strings = |names: &[&str]| names.iter().map(|n| n.to_string()).collect::<Vec<_>>();
    match name {
        "hand6" => Some(strings(&HAND6)),
        "hand2" => Some(strings(&["pix.p10", "wav.s2.v.var"])),
        "mean1" => Some(strings(&["pix.mean"])),
        "hand6+log+cap" => {
            let mut names = named_set("hand6+log")?;
            names.extend(CAPTURE_NAMES.iter().map(|n| n.to_string()));
            Some(names)
        }
        "hand6+log+ctr" => {
            let mut names = named_set("hand6+log")?;
            names.extend(CENTRE_NAMES.iter().map(|n| n.to_string()));
            Some(names)
        }
        "hand6+log+cap+ctr" => {
            let mut names = named_set("hand6+log+cap")?;
            names.extend(CENTRE_NAMES.iter().map(|n| n.to_string()));
            Some(names)
        }
        "scale_free" => {
            let mut names = strings(&["ratio.v.s1_s2", "wav.s2.v.kurt"]);
            names.extend(["var", "skew", "kurt"].map(|s| format!("{LOG_PREFIX}pix.{s}")));
            names.extend((1..=LEVELS).flat_map(|k| {
                BAND_NAMES
                    .iter()
                    .map(move |b| format!("{LOG_PREFIX}wav.s{k}.{b}.var"))
            }));
            Some(names)
        }
        "estimator" => {
            let mut names = named_set("hand6+log+cap+ctr")?;
            names.retain(|n| n != "cap.blur");
            let bands = || (1..=LEVELS).flat_map(|k| BAND_NAMES.iter().map(move |b| (k, b)));
            names.extend(
                bands()
                    .filter(|(k, _)| *k < LEVELS)
                    .map(|(k, b)| format!("{LOG_PREFIX}ratio.{b}.s{k}_s{}", k + 1)),
            );
            names.extend(bands().map(|(k, b)| format!("{LOG_PREFIX}wav.s{k}.{b}.kurt")));
            Some(names)
        }
        "hand6+cap" => Some(
            strings(&HAND6)
                .into_iter()
                .chain(CAPTURE_NAMES.iter().map(|n| n.to_string()))
                .collect(),
        ),
        "hand6+log" | "hand6+log+radial" | "hand6+log+radial+dep" => {
            let levels = LEVELS;
            let pixels = STAT_NAMES.iter().map(|s| format!("{LOG_PREFIX}pix.{s}"));
            let bands = (1..=levels).flat_map(|k| {
                BAND_NAMES
                    .iter()
                    .map(move |b| format!("{LOG_PREFIX}wav.s{k}.{b}.var"))
            });
            let inside = [(&RADIAL, "+radial"), (&DEPENDENCIES, "+dep")];
            let extended = BlockLayout {
                levels,
                families: (inside.into_iter())
                    .filter(|(_, part)| name.contains(part))
                    .map(|(family, _)| family)
                    .collect(),
            };
            let base = BlockLayout {
                families: Families::NONE,
                ..extended
            };
            let families = (extended.names().into_iter())
                .skip(base.count())
                .map(|n| format!("{LOG_PREFIX}{n}"));
            Some(
                strings(&HAND6)
                    .into_iter()
                    .chain(pixels)
                    .chain(bands)
                    .chain(families)
                    .collect(),
            )
        }
        _ => None,
    }
}
