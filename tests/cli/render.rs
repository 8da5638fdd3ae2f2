//! `reflectance render` end to end: manifest, images, resume, determinism, features.

use crate::common;

use reflectance_core::decode::rgbe;
use reflectance_render::envmap::EnvMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub(crate) fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(args)
        .output()
        .expect("run binary")
}

pub(crate) fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reflectance-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Two small synthetic probes and a list file naming them.
fn probes(dir: &Path) -> PathBuf {
    let maps = [
        EnvMap::from_fn(64, 32, |d| 0.3 + d.y.max(0.0) + 0.2 * (6.0 * d.x).sin()),
        EnvMap::from_fn(64, 32, |d| 0.5 + 0.4 * d.x + 0.1 * (9.0 * d.z).cos()),
    ];
    for (k, map) in maps.iter().enumerate() {
        std::fs::write(
            dir.join(format!("probe{k}.hdr")),
            rgbe::write_flat(map.width, map.height, &map.luminance),
        )
        .unwrap();
    }
    let list = dir.join("sets").join("two.txt");
    std::fs::create_dir_all(list.parent().unwrap()).unwrap();
    std::fs::write(&list, "# two probes\nprobe0.hdr\nprobe1.hdr\n").unwrap();
    list
}

fn classes(dir: &Path) -> PathBuf {
    let path = dir.join("classes.json");
    std::fs::write(
        &path,
        r#"{"classes": [{"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
                        {"name": "shiny", "rho_d": 0.3, "rho_s": 0.1, "alpha": 0.02}]}"#,
    )
    .unwrap();
    path
}

