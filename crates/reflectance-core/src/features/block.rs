//! One block of features ([`BlockLayout`], docs/design.md §3): the statistics of an image and
//! of its pyramid's subbands, the variance ratios, the band powers and the families inside
//! blocks. Every feature of a block, or only those a classifier reads: the same stages and
//! statistics on the same data, so the wanted values are bit-identical.

use super::families::Block;
use super::layout::{BlockLayout, STATS};
use super::observed::{Support, kept};
use super::pyramid::{self, Edge, Level};
use super::spectrum::{BandPowers, SpectrumPlan};
use super::stats::{Summary, log10_floor, moments, percentiles_with, summarize};
use ndarray::Array2;

/// Per-stage intermediate results, for tests and diagnostics.
pub struct Stages {
    /// The annulus unwrapped to the configured grid (rows: radius, columns: angle), in units
    /// of white.
    pub unwrapped: Array2<f64>,
    /// Its wavelet pyramid.
    pub pyramid: pyramid::Pyramid,
    /// Its oriented band powers.
    pub band_powers: BandPowers,
}

/// Every feature of one block of computed stages, over the observed part `support` says
/// (everything for `None`; see [`super::observed`]).
pub(crate) fn features(
    layout: &BlockLayout,
    stages: &Stages,
    support: Option<&Support>,
) -> Vec<f64> {
    let mut out = vec![f64::NAN; layout.count()];
    let mut scratch: Vec<u64> = Vec::new();
    let mut summary = |values: &Array2<f64>, keep: Option<&Array2<bool>>| {
        summarize(&kept(values, keep), &mut scratch)
    };
    let block = Block {
        image: &stages.unwrapped,
        pyramid: &stages.pyramid.levels,
        levels: layout.levels,
        support,
    };
    put_summary(
        &mut out[BlockLayout::PIXELS..],
        &summary(&stages.unwrapped, block.pixels()),
    );
    // Raw subband variances, [level][band], for the ratios.
    let mut variances = vec![[0.0; 3]; layout.levels];
    for (level, bands) in stages.pyramid.levels.iter().enumerate() {
        for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
            let s = summary(values, block.band(level, band));
            variances[level][band] = s.var;
            put_summary(&mut out[layout.band(level, band)..], &s);
        }
    }
    put_ratios(layout, &variances, |_, _| true, &mut out);
    let powers = match support {
        Some(s) => stages.band_powers.scaled(1.0 / s.fraction),
        None => stages.band_powers,
    };
    put_band_powers(&mut out[layout.band_powers()], &powers);
    for (inside, at) in layout.families_inside() {
        inside.put(&block, &|_| true, &mut out[at]);
    }
    out
}

/// The features of one block of an unwrapped image that `need` marks, into `out`; the others
/// are left as they are. Skipped: pyramid levels past the deepest one needed, unneeded
/// moments and percentiles, the band powers when none is needed.
pub(crate) fn subset(
    layout: &BlockLayout,
    spectrum: &SpectrumPlan,
    unwrapped: &Array2<f64>,
    need: &[bool],
    out: &mut [f64],
) {
    let levels = layout.levels;
    let stats_needed = |base: usize| need[base..base + STATS].iter().any(|&b| b);
    let ratio_needed = |band: usize, pair: usize| need[layout.ratio(band, pair)];
    // Which subbands need their variance (for ratios), and the deepest level needed.
    let inside: Vec<_> = layout.families_inside().collect();
    let mut deepest = (inside.iter())
        .filter_map(|(family, at)| family.deepest(levels, &|k| need[at.start + k]))
        .max();
    let mut band_var = vec![[false; 3]; levels];
    for (level, bands) in band_var.iter_mut().enumerate() {
        for (band, slot) in bands.iter_mut().enumerate() {
            let ratio = (level + 1 < levels && ratio_needed(band, level))
                || (level > 0 && ratio_needed(band, level - 1));
            *slot = ratio;
            if ratio || stats_needed(layout.band(level, band)) {
                deepest = deepest.max(Some(level));
            }
        }
    }
    fill_summary(&values_of(unwrapped), BlockLayout::PIXELS, false, need, out);
    let pyramid =
        deepest.map(|deepest| pyramid::build(unwrapped.view(), deepest + 1, Edge::Periodic));
    let built: &[Level] = pyramid.as_ref().map_or(&[], |p| &p.levels);
    if !built.is_empty() {
        let mut variances = vec![[f64::NAN; 3]; levels];
        for (level, bands) in built.iter().enumerate() {
            for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
                let base = layout.band(level, band);
                if band_var[level][band] || stats_needed(base) {
                    let force = band_var[level][band];
                    variances[level][band] =
                        fill_summary(&values_of(values), base, force, need, out);
                }
            }
        }
        put_ratios(layout, &variances, ratio_needed, out);
    }
    let block = Block {
        image: unwrapped,
        pyramid: built,
        levels,
        support: None,
    };
    for (family, at) in inside {
        if need[at.clone()].iter().any(|&b| b) {
            let start = at.start;
            family.put(&block, &|k| need[start + k], &mut out[at]);
        }
    }
    let powers = layout.band_powers();
    if need[powers.clone()].iter().any(|&b| b) {
        put_band_powers(&mut out[powers], &spectrum.band_powers(unwrapped.view()));
    }
}

