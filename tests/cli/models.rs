//! Model files and the registry: round trips, refusal of corrupt files, versions, activation,
//! and train → predict through the real binary.

use crate::common;

use reflectance_core::classify::{ClassifierKind, TrainSpec};
use reflectance_core::dataset::FeatureTable;
use reflectance_core::features::families::{LOG, RADIAL};
use reflectance_core::learn::FeatureSet;
use reflectance_core::model::registry::{Registry, RegistryError};
use reflectance_core::model::train::{self, TrainOptions, train};
use reflectance_core::model::{ModelError, ModelFile};
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reflectance-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The learning reference fixture: 432 rows of the 117 canonical features.
fn table() -> FeatureTable {
    FeatureTable::read(&common::fixtures().join("learn/table.csv")).unwrap()
}

fn trained(name: &str) -> ModelFile {
    let options = TrainOptions {
        name: name.into(),
        spec: TrainSpec::new(FeatureSet::Named("hand6"), ClassifierKind::Svm),
        seed: 1,
        cross_validate: false,
        classes: None,
        preprocessing: Default::default(),
        images: None,
        decode: Default::default(),
        estimator: None,
        no_white_references_only: false,
    };
    train(&table(), "fixture", &options).unwrap().model
}

#[test]
fn model_file_round_trip_and_corruption() {
    let mut model = trained("demo");
    let bytes = model.to_json().unwrap();
    let back = ModelFile::from_json(&bytes).unwrap();
    assert_eq!(back, model);
    assert_eq!(back.sha256.len(), 64);
    // Reformatting does not matter; editing a number does.
    let pretty =
        serde_json::to_vec_pretty(&serde_json::from_slice::<serde_json::Value>(&bytes).unwrap())
            .unwrap();
    assert!(ModelFile::from_json(&pretty).is_ok());
    let text = String::from_utf8(bytes.clone()).unwrap();
    let edited = text.replacen("\"c\":100.0", "\"c\":101.0", 1);
    assert_ne!(edited, text);
    assert!(matches!(
        ModelFile::from_json(edited.as_bytes()),
        Err(ModelError::Checksum { .. })
    ));
    assert!(matches!(
        ModelFile::from_json(&bytes[..bytes.len() / 2]),
        Err(ModelError::Json(_))
    ));
    let other_schema = text.replacen("\"schema_version\":1", "\"schema_version\":9", 1);
    assert!(matches!(
        ModelFile::from_json(other_schema.as_bytes()),
        Err(ModelError::Schema { .. })
    ));
    // A consistent checksum over inconsistent content is still refused by verification.
    let mut tampered = model.clone();
    tampered.self_test.probabilities[0] += 0.01;
    let bytes = tampered.to_json().unwrap();
    assert!(matches!(
        ModelFile::from_json(&bytes),
        Err(ModelError::SelfTest(_))
    ));
    let mut wrong_config = model.clone();
    wrong_config.features.config.unwrap.cols = 440;
    assert!(matches!(
        ModelFile::from_json(&wrong_config.to_json().unwrap()),
        Err(ModelError::Config(_))
    ));
}

#[test]
fn registry_versions_activation_and_deletion() {
    let root = temp_dir("registry");
    let registry = Registry::new(&root);
    assert!(registry.names().unwrap().is_empty());
    let mut model = trained("ward6");
    let (v1, dir1) = registry
        .publish(&mut model, &[("report.json", b"{}")])
        .unwrap();
    let (v2, _) = registry.publish(&mut model, &[]).unwrap();
    assert_eq!((v1, v2), (1, 2));
    assert!(dir1.join("report.json").is_file());
    assert_eq!(registry.names().unwrap(), ["ward6"]);
    assert_eq!(registry.versions("ward6").unwrap(), [1, 2]);
    assert_eq!(
        registry.active("ward6").unwrap(),
        2,
        "latest without ACTIVE"
    );
    registry.set_active("ward6", 1).unwrap();
    assert_eq!(registry.active("ward6").unwrap(), 1);
    assert_eq!(registry.load("ward6", 2).unwrap().version, 2);
    assert!(matches!(
        registry.delete("ward6", 1),
        Err(RegistryError::ActiveVersion { .. })
    ));
    registry.delete("ward6", 2).unwrap();
    assert_eq!(registry.versions("ward6").unwrap(), [1]);
    assert!(matches!(
        registry.load("ward6", 7),
        Err(RegistryError::UnknownVersion { .. })
    ));
    assert!(matches!(
        registry.load("../etc", 1),
        Err(RegistryError::BadName(_))
    ));
    // A half-written version (staging directory) is invisible and cleaned up.
    std::fs::create_dir_all(root.join("ward6/.3.tmp-1-0")).unwrap();
    assert_eq!(registry.versions("ward6").unwrap(), [1]);
    assert_eq!(registry.clean_staging().unwrap(), 1);
    // A corrupt model file is refused with its path.
    let path = root.join("ward6/1/model.json");
    let mut bytes = std::fs::read(&path).unwrap();
    let k = bytes.len() / 3;
    bytes[k] ^= 1;
    std::fs::write(&path, bytes).unwrap();
    let err = registry.load("ward6", 1).unwrap_err().to_string();
    assert!(err.contains("model.json"), "{err}");
}

