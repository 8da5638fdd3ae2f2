//! Model files and the registry: round trips, refusal of corrupt files, versions, activation,
//! and train → predict through the real binary.

use crate::common;

use reflectance::dataset::FeatureTable;
use reflectance::learn::{ClassifierKind, FeatureSet, TrainSpec};
use reflectance::model::registry::{Registry, RegistryError};
use reflectance::model::train::{TrainOptions, train};
use reflectance::model::{ModelError, ModelFile};
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
    let row = &reflectance::dataset::FeatureTable::read(&table)
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

#[test]
fn predict_rendered_spheres_with_a_trained_model() {
    use reflectance::image::decode::rgbe;
    use reflectance::render::envmap::EnvMap;
    let dir = temp_dir("predict");
    let bin = env!("CARGO_BIN_EXE_reflectance");
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
    let data = dir.join("data");
    let run = |args: &[&str]| {
        let out = Command::new(bin).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    run(&[
        "render",
        "--probes",
        probes.to_str().unwrap(),
        "--classes",
        classes.to_str().unwrap(),
        "--out",
        data.to_str().unwrap(),
        "--size",
        "96",
    ]);
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
    let extensions = radial.features.config.extensions();
    assert!(extensions.radial && extensions.log_domain);
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
