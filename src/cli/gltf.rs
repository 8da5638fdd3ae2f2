//! `reflectance gltf`: Ward materials as glTF 2.0 assets (a sphere with the material) for
//! renderers: every class of a class file, or one (ρd, ρs, α). The mapping:
//! [`reflectance_core::material::gltf`].

use super::{CliError, CliResult};
use clap::{Args, ValueEnum};
use reflectance_core::material::gltf::{Container, Rgb, parse_colour, sphere};
use reflectance_core::material::{Material, Ward, load_classes};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The container of the files a class file's classes are written to.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Format {
    /// JSON with the buffer embedded (`.gltf`).
    Gltf,
    /// Binary glTF (`.glb`).
    Glb,
}

#[derive(Args, Debug)]
pub struct GltfArgs {
    /// A class file: write OUT/<class>.gltf (or .glb, see --format) for each of its classes.
    #[arg(long, conflicts_with_all = ["rho_d", "rho_s", "alpha", "name"])]
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
    /// The single material's name in the file (1–64 of a-z, 0-9, '_', '-'; default
    /// `material`).
    #[arg(long, requires = "rho_d")]
    name: Option<String>,
    /// Its colour: linear r,g,b relative to white (any scale; the grey value keeps its
    /// luminance). Default: grey.
    #[arg(long, value_name = "R,G,B", value_parser = parse_colour)]
    colour: Option<Rgb>,
    /// The files' format for --classes (a single file's is its name's: .glb or .gltf).
    #[arg(long, value_enum, default_value_t = Format::Gltf)]
    format: Format,
    /// The .gltf or .glb file (one material) or the folder (a class file).
    #[arg(long)]
    out: PathBuf,
}

/// Write `material` (tinted by `colour`) as a glTF asset at `path`: binary glTF when the
/// name ends in `.glb`.
pub(super) fn write(
    path: &Path,
    material: &Material,
    colour: Option<Rgb>,
    about: Value,
) -> CliResult {
    material
        .validate()
        .map_err(reflectance_core::material::ClassFileError::from)?;
    let bytes = sphere(material, colour, about).encode(Container::of_path(path));
    reflectance_core::util::durable::write_atomic(path, &bytes)
        .map_err(|e| CliError::at(path.display(), e))
}

pub fn run(args: GltfArgs) -> CliResult {
    match (&args.classes, args.rho_d, args.rho_s, args.alpha) {
        (Some(classes), ..) => {
            let materials = load_classes(classes)?;
            std::fs::create_dir_all(&args.out).map_err(|e| CliError::at(args.out.display(), e))?;
            let extension = match args.format {
                Format::Gltf => "gltf",
                Format::Glb => "glb",
            };
            for material in &materials {
                let label = material.label();
                let path = args.out.join(format!("{label}.{extension}"));
                // The file's name, not its path: no machine's folders in files people share.
                let file = classes
                    .file_name()
                    .unwrap_or(classes.as_os_str())
                    .to_string_lossy();
                let about = json!({"source": format!("class {label:?} of {file}")});
                write(&path, material, args.colour, about)?;
                println!("{}", path.display());
            }
            Ok(())
        }
        (None, Some(rho_d), Some(rho_s), Some(alpha)) => {
            let name = args.name.unwrap_or_else(|| "material".into());
            if !reflectance_core::model::registry::valid_name(&name) {
                return Err(CliError::Invalid(format!(
                    "--name {name:?}: use 1–64 of a-z, 0-9, '_' and '-'"
                )));
            }
            let material = Material::new(
                name,
                Ward {
                    rho_d,
                    rho_s,
                    alpha,
                },
            );
            write(
                &args.out,
                &material,
                args.colour,
                json!({"source": "reflectance gltf"}),
            )?;
            println!("{}", args.out.display());
            Ok(())
        }
        _ => Err(CliError::Invalid(
            "give --classes C.json, or --rho-d, --rho-s and --alpha".into(),
        )),
    }
}