#[test]
fn train_and_cross_validate_through_the_binary() {
    let dir = temp_dir("train-predict");
    let bin = env!("CARGO_BIN_EXE_reflectance");
    let table = common::fixtures().join("learn/table.csv");
    let models = dir.join("models");
    let out = Command::new(bin)
        .args([
            "train",
            "--table",
            table.to_str().unwrap(),
            "--features",
            "hand6",
            "--classifier",
            "svm",
            "--models",
            models.to_str().unwrap(),
            "--name",
            "demo",
        ])
        .output()
        .unwrap();
    common::assert_success(&out);
    let printed = String::from_utf8(out.stdout).unwrap();
    assert_eq!(PathBuf::from(printed.trim()), models.join("demo/1"));
    assert!(models.join("demo/1/report.json").is_file());
    let model = Registry::new(&models).load("demo", 1).unwrap();
    let cv = model.training.cv.as_ref().unwrap();
    assert_eq!(cv.n, 432);
    // Every training image is an exemplar; a training row's nearest exemplar is itself.
    assert_eq!(model.exemplars.len(), 432);
    let row = &reflectance_core::dataset::FeatureTable::read(&table)
        .unwrap()
        .samples[17];
    let nearest = model.nearest(&row.values, 3).unwrap();
    assert_eq!(nearest[0].0.path, row.path);
    assert!(nearest[0].1 < 1e-9 && nearest[1].1 >= nearest[0].1);

    // Every new version goes through the activation policy, as a train job's does; the
    // version active before stays pinned.
    let registry = Registry::new(&models);
    assert_eq!(registry.active("demo").unwrap(), 1);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("version 1 activated (no active version)")
    );
    let again = |policy: &str, extra: &[&str]| {
        let mut args = vec![
            "train",
            "--table",
            table.to_str().unwrap(),
            "--features",
            "hand6",
            "--models",
            models.to_str().unwrap(),
            "--name",
            "demo",
            "--activate",
            policy,
        ];
        args.extend_from_slice(extra);
        let out = Command::new(bin).args(&args).output().unwrap();
        common::assert_success(&out);
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let same = again("if-better", &[]);
    assert!(
        same.contains("version 2 published, not activated (CV accuracy"),
        "{same}"
    );
    assert_eq!(registry.active("demo").unwrap(), 1);
    again("always", &[]);
    assert_eq!(registry.active("demo").unwrap(), 3);
    let never = again("never", &["--no-cv"]);
    assert!(
        never.contains("version 4 published, not activated (activate: never)"),
        "{never}"
    );
    assert_eq!(registry.active("demo").unwrap(), 3);

    let cv_json = Command::new(bin)
        .args([
            "cv",
            "--table",
            table.to_str().unwrap(),
            "--features",
            "hand6",
            "--classifier",
            "svm",
            "--json",
        ])
        .output()
        .unwrap();
    let report: serde_json::Value = serde_json::from_slice(&cv_json.stdout).unwrap();
    assert_eq!(report["accuracy"].as_f64().unwrap(), cv.accuracy);
    for key in [
        "n",
        "per_class",
        "confusion",
        "log_loss",
        "ece",
        "predictions",
    ] {
        assert!(report.get(key).is_some(), "{key}");
    }
    let bad = Command::new(bin)
        .args([
            "train",
            "--table",
            table.to_str().unwrap(),
            "--features",
            "hand7",
            "--models",
            models.to_str().unwrap(),
            "--name",
            "x",
        ])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("hand7"));
}