/// The needed statistics of one image or subband at `base` (the moments all, when
/// `force_moments`); returns the raw variance when the moments were computed (else NaN).
fn fill_summary(
    values: &[f64],
    base: usize,
    force_moments: bool,
    need: &[bool],
    out: &mut [f64],
) -> f64 {
    let mut known = None;
    if force_moments || need[base..base + 4].iter().any(|&b| b) {
        let m = moments(values);
        out[base..base + 4].copy_from_slice(&[
            m.mean,
            log10_floor(m.var),
            m.skew,
            log10_floor(m.kurt),
        ]);
        known = Some(m);
    }
    // Order statistics are exact, so one percentile alone (one selection) equals the same
    // percentile computed with the others.
    let wanted: Vec<usize> = (0..3).filter(|&k| need[base + 4 + k]).collect();
    if let [k] = wanted[..] {
        let [p] = percentiles_with(values, [[10.0, 50.0, 90.0][k]], known.as_ref());
        out[base + 4 + k] = p;
    } else if !wanted.is_empty() {
        let [p10, p50, p90] = percentiles_with(values, [10.0, 50.0, 90.0], known.as_ref());
        out[base + 4..base + 7].copy_from_slice(&[p10, p50, p90]);
    }
    known.map_or(f64::NAN, |m| m.var)
}

/// The variance ratios (log10 finer − log10 coarser) that `wanted` asks for.
fn put_ratios(
    layout: &BlockLayout,
    variances: &[[f64; 3]],
    wanted: impl Fn(usize, usize) -> bool,
    out: &mut [f64],
) {
    for band in 0..3 {
        for pair in 0..layout.levels - 1 {
            if wanted(band, pair) {
                out[layout.ratio(band, pair)] =
                    log10_floor(variances[pair][band]) - log10_floor(variances[pair + 1][band]);
            }
        }
    }
}

/// The log10 band powers, band by band and orientation by orientation, then the low band.
fn put_band_powers(out: &mut [f64], powers: &BandPowers) {
    let values = powers
        .oriented
        .iter()
        .flatten()
        .chain(std::iter::once(&powers.lo));
    for (slot, &p) in out.iter_mut().zip(values) {
        *slot = log10_floor(p);
    }
}

/// The values of an array in row-major order, borrowed when it is in standard layout.
fn values_of(a: &Array2<f64>) -> std::borrow::Cow<'_, [f64]> {
    match a.as_slice() {
        Some(s) => s.into(),
        None => a.iter().copied().collect::<Vec<f64>>().into(),
    }
}

/// The seven statistics of a summary at the start of `out`, in
/// [`super::stats::STAT_NAMES`] order.
fn put_summary(out: &mut [f64], s: &Summary) {
    out[..STATS].copy_from_slice(&[
        s.mean,
        log10_floor(s.var),
        s.skew,
        log10_floor(s.kurt),
        s.p10,
        s.p50,
        s.p90,
    ]);
}
