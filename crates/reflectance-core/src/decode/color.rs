//! Transfer functions for integer samples: sRGB (IEC 61966-2-1), linear, or a pure power law.

use std::fmt;
use std::sync::OnceLock;

/// How normalized integer samples `c ∈ [0, 1]` map to linear values.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum Encoding {
    /// The sRGB transfer function (IEC 61966-2-1), the default.
    #[default]
    Srgb,
    /// Samples are linear already.
    Linear,
    /// `c^g`, with `g` finite and positive.
    Gamma(f64),
}

impl Encoding {
    /// Parse `srgb`, `linear` or `gamma:<g>` (case-insensitive keyword, `g` finite and > 0).
    pub fn parse(text: &str) -> Option<Encoding> {
        let text = text.trim();
        match text.to_ascii_lowercase().as_str() {
            "srgb" => Some(Encoding::Srgb),
            "linear" => Some(Encoding::Linear),
            lower => {
                let g: f64 = lower.strip_prefix("gamma:")?.trim().parse().ok()?;
                (g.is_finite() && g > 0.0).then_some(Encoding::Gamma(g))
            }
        }
    }

    /// Linear value of a normalized sample.
    #[inline]
    pub fn decode(self, c: f64) -> f64 {
        match self {
            Encoding::Srgb => srgb_to_linear(c),
            Encoding::Linear => c,
            Encoding::Gamma(g) => c.powf(g),
        }
    }

    /// Linear value of every code of a `bits`-bit sample: `decode(v / (2^bits − 1))`.
    fn build_table(self, bits: u32) -> Vec<f64> {
        let max = f64::from((1u32 << bits) - 1);
        (0..=(1u32 << bits) - 1)
            .map(|v| self.decode(f64::from(v) / max))
            .collect()
    }

    /// Lookup table for `bits` ∈ {8, 16}; sRGB and linear tables are built once per process.
    pub(crate) fn table(self, bits: u32) -> TableRef {
        static SRGB8: OnceLock<Vec<f64>> = OnceLock::new();
        static SRGB16: OnceLock<Vec<f64>> = OnceLock::new();
        static LINEAR8: OnceLock<Vec<f64>> = OnceLock::new();
        static LINEAR16: OnceLock<Vec<f64>> = OnceLock::new();
        let cached = match (self, bits) {
            (Encoding::Srgb, 8) => &SRGB8,
            (Encoding::Srgb, _) => &SRGB16,
            (Encoding::Linear, 8) => &LINEAR8,
            (Encoding::Linear, _) => &LINEAR16,
            (Encoding::Gamma(_), _) => return TableRef::Owned(self.build_table(bits)),
        };
        TableRef::Static(cached.get_or_init(|| self.build_table(bits)))
    }
}

pub(crate) enum TableRef {
    Static(&'static [f64]),
    Owned(Vec<f64>),
}

impl std::ops::Deref for TableRef {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        match self {
            TableRef::Static(table) => table,
            TableRef::Owned(table) => table,
        }
    }
}

impl fmt::Display for Encoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Encoding::Srgb => f.write_str("srgb"),
            Encoding::Linear => f.write_str("linear"),
            Encoding::Gamma(g) => write!(f, "gamma:{g}"),
        }
    }
}

impl From<Encoding> for String {
    fn from(e: Encoding) -> String {
        e.to_string()
    }
}

impl TryFrom<String> for Encoding {
    type Error = super::DecodeError;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_values() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-15);
        // Linear segment and its junction with the power segment.
        assert_eq!(srgb_to_linear(0.04045), 0.04045 / 12.92);
        assert!((srgb_to_linear(0.5) - 0.214_041_140_482_232_55).abs() < 1e-15);
        // Code 128 of 255 (value computed independently with Python).
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_500_113_899_26).abs() < 1e-15);
        // Continuity at the junction (the two pieces agree to ~1e-8).
        let below = 0.04045 / 12.92;
        let above = ((0.04045f64 + 0.055) / 1.055).powf(2.4);
        assert!((below - above).abs() < 1e-7);
    }

    #[test]
    fn tables_match_the_curve() {
        let t8 = Encoding::Srgb.table(8);
        assert_eq!(t8.len(), 256);
        assert_eq!(t8[128], srgb_to_linear(128.0 / 255.0));
        let t16 = Encoding::Srgb.table(16);
        assert_eq!(t16.len(), 65536);
        assert_eq!(t16[65535], srgb_to_linear(1.0));
        let g = Encoding::Gamma(2.2).table(8);
        assert_eq!(g[51], (51.0f64 / 255.0).powf(2.2));
    }

    #[test]
    fn parse_encodings() {
        assert_eq!(Encoding::parse("sRGB"), Some(Encoding::Srgb));
        assert_eq!(Encoding::parse("linear"), Some(Encoding::Linear));
        assert_eq!(Encoding::parse("gamma:2.2"), Some(Encoding::Gamma(2.2)));
        for bad in [
            "gamma:",
            "gamma:0",
            "gamma:-1",
            "gamma:nan",
            "gamma:inf",
            "rec709",
            "",
        ] {
            assert_eq!(Encoding::parse(bad), None, "{bad}");
        }
    }
}
