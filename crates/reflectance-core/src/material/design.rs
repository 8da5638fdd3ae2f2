//! Materials over continuous Ward parameters, for learning to estimate (ρd, ρs, α) rather
//! than to name a class: a seeded Latin-hypercube design, so that N materials cover each
//! parameter's range evenly (one draw in each of N equal strata per dimension) rather than
//! clumping as independent draws would.
//!
//! ρs is uniform in [0, ρs_max]; ρd uniform in [0, 1 − ρs] (energy conservation); α is 0
//! (an ideal mirror) for a share of the materials, else log-uniform in [α_min, α_max].

use super::{Material, Ward};
use crate::util::rng::Rng;

/// The parameter ranges of the design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ranges {
    /// Largest ρs (ρs is uniform in [0, ρs_max]; ρd + ρs ≤ 1).
    pub rho_s_max: f64,
    /// Share of mirrors (α = 0), in [0, 1].
    pub mirror_share: f64,
    /// Smallest α of a non-mirror (> 0; α is log-uniform in [α_min, α_max]).
    pub alpha_min: f64,
    /// Largest α.
    pub alpha_max: f64,
}

impl Default for Ranges {
    fn default() -> Self {
        Ranges {
            rho_s_max: 0.8,
            mirror_share: 0.25,
            alpha_min: 0.005,
            alpha_max: 0.2,
        }
    }
}

/// `u ∈ [0, 1)` in stratum order: for each of `n` strata one point, at a random place
/// within it, the strata shuffled.
fn latin_column(n: usize, rng: &mut Rng) -> Vec<f64> {
    let mut strata: Vec<usize> = (0..n).collect();
    rng.shuffle(&mut strata);
    strata
        .into_iter()
        .map(|s| (s as f64 + rng.next_f64()) / n as f64)
        .collect()
}

/// The material of the unit-cube point (u_s, u_d, u_α).
fn material(name: String, [u_s, u_d, u_a]: [f64; 3], ranges: &Ranges) -> Material {
    let rho_s = ranges.rho_s_max * u_s;
    let rho_d = (1.0 - rho_s) * u_d;
    let alpha = if u_a < ranges.mirror_share {
        0.0
    } else {
        let t = (u_a - ranges.mirror_share) / (1.0 - ranges.mirror_share);
        let (lo, hi) = (ranges.alpha_min.log10(), ranges.alpha_max.log10());
        10f64.powf(lo + t * (hi - lo))
    };
    Material::new(
        name,
        Ward {
            rho_d,
            rho_s,
            alpha,
        },
    )
}

/// `n` materials named `m0001…`, a function of `(n, seed)` only.
pub fn continuous(n: usize, seed: u64, ranges: &Ranges) -> Vec<Material> {
    let mut rng = Rng::fork(seed, 0x77a2_d5e7);
    let columns = [
        latin_column(n, &mut rng),
        latin_column(n, &mut rng),
        latin_column(n, &mut rng),
    ];
    let width = n.to_string().len().max(4);
    (0..n)
        .map(|i| {
            let u = [columns[0][i], columns[1][i], columns[2][i]];
            material(format!("m{:0width$}", i + 1), u, ranges)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stratum_of_every_parameter_holds_one_material() {
        let n = 40;
        let ranges = Ranges::default();
        let design = continuous(n, 7, &ranges);
        assert_eq!(design.len(), n);
        let mut rho_s_strata: Vec<usize> = design
            .iter()
            .map(|m| (m.ward.rho_s / ranges.rho_s_max * n as f64) as usize)
            .collect();
        rho_s_strata.sort();
        assert_eq!(rho_s_strata, (0..n).collect::<Vec<_>>());
        let mut rho_d_strata: Vec<usize> = design
            .iter()
            .map(|m| (m.ward.rho_d / (1.0 - m.ward.rho_s) * n as f64) as usize)
            .collect();
        rho_d_strata.sort();
        assert_eq!(rho_d_strata, (0..n).collect::<Vec<_>>());
        let mirrors = design.iter().filter(|m| m.ward.alpha == 0.0).count();
        assert_eq!(mirrors, 10, "a quarter of 40");
        for m in &design {
            m.validate().unwrap();
            assert!(
                m.ward.alpha == 0.0 || (0.005..=0.2).contains(&m.ward.alpha),
                "{m:?}"
            );
        }
        assert_eq!(design[0].name, "m0001");
    }

    #[test]
    fn glossy_widths_are_log_uniform() {
        let design = continuous(300, 3, &Ranges::default());
        let logs: Vec<f64> = design
            .iter()
            .filter(|m| m.ward.alpha > 0.0)
            .map(|m| m.ward.alpha.log10())
            .collect();
        let (lo, hi) = (0.005f64.log10(), 0.2f64.log10());
        // Each quarter of the log range holds a quarter of the glossy materials (±1).
        for q in 0..4 {
            let a = lo + (hi - lo) * q as f64 / 4.0;
            let b = lo + (hi - lo) * (q + 1) as f64 / 4.0;
            let count = logs.iter().filter(|&&l| l >= a && l < b).count();
            assert!(count.abs_diff(logs.len() / 4) <= 1, "quarter {q}: {count}");
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_design() {
        let ranges = Ranges::default();
        assert_eq!(continuous(25, 11, &ranges), continuous(25, 11, &ranges));
        assert_ne!(continuous(25, 11, &ranges), continuous(25, 12, &ranges));
    }
}