#[test]
fn renders_a_dataset_that_resumes_and_feeds_the_features() {
    let dir = temp_dir("render");
    let list = probes(&dir);
    let classes = classes(&dir);
    let out = dir.join("out");
    let args = [
        "render",
        "--probes",
        list.to_str().unwrap(),
        "--classes",
        classes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "96",
        "--seed",
        "3",
    ];
    let first = run(&args);
    common::assert_success(&first);
    let manifest = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
    let lines: Vec<&str> = manifest.lines().collect();
    assert_eq!(lines[0], "path,class,illumination,cx,cy,r,white");
    assert_eq!(lines.len(), 1 + 2 * 3);
    assert!(
        lines[1].starts_with("probe0__matte.pfm,matte,probe0,47.5,47.5,43.63636363636363"),
        "{}",
        lines[1]
    );
    let image = std::fs::read(out.join("probe1__shiny.pfm")).unwrap();

    // Re-running skips complete images and reproduces the manifest exactly.
    std::fs::remove_file(out.join("probe1__chrome.pfm")).unwrap();
    let second = run(&args);
    assert!(
        String::from_utf8_lossy(&second.stderr)
            .contains("rendered 1 of 6 images (5 already complete)"),
        "{}",
        String::from_utf8_lossy(&second.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(out.join("manifest.csv")).unwrap(),
        manifest
    );

    // Deterministic for a seed: a fresh render is byte-identical.
    let again = dir.join("again");
    let mut fresh = args.to_vec();
    fresh[6] = again.to_str().unwrap();
    assert!(run(&fresh).status.success());
    assert_eq!(
        std::fs::read(again.join("probe1__shiny.pfm")).unwrap(),
        image
    );

    // The manifest feeds the feature extractor directly.
    let table = dir.join("features.csv");
    let features = run(&[
        "features",
        "--manifest",
        out.join("manifest.csv").to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
    ]);
    common::assert_success(&features);
    let table = reflectance_core::dataset::FeatureTable::read(&table).unwrap();
    assert_eq!(table.samples.len(), 6);
    // The white reference normalizes: a white-ish matte sphere's mean is below ρd = 0.8.
    let mean = table.samples[0].values[0];
    assert!(mean > 0.2 && mean < 0.8, "{mean}");
}

#[test]
fn augmentation_adds_views_with_suffixed_illuminations() {
    let dir = temp_dir("augment");
    let list = probes(&dir);
    let classes = classes(&dir);
    let out = dir.join("out");
    let result = run(&[
        "render",
        "--probes",
        list.to_str().unwrap(),
        "--classes",
        classes.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "72",
        "--rotations",
        "4",
        "--elevations",
        "40,50",
        "--contrasts",
        "0.7",
        "--reductions",
        "4",
        "--synthetic",
        "2",
    ]);
    common::assert_success(&result);
    let manifest = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
    let illuminations: std::collections::BTreeSet<&str> = manifest
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap())
        .collect();
    let expected = [
        "probe0",
        "probe0@el40",
        "probe0@el50",
        "probe0@lr4",
        "probe0@rot090",
        "probe0@rot180",
        "probe0@rot270",
        "synthetic@s1-0000",
        "synthetic@s1-0001",
    ];
    for e in expected {
        assert!(illuminations.contains(e), "{illuminations:?}");
    }
    // Probes in 8 views, synthetic maps in the original view only.
    assert_eq!(manifest.lines().count(), 1 + 2 * 8 * 3 + 2 * 3);
    // A flatter dynamic range and a coarser capture render different images of the scene.
    let original = std::fs::read(out.join("probe0__shiny.pfm")).unwrap();
    let flatter = std::fs::read(out.join("probe0@c0.7__shiny.pfm")).unwrap();
    let coarser = std::fs::read(out.join("probe0@lr4__shiny.pfm")).unwrap();
    assert_ne!(original, flatter);
    assert_ne!(original, coarser);
    // Cross-validation trains on the synthetic maps in every fold and never tests them.
    // Its stderr is not a terminal: progress comes as plain lines (here with no interval).
    let cv = Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "cv",
            "--manifest",
            out.join("manifest.csv").to_str().unwrap(),
            "--features",
            "hand2",
            "--classifier",
            "nn",
            "--json",
        ])
        .env("REFLECTANCE_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    common::assert_success(&cv);
    let progress = String::from_utf8_lossy(&cv.stderr);
    assert!(progress.contains("cv: 0/2 (0 %)"), "{progress}");
    assert!(
        progress
            .lines()
            .last()
            .unwrap()
            .starts_with("cv: 2 done in "),
        "{progress}"
    );
    let report: serde_json::Value = serde_json::from_slice(&cv.stdout).unwrap();
    assert_eq!(report["n"], 2 * 3);
    let folds = report["folds"].as_array().unwrap();
    let held_out: Vec<&str> = folds
        .iter()
        .map(|f| f["illumination"].as_str().unwrap())
        .collect();
    assert_eq!(held_out, ["probe0", "probe1"]);
    // The other probe's 8 views and both synthetic maps, 3 classes each.
    assert!(folds.iter().all(|f| f["n_train"] == (8 + 2) * 3));
    // Manifests given together learn from the rows of all: here the same one twice.
    let manifest = out.join("manifest.csv");
    let manifest = manifest.to_str().unwrap();
    let twice = run(&[
        "cv",
        "--manifest",
        manifest,
        "--manifest",
        manifest,
        "--features",
        "hand2",
        "--classifier",
        "nn",
        "--json",
    ]);
    common::assert_success(&twice);
    let report: serde_json::Value = serde_json::from_slice(&twice.stdout).unwrap();
    assert_eq!(report["n"], 2 * 2 * 3);
    let folds = report["folds"].as_array().unwrap();
    assert!(folds.iter().all(|f| f["n_train"] == 2 * (8 + 2) * 3));
}

