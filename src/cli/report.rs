//! `reflectance report --data DIR [--out DIR]`: the paper's Tables 1 and 2 on our data.

use super::{CliResult, RunArgs};
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
    #[command(flatten)]
    run: RunArgs,
}

pub fn run(args: ReportArgs) -> CliResult {
    let out = args.out.unwrap_or_else(|| report::default_out(&args.data));
    let options = args.run.limits.decode_options();
    let result = report::run(&args.data, &out, args.run.seed, &options)?;
    print!("{}", report::markdown(&result));
    eprintln!("written to {}", out.display());
    Ok(())
}