/// Three small synthetic probes in `dir/probes`, and a class file of three materials.
fn synthetic_probes_and_classes(dir: &Path) -> (PathBuf, PathBuf) {
    use reflectance_core::decode::rgbe;
    use reflectance_render::envmap::EnvMap;
    let maps = [
        EnvMap::from_fn(64, 32, |d| 0.3 + d.y.max(0.0) + 0.2 * (6.0 * d.x).sin()),
        EnvMap::from_fn(64, 32, |d| 0.5 + 0.4 * d.x + 0.1 * (9.0 * d.z).cos()),
        EnvMap::from_fn(64, 32, |d| {
            0.2 + 0.8 * (d.y + 0.3).max(0.0) * (1.0 + 0.5 * (4.0 * d.z).sin())
        }),
    ];
    let probes = dir.join("probes");
    std::fs::create_dir_all(&probes).unwrap();
    for (k, map) in maps.iter().enumerate() {
        std::fs::write(
            probes.join(format!("p{k}.hdr")),
            rgbe::write_flat(64, 32, &map.luminance),
        )
        .unwrap();
    }
    let classes = dir.join("classes.json");
    std::fs::write(
        &classes,
        r#"{"classes": [{"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
                        {"name": "dark", "rho_d": 0.1, "rho_s": 0.0, "alpha": 0.0}]}"#,
    )
    .unwrap();
    (probes, classes)
}

/// `train` of a hand6+log model on `manifest` into the registry `models` (no CV; calibrated
/// one illumination at a time), with `extra` arguments.
fn train_hand6_log(
    manifest: &Path,
    models: &Path,
    name: &str,
    extra: &[&str],
) -> std::process::Output {
    let (manifest, models) = (manifest.to_str().unwrap(), models.to_str().unwrap());
    let mut args = vec!["train", "--manifest", manifest, "--features", "hand6+log"];
    args.extend(["--calibration-folds", "0", "--no-cv", "--models", models]);
    args.extend(["--name", name]);
    args.extend(extra);
    Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(&args)
        .output()
        .unwrap()
}

/// Spheres of `classes` under `probes`, 96 px, into `out`.
fn render_spheres(probes: &Path, classes: &Path, out: &Path) {
    let (probes, classes) = (probes.to_str().unwrap(), classes.to_str().unwrap());
    let out = out.to_str().unwrap();
    run(&[
        "render",
        "--probes",
        probes,
        "--classes",
        classes,
        "--out",
        out,
        "--size",
        "96",
    ]);
}

