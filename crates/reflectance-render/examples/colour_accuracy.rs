//! How well the service reads a material's colour: coloured Ward spheres rendered channel by
//! channel under light probes (each channel of the map with that channel of the diffuse
//! albedo; the specular part is grey), photographed through the capture model with a white
//! card of reflectance 0.9 beside the sphere (random exposure, noise, blur, 8-bit PNG, JPEG
//! or 16-bit PNG), then classified with the card as `white_rect`. Markdown on stdout: the rg
//! chromaticity error of the answer's colour against the diffuse albedo's (a metal's: its
//! F0's), per material and over all.
//!
//!   cargo run --release -p reflectance-render --example colour_accuracy -- \
//!       PROBES.txt MODEL_DIR [--materials N] [--size N] [--seed S]

use rayon::prelude::*;
use reflectance_core::analysis::{Placement, WhiteSpec};
use reflectance_core::image::colour::luminance;
use reflectance_core::inference::{self, Answer, Input, LoadedModel};
use reflectance_core::material::CaptureRanges;
use reflectance_core::model::registry;
use reflectance_core::util::rng::Rng;
use reflectance_core::white::Rect;
use reflectance_render::capture::{Card, DrawSettings, capture_rgb};
use reflectance_render::envmap::EnvMap;
use reflectance_render::ward::Ward;
use reflectance_render::{Lighting, Quality, View, circle, render};
use std::path::{Path, PathBuf};
use std::sync::Arc;

const CARD_REFLECTANCE: f64 = 0.9;

struct Coloured {
    name: String,
    /// Luminance-1 colour of the diffuse albedo (a metal's F0).
    colour: [f64; 3],
    /// Its grey Ward parameters (ρd of luminance 1; each channel's is ρd times its colour).
    ward: Ward,
}

/// Colours of every hue at moderate to strong saturation, lightness by the albedo.
fn materials(n: usize, seed: u64) -> Vec<Coloured> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let hue = (i as f64 + rng.next_f64()) / n as f64 * std::f64::consts::TAU;
            let saturation = 0.25 + 0.55 * rng.next_f64();
            // An RGB of this hue and saturation around grey, made luminance 1.
            let rgb = [0.0, 2.0, 4.0]
                .map(|k: f64| 1.0 + saturation * (hue - k * std::f64::consts::PI / 3.0).cos());
            let colour = rgb.map(|c| c / luminance(rgb));
            let rho_s = [0.0, 0.03, 0.06, 0.1][rng.below(4) as usize];
            let alpha = [0.01, 0.03, 0.08][rng.below(3) as usize];
            // The brightest channel's albedo stays below 1 − ρs.
            let top = colour.iter().cloned().fold(0.0, f64::max);
            let rho_d = (0.15 + 0.45 * rng.next_f64()).min(0.95 * (1.0 - rho_s) / top);
            Coloured {
                name: format!("c{i:02}"),
                colour,
                ward: Ward {
                    rho_d,
                    rho_s,
                    alpha,
                },
            }
        })
        .collect()
}

fn chromaticity(rgb: [f64; 3]) -> [f64; 2] {
    let sum: f64 = rgb.iter().sum();
    [rgb[0] / sum, rgb[1] / sum]
}

