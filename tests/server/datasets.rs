//! Datasets over HTTP against the real router: an archive of labelled renders (some rows
//! without a circle, one image corrupt) is uploaded, located, listed, cross-validated and
//! trained on; names, limits, unusable archives and deletion while a job uses it.

use crate::admin::{TERMINAL, admin_server_with, authed, submit, wait_for};
use crate::common;

use axum::body::Body;
use axum::http::Request;
use common::server::{Part, TestServer, fixture, get, post_multipart, send};
use reflectance::ServerConfig as Config;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The fixture's 12 renders (3 classes under 4 probes) with a manifest of `rows`
/// (`path,class,illumination,cx,cy,r,white`, the circle left out of every third row), and
/// a file that is not an image listed too.
fn dataset_files(dir: &Path, lights: usize) -> (Vec<u8>, Vec<(String, PathBuf)>) {
    let mut manifest = String::from("path,class,illumination,cx,cy,r,white\n");
    let mut members = Vec::new();
    let mut rows = 0;
    for part in ["train", "test"] {
        let source = fixture().dir.join(part);
        let read = reflectance_core::dataset::read_manifest(&source.join("manifest.csv")).unwrap();
        for entry in read.entries {
            let light = entry.illumination.unwrap();
            let probe: usize = light.trim_start_matches("probe").parse().unwrap();
            if probe >= lights {
                continue;
            }
            let circle = entry.circle.unwrap();
            let circle = if rows % 3 == 0 {
                ",,".to_string()
            } else {
                format!("{},{},{}", circle.cx, circle.cy, circle.r)
            };
            let name = format!("{}/{}", light, entry.path);
            manifest.push_str(&format!(
                "{name},{},{light},{circle},{}\n",
                entry.class.unwrap(),
                entry.white.unwrap()
            ));
            members.push((name, entry.file));
            rows += 1;
        }
    }
    let junk = dir.join("notes.png");
    std::fs::write(&junk, b"not a png").unwrap();
    manifest.push_str("notes.png,matte,probe0,,,,\n");
    members.push(("notes.png".into(), junk));
    (manifest.into_bytes(), members)
}

fn archive(dir: &Path, lights: usize) -> Vec<u8> {
    std::fs::create_dir_all(dir).unwrap();
    let (manifest, members) = dataset_files(dir, lights);
    let path = dir.join("upload.tar.gz");
    reflectance::pack_archive(&manifest, &members, &path).unwrap();
    std::fs::read(path).unwrap()
}

async fn upload(server: &TestServer, name: &str, archive: &[u8]) -> common::server::Answer {
    let request = post_multipart(
        "/admin/v1/datasets",
        &[("name", Part::Text(name)), ("archive", Part::File(archive))],
    );
    send(&server.admin, authed(request)).await
}

fn delete(uri: &str) -> Request<Body> {
    authed(Request::delete(uri).body(Body::empty()).unwrap())
}

fn server(name: &str, tweak: impl FnOnce(&mut Config)) -> (TestServer, PathBuf) {
    admin_server_with(name, |cfg| {
        cfg.workers = 1;
        tweak(cfg);
    })
}

