//! `render --shard I/N`, `features --shard I/N` and `merge`: the parts of a sharded run join
//! into the unsharded run's files byte for byte; inconsistent parts and bad values are
//! refused.

use crate::common;
use crate::render::{run, temp_dir};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

/// Two of the shared light probes, listed by absolute path.
fn shared_probes(dir: &Path) -> PathBuf {
    let probes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/probes");
    let names =
        ["ict_grace.hdr", "debevec_beach.hdr"].map(|n| probes.join(n).display().to_string());
    let list = dir.join("probes.txt");
    std::fs::write(&list, names.join("\n")).unwrap();
    list
}

fn two_classes(dir: &Path) -> PathBuf {
    let path = dir.join("classes.json");
    std::fs::write(
        &path,
        r#"{"classes": [{"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
                        {"name": "shiny", "rho_d": 0.3, "rho_s": 0.1, "alpha": 0.02}]}"#,
    )
    .unwrap();
    path
}

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The parts `--shard I/4` writes beside `whole`.
fn parts(whole: &Path) -> Vec<PathBuf> {
    let (stem, extension) = text(whole).rsplit_once('.').unwrap();
    (0..4)
        .map(|i| PathBuf::from(format!("{stem}.shard-{i}-of-4.{extension}")))
        .collect()
}

fn merge(out: &Path, parts: &[PathBuf]) -> Output {
    let mut args = vec!["merge", "--out", text(out)];
    args.extend(parts.iter().map(|p| text(p)));
    run(&args)
}

/// Every file of a folder but the shard parts: name → bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| (e.file_name().into_string().unwrap(), e.path()))
        .filter(|(name, _)| !name.contains(".shard-"))
        .map(|(name, path)| (name, std::fs::read(path).unwrap()))
        .collect()
}

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/probes beside the repository"
)]
fn shards_merge_into_the_unsharded_render_and_feature_table() {
    let dir = temp_dir("shard");
    let (probes, classes) = (shared_probes(&dir), two_classes(&dir));
    // 2 probes × 2 turns × 2 classes + 1 synthetic map × 2 classes = 10 images, each with a
    // capture whose settings and noise are random draws.
    let render = |out: &Path, shard: Option<&str>| {
        let mut args = vec![
            "render",
            "--probes",
            text(&probes),
            "--classes",
            text(&classes),
        ];
        args.extend(["--out", text(out), "--size", "72", "--seed", "5"]);
        args.extend(["--rotations", "2", "--synthetic", "1", "--captures", "1"]);
        args.extend(shard.map(|s| ["--shard", s]).into_iter().flatten());
        let result = run(&args);
        common::assert_success(&result);
        result
    };
    let whole = dir.join("whole");
    render(&whole, None);
    let sharded = dir.join("sharded");
    let manifest_parts = parts(&sharded.join("manifest.csv"));
    for (i, part) in manifest_parts.iter().enumerate() {
        let result = render(&sharded, Some(&format!("{i}/4")));
        assert_eq!(String::from_utf8_lossy(&result.stdout).trim(), text(part));
        // Blocks [I·10/4, (I+1)·10/4): 2, 3, 2 and 3 images.
        let stderr = String::from_utf8_lossy(&result.stderr);
        let n = [2, 3, 2, 3][i];
        assert!(
            stderr.contains(&format!("rendered {n} of {n} images")),
            "{stderr}"
        );
    }
    assert!(!sharded.join("manifest.csv").exists());
    assert!(!sharded.join("captures.csv").exists());
    for file in ["manifest.csv", "captures.csv"] {
        common::assert_success(&merge(&sharded.join(file), &parts(&sharded.join(file))));
    }
    let (expected, got) = (files(&whole), files(&sharded));
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &expected {
        assert!(got[name] == *bytes, "{name} differs");
    }
    assert_eq!(expected.len(), 2 + 10 * 3, "{:?}", expected.keys());

    let manifest = whole.join("manifest.csv");
    let table = dir.join("features.csv");
    common::assert_success(&run(&[
        "features",
        "--manifest",
        text(&manifest),
        "--out",
        text(&table),
    ]));
    let shard_out = dir.join("shards").join("features.csv");
    std::fs::create_dir_all(shard_out.parent().unwrap()).unwrap();
    let table_parts = parts(&shard_out);
    for (i, part) in table_parts.iter().enumerate() {
        let shard = format!("{i}/4");
        let args = ["--manifest", text(&manifest), "--out", text(&shard_out)];
        let result = run(&[&["features", "--shard", &shard][..], &args].concat());
        common::assert_success(&result);
        assert_eq!(String::from_utf8_lossy(&result.stdout).trim(), text(part));
    }
    // The parts may be merged under another name.
    let merged = dir.join("merged.csv");
    // In any order.
    let shuffled = [3, 1, 0, 2].map(|i| table_parts[i].clone());
    common::assert_success(&merge(&merged, &shuffled));
    assert!(std::fs::read(&merged).unwrap() == std::fs::read(&table).unwrap());
}

