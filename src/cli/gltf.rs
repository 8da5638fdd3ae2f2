//! `reflectance gltf`: Ward materials as glTF 2.0 assets (a sphere with the material) for
//! renderers: every class of a class file, or one (ρd, ρs, α). The mapping:
//! [`crate::material::gltf`].

use super::{CliError, CliResult};
use crate::material::gltf::sphere_asset;
use crate::material::{Material, load_classes};
use clap::Args;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct GltfArgs {
    /// A class file: write OUT/<class>.gltf for each of its classes.
    #[arg(long, conflicts_with_all = ["rho_d", "rho_s", "alpha"])]
    classes: Option<PathBuf>,
    /// Diffuse reflectance ρd (with --rho-s and --alpha: one material, written to OUT).
    #[arg(long, requires_all = ["rho_s", "alpha"])]
    rho_d: Option<f64>,
    /// Specular reflectance ρs.
    #[arg(long, requires_all = ["rho_d", "alpha"])]
    rho_s: Option<f64>,
    /// Ward roughness α (0: a mirror).
    #[arg(long, requires_all = ["rho_d", "rho_s"])]
    alpha: Option<f64>,
    /// The .gltf file (one material) or the folder (a class file).
    #[arg(long)]
    out: PathBuf,
}

/// Write `material` as a glTF asset at `path`.
pub(super) fn write(path: &Path, material: &Material, about: Value) -> CliResult {
    material
        .validate()
        .map_err(crate::material::ClassFileError::from)?;
    let asset = sphere_asset(
        &material.name,
        material.rho_d,
        material.rho_s,
        material.alpha,
        about,
    );
    let text = serde_json::to_string(&asset)?;
    crate::util::durable::write_atomic(path, text.as_bytes())
        .map_err(|e| CliError::at(path.display(), e))
}

pub fn run(args: GltfArgs) -> CliResult {
    match (&args.classes, args.rho_d, args.rho_s, args.alpha) {
        (Some(classes), ..) => {
            let materials = load_classes(classes)?;
            std::fs::create_dir_all(&args.out).map_err(|e| CliError::at(args.out.display(), e))?;
            for material in &materials {
                let path = args.out.join(format!("{}.gltf", material.name));
                let about = json!({"source": format!("class {:?} of {}", material.name, classes.display())});
                write(&path, material, about)?;
                println!("{}", path.display());
            }
            Ok(())
        }
        (None, Some(rho_d), Some(rho_s), Some(alpha)) => {
            let material = Material {
                name: "material".into(),
                rho_d,
                rho_s,
                alpha,
            };
            write(&args.out, &material, json!({"source": "reflectance gltf"}))?;
            println!("{}", args.out.display());
            Ok(())
        }
        _ => Err(CliError::Invalid(
            "give --classes C.json, or --rho-d, --rho-s and --alpha".into(),
        )),
    }
}
