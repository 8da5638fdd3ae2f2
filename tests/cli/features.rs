//! `reflectance features` end to end, through the real binary.

use crate::common;

use common::fixtures;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(args)
        .output()
        .expect("run binary")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reflectance-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn fixture(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(fixtures().join("features").join(name)).unwrap())
        .unwrap()
}

fn image(name: &str) -> String {
    fixtures().join("features").join(name).display().to_string()
}

/// A one-line reason on stderr and a failure exit status.
fn assert_refused(out: &Output, needle: &str) {
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(stderr.contains(needle), "{stderr}");
}

#[test]
fn single_image_json_matches_the_reference() {
    let want = fixture("sphere_rgb8.json");
    let out = run(&[
        "features",
        &image("sphere_rgb8.png"),
        "--cx",
        "96.5",
        "--cy",
        "94.25",
        "--r",
        "85",
        "--white",
        "0.8",
    ]);
    common::assert_success(&out);
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(got["names"], want["names"]);
    for (g, w) in got["values"]
        .as_array()
        .unwrap()
        .iter()
        .zip(want["values"].as_array().unwrap())
    {
        let (g, w) = (g.as_f64().unwrap(), w.as_f64().unwrap());
        assert!((g - w).abs() <= 1e-9 * w.abs().max(1.0), "{g} vs {w}");
    }
    assert_eq!(got["geometry"]["method"], "given");
    assert_eq!(got["white"]["method"], "given");
    assert_eq!(got["white"]["value"], 0.8);
    assert_eq!(got["warnings"].as_array().unwrap().len(), 0);
}

#[test]
fn automatic_geometry_and_missing_white_are_reported() {
    let out = run(&["features", &image("sphere_gray16.png")]);
    assert!(out.status.success());
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(got["geometry"]["method"], "auto");
    assert!((got["geometry"]["r"].as_f64().unwrap() - 120.0).abs() < 1.0);
    assert_eq!(got["white"]["method"], "none");
    let warnings = got["warnings"].to_string();
    assert!(warnings.contains("no white reference"), "{warnings}");
}

#[test]
fn bad_requests_fail_with_one_line() {
    let img = image("sphere_gray8.png");
    let circle = ["--cx", "52.35", "--cy", "48.7", "--r", "40.3"];
    for white in ["0", "-1", "nan", "inf"] {
        let mut args = vec!["features", img.as_str(), "--white", white];
        args.extend(circle);
        assert_refused(&run(&args), "white");
    }
    assert_refused(
        &run(&["features", &img, "--cx", "500", "--cy", "48", "--r", "40"]),
        "outside",
    );
    assert_refused(
        &run(&["features", &img, "--cx", "50", "--cy", "48", "--r", "20"]),
        "below the minimum",
    );
    assert_refused(
        &run(&["features", &img, "--encoding", "gamma:-2"]),
        "encoding",
    );
    assert_refused(&run(&["features", "/nonexistent/x.png"]), "could not read");
    let noise = temp_dir("noise").join("noise.png");
    let samples: Vec<u8> = (0..128u32 * 128)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    std::fs::write(&noise, common::png8(128, 128, 1, &samples)).unwrap();
    assert_refused(
        &run(&["features", noise.to_str().unwrap()]),
        "could not find the sphere",
    );
    // The refusal asks for the flags that would place the sphere.
    assert_refused(
        &run(&["features", noise.to_str().unwrap()]),
        "give --cx, --cy and --r, or --mask",
    );
    // A file that is no image is named.
    let text = temp_dir("text").join("notes.png");
    std::fs::write(&text, "not an image").unwrap();
    assert_refused(
        &run(&[
            "classify",
            text.to_str().unwrap(),
            "--model",
            "models/ward6",
        ]),
        "notes.png: unsupported image format",
    );
}

fn write_manifest(dir: &Path, rows: &[&str]) -> PathBuf {
    let manifest = dir.join("manifest.csv");
    let mut text = String::from("path,class,illumination,cx,cy,r,white\n");
    for row in rows {
        text.push_str(row);
        text.push('\n');
    }
    std::fs::write(&manifest, text).unwrap();
    manifest
}

#[test]
fn manifest_to_feature_table() {
    let dir = temp_dir("manifest");
    let rows = [
        format!(
            "{},shiny,env1,52.35,48.7,40.3,1.0",
            image("sphere_gray8.png")
        ),
        format!(
            "{},chrome,env2,80.3,79.8,70.0,2.5",
            image("sphere_rgb_le.pfm")
        ),
        format!(
            "{},shiny,env2,181.6,180.2,170.4,1.0",
            image("sphere_gray_be.pfm")
        ),
    ];
    let rows: Vec<&str> = rows.iter().map(String::as_str).collect();
    let manifest = write_manifest(&dir, &rows);
    let out_csv = dir.join("features.csv");
    let out = run(&[
        "features",
        "--manifest",
        manifest.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
    ]);
    common::assert_success(&out);
    let table = reflectance_core::dataset::FeatureTable::read(&out_csv).unwrap();
    assert_eq!(table.names, reflectance_core::features::default_names());
    assert_eq!(table.samples.len(), 3);
    assert_eq!(
        (
            table.samples[1].class.as_str(),
            table.samples[1].illumination.as_str()
        ),
        ("chrome", "env2")
    );
    for (sample, name) in table.samples.iter().zip([
        "sphere_gray8.json",
        "sphere_rgb_le.json",
        "sphere_gray_be.json",
    ]) {
        let want = fixture(name);
        for (g, w) in sample.values.iter().zip(want["values"].as_array().unwrap()) {
            let w = w.as_f64().unwrap();
            assert!(
                (g - w).abs() <= 1e-9 * w.abs().max(1.0),
                "{name}: {g} vs {w}"
            );
        }
    }
}

