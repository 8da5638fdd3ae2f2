//! `reflectance dataset pack FOLDER --out A.tar.gz`: a folder of labelled photographs as
//! the archive `POST /admin/v1/datasets` takes, every image checked and its sphere located
//! as the server would.

use super::{CliError, CliResult, LimitArgs};
use crate::progress;
use clap::{Args, Subcommand};
use reflectance_core::dataset::ingest::{self, Coverage};
use reflectance_core::dataset::{Entry, Manifest, read_manifest};
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum DatasetCommand {
    /// Make a dataset archive (.tar.gz, or .tar) from a folder laid out as
    /// CLASS/ILLUMINATION/IMAGE, or from the folder's manifest.csv: every image is
    /// decoded and checked, spheres without a circle are located, and the written
    /// manifest holds every usable image with its circle. Refused images are listed on
    /// stderr and left out.
    Pack(PackArgs),
}

#[derive(Args, Debug)]
pub struct PackArgs {
    /// The folder of photographs.
    folder: PathBuf,
    /// The archive to write (.tar.gz or .tar).
    #[arg(long)]
    out: PathBuf,
    /// The manifest (`path,class,illumination[,cx,cy,r,white,encoding]`, paths relative to
    /// FOLDER); default: FOLDER/manifest.csv when it exists, else the CLASS/ILLUMINATION
    /// layout.
    #[arg(long)]
    manifest: Option<PathBuf>,
    #[command(flatten)]
    limits: LimitArgs,
}

const IMAGE_EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "tif", "tiff", "pnm", "pbm", "pgm", "ppm", "hdr", "pfm", "exr",
];

fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// The sorted subfolders (or files) of `dir` whose names are UTF-8.
fn children(dir: &Path, folders: bool) -> CliResult<Vec<(String, PathBuf)>> {
    let read = std::fs::read_dir(dir).map_err(|e| CliError::at(dir.display(), e))?;
    let mut found: Vec<(String, PathBuf)> = read
        .filter_map(|e| {
            let e = e.ok()?;
            let name = e.file_name().into_string().ok()?;
            let path = e.path();
            (!name.starts_with('.') && path.is_dir() == folders).then_some((name, path))
        })
        .collect();
    found.sort();
    Ok(found)
}

/// The manifest of a CLASS/ILLUMINATION/IMAGE folder (its rows have no line: 0).
fn manifest_of_layout(folder: &Path) -> CliResult<Manifest> {
    let mut entries = Vec::new();
    for (class, class_dir) in children(folder, true)? {
        for (light, light_dir) in children(&class_dir, true)? {
            for (file, path) in children(&light_dir, false)? {
                if is_image(&path) {
                    entries.push(Entry {
                        line: 0,
                        path: format!("{class}/{light}/{file}"),
                        file: path,
                        class: Some(class.clone()),
                        illumination: Some(light.clone()),
                        circle: None,
                        white: None,
                        encoding: None,
                        normals: None,
                        mask: None,
                    });
                }
            }
        }
    }
    if entries.is_empty() {
        return Err(CliError::Invalid(format!(
            "{}: no manifest.csv and no images laid out as CLASS/ILLUMINATION/IMAGE",
            folder.display()
        )));
    }
    Ok(Manifest {
        source: folder.join("manifest.csv"),
        entries,
    })
}

pub fn run(command: DatasetCommand) -> CliResult {
    let DatasetCommand::Pack(args) = command;
    let manifest = match &args.manifest {
        Some(path) => read_manifest(path)?,
        None if args.folder.join("manifest.csv").is_file() => {
            read_manifest(&args.folder.join("manifest.csv"))?
        }
        None => manifest_of_layout(&args.folder)?,
    };
    let options = args.limits.decode_options();
    let checked = progress::observed("images", |bar| ingest::ingest(&manifest, &options, bar))?;
    for refusal in &checked.refused {
        eprintln!("refused {}: {}", refusal.path, refusal.reason);
    }
    let coverage = Coverage::of(&checked.entries);
    let problem = match checked.entries.is_empty() {
        true => Some("no image is usable".to_string()),
        false => coverage.loio_problem(),
    };
    if let Some(problem) = problem {
        return Err(CliError::Invalid(format!(
            "{problem}; no archive written (the server would refuse it)"
        )));
    }
    let members: Vec<(String, PathBuf)> = checked
        .entries
        .iter()
        .map(|e| (e.path.clone(), e.file.clone()))
        .collect();
    crate::archive::pack(&ingest::manifest_csv(&checked.entries), &members, &args.out)
        .map_err(|e| CliError::at(args.out.display(), e))?;
    println!(
        "{}: {} images ({} located here, {} refused) of {} classes under {} illuminations",
        args.out.display(),
        checked.entries.len(),
        checked.located,
        checked.refused.len(),
        coverage.classes().len(),
        coverage.illuminations().len()
    );
    Ok(())
}
