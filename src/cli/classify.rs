//! `reflectance classify IMAGE [--model NAME | DIR/NAME[/VERSION]] [--white W | --white-image F]
//! [--cx X --cy Y --r R | --mask F | --normals N [--mask M]] [--json]`: one photograph, without a server or a
//! manifest; the same pipeline and, with `--json`, the same JSON as `POST /v1/classify`.

use super::{CliError, CliResult, LimitArgs, SphereArgs};
use clap::Args;
use reflectance_core::decode::Encoding;
use reflectance_core::inference::{
    self, Answer, ClassifyResponse, InferenceError, Input, LoadedModel,
};
use reflectance_core::white::Method as WhiteMethod;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// `reflectance help classify`'s examples.
pub const EXAMPLES: &str = "Examples:
  # the shipped ward6, the sphere found in the photograph, no white card (a set of classes)
  reflectance classify photo.jpg
  # the circle given, and a white card whose linear luminance is 0.8 of full scale
  reflectance classify photo.jpg --cx 96.5 --cy 94.25 --r 85 --white 0.8
  # the white card drawn as a rectangle of the photograph; the eleven classes; JSON
  reflectance classify photo.jpg --white-rect 10,10,40,30 --model ward11 --json
  # the material as glTF, for a renderer
  reflectance classify photo.jpg --white 0.8 --gltf ball.glb";

/// Which material `classify --gltf` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GltfMaterial {
    Auto,
    Class,
    Estimate,
}

#[derive(Args, Debug)]
pub struct ClassifyArgs {
    /// The photograph or rendering (PNG, JPEG, WebP, TIFF, PNM, Radiance HDR, PFM or OpenEXR).
    image: PathBuf,
    /// The model: a name (looked for in $REFLECTANCE_MODELS, ./models and the models beside
    /// the binary), `DIR/NAME` (its active version) or `DIR/NAME/VERSION`.
    #[arg(long, default_value = super::DEFAULT_MODEL)]
    model: PathBuf,
    #[command(flatten)]
    sphere: SphereArgs,
    /// How integer samples are linearized: srgb (default), linear or gamma:<g>.
    #[arg(long)]
    encoding: Option<Encoding>,
    /// Also report every extracted feature (with --json).
    #[arg(long)]
    all_features: bool,
    /// Also report the 3 nearest training images.
    #[arg(long)]
    explain: bool,
    /// The prediction set's coverage, from 0.5 to 0.999 (default 0.95).
    #[arg(long)]
    coverage: Option<f64>,
    /// Print the JSON answer of `POST /v1/classify` instead of a summary.
    #[arg(long)]
    json: bool,
    /// Also write the material as a glTF 2.0 asset (a sphere with it) to this file (binary
    /// glTF when it ends in .glb): the answer's download (`material.download`: the estimate
    /// when it agrees with the class named, else the class's material), or see
    /// --gltf-material. What it holds is said on stderr.
    #[arg(long, value_name = "FILE.gltf")]
    gltf: Option<PathBuf>,
    /// Which material --gltf writes: the answer's download (auto), the predicted class's, or
    /// the estimate.
    #[arg(long, value_enum, default_value_t = GltfMaterial::Auto, requires = "gltf")]
    gltf_material: GltfMaterial,
    #[command(flatten)]
    limits: LimitArgs,
}

fn load_model(path: &Path) -> CliResult<LoadedModel> {
    Ok(LoadedModel::new(super::load_model_file(path)?)?)
}

fn input(args: &ClassifyArgs) -> CliResult<Input> {
    let (locate, white) = args.sphere.placement_and_white()?;
    let answer = Answer {
        include_features: args.all_features,
        include_explain: args.explain,
        include_images: false,
        coverage: args.coverage,
    };
    let image = super::read(&args.image, "image")?;
    Ok(Input::new(image, white, locate, args.encoding, answer)?)
}

pub fn run(args: ClassifyArgs) -> CliResult {
    let started = Instant::now();
    let model = Arc::new(load_model(&args.model)?);
    let input = input(&args)?;
    let classified = inference::classify(model, input, args.limits.limits())
        .map_err(|e| CliError::Invalid(error_text(&e, &args)))?;
    let answer = classified.response(String::new(), started.elapsed().as_secs_f64() * 1e3);
    if let Some(path) = &args.gltf {
        write_gltf(path, &answer, args.gltf_material)?;
    }
    if args.json {
        let text = serde_json::to_string_pretty(&answer)?;
        println!("{text}");
    } else {
        print!("{}", summary(&answer));
    }
    Ok(())
}

/// The answer's material as glTF: its download, or the one asked for.
fn write_gltf(path: &Path, answer: &ClassifyResponse, which: GltfMaterial) -> CliResult {
    let Some(materials) = &answer.material else {
        return Err(CliError::Invalid(
            "--gltf: no material to write: without a white reference the estimate has no \
             rho_d and rho_s, and this model does not know its classes' parameters"
                .into(),
        ));
    };
    let offered = [Some(&materials.download), materials.alternative.as_ref()];
    let chosen = match which {
        GltfMaterial::Auto => Some(&materials.download),
        GltfMaterial::Class => offered.into_iter().flatten().find(|m| m.source == "class"),
        GltfMaterial::Estimate => offered
            .into_iter()
            .flatten()
            .find(|m| m.source == "estimate"),
    };
    let Some(chosen) = chosen else {
        let model = &answer.model.name;
        let why = match which {
            GltfMaterial::Estimate if answer.ward.is_none() => {
                format!(
                    "model {model} has no estimator of the Ward parameters; try --gltf-material class"
                )
            }
            GltfMaterial::Estimate if answer.white.method == WhiteMethod::None => {
                "no white reference was given, so the estimate has no rho_d and rho_s: give \
                 --white (the linear luminance of a white card at the sphere, a fraction of \
                 full scale: 0.8 for a card at 80 %), --white-image or --white-rect"
                    .to_string()
            }
            GltfMaterial::Estimate => "the estimate is not whole".to_string(),
            _ => format!(
                "model {model} does not know the parameters of class {}",
                answer.label
            ),
        };
        return Err(CliError::Invalid(format!("--gltf-material: {why}")));
    };
    let material = reflectance_core::material::Material::new(chosen.name.clone(), chosen.ward);
    let about = serde_json::json!({"source": format!("the {} of reflectance classify", chosen.source),
                                   "material": chosen, "model": answer.model, "label": answer.label,
                                   "note": materials.note});
    super::gltf::write(path, &material, chosen.colour, about)?;
    let what = match chosen.source.as_str() {
        "estimate" => "the estimate".to_string(),
        _ => format!("class {}'s material", chosen.name),
    };
    let note = if which == GltfMaterial::Auto {
        format!(" ({})", materials.note)
    } else {
        String::new()
    };
    eprintln!("wrote {}: {what}{note}", path.display());
    Ok(())
}