/// What the datasets folder holds besides the datasets: nothing once an upload ended.
fn leftovers(data: &Path) -> Vec<String> {
    let incoming = data.join("datasets/.incoming");
    std::fs::read_dir(incoming)
        .map(|d| {
            d.filter_map(|e| Some(e.ok()?.file_name().to_string_lossy().into_owned()))
                .collect()
        })
        .unwrap_or_default()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_uploaded_dataset_is_located_cross_validated_trained_on_and_deleted() {
    let (server, data) = server("datasets-flow", |_| {});
    let bytes = archive(&data.join("../upload"), 4);
    let answer = upload(&server, "spheres", &bytes).await;
    assert_eq!(
        answer.status,
        201,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    assert_eq!(
        answer.header("location"),
        Some("/admin/v1/datasets/spheres")
    );
    let info = answer.json();
    assert_eq!(info["dataset"], "datasets/spheres/manifest.csv");
    assert_eq!(
        (info["images"].as_u64(), info["located"].as_u64()),
        (Some(12), Some(4))
    );
    assert_eq!(info["classes"], json!(["chrome", "dark", "matte"]));
    assert_eq!(
        info["illuminations"],
        json!(["probe0", "probe1", "probe2", "probe3"])
    );
    let refused = info["refused"].as_array().unwrap();
    assert_eq!(refused.len(), 1, "{info}");
    assert_eq!(refused[0]["path"], "notes.png");
    assert!(
        refused[0]["reason"]
            .as_str()
            .unwrap()
            .contains("manifest line 14"),
        "{info}"
    );
    assert!(
        !data.join("datasets/spheres/notes.png").exists(),
        "refused files are not kept"
    );
    assert!(leftovers(&data).is_empty());

    // The circles found agree with the renderer's, and the stored manifest has them all.
    let detail = send(&server.admin, authed(get("/admin/v1/datasets/spheres"))).await;
    assert_eq!(detail.status, 200);
    let detail = detail.json();
    let rows = detail["manifest"].as_array().unwrap();
    assert_eq!(rows.len(), 12);
    for row in rows {
        let r = row["r"].as_f64().unwrap();
        assert!((r - 43.636).abs() < 0.05 * 43.636, "{row}");
        assert!((row["cx"].as_f64().unwrap() - 47.5).abs() < 1.0, "{row}");
    }
    let list = send(&server.admin, authed(get("/admin/v1/datasets")))
        .await
        .json();
    assert_eq!(list["datasets"][0]["name"], "spheres");
    upload(&server, "spheres", &bytes)
        .await
        .problem(409, "dataset-exists");

    // Leave-one-illumination-out on the upload, as on renders.
    let dataset = info["dataset"].as_str().unwrap();
    let cv = submit(
        &server,
        json!({"type": "cross_validate", "dataset": dataset}),
    )
    .await;
    let done = wait_for(&server, cv["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let result = &done["result"]["cv"];
    assert_eq!(result["n"], 12);
    let folds: Vec<&str> = result["folds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["illumination"].as_str().unwrap())
        .collect();
    assert_eq!(folds, ["probe0", "probe1", "probe2", "probe3"]);
    let confusion: u64 = result["confusion"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|row| row.as_array().unwrap().iter().map(|n| n.as_u64().unwrap()))
        .sum();
    assert_eq!(confusion, 12);
    // Chrome, a dark and a light matte under held-out light: told apart every time (12 of
    // 12, the confusion matrix diagonal).
    assert_eq!(result["accuracy"], 1.0, "{result}");
    assert_eq!(
        result["confusion"],
        json!([[4, 0, 0], [0, 4, 0], [0, 0, 4]])
    );
    let train = submit(
        &server,
        json!({"type": "train", "name": "mine", "dataset": dataset, "activate": "always"}),
    )
    .await;
    let done = wait_for(&server, train["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(
        done["result"]["model"],
        json!({"name": "mine", "version": 1})
    );
    // The model learned from the upload carries its own sets and domain calibration.
    let (image, _, _) = &fixture().held_out[0];
    let answer = send(
        &server.data,
        post_multipart("/v1/models/mine/classify", &[("image", Part::File(image))]),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let answer = answer.json();
    assert!(answer["prediction_set"].is_object(), "{answer}");
    assert!(answer["domain"]["score"].is_number(), "{answer}");

    // In use while a job waits for it (the single worker is busy rendering).
    let busy = submit(
        &server,
        json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": "renders/big", "size": 600}),
    )
    .await;
    let waiting = submit(
        &server,
        json!({"type": "cross_validate", "dataset": dataset}),
    )
    .await;
    let refused = send(&server.admin, delete("/admin/v1/datasets/spheres")).await;
    let problem = refused.problem(409, "dataset-in-use");
    assert!(
        problem["detail"]
            .as_str()
            .unwrap()
            .contains(waiting["id"].as_str().unwrap())
    );
    for job in [&waiting, &busy] {
        let id = job["id"].as_str().unwrap();
        let cancel = authed(common::server::post_json(
            &format!("/admin/v1/jobs/{id}/cancel"),
            &json!({}),
        ));
        send(&server.admin, cancel).await;
        wait_for(&server, id, TERMINAL).await;
    }
    let gone = send(&server.admin, delete("/admin/v1/datasets/spheres")).await;
    assert_eq!(gone.status, 204);
    assert!(!data.join("datasets/spheres").exists());
    send(&server.admin, authed(get("/admin/v1/datasets/spheres")))
        .await
        .problem(404, "dataset-not-found");
    send(&server.admin, delete("/admin/v1/datasets/spheres"))
        .await
        .problem(404, "dataset-not-found");
    assert!(leftovers(&data).is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploads_that_cannot_be_used_are_refused_whole_and_leave_nothing() {
    let limit = 200_000;
    let (server, data) = server("datasets-refused", |cfg| {
        cfg.datasets.archive_bytes = limit;
    });
    let dir = data.join("../upload");
    let full = archive(&dir.join("full"), 4);
    assert!(
        full.len() as u64 > limit,
        "the fixture archive must exceed the test limit"
    );
    let too_big = upload(&server, "big", &full)
        .await
        .problem(413, "archive-too-large");
    assert!(
        too_big["detail"]
            .as_str()
            .unwrap()
            .contains(&limit.to_string()),
        "{too_big}"
    );

    // Two probes only: every class under 2 illuminations.
    let two = archive(&dir.join("two"), 2);
    assert!(two.len() as u64 <= limit);
    let short = upload(&server, "two", &two)
        .await
        .problem(422, "unusable-dataset");
    let detail = short["detail"].as_str().unwrap();
    assert!(
        detail.contains("at least 3 illuminations") && detail.contains("chrome (2)"),
        "{detail}"
    );

    upload(&server, "junk", b"plain text, not an archive")
        .await
        .problem(422, "invalid-archive");
    let no_manifest = dir.join("nomanifest.tar");
    {
        let mut builder = tar::Builder::new(std::fs::File::create(&no_manifest).unwrap());
        let mut header = tar::Header::new_gnu();
        header.set_size(1);
        header.set_cksum();
        builder
            .append_data(&mut header, "a.png", &b"x"[..])
            .unwrap();
        builder.finish().unwrap();
    }
    let no_manifest = std::fs::read(no_manifest).unwrap();
    let missing = upload(&server, "nomanifest", &no_manifest)
        .await
        .problem(422, "unusable-dataset");
    assert!(missing["detail"].as_str().unwrap().contains("manifest.csv"));
    upload(&server, "Bad Name", &two)
        .await
        .problem(422, "invalid-field");
    let unnamed = post_multipart("/admin/v1/datasets", &[("archive", Part::File(&two))]);
    send(&server.admin, authed(unnamed))
        .await
        .problem(422, "missing-field");
    let extra = post_multipart(
        "/admin/v1/datasets",
        &[("name", Part::Text("x")), ("image", Part::File(&two))],
    );
    send(&server.admin, authed(extra))
        .await
        .problem(422, "unknown-field");
    let unauthorized = post_multipart("/admin/v1/datasets", &[("name", Part::Text("x"))]);
    send(&server.admin, unauthorized)
        .await
        .problem(401, "unauthorized");

    let list: Value = send(&server.admin, authed(get("/admin/v1/datasets")))
        .await
        .json();
    assert_eq!(list["datasets"], json!([]));
    assert!(leftovers(&data).is_empty(), "{:?}", leftovers(&data));
}

/// A tar of `manifest` at the root, `members` (archive path, file) and `links` (archive
/// path, target) as symbolic links.
fn tar_with_links(
    manifest: &[u8],
    members: &[(String, PathBuf)],
    links: &[(&str, &Path)],
) -> Vec<u8> {
    let mut builder = tar::Builder::new(Vec::new());
    let mut header = tar::Header::new_gnu();
    header.set_size(manifest.len() as u64);
    header.set_mode(0o644);
    header.set_cksum();
    builder
        .append_data(&mut header, "manifest.csv", manifest)
        .unwrap();
    for (name, file) in members {
        builder.append_path_with_name(file, name).unwrap();
    }
    for (name, target) in links {
        let mut header = tar::Header::new_gnu();
        header.set_entry_type(tar::EntryType::Symlink);
        header.set_size(0);
        header.set_mode(0o777);
        builder.append_link(&mut header, name, target).unwrap();
    }
    builder.into_inner().unwrap()
}

/// Manifest rows that leave the archive are refused by name, whatever the rest holds: an
/// absolute path to an image elsewhere on the server (one of the fixture's own files), a
/// path through `..` (to an image the archive does hold) and a path through a symbolic
/// link to a folder outside (the link itself refused as a member). Among usable rows the
/// upload keeps the 12 images of the archive, not 13 or more; alone, each is a 422 whose
/// detail names it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn manifest_rows_that_leave_the_archive_are_refused_by_name() {
    let (server, data) = server("datasets-escape", |_| {});
    let dir = data.join("../upload-escape");
    std::fs::create_dir_all(&dir).unwrap();
    let (manifest, members) = dataset_files(&dir, 4);
    let manifest = String::from_utf8(manifest).unwrap();
    // The first row with a circle: its fields after the path are reused.
    let row = manifest.lines().nth(2).unwrap();
    let (name, rest) = row.split_once(',').unwrap();
    let file = &members.iter().find(|(n, _)| n == name).unwrap().1;
    let absolute = std::fs::canonicalize(file).unwrap();
    let (light, base) = name.split_once('/').unwrap();
    let other = if light == "probe0" {
        "probe1"
    } else {
        "probe0"
    };
    let escapes = [
        (
            absolute.display().to_string(),
            "leaves the dataset's folder",
        ),
        (format!("{other}/../{name}"), "leaves the dataset's folder"),
        (format!("linked/{base}"), "no such image"),
    ];
    let folder = file.parent().unwrap();
    let links = [("linked", folder)];
    let mut all = manifest.clone();
    for (path, _) in &escapes {
        all.push_str(&format!("{path},{rest}\n"));
    }
    let bytes = tar_with_links(all.as_bytes(), &members, &links);
    let answer = upload(&server, "escapes", &bytes).await;
    assert_eq!(
        answer.status,
        201,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let info = answer.json();
    assert_eq!(info["images"], 12, "{info}");
    let refused = info["refused"].as_array().unwrap();
    let reason_of = |path: &str| {
        refused
            .iter()
            .find(|r| r["path"] == path)
            .map(|r| r["reason"].as_str().unwrap().to_string())
            .unwrap_or_else(|| panic!("{path} is not refused: {info}"))
    };
    for (path, why) in &escapes {
        assert!(reason_of(path).contains(why), "{path}: {info}");
    }
    assert!(
        reason_of("linked").contains("links are not accepted"),
        "{info}"
    );
    let detail = send(&server.admin, authed(get("/admin/v1/datasets/escapes")))
        .await
        .json();
    let kept = detail["manifest"].as_array().unwrap();
    assert_eq!(kept.len(), 12);
    assert!(
        kept.iter().all(|r| {
            let path = r["path"].as_str().unwrap();
            !path.starts_with('/') && !path.contains("..") && !path.starts_with("linked")
        }),
        "{detail}"
    );

    // Each alone: nothing usable, and the problem names it.
    for (k, (path, why)) in escapes.iter().enumerate() {
        let alone = format!("path,class,illumination,cx,cy,r,white\n{path},{rest}\n");
        let bytes = tar_with_links(alone.as_bytes(), &members, &links);
        let problem = upload(&server, &format!("alone{k}"), &bytes)
            .await
            .problem(422, "unusable-dataset");
        let detail = problem["detail"].as_str().unwrap();
        assert!(
            detail.contains(&format!("{path}: manifest line 2: ")) && detail.contains(why),
            "{detail}"
        );
    }
    assert!(leftovers(&data).is_empty(), "{:?}", leftovers(&data));
}