/// Run the binary; its stdout, or a panic with its stderr.
fn run(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn predict_rendered_spheres_with_a_trained_model() {
    let dir = temp_dir("predict");
    let (probes, classes) = synthetic_probes_and_classes(&dir);
    let data = dir.join("data");
    render_spheres(&probes, &classes, &data);
    let manifest = data.join("manifest.csv");
    let models = dir.join("models");
    let train = |name: &str, features: &str, extra: &[&str]| {
        let mut args = vec![
            "train",
            "--manifest",
            manifest.to_str().unwrap(),
            "--features",
            features,
            "--classifier",
            "nn",
            "--models",
            models.to_str().unwrap(),
            "--name",
            name,
        ];
        args.extend_from_slice(extra);
        run(&args);
    };
    let predict = |model: &str, out: &Path| {
        run(&[
            "predict",
            "--model",
            models.join(model).to_str().unwrap(),
            "--manifest",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    train("tiny", "mean1", &["--classes", classes.to_str().unwrap()]);
    let model = Registry::new(&models).load("tiny", 1).unwrap();
    assert_eq!(model.features.config.working_radius, None);
    assert_eq!(model.classes[1].name, "dark");
    assert_eq!(model.classes[1].ward.as_ref().unwrap().rho_d, 0.1);
    // The preprocessing given to train is recorded in the model's feature configuration.
    train(
        "tiny-wr",
        "mean1",
        &["--working-radius", "40", "--saturation", "1.25"],
    );
    let wr = Registry::new(&models).load("tiny-wr", 1).unwrap();
    assert_eq!(wr.features.config.working_radius, Some(40.0));
    assert_eq!(wr.features.config.saturation, Some(1.25));
    // Features named from an extension are extracted for training and again for predicting.
    train(
        "tiny-radial",
        "log.radial.r1_r2.pix.var,radial.r2_r3.wav.s1.v.var",
        &[],
    );
    let radial = Registry::new(&models).load("tiny-radial", 1).unwrap();
    let families = radial.features.config.families;
    assert!(families.contains(&RADIAL) && families.contains(&LOG));
    let predicted = predict("tiny-radial", &dir.join("radial.csv"));
    assert!(
        predicted.starts_with("accuracy 100.0 % (9/9)"),
        "{predicted}"
    );
    let predictions = dir.join("p.csv");
    let printed = predict("tiny", &predictions);
    // The training images themselves, by their nearest neighbour: all correct.
    assert!(
        printed.starts_with("accuracy 100.0 % (9/9) with tiny version 1"),
        "{printed}"
    );
    let csv = std::fs::read_to_string(&predictions).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "path,label,p_chrome,p_dark,p_matte,set,in_domain,domain_score,domain_failed"
    );
    assert_eq!(lines.len(), 10);
    assert!(lines[1].starts_with("p0__matte.pfm,matte,"), "{}", lines[1]);
    let explicit = predict("tiny/1", &predictions);
    assert_eq!(explicit, printed);
}

#[test]
fn a_classifier_for_objects_answers_objects_and_spheres_stay_as_they_were() {
    use reflectance_core::model::Request;
    let dir = temp_dir("objects");
    let (probes, classes) = synthetic_probes_and_classes(&dir);
    let render = |out: &Path, shape: &[&str]| {
        let mut args = vec!["render", "--probes", probes.to_str().unwrap()];
        args.extend(["--classes", classes.to_str().unwrap()]);
        args.extend(["--out", out.to_str().unwrap(), "--size", "96"]);
        args.extend(shape);
        run(&args)
    };
    let (spheres, torus) = (dir.join("spheres"), dir.join("torus"));
    render(&spheres, &[]);
    render(&torus, &["--shape", "torus"]);
    let (spheres_csv, torus_csv) = (spheres.join("manifest.csv"), torus.join("manifest.csv"));
    let models = dir.join("models");
    run(&[
        "train",
        "--manifest",
        spheres_csv.to_str().unwrap(),
        "--features",
        "hand6+log",
        "--calibration-folds",
        "0",
        "--no-cv",
        "--models",
        models.to_str().unwrap(),
        "--name",
        "m",
    ]);
    let train_objects = |manifests: &[&Path]| {
        let mut args = vec!["train-objects", "--calibration-folds", "0"];
        let base = models.join("m/1");
        args.extend(["--model", base.to_str().unwrap()]);
        args.extend(["--models", models.to_str().unwrap()]);
        for m in manifests {
            args.extend(["--manifest", m.to_str().unwrap()]);
        }
        Command::new(env!("CARGO_BIN_EXE_reflectance"))
            .args(&args)
            .output()
            .unwrap()
    };
    // Objects of two classes cannot teach a classifier of three.
    let two_classes = torus.join("two.csv");
    let rows = std::fs::read_to_string(&torus_csv).unwrap();
    let rows: Vec<&str> = rows.lines().filter(|l| !l.contains(",dark,")).collect();
    std::fs::write(&two_classes, rows.join("\n") + "\n").unwrap();
    let refused = train_objects(&[&two_classes]);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains(
            "the data's classes (chrome, matte) are not the model's (chrome, dark, matte)"
        ),
        "{stderr}"
    );
    let added = train_objects(&[&spheres_csv, &torus_csv]);
    common::assert_success(&added);
    assert_eq!(
        String::from_utf8_lossy(&added.stdout).trim(),
        models.join("m/2").display().to_string()
    );
    let registry = Registry::new(&models);
    let (v1, v2) = (
        registry.load("m", 1).unwrap(),
        registry.load("m", 2).unwrap(),
    );
    assert_eq!(v2.version, 2);
    assert_eq!(
        (&v2.classifier, &v2.no_white),
        (&v1.classifier, &v1.no_white)
    );
    assert_eq!(
        (&v2.prediction_sets, &v2.domain),
        (&v1.prediction_sets, &v1.domain)
    );
    let objects = v2.objects.as_ref().unwrap();
    assert_eq!(objects.training.as_ref().unwrap().images, 18);
    assert!(objects.prediction_sets.is_some() && objects.domain.is_some());
    // A manifest's first row, by column.
    let row = |manifest: &Path| {
        let text = std::fs::read_to_string(manifest).unwrap();
        let mut lines = text.lines().map(|l| l.split(',').map(String::from));
        let header = lines.next().unwrap();
        header
            .zip(lines.next().unwrap())
            .collect::<std::collections::HashMap<String, String>>()
    };
    let classify = |version: u32, args: &[&str]| {
        let model = models.join(format!("m/{version}"));
        let mut all = vec!["classify", "--model", model.to_str().unwrap(), "--json"];
        all.extend(args);
        let answer: serde_json::Value = serde_json::from_str(&run(&all)).unwrap();
        answer
    };
    // A sphere: version 2 answers exactly as version 1.
    let sphere = row(&spheres_csv);
    let image = spheres.join(&sphere["path"]);
    let mut sphere_args = vec![image.to_str().unwrap()];
    for (flag, column) in [
        ("--white", "white"),
        ("--cx", "cx"),
        ("--cy", "cy"),
        ("--r", "r"),
    ] {
        sphere_args.extend([flag, &sphere[column]]);
    }
    let (old, new) = (classify(1, &sphere_args), classify(2, &sphere_args));
    for field in ["probabilities", "prediction_set", "domain", "classifier"] {
        assert_eq!(old[field], new[field], "{field}");
    }
    assert_eq!(new["classifier"], "with_white");
    // An object by its normals: version 2's classifier for objects answers it.
    let object = row(&torus_csv);
    let (image, normals) = (torus.join(&object["path"]), torus.join(&object["normals"]));
    let answer = classify(
        2,
        &[
            image.to_str().unwrap(),
            "--white",
            &object["white"],
            "--normals",
            normals.to_str().unwrap(),
            "--all-features",
        ],
    );
    assert_eq!(answer["classifier"], "objects");
    let all = &answer["features"]["all"];
    let values: Vec<f64> = all["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let request = Request {
        white_given: true,
        object: true,
    };
    let expected = v2.head(request).classifier.predict_proba(&values).unwrap();
    let as_sphere = v1.classifier.predict_proba(&values).unwrap();
    let served = |label: &str| {
        let listed = answer["probabilities"].as_array().unwrap();
        let entry = listed.iter().find(|p| p["label"] == label).unwrap();
        entry["p"].as_f64().unwrap()
    };
    for (k, label) in v2.classifier.classes().iter().enumerate() {
        assert!((served(label) - expected[k]).abs() < 1e-12, "{label}");
    }
    let differs = expected
        .iter()
        .zip(&as_sphere)
        .any(|(a, b)| (a - b).abs() > 1e-6);
    assert!(differs, "{expected:?} {as_sphere:?}");

    // Retrained on the spheres, carrying version 2's classifier for objects: version 3 is
    // version 1's classifier (the same data and options) with version 2's heads.
    let retrain = |extra: &[&str]| train_hand6_log(&spheres_csv, &models, "m", extra);
    let v2_dir = models.join("m/2");
    let v2_dir = v2_dir.to_str().unwrap();
    // Another preprocessing cannot carry them, and nothing is published.
    let refused = retrain(&["--carry-from", v2_dir, "--saturation", "1.25"]);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains(
            "cannot carry its estimator and classifier for objects from m version 2: \
             its feature configuration differs"
        ),
        "{stderr}"
    );
    assert!(registry.load("m", 3).is_err());
    common::assert_success(&retrain(&["--carry-from", v2_dir]));
    let v3 = registry.load("m", 3).unwrap();
    assert_eq!(v3.objects, v2.objects);
    assert_eq!(
        (&v3.classifier, &v3.no_white),
        (&v1.classifier, &v1.no_white)
    );
    assert_eq!(
        v3.self_test.objects_probabilities,
        v2.self_test.objects_probabilities
    );
}

/// The shipped `ward6` version 2's estimator and classifier for objects carried into a copy of
/// it without them: the copy is version 2 again; a copy of another configuration refuses.
#[test]
fn the_estimator_and_the_objects_head_carry_exactly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shipped = Registry::new(root.join("models")).load("ward6", 2).unwrap();
    assert!(shipped.estimator.is_some() && shipped.objects.is_some());
    let mut bare = shipped.clone();
    (bare.estimator, bare.objects) = (None, None);
    bare.self_test.objects_probabilities = None;
    let mut other = bare.clone();
    train::carry_heads(&mut bare, &shipped).unwrap();
    assert_eq!(bare, shipped);
    other.features.config.saturation = Some(2.0);
    let refused = train::carry_heads(&mut other, &shipped).unwrap_err();
    assert!(
        refused
            .to_string()
            .ends_with("from ward6 version 2: its feature configuration differs"),
        "{refused}"
    );
    assert!(other.estimator.is_none() && other.objects.is_none());
}

