//! Feature extraction: a sphere in a luminance image → the unwrapped annulus → pyramid,
//! statistics and band powers → the feature vector in [`Layout`] order; or only the
//! features a classifier reads, bit-identical to the full vector's.

use super::centre;
use super::config::{ConfigError, FeatureConfig};
use super::layout::{BlockLayout, Layout, STATS};
use super::noise;
use super::observed::{Observed, ObservedError, Support, kept};
use super::outline;
use super::polar::{AngleTable, angle_table, unwrap, unwrap_footprints};
use super::pyramid::{self, Edge, Level};
use super::spectrum::{BandPowers, SpectrumPlan};
use super::stats::{Moments, Summary, moments, percentiles_with, summarize};
use super::{CENTRE_NAMES, LOG_PIXEL_FLOOR, ORIENTATION_PAIRS, RADIAL_RINGS};
use crate::image::circle::Circle;
use crate::object::normals::EquivalentSphere;
use ndarray::{Array2, ArrayView2};
use std::sync::{Arc, OnceLock};

/// Floor of a variance, kurtosis or power before its log10.
const LOG_FLOOR: f64 = 1e-30;
/// Floor of the noise at white and of the rim blur before their log10 (and their value when
/// they cannot be told).
const NOISE_FLOOR: f64 = 1e-4;

/// log10 of the floored unwrapped values: the image of the log-domain features.
fn log_pixels(unwrapped: &Array2<f64>) -> Array2<f64> {
    let values = unwrapped.as_standard_layout();
    let logs =
        super::log10::log10_floored(values.as_slice().expect("standard layout"), LOG_PIXEL_FLOOR);
    Array2::from_shape_vec(unwrapped.raw_dim(), logs).expect("same number of values")
}

/// What the capture measurements (see `noise`) found on one sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureMeasurements {
    /// Noise at white as a fraction of white (`None`: no block of the annulus to read it).
    pub noise: Option<f64>,
    /// Fraction of the annulus's pixels at full scale (0 for floating-point images).
    pub clipped: f64,
}

impl CaptureMeasurements {
    /// The measurements as a feature row of `layout` holds them (`cap.noise`, `cap.clipped`),
    /// when it has the capture family: the noise back from its floored log10 (`None` at the
    /// floor).
    pub fn of_row(layout: &super::Layout, row: &[f64]) -> Option<CaptureMeasurements> {
        let capture = layout.capture();
        let (noise, clipped) = (row.get(capture.start)?, row.get(capture.start + 1)?);
        Some(CaptureMeasurements {
            noise: (*noise > NOISE_FLOOR.log10()).then(|| 10f64.powf(*noise)),
            clipped: *clipped,
        })
    }
}

/// Pearson correlations of the coefficient magnitudes of a level's orientations, in
/// [`ORIENTATION_PAIRS`] order (the paper's §7: neighbouring orientations depend on each
/// other at edges, and a blur changes how much). 0 where a band is constant.
fn orientation_dependencies(level: &pyramid::Level, support: Option<&Level<bool>>) -> [f64; 3] {
    // Over the coefficients supported in all three bands.
    let alike = |s: &&Level<bool>| s.h.dim() == s.v.dim() && s.h.dim() == s.d.dim();
    let both = support.filter(alike).map(|s| {
        ndarray::Zip::from(&s.h)
            .and(&s.v)
            .and(&s.d)
            .map_collect(|&h, &v, &d| h && v && d)
    });
    let bands = [&level.h, &level.v, &level.d].map(|b| kept(b, both.as_ref()));
    let n = bands[0].len().max(1) as f64;
    let means = bands
        .each_ref()
        .map(|band| band.iter().map(|v| v.abs()).sum::<f64>() / n);
    // Two passes in f64: the means, then the centred products of every pair and square.
    let (mut products, mut squares) = ([0.0; 3], [0.0; 3]);
    for ((h, v), d) in bands[0].iter().zip(bands[1].iter()).zip(bands[2].iter()) {
        let c = [h.abs() - means[0], v.abs() - means[1], d.abs() - means[2]];
        for (k, (a, b)) in ORIENTATION_PAIRS.into_iter().enumerate() {
            products[k] += c[a] * c[b];
            squares[k] += c[k] * c[k];
        }
    }
    std::array::from_fn(|k| {
        let (a, b) = ORIENTATION_PAIRS[k];
        if squares[a] > 0.0 && squares[b] > 0.0 {
            products[k] / (squares[a] * squares[b]).sqrt()
        } else {
            0.0
        }
    })
}

fn log10_floor(v: f64) -> f64 {
    v.max(LOG_FLOOR).log10()
}

/// Computes feature vectors; holds the FFT plan and angle tables for its configuration.
#[derive(Debug)]
pub struct Extractor {
    config: FeatureConfig,
    layout: Layout,
    spectrum: SpectrumPlan,
    /// Angle tables for supersampling s = 1..=16, built on first use.
    angles: [OnceLock<Arc<AngleTable>>; 16],
}

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

