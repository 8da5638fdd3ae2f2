//! `reflectance materials --count N --out C.json [--seed S]`: a class file of N materials
//! over continuous Ward parameters (a Latin-hypercube design), for `render --classes`.

use super::{CliError, CliResult};
use clap::Args;
use reflectance_render::design::{self, Ranges};
use serde_json::json;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MaterialsArgs {
    /// How many materials (each a class of its own, named m0001…).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    count: u32,
    /// The class file to write (the format `render --classes` reads).
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub fn run(args: MaterialsArgs) -> CliResult {
    let ranges = Ranges::default();
    let materials = design::continuous(args.count as usize, args.seed, &ranges);
    let file = json!({
        "source": format!(
            "reflectance materials --count {} --seed {}: Latin hypercube, rho_s uniform in \
             [0, {}], rho_d uniform in [0, 1 - rho_s], alpha 0 for {} % of them, else \
             log-uniform in [{}, {}]",
            args.count, args.seed, ranges.rho_s_max, 100.0 * ranges.mirror_share,
            ranges.alpha_min, ranges.alpha_max
        ),
        "classes": materials,
    });
    let text = serde_json::to_string_pretty(&file)?;
    reflectance_core::util::durable::write_atomic(&args.out, format!("{text}\n").as_bytes())
        .map_err(|e| CliError::at(args.out.display(), e))?;
    println!("{}", args.out.display());
    Ok(())
}
