//! How far a Ward material's glTF export is from the material itself: both rendered under
//! the same light probes by the same estimator ([`reflectance_render::pbr`]), compared over
//! the sphere's disc, with glTF's BRDF as the Khronos sample viewer reads it and as Cycles
//! does (the exact Fresnel term); beside them, the plain mapping a user would write by hand
//! (baseColor ρd, roughness √α, glTF's default specular), as the viewer draws it. Markdown
//! on stdout: per material, the RMS difference relative to the Ward image's mean, the
//! difference of the disc's mean brightness, and the RMS difference as a photograph exposed
//! for white sees it (both images clipped at the white reference, in units of white).
//! Blender itself: scripts/gltf/blender/check.py.
//!
//!   cargo run --release -p reflectance-render --example gltf_mapping -- \
//!       PROBES_DIR CLASSES.json [CLASSES.json …] [--every K] [--size N] [--samples S]

use rayon::prelude::*;
use reflectance_core::material::gltf::{Pbr, pbr_of};
use reflectance_core::material::{Ward, load_classes};
use reflectance_render::View;
use reflectance_render::envmap::EnvMap;
use reflectance_render::pbr::{Brdf, Drawing, Gltf, Reading, draw};
use std::path::PathBuf;

/// The mapping a user writes by hand: no extension, glTF's default F0 of 0.04.
fn by_hand(w: &Ward) -> Pbr {
    Pbr {
        base_color: w.rho_d,
        metallic: 0.0,
        roughness: w.alpha.sqrt(),
        ior: 1.5,
        specular: 1.0,
    }
}

/// Differences over the disc between a reference image and another: (RMS relative to the
/// reference's mean, the relative difference of the means, and the RMS of both as a
/// photograph exposed for `white` sees them: clipped at white, in units of white).
fn compare(reference: &[Option<f64>], other: &[Option<f64>], white: f64) -> [f64; 3] {
    let pairs: Vec<(f64, f64)> = reference
        .iter()
        .zip(other)
        .filter_map(|(a, b)| Some(((*a)?, (*b)?)))
        .collect();
    let n = pairs.len() as f64;
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_other = pairs.iter().map(|p| p.1).sum::<f64>() / n;
    let rms = (pairs.iter().map(|(a, b)| (a - b).powi(2)).sum::<f64>() / n).sqrt();
    let clip = |v: f64| (v / white).min(1.0);
    let seen = (pairs
        .iter()
        .map(|&(a, b)| (clip(a) - clip(b)).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    [rms / mean, mean_other / mean - 1.0, seen]
}

struct Args {
    probes: PathBuf,
    classes: Vec<PathBuf>,
    every: usize,
    size: usize,
    samples: usize,
}

fn args() -> Result<Args, String> {
    let mut raw = std::env::args().skip(1);
    let mut args = Args {
        probes: PathBuf::new(),
        classes: Vec::new(),
        every: 1,
        size: 64,
        samples: 256,
    };
    let mut positional = Vec::new();
    while let Some(a) = raw.next() {
        let mut number = |name: &str| -> Result<usize, String> {
            raw.next()
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| format!("{name} needs a whole number"))
        };
        match a.as_str() {
            "--every" => args.every = number("--every")?.max(1),
            "--size" => args.size = number("--size")?.max(8),
            "--samples" => args.samples = number("--samples")?.max(1),
            _ => positional.push(PathBuf::from(a)),
        }
    }
    if positional.len() < 2 {
        return Err(
            "usage: gltf_mapping PROBES_DIR CLASSES.json… [--every K] [--size N] [--samples S]"
                .into(),
        );
    }
    args.probes = positional.remove(0);
    args.classes = positional;
    Ok(args)
}

fn main() -> Result<(), String> {
    let args = args()?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&args.probes)
        .map_err(|e| format!("{}: {e}", args.probes.display()))?
        .filter_map(|e| Some(e.ok()?.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "hdr"))
        .collect();
    paths.sort();
    let paths: Vec<PathBuf> = paths.into_iter().step_by(args.every).collect();
    let maps: Vec<(EnvMap, EnvMap)> = paths
        .par_iter()
        .map(|p| {
            let map = EnvMap::load(p).map_err(|e| format!("{}: {e}", p.display()))?;
            let reduced = map.block_averaged(8);
            Ok((map, reduced))
        })
        .collect::<Result<_, String>>()?;
    let view = View::default();
    println!(
        "{} probes, {} px discs, {} lobe samples per pixel; relative RMS difference over the disc \
         (mean over the probes) and the disc's mean brightness against Ward's\n",
        maps.len(),
        args.size,
        args.samples
    );
    println!(
        "| material | ρd | ρs | α | viewer: RMS | brightness | as photographed | Cycles' Fresnel: RMS | brightness | as photographed | by hand, viewer: RMS | brightness | as photographed |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut all = Vec::new();
    for file in &args.classes {
        let materials = load_classes(file).map_err(|e| e.to_string())?;
        let many = materials.len() > 20;
        for m in &materials {
            let drawing = Drawing {
                size: args.size,
                samples: args.samples,
                lobe_alpha: m.ward.alpha.max(0.005),
                seed: 7,
            };
            let pbr = pbr_of(&m.ward);
            let exports = [
                Gltf {
                    pbr,
                    reading: Reading::Viewer,
                },
                Gltf {
                    pbr,
                    reading: Reading::Cycles,
                },
                Gltf {
                    pbr: by_hand(&m.ward),
                    reading: Reading::Viewer,
                },
            ];
            let rows: Vec<[f64; 9]> = maps
                .par_iter()
                .map(|(map, reduced)| {
                    let white = reflectance_render::white(reduced, &view);
                    let ward = draw(map, reduced, &m.ward as &dyn Brdf, &view, &drawing);
                    let mut row = [0.0; 9];
                    for (k, export) in exports.iter().enumerate() {
                        let drawn = draw(map, reduced, export, &view, &drawing);
                        row[3 * k..3 * k + 3].copy_from_slice(&compare(&ward, &drawn, white));
                    }
                    row
                })
                .collect();
            let row: [f64; 9] =
                std::array::from_fn(|k| rows.iter().map(|r| r[k]).sum::<f64>() / rows.len() as f64);
            all.push(row);
            if !many {
                let cells: Vec<String> = row
                    .chunks(3)
                    .map(|c| {
                        format!(
                            "{:.1} % | {:+.1} % | {:.3}",
                            100.0 * c[0],
                            100.0 * c[1],
                            c[2]
                        )
                    })
                    .collect();
                println!(
                    "| {} | {} | {} | {} | {} |",
                    m.name,
                    m.ward.rho_d,
                    m.ward.rho_s,
                    m.ward.alpha,
                    cells.join(" | ")
                );
            }
        }
        if many {
            let summary = |k: usize, q: f64| {
                let mut v: Vec<f64> = all.iter().map(|r| r[k].abs()).collect();
                v.sort_by(f64::total_cmp);
                v[((v.len() - 1) as f64 * q).round() as usize]
            };
            for (what, q) in [("median", 0.5), ("90th percentile", 0.9)] {
                let cells: Vec<String> = (0..3)
                    .map(|k| {
                        format!(
                            "{:.1} % | {:.1} % | {:.3}",
                            100.0 * summary(3 * k, q),
                            100.0 * summary(3 * k + 1, q),
                            summary(3 * k + 2, q)
                        )
                    })
                    .collect();
                println!(
                    "| {} materials of {}: {what} of the absolute values | | | | {} |",
                    materials.len(),
                    file.display(),
                    cells.join(" | ")
                );
            }
        }
        all.clear();
    }
    Ok(())
}
