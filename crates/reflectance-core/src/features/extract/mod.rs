//! Feature extraction: a sphere → the white-normalized annulus → pyramid, statistics and band
//! powers ([`block`](super::block)) → the feature vector in [`Layout`] order, with the optional
//! families ([`super::families`]); or only the features a classifier reads, bit-identical to
//! the full vector's. One path for a photographed sphere and an object's equivalent sphere
//! ([`Sphere`]): a photographed sphere is the object whose observed part is everything.

use super::block::{self, Stages};
use super::config::{ConfigError, FeatureConfig};
use super::families::{CaptureMeasurements, Seen, capture};
use super::layout::Layout;
use super::observed::{Observed, ObservedError};
use super::polar::{AngleTable, angle_table, unwrap, unwrap_footprints};
use super::pyramid::{self, Edge};
use super::spectrum::SpectrumPlan;
use crate::image::circle::Circle;
use crate::object::normals::EquivalentSphere;
use ndarray::{Array2, ArrayView2, CowArray};
use std::cell::OnceCell;
use std::sync::{Arc, OnceLock};

/// Computes feature vectors; holds the FFT plan and angle tables for its configuration.
#[derive(Debug)]
pub struct Extractor {
    config: FeatureConfig,
    layout: Layout,
    spectrum: SpectrumPlan,
    /// Angle tables for supersampling s = 1..=16, built on first use.
    angles: [OnceLock<Arc<AngleTable>>; 16],
}

/// A sphere the features are read from.
#[derive(Clone, Copy, Debug)]
pub enum Sphere<'a> {
    /// A sphere in a photograph: its luminance and its circle (validated against the image).
    /// Every cell of its annulus is observed.
    Photographed {
        /// The luminance.
        luminance: ArrayView2<'a, f64>,
        /// The sphere.
        circle: &'a Circle,
    },
    /// An object's equivalent sphere (built at the working radius): observed where the object
    /// turns its normals.
    Equivalent(&'a EquivalentSphere),
}

/// What [`Extractor::extract_sphere`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Extracted {
    /// The feature values, in canonical order (those not wanted: NaN).
    pub values: Vec<f64>,
    /// The capture measurements, when asked for, of a photographed sphere (as the sphere is
    /// seen at the working radius, like the `cap.*` features).
    pub measured: Option<CaptureMeasurements>,
    /// Which of an equivalent sphere's annulus is observed (`None`: everything).
    pub observed: Option<Observed>,
}

impl Extractor {
    /// An extractor for `config`, once it is valid ([`FeatureConfig::validate`]); it plans
    /// the FFT of the configured grid, and is meant to be built once and shared.
    ///
    /// ```
    /// use ndarray::Array2;
    /// use reflectance_core::locate::{self, Circle};
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
    /// locate::validate(&circle, size, size, config.unwrap.outer, config.unwrap.r0)?;
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

    /// Number of features of this configuration (117 with the default one).
    pub fn feature_count(&self) -> usize {
        self.layout.count()
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
        self.extract_photographed(luminance, circle, white, None)
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
        self.extract_photographed(luminance, circle, white, Some(wanted))
    }

    fn extract_photographed(
        &self,
        luminance: ArrayView2<f64>,
        circle: &Circle,
        white: f64,
        wanted: Option<&[usize]>,
    ) -> Vec<f64> {
        let sphere = Sphere::Photographed { luminance, circle };
        match self.extract_sphere(sphere, white, None, wanted, false) {
            Ok(extracted) => extracted.values,
            Err(_) => unreachable!("a photographed sphere is observed everywhere"),
        }
    }

    /// The features of `sphere`, whose white is `white` and whose samples clip at
    /// `full_scale` (`None`: they do not, as in floating-point files; the clipping point
    /// matters to the capture measurements only): every one, or those at `wanted` (the
    /// others NaN; an equivalent sphere's blocks are computed whole); with `measure`, also a
    /// photographed sphere's capture measurements.
    ///
    /// The blocks read the annulus's observed part; each family of the sphere reads the
    /// sphere as its module says. An equivalent sphere whose annulus shows too little fails
    /// ([`ObservedError`]).
    pub fn extract_sphere(
        &self,
        sphere: Sphere<'_>,
        white: f64,
        full_scale: Option<f64>,
        wanted: Option<&[usize]>,
        measure: bool,
    ) -> Result<Extracted, ObservedError> {
        let (seen, mut values) = self.see(sphere, white, full_scale, wanted)?;
        let needed = |i: usize| wanted.is_none_or(|w| w.contains(&i));
        for (family, at) in self.layout.families_of_sphere() {
            let wanted = |k: usize| k < at.len() && needed(at.start + k);
            values.extend(&family.extract(&seen, &wanted)[..at.len()]);
        }
        let photographed = seen.equivalent.is_none();
        let measured = (measure && photographed).then(|| capture::measurements(&seen));
        Ok(Extracted {
            values,
            measured,
            observed: seen.observed,
        })
    }

