//! The isotropic Ward parameters (ρd, ρs, α): the one type every layer holds them in (a
//! class's material, a model's classes, an estimate's point, a training row's truth, a
//! request's query), with the one check of their rules and its one message.

use serde::{Deserialize, Serialize};

/// Ward reflectance parameters (of a class rendered from them, or estimated).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = WardParams))]
pub struct Ward {
    /// Diffuse reflectance ρd, in [0, 1].
    pub rho_d: f64,
    /// Specular reflectance ρs, in [0, 1] (0: matte).
    pub rho_s: f64,
    /// Roughness α, the standard deviation of the surface slope (0: a perfect mirror).
    pub alpha: f64,
}

/// Ward parameters that break the rules of [`Ward::validate`]: the rules, and the values.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "need 0 ≤ rho_d, 0 ≤ rho_s, rho_d + rho_s ≤ 1 and 0 ≤ alpha ≤ 1, not rho_d {}, rho_s {}, \
     alpha {}",
    .0.rho_d,
    .0.rho_s,
    .0.alpha
)]
pub struct InvalidWard(pub Ward);

impl Ward {
    /// The parameters, when they keep the rules of [`Ward::validate`].
    pub fn new(rho_d: f64, rho_s: f64, alpha: f64) -> Result<Ward, InvalidWard> {
        let ward = Ward {
            rho_d,
            rho_s,
            alpha,
        };
        ward.validate().map(|()| ward)
    }

    /// Check the rules: 0 ≤ ρd, 0 ≤ ρs, ρd + ρs ≤ 1 and 0 ≤ α ≤ 1 (none NaN).
    pub fn validate(&self) -> Result<(), InvalidWard> {
        // The sum may exceed 1 by rounding (0.7 + 0.3 in a class file); each part may not.
        let ok = (0.0..=1.0).contains(&self.rho_d)
            && (0.0..=1.0).contains(&self.rho_s)
            && self.rho_d + self.rho_s <= 1.0 + 1e-12
            && (0.0..=1.0).contains(&self.alpha);
        if ok { Ok(()) } else { Err(InvalidWard(*self)) }
    }

    /// Whether the two reflectances differ, to a camera without a white reference, mainly
    /// in how much light they reflect: the same kind of surface (matte: ρs = 0; metal: ρd <
    /// 0.02 with ρs > 0; else glossy) with the same roughness α (within 10 %). Without white,
    /// such spheres differ in the image mostly by a brightness scale, which the exposure
    /// hides (exactly so for matte ones).
    pub fn same_up_to_scale(&self, other: &Ward) -> bool {
        #[derive(PartialEq)]
        enum Kind {
            Matte,
            Metal,
            Glossy,
        }
        let kind = |w: &Ward| match (w.rho_d, w.rho_s) {
            (_, s) if s <= 0.0 => Kind::Matte,
            (d, _) if d < 0.02 => Kind::Metal,
            _ => Kind::Glossy,
        };
        let alpha_alike = (self.alpha - other.alpha).abs() <= 0.1 * self.alpha.max(other.alpha);
        kind(self) == kind(other) && (kind(self) == Kind::Matte || alpha_alike)
    }

    /// Whether one is a sharp metal mirror (ρd < 0.02, α ≤ 0.01) and the other a dark glossy
    /// surface with a sharp coat (ρd < 0.15, ρs > 0, α ≤ 0.01). A black billiard ball or
    /// lacquer is a dim mirror whose Fresnel coat reflects ever more toward the rim: without a
    /// white reference its image is a mirror's but for the brightness, which the exposure
    /// hides (issue #68; docs/accuracy.md, "Real materials").
    pub fn mirror_alike(&self, other: &Ward) -> bool {
        const SHARP: f64 = 0.01;
        let metal = |w: &Ward| w.rho_d < 0.02 && w.rho_s > 0.0 && w.alpha <= SHARP;
        let dark_coat = |w: &Ward| !metal(w) && w.rho_d < 0.15 && w.rho_s > 0.0 && w.alpha <= SHARP;
        (metal(self) && dark_coat(other)) || (dark_coat(self) && metal(other))
    }

