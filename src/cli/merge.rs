//! `reflectance merge --out F PART…`: the parts that `--shard I/N` runs wrote, joined into
//! the file the unsharded run writes.

use super::CliResult;
use clap::Args;
use reflectance_core::util::shard;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The joined file (e.g. manifest.csv or features.csv), written atomically.
    #[arg(long)]
    out: PathBuf,
    /// The parts, named NAME.shard-I-of-N[.EXT] as `render --shard` and `features --shard`
    /// write them, in any order: every shard 0…N-1 of one file exactly once.
    #[arg(required = true, value_name = "PART")]
    parts: Vec<PathBuf>,
}

pub fn run(args: MergeArgs) -> CliResult {
    let merged = shard::merge(&args.parts, &args.out)?;
    eprintln!(
        "merged {} shards, {} rows after the header",
        merged.shards, merged.rows
    );
    println!("{}", args.out.display());
    Ok(())
}