    /// `sphere` as the families of the sphere read it, and the features of its blocks.
    fn see<'a>(
        &self,
        sphere: Sphere<'a>,
        white: f64,
        full_scale: Option<f64>,
        wanted: Option<&[usize]>,
    ) -> Result<(Seen<'a>, Vec<f64>), ObservedError> {
        let (given, circle, reduced, annulus, observed, equivalent) = match sphere {
            Sphere::Photographed { luminance, circle } => {
                let reduced = self.reduce(luminance, circle);
                let (image, moved) = match &reduced {
                    Some((image, moved)) => (image.view(), moved),
                    None => (luminance, circle),
                };
                let annulus = self.unwrap_as_is(image, moved, white);
                (
                    CowArray::from(luminance),
                    *circle,
                    reduced,
                    annulus,
                    None,
                    None,
                )
            }
            Sphere::Equivalent(object) => {
                let (annulus, observed) = self.unwrap_equivalent(object, white)?;
                let filled = CowArray::from(object.filled());
                (
                    filled,
                    object.circle,
                    None,
                    annulus,
                    Some(observed),
                    Some(object),
                )
            }
        };
        let (values, annulus) = self.blocks(annulus, observed.as_ref(), wanted);
        let seen = Seen {
            given,
            circle,
            reduced,
            white,
            full_scale,
            blur_as_seen: self.config.blur_at_working_radius,
            annulus,
            observed,
            equivalent,
            capture: OnceCell::new(),
        };
        Ok((seen, values))
    }

    /// The blocks' features of an annulus, every one or those at `wanted` (over the observed
    /// part, every one); and the annulus back.
    fn blocks(
        &self,
        annulus: Array2<f64>,
        observed: Option<&Observed>,
        wanted: Option<&[usize]>,
    ) -> (Vec<f64>, Array2<f64>) {
        match (observed, wanted) {
            (None, Some(wanted)) => (self.subset_of_blocks(&annulus, wanted), annulus),
            (None, None) => {
                let stages = self.stages_of_unwrapped(annulus);
                let values = self.blocks_of(&stages, None);
                (values, stages.unwrapped)
            }
            (Some(observed), _) => (self.features_over(&annulus, observed), annulus),
        }
    }

    /// The blocks' features of computed stages: their block, and the block again of each
    /// family of blocks, over the observed part `support` says (everything for `None`).
    fn blocks_of(&self, stages: &Stages, support: Option<&super::observed::Support>) -> Vec<f64> {
        let mut values = block::features(&self.layout.block, stages, support);
        for (image, _) in self.layout.blocks_again() {
            let again = self.stages_of_unwrapped(image(&stages.unwrapped));
            values.extend(block::features(&self.layout.block, &again, support));
        }
        values
    }

    /// The wanted features of the blocks (the unwrapped image's, then each family of
    /// blocks'); the others NaN.
    fn subset_of_blocks(&self, unwrapped: &Array2<f64>, wanted: &[usize]) -> Vec<f64> {
        let n = self.layout.blocks().end;
        let first = 0..self.layout.block.count();
        let mut need = vec![false; n];
        for &i in wanted {
            if let Some(slot) = need.get_mut(i) {
                *slot = true;
            }
        }
        let mut out = vec![f64::NAN; n];
        let (layout, spectrum) = (&self.layout.block, &self.spectrum);
        block::subset(
            layout,
            spectrum,
            unwrapped,
            &need[first.clone()],
            &mut out[first],
        );
        for (image, at) in self.layout.blocks_again() {
            if need[at.clone()].iter().any(|&b| b) {
                let again = image(unwrapped);
                block::subset(layout, spectrum, &again, &need[at.clone()], &mut out[at]);
            }
        }
        out
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

    /// The feature vector of computed stages: one block ([`super::BlockLayout`]).
    pub fn features_of(&self, stages: &Stages) -> Vec<f64> {
        block::features(&self.layout.block, stages, None)
    }

    /// The blocks' features of an annulus with missing cells (an object's equivalent
    /// sphere, unwrapped): the statistics over the observed part ([`super::observed`]).
    pub fn features_over(&self, unwrapped: &Array2<f64>, observed: &Observed) -> Vec<f64> {
        let support = observed.support(self.config.levels);
        let stages = self.stages_of_unwrapped(observed.filled(unwrapped));
        self.blocks_of(&stages, Some(&support))
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
}

#[cfg(test)]
mod tests;