#[test]
fn merge_refuses_missing_duplicate_and_mismatched_parts() {
    let dir = temp_dir("merge-bad");
    let write = |name: &str, content: &str| {
        let path = dir.join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, content).unwrap();
        path
    };
    let p0 = write("t.shard-0000-of-0003.csv", "a,b\n1,2\n");
    let p1 = write("t.shard-0001-of-0003.csv", "a,b\n3,\"x\ny\"\n");
    // A shard may have no rows (fewer items than shards).
    let p2 = write("t.shard-0002-of-0003.csv", "a,b\n");
    let again = write("again/t.shard-1-of-3.csv", "a,b\n3,4\n");
    let four = write("t.shard-0002-of-0004.csv", "a,b\n");
    let header = write("header/t.shard-0002-of-0003.csv", "a,c\n");
    let other = write("u.shard-0002-of-0003.csv", "a,b\n");
    let ragged = write("ragged/t.shard-0002-of-0003.csv", "a,b\n5\n");
    let whole = write("t.csv", "a,b\n");
    let out = dir.join("merged.csv");
    let cases: [(&[&PathBuf], &str); 8] = [
        (&[&p0, &p2], "missing shard(s) 1 of 3"),
        (&[&p0, &p1, &again, &p2], "shard 1 of 3 is given twice"),
        (&[&p0, &p1, &four], "one of 4 shards, but"),
        (&[&p0, &p1, &header], "the header differs from that of"),
        (&[&p0, &p1, &other], "a part of u.csv, but"),
        (&[&p0, &p1, &ragged], "ragged/t.shard-0002-of-0003.csv"),
        (&[&p0, &whole], "t.csv: not a shard part"),
        (&[&p0, &p0, &p1, &p2], "is given twice"),
    ];
    for (given, needle) in cases {
        let given: Vec<PathBuf> = given.iter().map(|p| p.to_path_buf()).collect();
        let result = merge(&out, &given);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{needle}: {stderr}");
        assert!(stderr.contains(needle), "{needle}: {stderr}");
        assert!(!out.exists(), "{needle}: wrote the output");
    }
    common::assert_success(&merge(&out, &[p2, p0, p1]));
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "a,b\n1,2\n3,\"x\ny\"\n"
    );
}

#[test]
fn bad_shard_values_name_the_flag() {
    let render = [
        "render",
        "--probes",
        "p",
        "--classes",
        "c.json",
        "--out",
        "o",
    ];
    let features = ["features", "--manifest", "m.csv", "--out", "f.csv"];
    for value in ["4/4", "0/0", "2", "x/4", "-1/4", "1/2/3"] {
        let flag = format!("--shard={value}");
        for command in [&render[..], &features[..]] {
            let result = run(&[command, &[flag.as_str()]].concat());
            let stderr = String::from_utf8_lossy(&result.stderr);
            assert_eq!(result.status.code(), Some(2), "{value}: {stderr}");
            assert!(stderr.contains("--shard"), "{value}: {stderr}");
        }
    }
    // Only a manifest is sharded.
    let result = run(&["features", "image.png", "--shard", "0/2"]);
    assert_eq!(result.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&result.stderr).contains("--manifest"));
}