fn probes(list: &Path) -> Result<Vec<PathBuf>, String> {
    let text = std::fs::read_to_string(list).map_err(|e| format!("{}: {e}", list.display()))?;
    Ok(text
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
        .map(PathBuf::from)
        .collect())
}

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let (list, model) = (
        args.next().ok_or(
            "usage: colour_accuracy PROBES.txt MODEL_DIR [--materials N] [--size N] [--seed S]",
        )?,
        args.next().ok_or("give the model, e.g. models/ward6")?,
    );
    let (mut n, mut size, mut seed) = (24usize, 192usize, 1u64);
    while let Some(flag) = args.next() {
        let value: u64 = args
            .next()
            .and_then(|v| v.parse().ok())
            .ok_or(format!("{flag} needs a number"))?;
        match flag.as_str() {
            "--materials" => n = value as usize,
            "--size" => size = value as usize,
            "--seed" => seed = value,
            _ => return Err(format!("unknown flag {flag}")),
        }
    }
    let file = registry::load_path(Path::new(&model)).map_err(|e| e.to_string())?;
    let model = Arc::new(LoadedModel::new(file).map_err(|e| e.to_string())?);
    let materials = materials(n, seed);
    let view = View::default();
    let ranges = CaptureRanges::default();
    let probes = probes(Path::new(&list))?;
    let mut errors: Vec<Vec<f64>> = vec![Vec::new(); materials.len()];
    for (p, probe) in probes.iter().enumerate() {
        let maps = EnvMap::load_channels(probe).map_err(|e| e.to_string())?;
        let lightings: Vec<Lighting> = maps.into_iter().map(Lighting::new).collect();
        let whites: Vec<f64> = lightings.iter().map(|l| l.white(&view)).collect();
        let white = luminance([whites[0], whites[1], whites[2]]);
        let rows: Vec<(usize, f64)> = materials
            .par_iter()
            .enumerate()
            .map(|(m, mat)| {
                let channels: Vec<_> = (0..3)
                    .map(|c| {
                        let ward = Ward {
                            rho_d: mat.ward.rho_d * mat.colour[c],
                            ..mat.ward
                        };
                        let mut rng = Rng::fork(seed, (p * 1000 + m) as u64);
                        let r = render(
                            &lightings[c],
                            &ward,
                            size,
                            &view,
                            &Quality::default(),
                            &mut rng,
                        );
                        ndarray::Array2::from_shape_vec(
                            (size, size),
                            r.luminance.iter().map(|&v| f64::from(v)).collect(),
                        )
                        .expect("a square render")
                    })
                    .collect();
                let mut rng = Rng::fork(seed ^ 0xc0105, (p * 1000 + m) as u64);
                let settings = ranges.sample(&mut rng);
                let sphere = circle(size);
                let captured_size = (size as f64 * settings.radius / sphere.r).round() as usize;
                let side = (captured_size / 8).max(4);
                let card = Card {
                    rect: [1, 1, side, side],
                    rgb: [0, 1, 2].map(|c| whites[c] * CARD_REFLECTANCE),
                };
                let capture = capture_rgb(
                    [channels[0].view(), channels[1].view(), channels[2].view()],
                    &sphere,
                    white,
                    Some(card),
                    &settings,
                    &mut rng,
                )
                .expect("valid capture settings");
                let white = WhiteSpec::Rect {
                    rect: Rect {
                        x: 2.0,
                        y: 2.0,
                        w: (side - 2) as f64,
                        h: (side - 2) as f64,
                    },
                    reflectance: CARD_REFLECTANCE,
                };
                let input = Input::new(
                    capture.bytes.into(),
                    white,
                    Placement::Circle(capture.circle),
                    Some(capture.quantization.encoding()),
                    Answer::default(),
                )
                .expect("a capture is a valid input");
                let answer = inference::classify(model.clone(), input, Default::default())
                    .map(|c| c.response(String::new(), 0.0));
                let error = match answer.ok().and_then(|a| a.colour.rgb) {
                    Some(rgb) => {
                        let (a, b) = (chromaticity(rgb), chromaticity(mat.colour));
                        (a[0] - b[0]).hypot(a[1] - b[1])
                    }
                    None => f64::NAN,
                };
                (m, error)
            })
            .collect();
        for (m, e) in rows {
            errors[m].push(e);
        }
        eprintln!("{} of {} probes", p + 1, probes.len());
    }
    println!(
        "{} coloured materials × {} probes, {size}² renders through the capture model, white card 0.9\n",
        materials.len(),
        probes.len()
    );
    println!(
        "| material | rg of the albedo | ρd | ρs | α | rg error: median | 90th percentile | failed |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut all = Vec::new();
    for (mat, e) in materials.iter().zip(&errors) {
        let mut ok: Vec<f64> = e.iter().copied().filter(|v| v.is_finite()).collect();
        ok.sort_by(f64::total_cmp);
        let q = |p: f64| {
            ok.get(((ok.len().max(1) - 1) as f64 * p).round() as usize)
                .copied()
                .unwrap_or(f64::NAN)
        };
        let [r, g] = chromaticity(mat.colour);
        println!(
            "| {} | {r:.3}, {g:.3} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {} |",
            mat.name,
            mat.ward.rho_d,
            mat.ward.rho_s,
            mat.ward.alpha,
            q(0.5),
            q(0.9),
            e.len() - ok.len()
        );
        all.extend(ok);
    }
    all.sort_by(f64::total_cmp);
    let q = |p: f64| all[((all.len() - 1) as f64 * p).round() as usize];
    println!(
        "| **all** | | | | | **{:.4}** | **{:.4}** | |",
        q(0.5),
        q(0.9)
    );
    Ok(())
}