    /// Whether the two differ only in how sharply they mirror, both at most `alpha` rough:
    /// reflecting (ρs > 0), their diffuse parts within 10 % and specular parts within 25 % of
    /// each other, their α different. A sphere too small to show a blur of `alpha` shows them
    /// alike (the paper's pairs of Figure 12, sharp against α = 0.02).
    pub fn blur_alike(&self, other: &Ward, alpha: f64) -> bool {
        let near = |a: f64, b: f64, share: f64| (a - b).abs() <= share * a.max(b);
        self.alpha != other.alpha
            && self.alpha.max(other.alpha) <= alpha
            && self.rho_s > 0.0
            && other.rho_s > 0.0
            && near(self.rho_d, other.rho_d, 0.1)
            && near(self.rho_s, other.rho_s, 0.25)
    }

    /// Whether `self` is matte and `other` a glossy dielectric (ρs > 0, ρd ≥ 0.02) with a
    /// diffuse reflectance within a factor 2 of it: what a matte answer becomes when the
    /// sphere shows a highlight, which no matte surface makes ([`crate::features::lighting`]).
    pub fn glossy_alike(&self, other: &Ward) -> bool {
        let matte = self.rho_s <= 0.0;
        let glossy = other.rho_s > 0.0 && other.rho_d >= 0.02;
        let (low, high) = (self.rho_d.min(other.rho_d), self.rho_d.max(other.rho_d));
        matte && glossy && high <= 2.0 * low
    }