/// `train --no-white-references-only` fits the classifier without white on the classes'
/// reference materials alone: as a model trained on the manifest without its members' rows.
#[test]
fn the_classifier_without_white_can_leave_the_members_out() {
    let dir = temp_dir("references");
    let (probes, _) = synthetic_probes_and_classes(&dir);
    let classes = dir.join("members.json");
    std::fs::write(
        &classes,
        r#"{"classes": [{"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
                        {"name": "dark", "rho_d": 0.1, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "dark", "member": "lacquer", "rho_d": 0.01, "rho_s": 0.04,
                         "alpha": 0.0, "ior": 1.5}]}"#,
    )
    .unwrap();
    let out = dir.join("spheres");
    render_spheres(&probes, &classes, &out);
    let manifest = out.join("manifest.csv");
    let text = std::fs::read_to_string(&manifest).unwrap();
    assert_eq!(
        text.lines().filter(|l| l.contains("dark+lacquer")).count(),
        3
    );
    let references = out.join("references.csv");
    let kept: Vec<&str> = text.lines().filter(|l| !l.contains('+')).collect();
    std::fs::write(&references, kept.join("\n") + "\n").unwrap();
    let models = dir.join("models");
    let train = |manifest: &Path, name: &str, extra: &[&str]| {
        common::assert_success(&train_hand6_log(manifest, &models, name, extra));
        Registry::new(&models).load(name, 1).unwrap()
    };
    let with_members = train(&manifest, "all", &[]);
    let without_members = train(&manifest, "refs", &["--no-white-references-only"]);
    let references_alone = train(&references, "alone", &[]);
    let no_white = |m: &ModelFile| m.no_white.clone().unwrap().classifier;
    assert_eq!(no_white(&without_members), no_white(&references_alone));
    assert_ne!(no_white(&without_members), no_white(&with_members));
    // The classifier with white still learns from the members.
    assert_eq!(without_members.classifier, with_members.classifier);
    assert_ne!(without_members.classifier, references_alone.classifier);
}

/// `classify` on the shipped default without naming it, a model by name from any folder
/// (found beside the binary's repository), and an unknown name that says where it looked.
#[test]
fn classify_finds_models_by_name() {
    let image = common::fixtures().join("features/sphere_rgb8.png");
    let elsewhere = temp_dir("by-name");
    let classify = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_reflectance"))
            .current_dir(&elsewhere)
            .env_remove("REFLECTANCE_MODELS")
            .arg("classify")
            .arg(&image)
            .args(common::README_SPHERE_FLAGS)
            .args(extra)
            .output()
            .unwrap()
    };
    for extra in [&[][..], &["--model", "ward6"], &["--model", "ward11"]] {
        let out = classify(extra);
        common::assert_success(&out);
        let text = String::from_utf8_lossy(&out.stdout);
        let name = extra.get(1).copied().unwrap_or("ward6");
        assert!(text.contains(&format!("model {name} version")), "{text}");
    }
    let out = classify(&["--model", "ward7"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no model \"ward7\" in models, "), "{err}");
    assert!(err.contains("REFLECTANCE_MODELS"), "{err}");
}