/// A classification's failure, naming the file it is about and asking for the flags that
/// would mend it.
fn error_text(e: &InferenceError, args: &ClassifyArgs) -> String {
    match e {
        InferenceError::Decode { part, source } => {
            let file = match *part {
                "white_image: " => args.sphere.white_image.as_ref(),
                "mask: " => args.sphere.mask.as_ref(),
                _ => Some(&args.image),
            };
            let file = file.map_or(String::new(), |f| format!("{}: ", f.display()));
            format!("{file}{source}")
        }
        InferenceError::Analysis(e) => super::analysis_error(e),
        InferenceError::Normals(e) => {
            let file = args
                .sphere
                .normals
                .as_ref()
                .map_or(String::new(), |f| format!("{}: ", f.display()));
            format!("{file}{e}")
        }
        other => other.to_string(),
    }
}

/// A coverage as a percentage for people: 95, 99.9.
pub(super) fn percent(coverage: f64) -> String {
    format!("{}", (coverage * 1e5).round() / 1e3)
}

/// The answer for a person: the label, every probability, the circle, the warnings.
fn summary(answer: &ClassifyResponse) -> String {
    let mut out = format!(
        "{}  (p = {:.3}; model {} version {})\n",
        answer.label,
        answer.probabilities.first().map_or(0.0, |p| p.p),
        answer.model.name,
        answer.model.version
    );
    for p in &answer.probabilities {
        out.push_str(&format!("  {:<14} {:.3}\n", p.label, p.p));
    }
    if let Some(set) = &answer.prediction_set {
        out.push_str(&format!(
            "prediction set ({} %): {}\n",
            percent(set.coverage),
            set.labels.join(", ")
        ));
    }
    let d = &answer.domain;
    let score = match (d.score, d.threshold) {
        (Some(s), Some(t)) => format!(" (score {s:.1}, threshold {t:.1})"),
        _ => " (no domain calibration)".to_string(),
    };
    match d.in_domain {
        true => out.push_str(&format!("domain: in{score}\n")),
        false => out.push_str(&format!("domain: OUT{score}: {}\n", d.reasons.join("; "))),
    }
    let g = &answer.geometry;
    let how = match answer.observed_fraction {
        Some(f) => format!(
            " of the object, {:.0} % of it observed, {:.0} % not convex, {:.0} % in its own shadow",
            f * 100.0,
            answer.not_convex_fraction.unwrap_or(0.0) * 100.0,
            answer.shadowed_fraction.unwrap_or(0.0) * 100.0
        ),
        None => g
            .confidence
            .map_or(String::new(), |c| format!(", confidence {c:.2}")),
    };
    out.push_str(&format!(
        "sphere: cx {:.2}, cy {:.2}, r {:.2} ({}{how}); white {} ({})\n",
        g.cx,
        g.cy,
        g.r,
        inference::wire_name(&g.method),
        reflectance_core::dataset::format_f64(answer.white.value),
        inference::wire_name(&answer.white.method)
    ));
    if let Some(w) = &answer.ward {
        let part = |name: &str, i: &reflectance_core::estimate::Interval| {
            format!("{name} {:.3} [{:.3}, {:.3}]", i.value, i.low, i.high)
        };
        let mut parts = Vec::new();
        if let (Some(d), Some(s)) = (&w.rho_d, &w.rho_s) {
            parts.extend([part("rho_d", d), part("rho_s", s)]);
        }
        parts.extend([
            part("alpha", &w.alpha),
            part("specular fraction", &w.specular_fraction),
        ]);
        let unknown = match &w.unknown {
            Some(_) => "; rho_d and rho_s unknown without a white reference",
            None => "",
        };
        out.push_str(&format!(
            "estimate (90 % intervals): {}{unknown}\n",
            parts.join(", ")
        ));
    }
    if let Some(m) = &answer.material {
        out.push_str(&format!("material: {}\n", m.note));
    }
    match (&answer.colour.rgb, &answer.colour.srgb) {
        (Some([r, g, b]), Some(hex)) => out.push_str(&format!(
            "colour ({}): rgb {r:.3}, {g:.3}, {b:.3} (luminance 1), albedo {hex}\n",
            answer.colour.note
        )),
        _ => out.push_str(&format!("colour: {}\n", answer.colour.note)),
    }
    for warning in &answer.warnings {
        out.push_str(&format!("warning: {warning}\n"));
    }
    for n in answer.explain.iter().flatten() {
        out.push_str(&format!(
            "near: {} ({}, {}), distance {:.3}\n",
            n.path, n.class, n.illumination, n.distance
        ));
    }
    out
}
