//! `reflectance gltf` and `classify --gltf` through the real binary: files read back and
//! checked against known values of the mapping (docs/design.md §8), the material a download
//! holds, binary glTF, and the colour read against a white card in colour.

use crate::common::{README_SPHERE_FLAGS, assert_success, fixtures};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn reflectance(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// The JSON document of a `.gltf`, or of a `.glb`'s JSON chunk.
fn document(path: &Path) -> Value {
    let bytes = std::fs::read(path).unwrap();
    if bytes.starts_with(b"glTF") {
        let length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(&bytes[16..20], b"JSON");
        return serde_json::from_slice(&bytes[20..20 + length]).unwrap();
    }
    serde_json::from_slice(&bytes).unwrap()
}

fn number(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "reflectance-cli-gltf-{}-{name}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Known answers of the mapping: ρs 0.1 → F0 0.07993 (solved independently in numpy),
/// ior 1.7883, baseColor ρd / (1 − F0), GGX roughness √(0.7 α); a metal's F0 averages ρs
/// over the disc, (ρs − 1/21)/(1 − 1/21).
#[test]
fn a_single_material_as_gltf_and_glb() {
    let dir = temp("single");
    for file in ["j.gltf", "j.glb"] {
        let out = dir.join(file);
        assert_success(&reflectance(&[
            "gltf",
            "--rho-d",
            "0.25",
            "--rho-s",
            "0.1",
            "--alpha",
            "0.02",
            "--name",
            "j",
            "--out",
            out.to_str().unwrap(),
        ]));
        let doc = document(&out);
        let material = &doc["materials"][0];
        assert_eq!(material["name"], "j", "{file}");
        assert_eq!(doc["extras"]["ward"]["rho_d"], 0.25);
        assert_eq!(doc["extras"]["ward"]["rho_s"], 0.1);
        let ior = number(&material["extensions"]["KHR_materials_ior"]["ior"]);
        assert!((ior - 1.7883).abs() < 2e-3, "{ior}");
        let pbr = &material["pbrMetallicRoughness"];
        assert!((number(&pbr["baseColorFactor"][0]) - 0.25 / (1.0 - 0.07993)).abs() < 1e-3);
        assert!((number(&pbr["roughnessFactor"]).powi(2) - 0.014).abs() < 1e-12);
        assert_eq!(
            std::fs::read(&out).unwrap().starts_with(b"glTF"),
            file.ends_with(".glb")
        );
    }
    let refused = reflectance(&[
        "gltf",
        "--rho-d",
        "0.2",
        "--rho-s",
        "0.1",
        "--alpha",
        "0",
        "--name",
        "A B",
        "--out",
        dir.join("x.gltf").to_str().unwrap(),
    ]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--name"));
}

/// The README's example: the answer names chrome, the estimate is nearest gray_shiny. The
/// download holds chrome's material, said on stderr; the estimate, asked for, holds the
/// estimate's (ρd 0.287, ρs 0.105: not swapped).
#[test]
fn classify_writes_the_material_the_answer_names() {
    let dir = temp("classify");
    let image = fixtures().join("features/sphere_rgb8.png");
    let run = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "classify",
            image.to_str().unwrap(),
            "--model",
            "models/ward6",
            "--gltf",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(&README_SPHERE_FLAGS);
        args.extend_from_slice(extra);
        let output = Command::new(env!("CARGO_BIN_EXE_reflectance"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        assert_success(&output);
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let download = dir.join("download.glb");
    let said = run(&download, &[]);
    assert!(said.contains("class chrome's material"), "{said}");
    assert!(said.contains("nearest gray_shiny"), "{said}");
    let doc = document(&download);
    assert_eq!(doc["extras"]["ward"]["rho_s"], 0.75);
    let pbr = &doc["materials"][0]["pbrMetallicRoughness"];
    assert_eq!(pbr["metallicFactor"], 1.0);
    assert!(
        (number(&pbr["baseColorFactor"][0]) - (0.75 - 1.0 / 21.0) / (1.0 - 1.0 / 21.0)).abs()
            < 1e-12
    );

    let estimate = dir.join("estimate.gltf");
    let said = run(&estimate, &["--gltf-material", "estimate"]);
    assert!(said.contains("the estimate"), "{said}");
    let ward = &document(&estimate)["extras"]["ward"];
    assert!((number(&ward["rho_d"]) - 0.287).abs() < 5e-4, "{ward}");
    assert!((number(&ward["rho_s"]) - 0.105).abs() < 5e-4, "{ward}");
    assert!((number(&ward["alpha"]) - 0.0083).abs() < 5e-4, "{ward}");
    let material = &document(&estimate)["materials"][0];
    assert_eq!(
        material["pbrMetallicRoughness"]["metallicFactor"], 0.0,
        "a dielectric"
    );
    // The pinned factors, from the mapping's formulas written out here: F0 of the ior
    // ((n − 1)/(n + 1))², near the 0.08 of ρs 0.1 (ρs 0.105 gives a little more); the base
    // colour ρd / (1 − F0) with ρd 0.287 (ρs there instead would give 0.11); the GGX
    // roughness √(0.7 α).
    let ior = number(&material["extensions"]["KHR_materials_ior"]["ior"]);
    let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
    assert!((0.079..0.095).contains(&f0), "F0 {f0} (ior {ior})");
    let pbr = &material["pbrMetallicRoughness"];
    let base = number(&pbr["baseColorFactor"][0]);
    assert!(
        (base - number(&ward["rho_d"]) / (1.0 - f0)).abs() < 1e-9,
        "{pbr}"
    );
    assert!((base - 0.287 / (1.0 - f0)).abs() < 1e-3, "{pbr}");
    let roughness = number(&pbr["roughnessFactor"]);
    assert!(
        (roughness.powi(2) - 0.7 * number(&ward["alpha"])).abs() < 1e-9,
        "{pbr}"
    );
}

/// `gltf --classes`: one file per class, each with its own parameters in `extras.ward`
/// and the factors of the mapping: a matte's base colour is ρd, chrome's a metal's F0
/// (ρs − 1/21)/(1 − 1/21), a mirror's roughness 0.
#[test]
fn every_class_of_a_class_file_as_gltf() {
    let dir = temp("classes");
    let classes = dir.join("classes.json");
    std::fs::write(
        &classes,
        r#"{"classes": [{"name": "matte", "rho_d": 0.9, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
                        {"name": "glossy", "rho_d": 0.25, "rho_s": 0.1, "alpha": 0.02}]}"#,
    )
    .unwrap();
    let out = dir.join("out");
    assert_success(&reflectance(&[
        "gltf",
        "--classes",
        classes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let matte = document(&out.join("matte.gltf"));
    assert_eq!(matte["extras"]["ward"]["rho_d"], 0.9);
    assert_eq!(matte["extras"]["ward"]["rho_s"], 0.0);
    let pbr = &matte["materials"][0]["pbrMetallicRoughness"];
    assert_eq!(pbr["metallicFactor"], 0.0);
    assert!(
        (number(&pbr["baseColorFactor"][0]) - 0.9).abs() < 1e-6,
        "{pbr}"
    );
    let chrome = document(&out.join("chrome.gltf"));
    assert_eq!(chrome["extras"]["ward"]["rho_d"], 0.0);
    assert_eq!(chrome["extras"]["ward"]["rho_s"], 0.75);
    let pbr = &chrome["materials"][0]["pbrMetallicRoughness"];
    assert_eq!(pbr["metallicFactor"], 1.0);
    assert_eq!(number(&pbr["roughnessFactor"]), 0.0);
    let metal = (0.75 - 1.0 / 21.0) / (1.0 - 1.0 / 21.0);
    assert!(
        (number(&pbr["baseColorFactor"][0]) - metal).abs() < 1e-6,
        "{pbr}"
    );
    // ρs 0.1 → F0 0.07993 (solved independently in numpy), as in the single material.
    let glossy = document(&out.join("glossy.gltf"));
    assert_eq!(glossy["extras"]["ward"]["rho_d"], 0.25);
    assert_eq!(glossy["extras"]["ward"]["rho_s"], 0.1);
    let pbr = &glossy["materials"][0]["pbrMetallicRoughness"];
    assert!((number(&pbr["baseColorFactor"][0]) - 0.25 / (1.0 - 0.07993)).abs() < 1e-3);
    // The class file by its name: no machine's folders in a file people share.
    let text = std::fs::read_to_string(out.join("glossy.gltf")).unwrap();
    assert!(!text.contains(dir.to_str().unwrap()), "{text}");
    assert_eq!(
        glossy["extras"]["about"]["source"],
        "class \"glossy\" of classes.json"
    );
}

/// `classify --gltf-material estimate` says why there is no estimate: here, no white.
#[test]
fn an_estimate_without_white_names_the_missing_white() {
    let out = temp("no-white").join("ball.glb");
    let image = fixtures().join("features/sphere_rgb8.png");
    // The README's circle without its white.
    let circle = &README_SPHERE_FLAGS[2..];
    let mut args = vec!["classify", image.to_str().unwrap()];
    args.extend(circle);
    args.extend([
        "--gltf",
        out.to_str().unwrap(),
        "--gltf-material",
        "estimate",
    ]);
    let answer = reflectance(&args);
    assert!(!answer.status.success());
    let err = String::from_utf8_lossy(&answer.stderr);
    assert!(err.contains("no white reference was given"), "{err}");
    assert!(err.contains("--white"), "{err}");
    assert!(!out.exists());
}

/// A flat RGB "sphere" of linear (0.5, 0.25, 0.125) beside a white card of 0.8: the colour
/// read against the card is the sphere's over the card's, at luminance 1, and the download
/// is tinted by it.
#[test]
fn the_colour_is_read_against_a_white_card_in_colour() {
    let dir = temp("colour");
    let (size, r) = (200u32, 80.0);
    let c = (f64::from(size) - 1.0) / 2.0;
    let mut samples = Vec::new();
    for i in 0..size * size {
        let (x, y) = (f64::from(i % size), f64::from(i / size));
        let rgb: [f64; 3] = if x < 20.0 && y < 20.0 {
            [0.8; 3]
        } else if (x - c).hypot(y - c) <= r {
            // A mild shading keeps the detector's rim and the features alive.
            let shade = 0.8 + 0.2 * (1.0 - ((x - c).hypot(y - c) / r).powi(2)).sqrt();
            [0.5 * shade, 0.25 * shade, 0.125 * shade]
        } else {
            [0.02; 3]
        };
        samples.extend(
            rgb.iter()
                .flat_map(|v| ((v * 65535.0).round() as u16).to_be_bytes()),
        );
    }
    let mut png = Vec::new();
    let to_native: Vec<u8> = samples
        .chunks_exact(2)
        .flat_map(|b| u16::from_be_bytes([b[0], b[1]]).to_ne_bytes())
        .collect();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &to_native,
        size,
        size,
        image::ExtendedColorType::Rgb16,
    )
    .unwrap();
    let path = dir.join("red.png");
    std::fs::write(&path, png).unwrap();
    let out = dir.join("red.gltf");
    let output = Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "classify",
            path.to_str().unwrap(),
            "--model",
            "models/ward6",
            "--encoding",
            "linear",
            "--white-rect",
            "2,2,16,16",
            "--cx",
            &c.to_string(),
            "--cy",
            &c.to_string(),
            "--r",
            "80",
            "--json",
            "--gltf",
            out.to_str().unwrap(),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert_success(&output);
    let answer: Value = serde_json::from_slice(&output.stdout).unwrap();
    let rgb: Vec<f64> = answer["colour"]["rgb"]
        .as_array()
        .unwrap_or_else(|| panic!("{}", answer["colour"]))
        .iter()
        .map(number)
        .collect();
    // (0.5, 0.25, 0.125) at luminance 1: Rec. 709 weights give 0.2966875 for the ratio.
    let y = 0.2126 * 0.5 + 0.7152 * 0.25 + 0.0722 * 0.125;
    for (got, want) in rgb.iter().zip([0.5 / y, 0.25 / y, 0.125 / y]) {
        assert!((got - want).abs() < 0.01 * want, "{rgb:?}");
    }
    let chromaticity: Vec<f64> = answer["colour"]["chromaticity"]
        .as_array()
        .unwrap()
        .iter()
        .map(number)
        .collect();
    assert!(
        (chromaticity[0] - 4.0 / 7.0).abs() < 2e-3 && (chromaticity[1] - 2.0 / 7.0).abs() < 2e-3
    );
    let doc = document(&out);
    let base: Vec<f64> = doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"]
        .as_array()
        .unwrap()
        .iter()
        .map(number)
        .collect();
    assert!(
        (base[0] / base[1] - 2.0).abs() < 0.03 && (base[1] / base[2] - 2.0).abs() < 0.03,
        "{base:?}"
    );
    assert_eq!(doc["extras"]["colour"].as_array().unwrap().len(), 3);
    // A white given as a number reads no colour, and says so.
    let grey = reflectance(&[
        "classify",
        path.to_str().unwrap(),
        "--model",
        "models/ward6",
        "--encoding",
        "linear",
        "--white",
        "0.8",
        "--cx",
        &c.to_string(),
        "--cy",
        &c.to_string(),
        "--r",
        "80",
        "--json",
    ]);
    let answer: Value = serde_json::from_slice(&grey.stdout).unwrap_or(Value::Null);
    assert!(
        answer["colour"].get("rgb").is_none(),
        "{}",
        answer["colour"]
    );
    assert!(
        answer["colour"]["note"]
            .as_str()
            .unwrap_or("")
            .starts_with("unknown")
    );
}
