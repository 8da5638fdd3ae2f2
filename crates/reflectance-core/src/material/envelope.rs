//! The captures a model was trained for: the ranges the camera model drew its settings
//! from, and what the capture measurements found on the training images. Serving reads it
//! to say when an input lies outside what the model saw.

use crate::features::CaptureMeasurements;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The ranges a capture's settings are drawn from (and that a model trained on such
/// captures records, so that serving can say when an input falls outside them).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureRanges {
    /// Sphere radius (px), drawn log-uniformly.
    pub radius: [f64; 2],
    /// Exposure: white as a fraction of full scale.
    pub exposure: [f64; 2],
    /// Noise: σ at white, as a fraction of white.
    pub noise: [f64; 2],
    /// Lens blur σ (px).
    pub blur: [f64; 2],
    /// JPEG quality of the captures saved as JPEG (1–100).
    pub jpeg_quality: [u8; 2],
    /// Largest relative white error (±).
    pub white_error: f64,
    /// Largest centre error (px, ± in x and y).
    pub centre_error: f64,
    /// Largest relative radius error (±).
    pub radius_error: f64,
}

impl Default for CaptureRanges {
    /// The ranges of issue 16: what the shipped models are trained and measured for.
    fn default() -> Self {
        CaptureRanges {
            radius: [60.0, 400.0],
            exposure: [0.2, 0.8],
            noise: [0.0, 0.025],
            blur: [0.0, 1.0],
            jpeg_quality: [70, 98],
            white_error: 0.05,
            centre_error: 1.0,
            radius_error: 0.015,
        }
    }
}

/// Capture ranges out of their bounds.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("invalid capture settings: ranges out of bounds: {0}")]
pub struct InvalidRanges(pub String);

impl CaptureRanges {
    /// Check the bounds: every range ordered, radius ≥ [`crate::locate::MIN_RADIUS`],
    /// exposure in [0.01, 1], noise ≤ 0.5, blur ≤ 10 px, qualities in 1–100 and the errors
    /// below their limits.
    pub fn validate(&self) -> Result<(), InvalidRanges> {
        let ordered = |[lo, hi]: [f64; 2], min: f64, max: f64| lo >= min && lo <= hi && hi <= max;
        let ok = ordered(self.radius, crate::locate::MIN_RADIUS, 4096.0)
            && ordered(self.exposure, 0.01, 1.0)
            && ordered(self.noise, 0.0, 0.5)
            && ordered(self.blur, 0.0, 10.0)
            && (1..=100).contains(&self.jpeg_quality[0])
            && self.jpeg_quality[0] <= self.jpeg_quality[1]
            && self.jpeg_quality[1] <= 100
            && (0.0..0.5).contains(&self.white_error)
            && (0.0..=10.0).contains(&self.centre_error)
            && (0.0..0.5).contains(&self.radius_error);
        if ok {
            Ok(())
        } else {
            Err(InvalidRanges(format!("{self:?}")))
        }
    }
}

/// What marks a capture's training view: `<probe><view>@cap<k>`.
pub const VIEW_TAG: &str = "@cap";

/// The captures a model was trained for: the ranges its `@cap` training views were drawn
/// from and what the capture measurements found on its training images, by class (a
/// mirror's reflections read as more noise, and clip more, than a matte sphere's shading).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureEnvelope {
    /// The ranges its training views were drawn from.
    pub ranges: CaptureRanges,
    /// Per class, the 99th percentile of the noise at white estimated on its training
    /// images (fraction of white); empty when the training table has no `cap.noise`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub noise_p99: BTreeMap<String, f64>,
    /// Per class, the 99th percentile of their clipped fractions; empty without
    /// `cap.clipped`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub clipped_p99: BTreeMap<String, f64>,
}

/// How far past the training envelope an input may go before the answer warns: the
/// estimates scatter, and a model degrades gradually beyond its ranges.
const RADIUS_MARGIN: f64 = 0.05;
const NOISE_MARGIN: f64 = 1.25;
const CLIPPED_MARGIN: f64 = 0.02;

impl CaptureEnvelope {
    /// Why an input of sphere radius `radius` (px, as given) with these measurements,
    /// classified as `class`, lies outside the envelope: the response's warnings (empty:
    /// inside). A model that reduces spheres to a `working_radius` within the range sees
    /// larger ones as it saw its own.
    pub fn outside(
        &self,
        radius: f64,
        working_radius: Option<f64>,
        class: &str,
        measured: &CaptureMeasurements,
    ) -> Vec<String> {
        self.outside_of(radius, working_radius, Some(class), measured)
    }