#[test]
fn bad_inputs_are_reported() {
    let dir = temp_dir("render-bad");
    let list = probes(&dir);
    let classes = classes(&dir);
    let bad_classes = dir.join("bad.json");
    std::fs::write(
        &bad_classes,
        r#"{"classes": [{"name": "x", "rho_d": 0.9, "rho_s": 0.5, "alpha": 0.0}]}"#,
    )
    .unwrap();
    let out = dir.join("out");
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "--probes",
                list.to_str().unwrap(),
                "--classes",
                bad_classes.to_str().unwrap(),
            ],
            "rho_d + rho_s",
        ),
        (
            &[
                "--probes",
                "/nonexistent/list.txt",
                "--classes",
                classes.to_str().unwrap(),
            ],
            "/nonexistent/list.txt",
        ),
        (
            &[
                "--probes",
                list.to_str().unwrap(),
                "--classes",
                classes.to_str().unwrap(),
                "--size",
                "4",
            ],
            "size",
        ),
        (
            &[
                "--probes",
                list.to_str().unwrap(),
                "--classes",
                classes.to_str().unwrap(),
                "--reductions",
                "1",
            ],
            "reductions within 2…16",
        ),
        (
            &[
                "--probes",
                classes.to_str().unwrap(),
                "--classes",
                classes.to_str().unwrap(),
            ],
            "was not found",
        ),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["render", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let result = run(&args);
        assert!(!result.status.success());
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(stderr.contains(needle), "{needle}: {stderr}");
    }
}