    /// The reflectance in words, for people: the tone of the diffuse part, and how much and
    /// how sharply the surface mirrors its surroundings.
    pub fn describe(&self) -> String {
        let sharpness = match self.alpha {
            a if a <= 0.0 => "sharp",
            a if a <= 0.03 => "slightly blurred",
            _ => "blurred",
        };
        let tone = match self.rho_d {
            d if d < 0.15 => "black",
            d if d < 0.5 => "grey",
            _ => "white",
        };
        match (self.rho_d, self.rho_s) {
            (_, s) if s <= 0.0 => format!("{tone} matte"),
            (d, s) if d < 0.02 && s >= 0.5 => {
                format!("metal: a mirror with {sharpness} reflections")
            }
            (_, s) if s < 0.15 => format!("{tone}, faintly glossy: {sharpness} reflections"),
            _ => format!("{tone}, glossy: {sharpness} reflections"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ward(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
        Ward {
            rho_d,
            rho_s,
            alpha,
        }
    }

    #[test]
    fn each_reflectance_is_at_most_one_and_their_sum_rounds() {
        assert!(ward(1.0, 0.0, 0.05).validate().is_ok());
        // A sum above 1 by rounding only, as class files hold.
        assert!(ward(0.700_000_000_000_000_1, 0.3, 0.05).validate().is_ok());
        assert!(ward(1.000_000_000_000_000_2, 0.0, 0.05).validate().is_err());
        assert!(ward(0.0, 1.000_000_000_000_000_2, 0.05).validate().is_err());
        assert!(ward(0.6, 0.5, 0.05).validate().is_err());
        assert!(ward(-0.0001, 0.5, 0.05).validate().is_err());
        assert!(ward(0.1, 0.1, 1.0).validate().is_ok());
        assert!(ward(0.1, 0.1, 1.5).validate().is_err());
        assert!(ward(0.1, 0.1, -0.1).validate().is_err());
        assert!(ward(f64::NAN, 0.1, 0.0).validate().is_err());
        assert_eq!(Ward::new(0.7, 0.25, 0.01), Ok(ward(0.7, 0.25, 0.01)));
    }

    /// One message states every rule, and the values that break one.
    #[test]
    fn the_message_states_every_rule_and_the_values() {
        let e = Ward::new(0.1, 0.1, 2.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "need 0 ≤ rho_d, 0 ≤ rho_s, rho_d + rho_s ≤ 1 and 0 ≤ alpha ≤ 1, not rho_d 0.1, \
             rho_s 0.1, alpha 2"
        );
    }

    #[test]
    fn the_papers_eleven_reflectances_have_eleven_descriptions() {
        let described: Vec<String> = [
            ward(0.1, 0.0, 0.0),
            ward(0.9, 0.0, 0.0),
            ward(0.35, 0.0, 0.0),
            ward(0.0, 0.75, 0.0),
            ward(0.05, 0.05, 0.0),
            ward(0.7, 0.2, 0.0),
            ward(0.05, 0.05, 0.02),
            ward(0.7, 0.25, 0.02),
            ward(0.25, 0.1, 0.0),
            ward(0.25, 0.1, 0.02),
            ward(0.0, 0.75, 0.02),
        ]
        .iter()
        .map(Ward::describe)
        .collect();
        let unique: std::collections::HashSet<_> = described.iter().collect();
        assert_eq!(unique.len(), 11, "{described:?}");
        assert_eq!(described[0], "black matte");
        assert_eq!(described[3], "metal: a mirror with sharp reflections");
        assert_eq!(described[7], "white, glossy: slightly blurred reflections");
        assert_eq!(described[8], "grey, faintly glossy: sharp reflections");
    }

    #[test]
    fn reflectances_alike_up_to_a_brightness_scale() {
        let (black, white) = (ward(0.1, 0.0, 0.0), ward(0.9, 0.0, 0.0));
        let (black_shiny, gray_shiny) = (ward(0.1, 0.1, 0.01), ward(0.25, 0.05, 0.01));
        let chrome = ward(0.0, 0.75, 0.0);
        assert!(black.same_up_to_scale(&white) && white.same_up_to_scale(&black));
        assert!(black_shiny.same_up_to_scale(&gray_shiny));
        assert!(!black_shiny.same_up_to_scale(&black));
        assert!(!chrome.same_up_to_scale(&black_shiny));
        // The paper's E and G differ only in α.
        assert!(!ward(0.05, 0.05, 0.0).same_up_to_scale(&ward(0.05, 0.05, 0.02)));
        assert!(chrome.same_up_to_scale(&ward(0.0, 0.5, 0.0)));
    }

    #[test]
    fn a_sharp_metal_and_a_dark_sharp_coat_are_mirrors_alike() {
        let chrome = ward(0.0, 0.75, 0.0);
        let black_shiny = ward(0.1, 0.1, 0.01);
        assert!(chrome.mirror_alike(&black_shiny) && black_shiny.mirror_alike(&chrome));
        // Not: two metals, a grey or white coat, a blurred coat, a matte, a blurred metal.
        assert!(!chrome.mirror_alike(&ward(0.0, 0.5, 0.0)));
        assert!(!chrome.mirror_alike(&ward(0.25, 0.05, 0.01)));
        assert!(!chrome.mirror_alike(&ward(0.1, 0.1, 0.02)));
        assert!(!chrome.mirror_alike(&ward(0.1, 0.0, 0.0)));
        assert!(!ward(0.0, 0.75, 0.02).mirror_alike(&black_shiny));
        // A highlight on a matte answer: the glossy classes of a like diffuse part.
        let (white_matte, white_shiny) = (ward(0.9, 0.0, 0.0), ward(0.7, 0.25, 0.01));
        assert!(white_matte.glossy_alike(&white_shiny));
        assert!(ward(0.1, 0.0, 0.0).glossy_alike(&black_shiny));
        assert!(!white_matte.glossy_alike(&ward(0.25, 0.05, 0.01)));
        assert!(!white_matte.glossy_alike(&chrome) && !white_shiny.glossy_alike(&white_matte));
    }

    #[test]
    fn the_paper_s_sharp_and_slightly_blurred_pairs_are_blur_alike() {
        // Figure 12's pairs: D and K, E and G, F and H, I and J (α 0 against 0.02).
        let pairs = [
            (ward(0.0, 0.75, 0.0), ward(0.0, 0.75, 0.02)),
            (ward(0.05, 0.05, 0.0), ward(0.05, 0.05, 0.02)),
            (ward(0.7, 0.2, 0.0), ward(0.7, 0.25, 0.02)),
            (ward(0.25, 0.1, 0.0), ward(0.25, 0.1, 0.02)),
        ];
        for (sharp, blurred) in pairs {
            assert!(sharp.blur_alike(&blurred, 0.025) && blurred.blur_alike(&sharp, 0.025));
            // A sphere large enough to show α 0.02 tells them apart.
            assert!(!sharp.blur_alike(&blurred, 0.015));
        }
        // Not: the same class, two matte ones, another tone or another coat.
        let e = ward(0.05, 0.05, 0.0);
        assert!(!e.blur_alike(&e, 0.1));
        assert!(!ward(0.1, 0.0, 0.0).blur_alike(&ward(0.1, 0.0, 0.02), 0.1));
        assert!(!e.blur_alike(&ward(0.25, 0.1, 0.02), 0.1));
        assert!(!e.blur_alike(&ward(0.05, 0.1, 0.02), 0.1));
        // The paper's six classes hold no such pair (ward6's answers keep their sets).
        let file = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../data/classes/classes6.json"
        );
        let six = crate::material::load_classes(std::path::Path::new(file)).unwrap();
        assert_eq!(six.len(), 6);
        for a in &six {
            assert!(
                six.iter().all(|b| !a.ward.blur_alike(&b.ward, 0.1)),
                "{}",
                a.name
            );
        }
    }
}