#[test]
fn a_bad_manifest_row_names_its_line() {
    let dir = temp_dir("badrow");
    let good = format!("{},a,e,52.35,48.7,40.3,1", image("sphere_gray8.png"));
    let manifest = write_manifest(&dir, &[&good, "missing.png,a,e,1,2,40,1", &good]);
    let out_csv = dir.join("f.csv");
    let out = run(&[
        "features",
        "--manifest",
        manifest.to_str().unwrap(),
        "--out",
        out_csv.to_str().unwrap(),
    ]);
    assert_refused(&out, "line 3");
    assert!(!out_csv.exists(), "nothing is written on failure");
    let manifest = write_manifest(&dir, &[&good, "x.png,a,e,abc,2,40,1"]);
    assert_refused(
        &run(&[
            "features",
            "--manifest",
            manifest.to_str().unwrap(),
            "--out",
            out_csv.to_str().unwrap(),
        ]),
        "cx is not a number",
    );
}

#[test]
fn extensions_extend_the_canonical_ones() {
    let img = image("sphere_rgb8.png");
    let circle = [
        "--cx", "96.5", "--cy", "94.25", "--r", "85", "--white", "0.8",
    ];
    let plain = run(&[&["features", img.as_str()][..], &circle[..]].concat());
    let extended = run(&[
        &["features", img.as_str(), "--log-features"][..],
        &circle[..],
    ]
    .concat());
    let (plain, extended): (Value, Value) = (
        serde_json::from_slice(&plain.stdout).unwrap(),
        serde_json::from_slice(&extended.stdout).unwrap(),
    );
    let (names, values) = (
        extended["names"].as_array().unwrap(),
        extended["values"].as_array().unwrap(),
    );
    assert_eq!((names.len(), values.len()), (234, 234));
    assert_eq!(names[117], "log.pix.mean");
    assert_eq!(
        &values[..117],
        plain["values"].as_array().unwrap().as_slice()
    );
    // log10 is monotone: log.pix.p50 is log10 of the median, up to the interpolation between
    // the two middle values of an even count.
    let p50 = values[5].as_f64().unwrap();
    let log_p50 = values[117 + 5].as_f64().unwrap();
    assert!(
        (log_p50 - p50.max(1e-4).log10()).abs() < 1e-6,
        "{log_p50} vs log10 {p50}"
    );
    // The radial changes close each block; the rest is unchanged.
    let radial = run(&[
        &[
            "features",
            img.as_str(),
            "--log-features",
            "--radial-features",
        ][..],
        &circle[..],
    ]
    .concat());
    let radial: Value = serde_json::from_slice(&radial.stdout).unwrap();
    let (radial_names, radial_values) = (
        radial["names"].as_array().unwrap(),
        radial["values"].as_array().unwrap(),
    );
    // Two ring pairs × 14 per block.
    assert_eq!(radial_values.len(), 290);
    assert_eq!(
        [&radial_names[117], &radial_names[145], &radial_names[289]],
        [
            "radial.r1_r2.pix.mean",
            "log.pix.mean",
            "log.radial.r2_r3.wav.s4.d.var"
        ]
    );
    assert_eq!(&radial_values[..117], &values[..117]);
    assert_eq!(&radial_values[145..262], &values[117..]);
    // The orientation dependencies close each block after the radial changes.
    let every = run(&[
        &[
            "features",
            img.as_str(),
            "--log-features",
            "--radial-features",
            "--dependency-features",
        ][..],
        &circle[..],
    ]
    .concat());
    let every: Value = serde_json::from_slice(&every.stdout).unwrap();
    let (every_names, every_values) = (
        every["names"].as_array().unwrap(),
        every["values"].as_array().unwrap(),
    );
    assert_eq!(every_values.len(), 314);
    assert_eq!(
        [&every_names[145], &every_names[156], &every_names[157]],
        ["dep.s1.hv", "dep.s4.vd", "log.pix.mean"]
    );
    assert_eq!(&every_values[..145], &radial_values[..145]);
    assert_eq!(&every_values[157..302], &radial_values[145..]);
    let correlations = every_values[145..157].iter().chain(&every_values[302..]);
    assert!(
        correlations
            .map(|c| c.as_f64().unwrap())
            .all(|c| (-1.0..=1.0).contains(&c))
    );
}