/// `materials` writes a class file of continuous Ward parameters that `render` takes.
#[test]
fn materials_design_a_class_file_that_render_and_the_estimate_take() {
    let dir = temp_dir("materials");
    let file = dir.join("materials.json");
    let file_arg = file.to_str().unwrap();
    let design = || {
        let args = [
            "materials",
            "--count",
            "8",
            "--seed",
            "5",
            "--out",
            file_arg,
        ];
        common::assert_success(&run(&args));
        std::fs::read(&file).unwrap()
    };
    let first = design();
    assert_eq!(design(), first, "not deterministic");
    let doc: serde_json::Value = serde_json::from_slice(&first).unwrap();
    let classes = doc["classes"].as_array().unwrap();
    assert_eq!(classes.len(), 8);
    let names: Vec<&str> = classes
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names[0], "m0001");
    assert_eq!(names[7], "m0008");
    for c in classes {
        let (d, s, a) = (
            c["rho_d"].as_f64().unwrap(),
            c["rho_s"].as_f64().unwrap(),
            c["alpha"].as_f64().unwrap(),
        );
        assert!((0.0..=0.8).contains(&s) && d >= 0.0 && d + s <= 1.0, "{c}");
        assert!(a == 0.0 || (0.005..=0.2).contains(&a), "{c}");
    }
    // A quarter of the 16 images (2 probes × 8 materials), then all of them.
    let list = probes(&dir);
    let render_out = dir.join("rendered");
    let render = |more: &[&str]| {
        let base = [
            "render",
            "--probes",
            list.to_str().unwrap(),
            "--classes",
            file_arg,
            "--out",
            render_out.to_str().unwrap(),
            "--size",
            "72",
        ];
        common::assert_success(&run(&[&base[..], more].concat()));
    };
    render(&["--shard", "0/4"]);
    let part = std::fs::read_to_string(render_out.join("manifest.shard-0-of-4.csv")).unwrap();
    assert_eq!(part.lines().count(), 1 + 4, "{part}");
    assert!(part.contains(",m0001,"), "{part}");
    let out = run(&["materials", "--count", "0", "--out", file_arg]);
    assert_eq!(out.status.code(), Some(2));

    // Every image of the design, its features, and the leave-one-illumination-out estimate.
    render(&[]);
    let table = dir.join("features.csv");
    let manifest = render_out.join("manifest.csv");
    common::assert_success(&run(&[
        "features",
        "--manifest",
        manifest.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
        "--centre-features",
    ]));
    let cv = |more: &[&str]| {
        let base = [
            "cv",
            "--table",
            table.to_str().unwrap(),
            "--features",
            "hand6",
            "--estimate",
        ];
        run(&[&base[..], more].concat())
    };
    // The small ridge is the quickest regression to cross-validate.
    let ridge = [
        "--ward-classes",
        file_arg,
        "--regressor",
        "ridge",
        "--ridge-features",
        "50",
    ];
    let out = cv(&[&ridge[..], &["--json"]].concat());
    common::assert_success(&out);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["n"], 16, "{report}");
    let out = cv(&[]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "--estimate without --ward-classes"
    );

    // The report: every held-out estimate, with the per-illumination errors.
    let report_dir = dir.join("estimate");
    let report_arg = report_dir.to_str().unwrap();
    common::assert_success(&cv(&[&ridge[..], &["--out", report_arg]].concat()));
    let written: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report_dir.join("estimate.json")).unwrap()).unwrap();
    let rows = written["details"]["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 16, "{written}");
    assert_eq!(written["report"], report, "--json and --out disagree");
    assert_summary_matches_rows(&report, rows);
    assert_eq!(
        written["details"]["illuminations"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    let md = std::fs::read_to_string(report_dir.join("estimate.md")).unwrap();
    assert!(md.contains("### Per illumination"), "{md}");

    // A model with an estimator: predict writes the estimate and measures it.
    let models = dir.join("models");
    let table_arg = table.to_str().unwrap();
    common::assert_success(&run(&[
        "train",
        "--table",
        table_arg,
        "--features",
        "hand6",
        "--no-cv",
        "--models",
        models.to_str().unwrap(),
        "--name",
        "m",
        "--estimator-table",
        table_arg,
        "--estimator-classes",
        file_arg,
        "--estimator-features",
        "pix.mean,ctr.mean,ctr.cos",
    ]));
    // The estimator reads its own features, the classifier hand6; by default it is boosted
    // trees (one ensemble per output) predicting the total relative to ctr.cos.
    let model: serde_json::Value =
        serde_json::from_slice(&std::fs::read(models.join("m/1/model.json")).unwrap()).unwrap();
    let estimator = &model["estimator"];
    assert_eq!(
        estimator["inputs"],
        serde_json::json!(["pix.mean", "ctr.mean", "ctr.cos"])
    );
    assert_eq!(estimator["total_anchor"], 2);
    assert_eq!(
        estimator["trees"]["trees"].as_array().map(Vec::len),
        Some(4)
    );
    assert_eq!(estimator["boost"]["trees"], 300);
    assert_eq!(model["features"]["set"], "hand6");
    let predictions = dir.join("predictions.csv");
    let out = run(&[
        "predict",
        "--model",
        models.join("m").to_str().unwrap(),
        "--manifest",
        manifest.to_str().unwrap(),
        "--out",
        predictions.to_str().unwrap(),
        "--ward-classes",
        file_arg,
    ]);
    common::assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("estimate: over 2 illuminations, 16 images"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(&predictions).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.ends_with(
            ",rho_d,rho_d_low,rho_d_high,rho_s,rho_s_low,rho_s_high,alpha,alpha_low,alpha_high"
        ),
        "{header}"
    );
    assert_eq!(
        csv.lines().nth(1).unwrap().split(',').count(),
        header.split(',').count()
    );
}

/// The estimate report's figures, recomputed from the held-out rows it writes: the mean
/// errors, mirror-or-not, and the coverage of each row's ρ intervals.
fn assert_summary_matches_rows(report: &serde_json::Value, rows: &[serde_json::Value]) {
    let n = rows.len() as f64;
    let mean = |f: &dyn Fn(&serde_json::Value) -> f64| rows.iter().map(f).sum::<f64>() / n;
    let value = |row: &serde_json::Value, p: &str| row["estimate"][p]["value"].as_f64().unwrap();
    let truth = |row: &serde_json::Value, p: &str| row["truth"][p].as_f64().unwrap();
    let covered = |row: &serde_json::Value, p: &str| {
        let (t, e) = (truth(row, p), &row["estimate"][p]);
        f64::from(u8::from(
            e["low"].as_f64().unwrap() <= t && t <= e["high"].as_f64().unwrap(),
        ))
    };
    let expected = [
        (
            "mae_rho_d",
            mean(&|r| (value(r, "rho_d") - truth(r, "rho_d")).abs()),
        ),
        (
            "mae_rho_s",
            mean(&|r| (value(r, "rho_s") - truth(r, "rho_s")).abs()),
        ),
        (
            "mae_total",
            mean(&|r| {
                (value(r, "rho_d") + value(r, "rho_s") - truth(r, "rho_d") - truth(r, "rho_s"))
                    .abs()
            }),
        ),
        (
            "mirror_accuracy",
            mean(&|r| {
                f64::from(u8::from(
                    (value(r, "alpha") == 0.0) == (truth(r, "alpha") == 0.0),
                ))
            }),
        ),
        ("coverage_rho_d", mean(&|r| covered(r, "rho_d"))),
        ("coverage_rho_s", mean(&|r| covered(r, "rho_s"))),
    ];
    for (key, want) in expected {
        let got = report[key].as_f64().unwrap();
        assert!(
            (got - want).abs() < 1e-12,
            "{key}: report {got}, rows {want}"
        );
    }
}

#[test]
fn a_shape_renders_from_its_normals_with_the_map_beside() {
    let dir = temp_dir("render-shape");
    let probe =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/probes/polyhaven_dresden_square.hdr");
    let list = dir.join("one.txt");
    std::fs::write(&list, format!("{}\n", probe.display())).unwrap();
    std::fs::write(
        dir.join("classes.json"),
        r#"{"classes": [{"name": "shiny", "rho_d": 0.3, "rho_s": 0.1, "alpha": 0.05}]}"#,
    )
    .unwrap();
    let cube = dir.join("cube.obj");
    std::fs::write(
        &cube,
        "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 2 3 7 6\nf 4 1 5 8\n",
    )
    .unwrap();
    let render_with = |shape: &str, out: &Path, more: &[&str]| {
        let classes = dir.join("classes.json");
        let mut args = vec!["render", "--probes", list.to_str().unwrap()];
        args.extend(["--classes", classes.to_str().unwrap(), "--out"]);
        args.extend([
            out.to_str().unwrap(),
            "--size",
            "72",
            "--pixel-samples",
            "2",
        ]);
        args.extend(["--shape", shape]);
        args.extend(more);
        run(&args)
    };
    let render_shape = |shape: &str, out: &Path| render_with(shape, out, &[]);
    // One render (the probe's lighting takes seconds in a debug build): a mesh file.
    let mesh = format!("mesh:{}", cube.display());
    let out = dir.join("mesh");
    common::assert_success(&render_shape(&mesh, &out));
    let name = "polyhaven_dresden_square__shiny";
    let png = std::fs::read(out.join(format!("{name}.normals.png"))).unwrap();
    let limits = reflectance_core::decode::Limits::default();
    let map = reflectance_core::object::normals::NormalMap::from_png(&png, &limits).unwrap();
    assert_eq!((map.width(), map.height()), (72, 72));
    // The object is lit where the map has normals, and only there.
    let pfm = out.join(format!("{name}.pfm"));
    let image = reflectance_core::decode::decode_file(&pfm, &Default::default()).unwrap();
    let lit = image.luminance.indexed_iter().filter(|(_, v)| **v > 0.0);
    let lit: Vec<(usize, usize)> = lit.map(|(at, _)| at).collect();
    assert!(lit.len() > 500, "{}", lit.len());
    assert!(lit.iter().all(|&(r, c)| map.at(r, c).is_some()));
    // The manifest places it by its normal map, not by the sphere's circle.
    let manifest = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
    assert!(manifest.starts_with("path,class,illumination,cx,cy,r,white,normals\n"));
    let row = format!("{name}.pfm,shiny,polyhaven_dresden_square,,,,");
    assert!(manifest.contains(&row), "{manifest}");
    assert!(manifest.ends_with(&format!(",{name}.normals.png\n")));
    // Complete with its normals: a re-run renders nothing.
    let again = render_shape(&mesh, &out);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(
        stderr.contains("rendered 0 of 1 images (1 already complete)"),
        "{stderr}"
    );
    // Classified from its normals: a cube shows three of them, too little of the sphere, and
    // the answer says so; a torus shows all of it, and its hole's saddles (a fifth of it) are
    // left out: it shadows itself there, so the answer's set is the widest.
    let ward6 = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/ward6");
    let classify = |out: &Path| {
        let (image, normals) = (
            out.join(format!("{name}.pfm")),
            out.join(format!("{name}.normals.png")),
        );
        run(&[
            "classify",
            image.to_str().unwrap(),
            "--model",
            ward6.to_str().unwrap(),
            "--white",
            "1",
            "--normals",
            normals.to_str().unwrap(),
        ])
    };
    let cube = classify(&out);
    assert!(!cube.status.success());
    let stderr = String::from_utf8_lossy(&cube.stderr);
    assert!(
        stderr.contains("the features need at least 20 %"),
        "{stderr}"
    );
    let torus = dir.join("torus");
    common::assert_success(&render_shape("torus", &torus));
    let answer = classify(&torus);
    common::assert_success(&answer);
    let stdout = String::from_utf8_lossy(&answer.stdout);
    assert!(
        stdout.contains("(normals of the object, 100 % of it observed, 20 % not convex, ")
            && stdout.contains(" % in its own shadow)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("% in its own shadow (it shadows and lights itself)"),
        "{stdout}"
    );
    // The manifest's row reads the object as `classify --normals` does: the same features.
    let ward6_radius = "116.36363636363636";
    let table = dir.join("torus.csv");
    let manifest = torus.join("manifest.csv");
    common::assert_success(&run(&[
        "features",
        "--manifest",
        manifest.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
        "--log-features",
        "--working-radius",
        ward6_radius,
        "--saturation",
        "1.25",
    ]));
    let table = reflectance_core::dataset::FeatureTable::read(&table).unwrap();
    let white = std::fs::read_to_string(&manifest).unwrap();
    let white = white.lines().nth(1).unwrap().split(',').nth(6).unwrap();
    let (image, normals) = (
        torus.join(format!("{name}.pfm")),
        torus.join(format!("{name}.normals.png")),
    );
    let answer = run(&[
        "classify",
        image.to_str().unwrap(),
        "--model",
        ward6.to_str().unwrap(),
        "--white",
        white,
        "--normals",
        normals.to_str().unwrap(),
        "--json",
        "--all-features",
    ]);
    common::assert_success(&answer);
    let answer: serde_json::Value = serde_json::from_slice(&answer.stdout).unwrap();
    let all = &answer["features"]["all"];
    let served: std::collections::HashMap<&str, f64> = all["names"]
        .as_array()
        .unwrap()
        .iter()
        .zip(all["values"].as_array().unwrap())
        .map(|(n, v)| (n.as_str().unwrap(), v.as_f64().unwrap()))
        .collect();
    for (name, value) in table.names.iter().zip(&table.samples[0].values) {
        assert_eq!(served[name.as_str()], *value, "{name}");
    }
    // Its captures keep its geometry: the same map fits them, and the manifest says so.
    let captured = dir.join("captured");
    common::assert_success(&render_with("torus", &captured, &["--captures", "2"]));
    let manifest =
        reflectance_core::dataset::read_manifest(&captured.join("manifest.csv")).unwrap();
    assert_eq!(manifest.entries.len(), 3);
    for entry in &manifest.entries {
        let normals = entry.normals.as_ref().unwrap();
        assert_eq!(normals.path, format!("{name}.normals.png"));
        assert!(entry.circle.is_none());
        let image = reflectance_core::decode::decode_file(&entry.file, &Default::default());
        assert_eq!(image.unwrap().luminance.dim(), (72, 72), "{}", entry.path);
    }
    let captures = std::fs::read_to_string(captured.join("captures.csv")).unwrap();
    for row in captures.lines().skip(1) {
        let fields: Vec<&str> = row.split(',').collect();
        // The render's radius (72 / 2.2), no centre or radius error.
        assert!(fields[1].starts_with("32.72"), "{row}");
        assert_eq!(&fields[9..], ["0.0", "0.0", "0.0"], "{row}");
    }
    let unknown = render_shape("cube", &dir.join("bad"));
    assert!(!unknown.status.success());
    let stderr = String::from_utf8_lossy(&unknown.stderr);
    assert!(stderr.contains("unknown shape"), "{stderr}");
    let missing = render_shape("mesh:/nonexistent/x.ply", &dir.join("missing"));
    assert!(!missing.status.success());
}
