//! `reflectance report --data DIR [--out DIR]`: the paper's Tables 1 and 2 on our data.

use super::{CliResult, LimitArgs};
use crate::image::decode::DecodeOptions;
use crate::report;
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Folder holding the rendered data sets paper9_6, paper9_11, all_6 and all_11.
    #[arg(long)]
    data: PathBuf,
    /// Output folder for report.md, report.json and the plots (default DATA/report).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    limits: LimitArgs,
}

pub fn run(args: ReportArgs) -> CliResult {
    let out = args.out.unwrap_or_else(|| report::default_out(&args.data));
    let options = DecodeOptions {
        encoding: None,
        limits: args.limits.limits(),
    };
    let result = report::run(&args.data, &out, args.seed, &options).map_err(|e| e.to_string())?;
    print!("{}", report::markdown(&result));
    eprintln!("written to {}", out.display());
    Ok(())
}
