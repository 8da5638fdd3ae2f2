//! `reflectance report`: Tables 1 and 2, JSON and plots, on tiny rendered data sets.

use crate::common;

use reflectance_core::decode::rgbe;
use reflectance_render::envmap::EnvMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reflectance-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Four probes and two synthetic illuminations × three classes at 80 px: small enough for
/// every table cell.
fn render(dir: &Path) -> PathBuf {
    let probes = dir.join("probes");
    std::fs::create_dir_all(&probes).unwrap();
    for k in 0..4 {
        let f = k as f64;
        let map = EnvMap::from_fn(64, 32, move |d| {
            0.3 + (d.y + 0.2 * f).max(0.0) + 0.2 * ((5.0 + f) * d.x).sin()
        });
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
    let out = dir.join("render");
    let status = Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "render",
            "--probes",
            probes.to_str().unwrap(),
            "--classes",
            classes.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--size",
            "80",
            "--synthetic",
            "2",
        ])
        .status()
        .unwrap();
    assert!(status.success());
    out
}

#[test]
fn report_writes_both_tables_json_and_plots() {
    let dir = temp_dir("report");
    let rendered = render(&dir);
    let data = dir.join("data");
    for name in ["paper9_6", "paper9_11", "all_6", "all_11", "materials"] {
        let target = data.join(name);
        std::fs::create_dir_all(&target).unwrap();
        for entry in std::fs::read_dir(&rendered).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), target.join(entry.file_name())).unwrap();
        }
    }
    // The estimate's data set: the same renders, with the Ward parameters they were made of.
    std::fs::copy(
        dir.join("classes.json"),
        data.join("materials/materials.json"),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(["report", "--data", data.to_str().unwrap()])
        .output()
        .unwrap();
    common::assert_success(&out);
    let md = String::from_utf8(out.stdout).unwrap();
    assert!(
        md.contains("## Table 1") && md.contains("## Table 2"),
        "{md}"
    );
    for row in [
        "| chance | 33.3 | 33.3 | 33.3 | 33.3 |",
        "| mean1 |",
        "| hand6 |",
        "| auto6 |",
        "| pca6 |",
        "| knn5 | all |",
    ] {
        assert!(md.contains(row), "{row}\n{md}");
    }
    // The paper's hand6 figures appear beside ours.
    assert!(md.contains("(98.1)") && md.contains("(98.5)"), "{md}");
    let report_dir = data.join("report");
    assert_eq!(
        std::fs::read_to_string(report_dir.join("report.md")).unwrap(),
        md
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(report_dir.join("report.json")).unwrap()).unwrap();
    // Per data set: 6 Table 1 rows, 4 more Table 2 cells, 3 rows for each of our protocols.
    assert_eq!(json["cells"].as_array().unwrap().len(), 4 * (6 + 4 + 3 + 3));
    for row in [
        "| **hand6+log, augmented training views** |",
        "| **hand6, views + synthetic illuminations** |",
        "| **hand6+log+radial, views + synthetic illuminations** |",
    ] {
        assert!(md.contains(row), "{row}\n{md}");
    }
    for dataset in json["datasets"].as_array().unwrap() {
        assert_eq!(dataset["synthetic_rows"], 2 * 3);
        assert_eq!(dataset["rows"], (4 + 2) * 3);
    }
    // Known answers: a bright matte, a dark matte and a mirror differ in brightness alone,
    // so every classifier on every feature set that holds the mean tells them apart under
    // every held-out light (pca6 keeps whatever varies most, which need not be brightness).
    for cell in json["cells"].as_array().unwrap() {
        let (acc, correct) = (
            cell["accuracy"].as_f64().unwrap(),
            cell["correct"].as_u64().unwrap(),
        );
        assert_eq!(cell["n"], 12);
        assert_eq!(acc, correct as f64 / 12.0, "{cell}");
        let per_class: u64 = (cell["per_class"].as_array().unwrap().iter())
            .map(|c| c["correct"].as_u64().unwrap())
            .sum();
        assert_eq!(per_class, correct, "{cell}");
        if cell["features"] != "pca6" {
            assert_eq!(correct, 12, "{cell}");
        }
    }
    // The plots need DejaVu Sans; CI installs it and sets REFLECTANCE_REQUIRE_FONTS.
    let font = Path::new("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf").exists();
    assert!(
        font || std::env::var_os("REFLECTANCE_REQUIRE_FONTS").is_none(),
        "REFLECTANCE_REQUIRE_FONTS is set but DejaVu Sans is missing"
    );
    if font {
        for plot in [
            "confusion_all_11_hand6_paper.png",
            "confusion_paper9_6_hand6_log_augmented.png",
            "fig7_paper9_6.png",
            "fig7_all_6.png",
        ] {
            let img = image::open(report_dir.join(plot)).unwrap();
            assert!(img.width() > 200 && img.height() > 200, "{plot}");
        }
    }
    // The Ward-parameter estimate over the four probes' originals (synthetic maps left out).
    assert!(md.contains("## Beyond the paper"), "{md}");
    assert_eq!(json["estimate"]["n"], 12, "{}", json["estimate"]);
    assert_eq!(json["estimate"]["illuminations"], 4);
    // Totals of 0.8, 0.75 and 0.1: guessing their mean would be off by 0.3 on average, and a
    // mirror is told from a matte sphere every time.
    let mae = json["estimate"]["mae_total"].as_f64().unwrap();
    assert!(mae < 0.05, "{mae}");
    assert_eq!(json["estimate"]["mirror_accuracy"], 1.0);
    let estimate_md = std::fs::read_to_string(report_dir.join("estimate.md")).unwrap();
    assert!(
        estimate_md.contains("### Per illumination"),
        "{estimate_md}"
    );
    // Cached features are reused on a second run.
    assert!(data.join("all_6/features.csv").is_file());
}