impl Extractor {
    /// An extractor for `config`, once it is valid ([`FeatureConfig::validate`]); it plans
    /// the FFT of the configured grid, and is meant to be built once and shared.
    ///
    /// ```
    /// use ndarray::Array2;
    /// use reflectance_core::locate::{Circle};
    /// use reflectance_core::{Extractor, FeatureConfig};
    ///
    /// // A matte (Lambertian) sphere of albedo 0.6 lit from the upper left, on black.
    /// let (size, r) = (160, 64.0);
    /// let centre = (size as f64 - 1.0) / 2.0;
    /// let light = [-0.4, -0.5, 0.768];
    /// let luminance = Array2::from_shape_fn((size, size), |(y, x)| {
    ///     let (nx, ny) = ((x as f64 - centre) / r, (y as f64 - centre) / r);
    ///     let d2 = nx * nx + ny * ny;
    ///     if d2 >= 1.0 {
    ///         return 0.0;
    ///     }
    ///     let nz = (1.0 - d2).sqrt();
    ///     0.6 * (nx * light[0] + ny * light[1] + nz * light[2]).max(0.0)
    /// });
    /// let circle = Circle { cx: centre, cy: centre, r };
    ///
    /// let config = FeatureConfig::default();
    /// let extractor = Extractor::new(config)?;
    /// // The circle must fit the image with its sampled annulus.
    /// geometry::validate(&circle, size, size, config.unwrap.outer, config.unwrap.r0)?;
    /// let values = extractor.extract(luminance.view(), &circle, 1.0);
    /// assert_eq!(values.len(), 117);
    /// assert!(values.iter().all(|v| v.is_finite()));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(config: FeatureConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Extractor {
            spectrum: SpectrumPlan::new(config.unwrap.rows, config.unwrap.cols),
            layout: config.layout(),
            config,
            angles: Default::default(),
        })
    }

    /// The configuration it extracts.
    pub fn config(&self) -> &FeatureConfig {
        &self.config
    }

    fn angles(&self, s: usize) -> Arc<AngleTable> {
        let build = || Arc::new(angle_table(self.config.unwrap.cols, s));
        match self.angles.get(s - 1) {
            Some(cell) => cell.get_or_init(build).clone(),
            None => build(),
        }
    }

    /// The image the features see: the sphere reduced to the working radius, when the
    /// configuration has one and the sphere is larger (`None`: the image as it is).
    fn reduce(&self, luminance: ArrayView2<f64>, circle: &Circle) -> Option<(Array2<f64>, Circle)> {
        self.config
            .working_radius
            .and_then(|target| crate::image::resample::to_radius(luminance, circle, target))
    }

    /// The unwrapped, white-normalized annulus (after reduction to the working radius, if
    /// the configuration has one and the sphere is larger).
    pub fn unwrap(&self, luminance: ArrayView2<f64>, circle: &Circle, white: f64) -> Array2<f64> {
        let reduced = self.reduce(luminance, circle);
        let (luminance, circle) = match &reduced {
            Some((image, moved)) => (image.view(), moved),
            None => (luminance, circle),
        };
        self.unwrap_as_is(luminance, circle, white)
    }

    fn unwrap_as_is(&self, luminance: ArrayView2<f64>, circle: &Circle, white: f64) -> Array2<f64> {
        let angles = self.angles(self.config.unwrap.supersampling(circle.r));
        let gain = 1.0 / white;
        let mut grid = if gain.is_finite() {
            unwrap(luminance, circle, &self.config.unwrap, &angles, gain)
        } else {
            // A subnormal white has no finite reciprocal: divide instead.
            let mut grid = unwrap(luminance, circle, &self.config.unwrap, &angles, 1.0);
            grid.mapv_inplace(|v| v / white);
            grid
        };
        if let Some(ceiling) = self.config.saturation {
            grid.mapv_inplace(|v| v.min(ceiling));
        }
        grid
    }

    /// Feature values (canonical order, transformed) of a sphere in a luminance image.
    /// The circle must already be validated against the image.
    pub fn extract(&self, luminance: ArrayView2<f64>, circle: &Circle, white: f64) -> Vec<f64> {
        self.extract_measured(luminance, circle, white, None, None, false)
            .0
    }

    /// [`Extractor::extract`], or [`Extractor::extract_subset`] when `wanted` is given, of an
    /// image whose samples clip at `full_scale` (`None`: they do not, as in floating-point
    /// files; the clipping point matters to the capture measurements only); with `measure`
    /// also the image's capture measurements (as the sphere is seen at the working radius,
    /// like the `cap.*` features).
    pub fn extract_measured(
        &self,
        luminance: ArrayView2<f64>,
        circle: &Circle,
        white: f64,
        full_scale: Option<f64>,
        wanted: Option<&[usize]>,
        measure: bool,
    ) -> (Vec<f64>, Option<CaptureMeasurements>) {
        let reduced = self.reduce(luminance, circle);
        let (seen, seen_circle) = match &reduced {
            Some((image, moved)) => (image.view(), moved),
            None => (luminance, circle),
        };
        let measured = || CaptureMeasurements {
            noise: noise::noise_at_white(
                seen,
                seen_circle,
                white,
                full_scale.unwrap_or(f64::INFINITY),
            ),
            clipped: full_scale.map_or(0.0, |f| noise::clipped_fraction(luminance, circle, f)),
        };
        let unwrapped = self.unwrap_as_is(seen, seen_circle, white);
        let mut values = match wanted {
            None => {
                let stages = self.stages_of_unwrapped(unwrapped);
                let mut values = self.features_of(&stages);
                if self.config.log_domain {
                    let log = log_pixels(&stages.unwrapped);
                    values.extend(self.features_of(&self.stages_of_unwrapped(log)));
                }
                values
            }
            Some(wanted) => self.subset_of_blocks(&unwrapped, wanted),
        };
        let mut measurements = measure.then(measured);
        let needed = |range: std::ops::Range<usize>| {
            wanted.is_none_or(|w| w.iter().any(|i| range.contains(i)))
        };
        if self.config.capture {
            // The rim's blur is the dearest; it is measured only when wanted.
            let start = self.layout.capture().start;
            let [noise, clipped, blur] = [0, 1, 2].map(|k| needed(start + k..start + k + 1));
            let mut capture = [f64::NAN; 3];
            if noise || clipped {
                let m = *measurements.get_or_insert_with(measured);
                capture[0] = m.noise.unwrap_or(0.0).max(NOISE_FLOOR).log10();
                capture[1] = m.clipped;
            }
            if blur {
                let sigma = noise::rim_blur(luminance, circle).unwrap_or(0.0) / circle.r;
                capture[2] = sigma.max(NOISE_FLOOR).log10();
            }
            values.extend(capture);
        }
        if self.config.centre {
            let family = match needed(self.layout.centre()) {
                true => centre::centre_features(seen, seen_circle, white),
                false => [f64::NAN; CENTRE_NAMES.len()],
            };
            values.extend(&family[..self.layout.centre().len()]);
        }
        if self.config.domain {
            // On the image as given: the reduction to the working radius crops the rim's
            // surroundings away.
            values.push(match needed(self.layout.domain()) {
                true => outline::outline(luminance, circle),
                false => f64::NAN,
            });
        }
        (values, measurements.filter(|_| measure))
    }

    /// The stages of a sphere's extraction: unwrapped, its pyramid and its band powers.
    pub fn stages(&self, luminance: ArrayView2<f64>, circle: &Circle, white: f64) -> Stages {
        let unwrapped = self.unwrap(luminance, circle, white);
        self.stages_of_unwrapped(unwrapped)
    }

    /// The stages of an annulus already unwrapped (the pyramid with a periodic edge in angle).
    pub fn stages_of_unwrapped(&self, unwrapped: Array2<f64>) -> Stages {
        let pyramid = pyramid::build(unwrapped.view(), self.config.levels, Edge::Periodic);
        let band_powers = self.spectrum.band_powers(unwrapped.view());
        Stages {
            unwrapped,
            pyramid,
            band_powers,
        }
    }

    /// The feature vector of computed stages: one block ([`BlockLayout`]).
    pub fn features_of(&self, stages: &Stages) -> Vec<f64> {
        self.block_features(stages, None)
    }

    /// One block's features of computed stages, over the observed part `support` says
    /// (everything for `None`; see [`observed`]).
    fn block_features(&self, stages: &Stages, support: Option<&Support>) -> Vec<f64> {
        let layout = &self.layout.block;
        let mut out = vec![f64::NAN; layout.count()];
        let mut scratch: Vec<u64> = Vec::new();
        let mut summary = |values: &Array2<f64>, keep: Option<&Array2<bool>>| {
            summarize(&kept(values, keep), &mut scratch)
        };
        let pixels = support.map(|s| s.pixels);
        let level_support = |level: usize| support.and_then(|s| s.levels.get(level));
        put_summary(
            &mut out[BlockLayout::PIXELS..],
            &summary(&stages.unwrapped, pixels),
        );
        // Raw subband variances, [level][band], for the ratios.
        let mut variances = vec![[0.0; 3]; self.config.levels];
        for (level, bands) in stages.pyramid.levels.iter().enumerate() {
            let keeps = oriented(level_support(level));
            for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
                let s = summary(values, keeps[band]);
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
        if layout.radial {
            let all = |_| true;
            put_ring_changes(layout, &stages.unwrapped, pixels, None, all, &mut out);
            for (level, bands) in stages.pyramid.levels.iter().enumerate() {
                let keeps = oriented(level_support(level));
                for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
                    let slot = Some(BlockLayout::radial_band_slot(level, band));
                    put_ring_changes(layout, values, keeps[band], slot, all, &mut out);
                }
            }
        }
        if layout.dependencies {
            for (level, bands) in stages.pyramid.levels.iter().enumerate() {
                let dependencies = orientation_dependencies(bands, level_support(level));
                for (pair, value) in dependencies.into_iter().enumerate() {
                    out[layout.dependency(level, pair)] = value;
                }
            }
        }
        out
    }

    /// The blocks' features of an annulus with missing cells (an object's equivalent
    /// sphere, unwrapped): the statistics over the observed part ([`observed`]).
    pub fn features_over(&self, unwrapped: &Array2<f64>, observed: &Observed) -> Vec<f64> {
        let support = observed.support(self.config.levels);
        let stages = self.stages_of_unwrapped(observed.filled(unwrapped));
        let mut values = self.block_features(&stages, Some(&support));
        if self.config.log_domain {
            let log = self.stages_of_unwrapped(log_pixels(&stages.unwrapped));
            values.extend(self.block_features(&log, Some(&support)));
        }
        values
    }

    /// An object's equivalent sphere unwrapped as a sphere's annulus (it is built at the
    /// working radius), in units of white, with the cells it observes.
    pub fn unwrap_equivalent(
        &self,
        sphere: &EquivalentSphere,
        white: f64,
    ) -> Result<(Array2<f64>, Observed), ObservedError> {
        let seen = sphere.observed.mapv(f64::from);
        let angles = self.angles(self.config.unwrap.supersampling(sphere.circle.r));
        let unwrap_cfg = &self.config.unwrap;
        let coverage = unwrap(seen.view(), &sphere.circle, unwrap_cfg, &angles, 1.0);
        let observed = Observed::from_coverage(&coverage)?;
        Ok((self.annulus_of_equivalent(sphere, white), observed))
    }

    /// An object's equivalent sphere's annulus in units of white: its pixels resampled once
    /// onto the unwrap's samples ([`unwrap_footprints`]); a cell none of them reached (a
    /// missing one, or one filled between pixels) is the unwrap of the sphere's grid.
    fn annulus_of_equivalent(&self, sphere: &EquivalentSphere, white: f64) -> Array2<f64> {
        let angles = self.angles(self.config.unwrap.supersampling(sphere.circle.r));
        let (splat, reached) = unwrap_footprints(
            &sphere.footprints,
            &sphere.circle,
            &self.config.unwrap,
            &angles,
        );
        let ceiling = self.config.saturation.unwrap_or(f64::INFINITY);
        let mut annulus = splat.mapv(|v| (v / white).min(ceiling));
        if reached.iter().any(|&r| !r) {
            let grid = self.unwrap_as_is(sphere.luminance.view(), &sphere.circle, white);
            ndarray::Zip::from(&mut annulus)
                .and(&grid)
                .and(&reached)
                .for_each(|a, &g, &r| {
                    if !r {
                        *a = g;
                    }
                });
        }
        annulus
    }

    /// The stages of an object's equivalent sphere: its unwrapped annulus with the missing
    /// cells as they are (0), for pictures.
    pub fn stages_of_equivalent(&self, sphere: &EquivalentSphere, white: f64) -> Stages {
        self.stages_of_unwrapped(self.annulus_of_equivalent(sphere, white))
    }

    /// Every feature of an object's equivalent sphere, and which of its annulus is observed:
    /// the blocks over the observed part; the capture family as far as it can be told (the
    /// noise of the equivalent sphere's observed cells, which is what its fine bands carry;
    /// the clipped share of the observed cells; the rim blur at its floor, since the sphere
    /// has no rim); the centre and domain families of the sphere with its missing cells
    /// filled.
    pub fn extract_equivalent(
        &self,
        sphere: &EquivalentSphere,
        white: f64,
        full_scale: Option<f64>,
    ) -> Result<(Vec<f64>, Observed), ObservedError> {
        let (unwrapped, observed) = self.unwrap_equivalent(sphere, white)?;
        let mut values = self.features_over(&unwrapped, &observed);
        if self.config.capture {
            let ceiling = full_scale.map_or(f64::INFINITY, |f| noise::CLIPPED * f / white);
            let kept = kept(&unwrapped, Some(&observed.mask));
            let clipped = kept.iter().filter(|&&v| v >= ceiling).count();
            let c = &sphere.circle;
            let seen = |row: usize, col: usize| sphere.observed[(row, col)];
            let noise =
                noise::noise_at_white_where(sphere.luminance.view(), c, white, f64::INFINITY, seen);
            let floor = NOISE_FLOOR.log10();
            let noise = noise.map_or(floor, |n| n.max(NOISE_FLOOR).log10());
            values.extend([noise, clipped as f64 / kept.len().max(1) as f64, floor]);
        }
        let filled = sphere.filled();
        if self.config.centre {
            let family = centre::centre_features(filled.view(), &sphere.circle, white);
            values.extend(&family[..self.layout.centre().len()]);
        }
        if self.config.domain {
            values.push(outline::outline(filled.view(), &sphere.circle));
        }
        Ok((values, observed))
    }

    /// Number of features of this configuration (117 with the default one).
    pub fn feature_count(&self) -> usize {
        self.layout.count()
    }

    /// [`Extractor::extract`] computing only the features at the indices `wanted` (into the
    /// canonical order); every other entry is NaN. The wanted values are bit-identical to
    /// `extract`'s: the same stages and statistics run on the same data, and those nobody
    /// reads are skipped (pyramid levels past the deepest one needed, unneeded moments and
    /// percentiles, the band powers). A classifier that reads a handful of features (e.g.
    /// `hand6`) needs a fraction of the work.
    pub fn extract_subset(
        &self,
        luminance: ArrayView2<f64>,
        circle: &Circle,
        white: f64,
        wanted: &[usize],
    ) -> Vec<f64> {
        self.extract_measured(luminance, circle, white, None, Some(wanted), false)
            .0
    }

    /// The wanted features of the blocks (the unwrapped image's, then its log10's).
    fn subset_of_blocks(&self, unwrapped: &Array2<f64>, wanted: &[usize]) -> Vec<f64> {
        let n = self.layout.blocks().end;
        let block = self.layout.block.count();
        let mut need = vec![false; n];
        for &i in wanted {
            if let Some(slot) = need.get_mut(i) {
                *slot = true;
            }
        }
        let mut out = vec![f64::NAN; n];
        self.subset_of(unwrapped, &need[..block], &mut out[..block]);
        if self.layout.log_domain && need[block..].iter().any(|&b| b) {
            let log = log_pixels(unwrapped);
            self.subset_of(&log, &need[block..], &mut out[block..]);
        }
        out
    }

    /// The needed features of one block of an unwrapped image into `out`.
    fn subset_of(&self, unwrapped: &Array2<f64>, need: &[bool], out: &mut [f64]) {
        let layout = &self.layout.block;
        let levels = layout.levels;
        let stats_needed = |base: usize| need[base..base + STATS].iter().any(|&b| b);
        let ratio_needed = |band: usize, pair: usize| need[layout.ratio(band, pair)];
        let radial_needed = |slot: usize| {
            layout.radial && (0..RADIAL_RINGS - 1).any(|pair| need[layout.radial(pair, slot)])
        };
        let dependencies_needed = |level: usize| {
            layout.dependencies
                && (0..ORIENTATION_PAIRS.len()).any(|pair| need[layout.dependency(level, pair)])
        };
        // Which subbands need their variance (for ratios), and the deepest level needed.
        let mut deepest = None;
        let mut band_var = vec![[false; 3]; levels];
        for (level, bands) in band_var.iter_mut().enumerate() {
            if dependencies_needed(level) {
                deepest = Some(level);
            }
            for (band, slot) in bands.iter_mut().enumerate() {
                let ratio = (level + 1 < levels && ratio_needed(band, level))
                    || (level > 0 && ratio_needed(band, level - 1));
                *slot = ratio;
                let radial = radial_needed(BlockLayout::radial_band_slot(level, band));
                if ratio || radial || stats_needed(layout.band(level, band)) {
                    deepest = Some(level);
                }
            }
        }
        fill_summary(&values_of(unwrapped), BlockLayout::PIXELS, false, need, out);
        if radial_needed(0) || radial_needed(1) {
            put_ring_changes(layout, unwrapped, None, None, |i| need[i], out);
        }
        if let Some(deepest) = deepest {
            let pyramid = pyramid::build(unwrapped.view(), deepest + 1, Edge::Periodic);
            let mut variances = vec![[f64::NAN; 3]; levels];
            for (level, bands) in pyramid.levels.iter().enumerate() {
                for (band, values) in [&bands.h, &bands.v, &bands.d].into_iter().enumerate() {
                    let base = layout.band(level, band);
                    if band_var[level][band] || stats_needed(base) {
                        variances[level][band] = fill_summary(
                            &values_of(values),
                            base,
                            band_var[level][band],
                            need,
                            out,
                        );
                    }
                    let slot = BlockLayout::radial_band_slot(level, band);
                    if radial_needed(slot) {
                        put_ring_changes(layout, values, None, Some(slot), |i| need[i], out);
                    }
                }
                if dependencies_needed(level) {
                    for (pair, value) in orientation_dependencies(bands, None)
                        .into_iter()
                        .enumerate()
                    {
                        let at = layout.dependency(level, pair);
                        if need[at] {
                            out[at] = value;
                        }
                    }
                }
            }
            put_ratios(layout, &variances, ratio_needed, out);
        }
        let powers = layout.band_powers();
        if need[powers.clone()].iter().any(|&b| b) {
            put_band_powers(
                &mut out[powers],
                &self.spectrum.band_powers(unwrapped.view()),
            );
        }
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

/// The radial changes of an image: its pixels' mean and variance (`subband` None) or a
/// subband's variance (`Some(slot)`), at the indices `wanted` accepts.
fn put_ring_changes(
    layout: &BlockLayout,
    values: &Array2<f64>,
    keep: Option<&Array2<bool>>,
    subband: Option<usize>,
    wanted: impl Fn(usize) -> bool,
    out: &mut [f64],
) {
    for (pair, [mean, var]) in ring_changes(values, keep).into_iter().enumerate() {
        let changes = match subband {
            None => [
                (layout.radial(pair, 0), mean),
                (layout.radial(pair, 1), var),
            ]
            .to_vec(),
            Some(slot) => [(layout.radial(pair, slot), var)].to_vec(),
        };
        for (at, value) in changes.into_iter().filter(|&(at, _)| wanted(at)) {
            out[at] = value;
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

/// `[mean, log10 variance]` of each ring of rows minus those of the ring inside it, over
/// the values `keep` keeps ([`kept`]). Ring k (from 0, innermost) holds rows
/// ⌊k·n/R⌋ .. ⌊(k+1)·n/R⌋ of n, R = [`RADIAL_RINGS`].
fn ring_changes(a: &Array2<f64>, keep: Option<&Array2<bool>>) -> [[f64; 2]; RADIAL_RINGS - 1] {
    let rows = a.nrows();
    let ring = |k: usize| {
        let span = ndarray::s![k * rows / RADIAL_RINGS..(k + 1) * rows / RADIAL_RINGS, ..];
        let values = a.slice(span).to_owned();
        let keep = keep.map(|m| m.slice(span).to_owned());
        moments(&kept(&values, keep.as_ref()))
    };
    let rings: [Moments; RADIAL_RINGS] = std::array::from_fn(ring);
    std::array::from_fn(|t| {
        let (inner, outer) = (&rings[t], &rings[t + 1]);
        [
            outer.mean - inner.mean,
            log10_floor(outer.var) - log10_floor(inner.var),
        ]
    })
}

/// The keeps of a level's three bands, in h, v, d order (none without support).
fn oriented(support: Option<&Level<bool>>) -> [Option<&Array2<bool>>; 3] {
    match support {
        Some(s) => [Some(&s.h), Some(&s.v), Some(&s.d)],
        None => [None; 3],
    }
}

/// The seven statistics of a summary at the start of `out`, in [`STAT_NAMES`] order.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::polar::UnwrapConfig;
    use crate::features::{CAPTURE_NAMES, CENTRE_NAMES, DOMAIN_NAMES, FEATURE_COUNT, RADIAL_RINGS};
    use crate::features::{Extensions, Preprocessing, default_names, named_set};
    use crate::image::circle::Circle;

    #[test]
    fn names_are_canonical_and_unique() {
        let names = default_names();
        assert_eq!(names.len(), FEATURE_COUNT);
        let unique: std::collections::HashSet<_> = names.iter().collect();
        assert_eq!(unique.len(), FEATURE_COUNT);
        assert_eq!(names[0], "pix.mean");
        assert_eq!(names[7], "wav.s1.h.mean");
        assert_eq!(names[7 + 7 + 1], "wav.s1.v.var");
        assert_eq!(names[90], "wav.s4.d.p90");
        assert_eq!(names[91], "ratio.h.s1_s2");
        assert_eq!(names[99], "ratio.d.s3_s4");
        assert_eq!(names[100], "fft.b1.f0.pow");
        assert_eq!(names[115], "fft.b4.f135.pow");
        assert_eq!(names[116], "fft.lo.pow");
        for set in ["hand6", "hand2", "mean1"] {
            for n in named_set(set).unwrap() {
                assert!(names.contains(&n), "{n}");
            }
        }
        let extended = FeatureConfig::with_log_domain().names();
        assert_eq!(extended.len(), 2 * FEATURE_COUNT);
        assert_eq!(extended[FEATURE_COUNT], "log.pix.mean");
        for n in named_set("hand6+log").unwrap() {
            assert!(extended.contains(&n), "{n}");
        }
        let every = FeatureConfig::extended(Extensions::ALL, Preprocessing::default()).names();
        let block = FEATURE_COUNT + (RADIAL_RINGS - 1) * 14 + 12;
        assert_eq!(every.len(), 2 * block + 3 + 6 + 1);
        assert_eq!(every[2 * block..2 * block + 3], CAPTURE_NAMES);
        assert_eq!(every[2 * block + 3..2 * block + 9], CENTRE_NAMES);
        assert_eq!(every[2 * block + 9..], DOMAIN_NAMES);
        assert_eq!(every[..FEATURE_COUNT], names[..]);
        let last_pair = format!("r{}_r{RADIAL_RINGS}", RADIAL_RINGS - 1);
        assert_eq!(
            [&every[FEATURE_COUNT], &every[FEATURE_COUNT + 2]],
            ["radial.r1_r2.pix.mean", "radial.r1_r2.wav.s1.h.var"]
        );
        assert_eq!(
            every[block - 13],
            format!("radial.{last_pair}.wav.s4.d.var")
        );
        assert_eq!(
            [&every[block - 12], &every[block - 10], &every[block - 1]],
            ["dep.s1.hv", "dep.s1.vd", "dep.s4.vd"]
        );
        assert_eq!(every[block], "log.pix.mean");
        assert_eq!(
            every[2 * block - 13],
            format!("log.radial.{last_pair}.wav.s4.d.var")
        );
        assert_eq!(every[2 * block - 1], "log.dep.s4.vd");
        for set in ["hand6+log+radial", "hand6+log+radial+dep"] {
            for n in named_set(set).unwrap() {
                assert!(every.contains(&n), "{n}");
            }
        }
    }

    #[test]
    fn extensions_of_names_and_specs() {
        let of_spec = |spec: &str| {
            let e = Extensions::of_spec(spec);
            (e.log_domain, e.radial)
        };
        assert_eq!(of_spec("hand6"), (false, false));
        assert_eq!(of_spec("all"), (false, false));
        assert_eq!(of_spec("hand6+log"), (true, false));
        assert_eq!(of_spec("hand6+log+radial"), (true, true));
        assert_eq!(
            of_spec("pix.mean, radial.r1_r2.wav.s1.v.var"),
            (false, true)
        );
        assert_eq!(of_spec("log.radial.r1_r2.pix.var"), (true, true));
        assert_eq!(of_spec("log.pix.mean,pix.p10"), (true, false));
        let config = FeatureConfig::extended(Extensions::ALL, Preprocessing::at_radius(80.0));
        let names = config.names();
        assert_eq!(
            Extensions::of_names(names.iter().map(String::as_str)),
            config.extensions()
        );
    }

    /// An unwrapped image of `pattern(row, col)` times `gain(ring)` (rings of equal height,
    /// innermost first).
    fn by_ring(pattern: impl Fn(usize, usize) -> f64, gain: impl Fn(usize) -> f64) -> Array2<f64> {
        let u = UnwrapConfig::default();
        Array2::from_shape_fn((u.rows, u.cols), |(i, j)| {
            pattern(i, j) * gain(i * RADIAL_RINGS / u.rows)
        })
    }

    #[test]
    fn radial_changes_compare_each_ring_of_the_annulus_with_the_one_inside_it() {
        let extractor = Extractor::new(FeatureConfig::extended(
            Extensions::ALL,
            Preprocessing::default(),
        ))
        .unwrap();
        let names = extractor.config().names();
        let per = 2 + 3 * 4; // pixel mean and variance, 12 subband variances
        let radial = |unwrapped: Array2<f64>| {
            let values = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped));
            let range = FEATURE_COUNT..FEATURE_COUNT + (RADIAL_RINGS - 1) * per;
            names[range.clone()]
                .iter()
                .cloned()
                .zip(values[range].iter().copied())
                .collect::<Vec<(String, f64)>>()
        };
        let value = |changes: &[(String, f64)], n: &str| {
            changes.iter().find(|(m, _)| m == n).map(|c| c.1).unwrap()
        };
        // Angular structure only, the same at every radius: nothing changes.
        let stripes =
            |_: usize, j: usize| 1.0 + 0.5 * (j as f64 * 0.7).sin() + 0.1 * (j % 5) as f64;
        for (name, value) in radial(by_ring(stripes, |_| 1.0)) {
            assert!(value.abs() < 1e-9, "{name} = {value}");
        }
        // Ring k (from 1) k × brighter: the mean grows by the ring-1 mean from ring to ring,
        // the variance by (k + 1)² / k².
        let u = by_ring(stripes, |k| (k + 1) as f64);
        let ring1_mean = u
            .slice(ndarray::s![..96 / RADIAL_RINGS, ..])
            .mean()
            .unwrap();
        let changes = radial(u);
        for k in 1..RADIAL_RINGS {
            let pair = format!("radial.r{k}_r{}.pix", k + 1);
            let mean = value(&changes, &format!("{pair}.mean"));
            assert!((mean - ring1_mean).abs() < 1e-12, "{pair}: {mean}");
            let var = value(&changes, &format!("{pair}.var"));
            let ratio = ((k + 1) * (k + 1)) as f64 / (k * k) as f64;
            assert!((var - ratio.log10()).abs() < 1e-12, "{pair}: {var}");
        }
        // Finer angular structure in the outermost ring: the finest vertical subband's
        // energy moves out, the coarsest's in.
        let outermost = RADIAL_RINGS - 1;
        let finer = |i: usize, j: usize| {
            let period = if i * RADIAL_RINGS / 96 == outermost {
                4.0
            } else {
                32.0
            };
            (std::f64::consts::TAU * j as f64 / period).sin()
        };
        let changes = radial(by_ring(finer, |_| 1.0));
        let last = format!("radial.r{outermost}_r{}.wav", outermost + 1);
        assert!(
            value(&changes, &format!("{last}.s1.v.var")) > 2.0,
            "{changes:?}"
        );
        assert!(
            value(&changes, &format!("{last}.s4.v.var")) < -0.5,
            "{changes:?}"
        );
    }

    #[test]
    fn log_domain_features_are_the_features_of_the_log_image() {
        let img = ndarray::Array2::from_shape_fn((120, 130), |(y, x)| {
            let d = ((x as f64 - 64.0).powi(2) + (y as f64 - 59.5).powi(2)).sqrt();
            if d < 55.0 {
                0.2 + 0.5 * ((x as f64) * 0.3).sin().abs() + 0.001 * (y % 7) as f64
            } else {
                0.0
            }
        });
        let circle = Circle {
            cx: 64.0,
            cy: 59.5,
            r: 55.0,
        };
        let plain = Extractor::new(FeatureConfig::default()).unwrap();
        let extended = Extractor::new(FeatureConfig::with_log_domain()).unwrap();
        let values = extended.extract(img.view(), &circle, 0.8);
        assert_eq!(
            &values[..FEATURE_COUNT],
            plain.extract(img.view(), &circle, 0.8).as_slice()
        );
        let log = plain
            .unwrap(img.view(), &circle, 0.8)
            .mapv(|v| v.max(LOG_PIXEL_FLOOR).log10());
        let expected = plain.features_of(&plain.stages_of_unwrapped(log));
        // libm's log10 and ours differ by up to 2 ulp.
        for (got, want) in values[FEATURE_COUNT..].iter().zip(&expected) {
            assert!(
                (got - want).abs() <= 1e-12 * want.abs().max(1e-3),
                "{got} vs {want}"
            );
        }
    }

    #[test]
    fn white_scales_the_unwrap_even_without_a_finite_reciprocal() {
        let img = Array2::from_shape_fn((128, 128), |(y, x)| 0.5 + 0.001 * (x + 3 * y) as f64);
        let circle = Circle {
            cx: 64.0,
            cy: 63.5,
            r: 60.0,
        };
        let extractor = Extractor::new(FeatureConfig::default()).unwrap();
        let unit = extractor.unwrap(img.view(), &circle, 1.0);
        let half = extractor.unwrap(img.view(), &circle, 0.5);
        assert!(
            unit.iter()
                .zip(&half)
                .all(|(u, h)| (2.0 * u - h).abs() < 1e-14)
        );
        // 1/1e-310 overflows; the cells are still the (finite) quotients.
        let faint = img.mapv(|v| v * 1e-300);
        let tiny = extractor.unwrap(faint.view(), &circle, 1e-310);
        assert!(
            unit.iter()
                .zip(&tiny)
                .all(|(u, t)| (u * 1e10 - t).abs() <= 1e-12 * t)
        );
    }

    #[test]
    fn saturation_clips_the_white_normalized_unwrap() {
        let img = Array2::from_shape_fn((128, 128), |(y, x)| 0.02 * (x + y) as f64);
        let circle = Circle {
            cx: 64.0,
            cy: 63.5,
            r: 60.0,
        };
        let free = Extractor::new(FeatureConfig::default()).unwrap();
        let config = FeatureConfig {
            saturation: Some(1.25),
            ..FeatureConfig::default()
        };
        let clipped = Extractor::new(config).unwrap();
        let white = 2.0;
        let before = free.unwrap(img.view(), &circle, white);
        let after = clipped.unwrap(img.view(), &circle, white);
        assert!(before.iter().any(|&v| v > 1.5) && before.iter().any(|&v| v < 1.0));
        for (b, a) in before.iter().zip(&after) {
            assert_eq!(*a, b.min(1.25));
        }
        let features = |e: &Extractor| e.extract(img.view(), &circle, white);
        assert_ne!(features(&free), features(&clipped));
    }

    /// A rows × cols field of uniform noise around 0.5 (a stationary texture).
    fn noise_field(rows: usize, cols: usize, seed: u64) -> Array2<f64> {
        let mut rng = crate::util::rng::Rng::new(seed);
        Array2::from_shape_fn((rows, cols), |_| 0.25 + 0.5 * rng.next_f64())
    }

    fn observed_where(rows: usize, cols: usize, seen: impl Fn(usize, usize) -> bool) -> Observed {
        let coverage = Array2::from_shape_fn((rows, cols), |(r, c)| f64::from(seen(r, c)));
        Observed::from_coverage(&coverage).unwrap()
    }

    #[test]
    fn features_over_a_fully_observed_annulus_are_the_features() {
        let config = FeatureConfig {
            log_domain: true,
            radial: true,
            dependencies: true,
            ..FeatureConfig::default()
        };
        let extractor = Extractor::new(config).unwrap();
        let (rows, cols) = (config.unwrap.rows, config.unwrap.cols);
        let unwrapped = noise_field(rows, cols, 3);
        let everything = observed_where(rows, cols, |_, _| true);
        let over = extractor.features_over(&unwrapped, &everything);
        let mut want = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped.clone()));
        let log = extractor.stages_of_unwrapped(log_pixels(&unwrapped));
        want.extend(extractor.features_of(&log));
        assert_eq!(over.len(), want.len());
        for (k, (a, b)) in over.iter().zip(&want).enumerate() {
            assert_eq!(a.to_bits(), b.to_bits(), "feature {k}: {a} against {b}");
        }
    }

    #[test]
    fn features_over_half_a_texture_estimate_the_whole_textures_statistics() {
        let extractor = Extractor::new(FeatureConfig::default()).unwrap();
        let config = extractor.config();
        let (rows, cols) = (config.unwrap.rows, config.unwrap.cols);
        let names = extractor.layout.names();
        let at = |name: &str| names.iter().position(|n| n == name).unwrap();
        let unwrapped = noise_field(rows, cols, 5);
        let whole = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped.clone()));
        // Half the angles seen, and what fills the other half must not matter.
        let half = observed_where(rows, cols, |_, c| c < cols / 2);
        let mut hidden = unwrapped.clone();
        for ((_, c), v) in hidden.indexed_iter_mut() {
            if c >= cols / 2 {
                *v = 40.0;
            }
        }
        let over = extractor.features_over(&hidden, &half);
        for name in [
            "pix.mean",
            "pix.var",
            "pix.p50",
            "wav.s1.h.var",
            "wav.s2.v.var",
            "wav.s3.d.var",
        ] {
            let (a, b) = (over[at(name)], whole[at(name)]);
            assert!((a - b).abs() < 0.05, "{name}: {a} over half, {b} whole");
        }
        // The band powers still sum to the (observed) variance.
        let layout = &extractor.layout.block;
        let total: f64 = over[layout.band_powers()]
            .iter()
            .map(|p| 10f64.powf(*p))
            .sum();
        let var = 10f64.powf(over[at("pix.var")]);
        assert!((total / var - 1.0).abs() < 1e-6, "{total} against {var}");
    }

    #[test]
    fn subsets_are_bit_identical_to_the_full_extraction() {
        let size = 200;
        let luminance = Array2::from_shape_fn((size, size), |(y, x)| {
            let (dx, dy) = (x as f64 - 99.5, y as f64 - 99.5);
            let d2 = (dx * dx + dy * dy) / (90.0 * 90.0);
            if d2 > 1.0 {
                0.0
            } else {
                0.3 + 0.5 * (1.0 - d2).sqrt() + 0.1 * (dx / 5.0).sin() * (dy / 7.0).cos()
            }
        });
        let circle = Circle {
            cx: 99.5,
            cy: 99.5,
            r: 90.0,
        };
        let extractor = Extractor::new(FeatureConfig::default()).unwrap();
        assert_eq!(extractor.feature_count(), FEATURE_COUNT);
        let full = extractor.extract(luminance.view(), &circle, 0.9);
        let names = default_names();
        let index = |n: &str| names.iter().position(|m| m == n).unwrap();
        let hand6: Vec<usize> = named_set("hand6")
            .unwrap()
            .iter()
            .map(|n| index(n))
            .collect();
        let subsets: Vec<Vec<usize>> = vec![
            hand6,
            vec![index("ratio.d.s3_s4")],
            vec![index("fft.b2.f45.pow"), index("wav.s4.h.p90")],
            vec![index("pix.p50"), index("wav.s1.v.skew")],
            vec![
                index("pix.p90"),
                index("wav.s2.d.p10"),
                index("wav.s2.d.p50"),
            ],
            (0..FEATURE_COUNT).collect(),
            vec![],
        ];
        let extended = Extractor::new(FeatureConfig::extended(
            Extensions::ALL,
            Preprocessing::at_radius(60.0),
        ))
        .unwrap();
        let extended_full = extended.extract(luminance.view(), &circle, 0.9);
        let block = FEATURE_COUNT + (RADIAL_RINGS - 1) * 14 + 12;
        let count = 2 * block + 3 + 6 + 1;
        assert_eq!(extended.feature_count(), count);
        assert_eq!(extended_full.len(), count);
        let extended_subsets = [
            vec![3, block + 1, block + 99, 2 * block - 1],
            // dep.s3.vd alone (three pyramid levels), dep.s1.hv and log.dep.s4.hd
            vec![block - 4],
            vec![block - 12, 2 * block - 2],
            // radial.r1_r2.pix.var, radial.r1_r2.wav.s2.v.var; two of the log-domain block
            vec![FEATURE_COUNT + 1, FEATURE_COUNT + 6],
            vec![block + FEATURE_COUNT, block + FEATURE_COUNT + 13],
            // The capture measurements, alone and with a block feature.
            vec![2 * block + 1],
            vec![5, 2 * block],
            vec![2 * block + 2],
            // The centre features, alone, with a capture measurement and with a block feature.
            vec![2 * block + 4],
            vec![2 * block + 2, 2 * block + 3],
            vec![7, count - 2],
            // The domain measurement, alone and with a centre feature.
            vec![count - 1],
            vec![count - 2, count - 1],
            (0..count).collect::<Vec<_>>(),
        ];
        for wanted in extended_subsets {
            let part = extended.extract_subset(luminance.view(), &circle, 0.9, &wanted);
            assert_eq!(part.len(), count);
            for &i in &wanted {
                assert_eq!(
                    part[i].to_bits(),
                    extended_full[i].to_bits(),
                    "extended {i}"
                );
            }
        }
        for wanted in subsets {
            let part = extractor.extract_subset(luminance.view(), &circle, 0.9, &wanted);
            assert_eq!(part.len(), FEATURE_COUNT);
            for (i, (a, b)) in part.iter().zip(&full).enumerate() {
                if wanted.contains(&i) {
                    assert_eq!(a.to_bits(), b.to_bits(), "{}", names[i]);
                }
            }
        }
    }

    #[test]
    fn orientation_dependencies_correlate_subband_magnitudes() {
        let pattern = Array2::from_shape_fn((8, 16), |(i, j)| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        let level = pyramid::Level {
            v: pattern.mapv(|x| -3.0 * x),
            d: Array2::from_elem((8, 16), 0.5),
            h: pattern,
        };
        // |v| = 3|h| exactly; d is constant, so it correlates with nothing.
        let [hv, hd, vd] = orientation_dependencies(&level, None);
        assert!((hv - 1.0).abs() < 1e-12, "{hv}");
        assert_eq!((hd, vd), (0.0, 0.0));
        let opposite = Array2::from_shape_fn((8, 16), |(i, _)| if i < 4 { 1.0 } else { 2.0 });
        let level = pyramid::Level {
            h: opposite.clone(),
            v: opposite.mapv(|x| 3.0 - x),
            d: opposite,
        };
        let [hv, hd, _] = orientation_dependencies(&level, None);
        assert!(
            (hv + 1.0).abs() < 1e-12 && (hd - 1.0).abs() < 1e-12,
            "{hv} {hd}"
        );
    }

    #[test]
    fn orientation_dependencies_ignore_the_brightness_of_the_image() {
        let config = FeatureConfig::extended(
            Extensions {
                dependencies: true,
                ..Extensions::default()
            },
            Preprocessing::default(),
        );
        let extractor = Extractor::new(config).unwrap();
        let u = config.unwrap;
        let image = Array2::from_shape_fn((u.rows, u.cols), |(i, j)| {
            1.0 + (0.3 * i as f64).sin() * (0.2 * j as f64).cos() + ((i * j) % 7) as f64 / 7.0
        });
        let deps = |scale: f64| {
            let values =
                extractor.features_of(&extractor.stages_of_unwrapped(image.mapv(|v| v * scale)));
            values[FEATURE_COUNT..].to_vec()
        };
        let (one, three) = (deps(1.0), deps(3.0));
        assert_eq!(one.len(), 12);
        assert!(one.iter().all(|c| (-1.0..=1.0).contains(c)));
        assert!(one.iter().any(|c| c.abs() > 0.01), "{one:?}");
        for (a, b) in one.iter().zip(&three) {
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
    }

    #[test]
    fn a_model_file_from_before_ctr_cos_extracts_its_own_five_centre_values() {
        let config = FeatureConfig::extended(
            Extensions {
                centre: true,
                domain: true,
                ..Extensions::default()
            },
            Preprocessing::default(),
        );
        let mut json = serde_json::to_value(config).unwrap();
        assert_eq!(json["centre_cos"], true);
        json.as_object_mut().unwrap().remove("centre_cos");
        let old: FeatureConfig = serde_json::from_value(json).unwrap();
        let (names, old_names) = (config.names(), old.names());
        assert_eq!(
            names[FEATURE_COUNT..],
            [
                "ctr.mean",
                "ctr.core",
                "ctr.p10",
                "ctr.p50",
                "ctr.p90",
                "ctr.cos",
                "dom.outline"
            ]
        );
        let without_cos: Vec<&String> = names.iter().filter(|n| *n != "ctr.cos").collect();
        assert_eq!(old_names.iter().collect::<Vec<_>>(), without_cos);
        let circle = Circle {
            cx: 60.0,
            cy: 60.0,
            r: 50.0,
        };
        let image = Array2::from_shape_fn((121, 121), |(y, x)| {
            0.2 + 0.1 * ((x as f64 * 0.3).sin() + (y as f64 * 0.2).cos()).abs()
        });
        let new_row = Extractor::new(config)
            .unwrap()
            .extract(image.view(), &circle, 0.5);
        let old_row = Extractor::new(old)
            .unwrap()
            .extract(image.view(), &circle, 0.5);
        assert_eq!(old_row.len(), old_names.len());
        let cos = names.iter().position(|n| n == "ctr.cos").unwrap();
        let mut expected = new_row.clone();
        expected.remove(cos);
        assert_eq!(old_row, expected);
    }

    #[test]
    fn config_validation() {
        let ok = FeatureConfig::default();
        assert_eq!(ok.validate(), Ok(()));
        let mut bad = ok;
        bad.unwrap.cols = 440;
        assert!(matches!(
            bad.validate(),
            Err(ConfigError::WidthNotDivisible { .. })
        ));
        let mut bad = ok;
        bad.unwrap.rows = 64;
        assert!(matches!(
            bad.validate(),
            Err(ConfigError::HeightTooSmall { level: 3, .. })
        ));
        let mut bad = ok;
        bad.unwrap.inner = 0.95;
        assert!(matches!(
            bad.validate(),
            Err(ConfigError::BadAnnulus { .. })
        ));
        for saturation in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let bad = FeatureConfig {
                saturation: Some(saturation),
                ..ok
            };
            assert!(matches!(bad.validate(), Err(ConfigError::BadSaturation(_))));
        }
    }
}