    /// Why an input lies outside the envelope of every class (the domain check's reasons:
    /// whatever its class, the model never saw such a capture).
    pub fn outside_every_class(
        &self,
        radius: f64,
        working_radius: Option<f64>,
        measured: &CaptureMeasurements,
    ) -> Vec<String> {
        self.outside_of(radius, working_radius, None, measured)
    }

    fn outside_of(
        &self,
        radius: f64,
        working_radius: Option<f64>,
        class: Option<&str>,
        measured: &CaptureMeasurements,
    ) -> Vec<String> {
        let mut out = Vec::new();
        let [low, high] = self.ranges.radius;
        let reduced = working_radius.is_some_and(|w| w <= high);
        let too_large = radius > high * (1.0 + RADIUS_MARGIN) && !reduced;
        if radius < low * (1.0 - RADIUS_MARGIN) || too_large {
            out.push(format!(
                "the sphere's radius {radius:.0} px is outside the {low:.0}–{high:.0} px the model \
                 was trained for"
            ));
        }
        let limit = |by_class: &BTreeMap<String, f64>| match class {
            Some(class) => by_class.get(class).copied(),
            None => by_class.values().copied().reduce(f64::max),
        };
        let on = class.map_or(String::new(), |c| format!(" on {c}"));
        let noise_limit =
            limit(&self.noise_p99).map_or(self.ranges.noise[1], |p| p.max(self.ranges.noise[1]));
        if let Some(noise) = measured.noise.filter(|n| *n > noise_limit * NOISE_MARGIN) {
            out.push(format!(
                "the image's noise, estimated at {:.1} % of white, is above the {:.1} % the \
                 model was trained for{on}: expect lower accuracy",
                100.0 * noise,
                100.0 * noise_limit
            ));
        }
        let clipped_limit = limit(&self.clipped_p99).unwrap_or(0.0);
        if measured.clipped > clipped_limit + CLIPPED_MARGIN {
            let of = class.map_or(String::new(), |c| format!(" for {c}"));
            out.push(format!(
                "{:.1} % of the sphere's pixels are clipped (the model was trained on up to \
                 {:.1} %{of}): lower the exposure",
                100.0 * measured.clipped,
                100.0 * clipped_limit
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_outside_the_training_envelope_are_named() {
        let envelope = CaptureEnvelope {
            ranges: CaptureRanges::default(),
            noise_p99: BTreeMap::from([("matte".into(), 0.03), ("mirror".into(), 0.3)]),
            clipped_p99: BTreeMap::from([("matte".into(), 0.05), ("mirror".into(), 0.3)]),
        };
        let clean = CaptureMeasurements {
            noise: Some(0.01),
            clipped: 0.0,
            shading: None,
        };
        let outside = |radius, working_radius, m: &CaptureMeasurements| {
            envelope.outside(radius, working_radius, "matte", m)
        };
        assert!(outside(100.0, None, &clean).is_empty());
        // Within the margins: 0.95 × 60 px, 1.25 × 3 %, 5 % + 2 %.
        let near = CaptureMeasurements {
            noise: Some(0.037),
            clipped: 0.069,
            shading: None,
        };
        assert!(outside(57.5, None, &near).is_empty());
        let small = outside(50.0, Some(116.0), &clean);
        assert_eq!(small.len(), 1);
        assert!(small[0].contains("radius 50 px") && small[0].contains("60–400"));
        // Larger spheres are reduced to the working radius, when there is one.
        assert!(outside(900.0, Some(116.0), &clean).is_empty());
        assert_eq!(outside(900.0, None, &clean).len(), 1);
        let noisy = CaptureMeasurements {
            noise: Some(0.05),
            clipped: 0.0,
            shading: None,
        };
        let said = outside(100.0, None, &noisy);
        assert!(
            said.len() == 1 && said[0].contains("5.0 % of white"),
            "{said:?}"
        );
        let clipped = CaptureMeasurements {
            noise: None,
            clipped: 0.2,
            shading: None,
        };
        let said = outside(100.0, None, &clipped);
        assert!(said.len() == 1 && said[0].contains("20.0 %"), "{said:?}");
        // A mirror's envelope is wider.
        assert!(envelope.outside(100.0, None, "mirror", &clipped).is_empty());
        assert!(envelope.outside(100.0, None, "mirror", &noisy).is_empty());
        // Without measured percentiles the ranges decide: 2.5 % noise, nothing clipped.
        let ranges_only = CaptureEnvelope {
            noise_p99: BTreeMap::new(),
            clipped_p99: BTreeMap::new(),
            ..envelope
        };
        assert_eq!(ranges_only.outside(100.0, None, "matte", &near).len(), 2);
    }
}
