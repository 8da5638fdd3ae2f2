//! The admin plane against the real router (in-process) and the real binary: auth, jobs
//! (render → train → activation changes what /v1/classify reports), cancellation, the
//! bounded queue, restarts, activation refusing a corrupt model, data-dir confinement.

use crate::common;

use axum::body::Body;
use axum::http::Request;
use common::server::{
    CLASSES_JSON, Part, TOKEN, TestServer, config, fixture, free_port, get, models_copy, post_json,
    post_multipart, send, start, temp_dir, with_token, write_probes,
};
use reflectance::ServerConfig as Config;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A data directory with four probes and the class file.
pub(crate) fn data_dir(name: &str) -> PathBuf {
    let dir = temp_dir(name).join("data");
    write_probes(&dir.join("probes"));
    std::fs::write(dir.join("classes.json"), CLASSES_JSON).unwrap();
    dir
}

fn admin_server(name: &str, workers: usize, queue: usize) -> (TestServer, PathBuf) {
    admin_server_with(name, |cfg| {
        cfg.workers = workers;
        cfg.job_queue = queue;
    })
}

pub(crate) fn admin_server_with(
    name: &str,
    tweak: impl FnOnce(&mut Config),
) -> (TestServer, PathBuf) {
    let data = data_dir(name);
    let mut cfg = config(&models_copy(&format!("{name}-models")));
    cfg.admin_token = Some(TOKEN.into());
    cfg.jobs_dir = data.join("jobs");
    cfg.data_dir = data.clone();
    tweak(&mut cfg);
    (start(cfg), data)
}

pub(crate) fn authed(request: Request<Body>) -> Request<Body> {
    with_token(request, TOKEN)
}

pub(crate) async fn submit(server: &TestServer, job: Value) -> Value {
    let answer = send(&server.admin, authed(post_json("/admin/v1/jobs", &job))).await;
    assert_eq!(
        answer.status,
        202,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let doc = answer.json();
    let id = doc["id"].as_str().unwrap();
    assert_eq!(
        answer.header("location"),
        Some(format!("/admin/v1/jobs/{id}").as_str())
    );
    assert_eq!(doc["state"], "queued");
    doc
}

async fn job(server: &TestServer, id: &str) -> Value {
    let answer = send(&server.admin, authed(get(&format!("/admin/v1/jobs/{id}")))).await;
    assert_eq!(answer.status, 200);
    answer.json()
}

/// Poll until the job is in one of `states`.
pub(crate) async fn wait_for(server: &TestServer, id: &str, states: &[&str]) -> Value {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let doc = job(server, id).await;
        if states.contains(&doc["state"].as_str().unwrap()) {
            return doc;
        }
        assert!(Instant::now() < deadline, "job stuck: {doc}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

pub(crate) const TERMINAL: &[&str] = &["succeeded", "failed", "cancelled"];

async fn classified_version(server: &TestServer) -> String {
    let (image, _, white) = &fixture().held_out[0];
    let white = white.to_string();
    let answer = send(
        &server.data,
        post_multipart(
            "/v1/classify",
            &[
                ("image", Part::File(image)),
                ("white", Part::Text(&white)),
                ("cx", Part::Text("47.5")),
                ("cy", Part::Text("47.5")),
                ("r", Part::Text("43.63636363636363")),
            ],
        ),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    let version = answer.header("x-model-version").unwrap().to_string();
    assert_eq!(answer.json()["model"]["version"].to_string(), version);
    version
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn admin_requires_the_bearer_token() {
    let (server, _) = admin_server("auth", 1, 4);
    for request in [
        get("/admin/v1/jobs"),
        with_token(get("/admin/v1/jobs"), "wrong-token-0123456789abcdef"),
        with_token(get("/admin/v1/jobs"), &TOKEN[..TOKEN.len() - 1]),
        post_json("/admin/v1/jobs", &json!({"type": "render"})),
        get("/admin/v1/models/ward6/versions"),
    ] {
        let answer = send(&server.admin, request).await;
        answer.problem(401, "unauthorized");
        assert_eq!(answer.header("www-authenticate"), Some("Bearer"));
    }
    let mut basic = get("/admin/v1/jobs");
    basic
        .headers_mut()
        .insert("authorization", format!("Basic {TOKEN}").parse().unwrap());
    send(&server.admin, basic)
        .await
        .problem(401, "unauthorized");
    let answer = send(&server.admin, authed(get("/admin/v1/jobs"))).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.json(), json!({"jobs": []}));
    // The admin routes are not on the data plane.
    send(&server.data, authed(get("/admin/v1/jobs")))
        .await
        .problem(404, "not-found");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn render_train_activate_roll_back_and_delete() {
    let (server, data) = admin_server("train", 1, 4);
    assert_eq!(classified_version(&server).await, "1");

    // Render a dataset into the data directory.
    let render = submit(
        &server,
        json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": "renders/r96", "size": 96}),
    )
    .await;
    let done = wait_for(&server, render["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(
        done["result"]["render"]["manifest"],
        "renders/r96/manifest.csv"
    );
    assert_eq!(done["result"]["render"]["images"], 12);
    assert_eq!(
        done["progress"],
        json!({"stage": "done", "done": 12, "total": 12})
    );
    assert!(data.join("renders/r96/probe3__chrome.pfm").is_file());

    // Train on it (features are extracted by the job) and activate.
    let train = submit(
        &server,
        json!({"type": "train", "name": "ward6", "dataset": "renders/r96/manifest.csv",
               "features": "hand6", "activate": "always", "seed": 3}),
    )
    .await;
    assert_eq!(
        train["request"]["classifier"], "svm",
        "defaults filled in: {train}"
    );
    let done = wait_for(&server, train["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let progress = &done["progress"];
    assert_eq!(progress["stage"], "done", "{done}");
    assert!(
        progress["total"].as_u64() > Some(0) && progress["done"] == progress["total"],
        "a finished job shows its work complete: {done}"
    );
    let result = &done["result"];
    assert_eq!(result["model"], json!({"name": "ward6", "version": 2}));
    assert_eq!(result["activated"], true);
    assert_eq!(result["images"], 12);
    let cv = &result["cv"];
    assert_eq!(cv["n"], 12);
    assert_eq!(cv["folds"].as_array().unwrap().len(), 4);
    assert_eq!(cv["confusion"].as_array().unwrap().len(), 3);
    assert!(done["started"].is_string() && done["finished"].is_string());
    assert!(
        data.join("jobs")
            .join(format!("{}.json", done["id"].as_str().unwrap()))
            .is_file()
    );

    // Activation changed what classification reports.
    assert_eq!(classified_version(&server).await, "2");
    let versions = send(
        &server.admin,
        authed(get("/admin/v1/models/ward6/versions")),
    )
    .await
    .json();
    assert_eq!(versions["active"], 2);
    assert_eq!(versions["versions"].as_array().unwrap().len(), 2);
    assert!(versions["versions"][1]["cv_accuracy"].is_number());

    // The same training again is not better: if_better keeps version 2 (the classifier
    // without white of a hand6 model does not exist, so leaving members out of it is moot).
    let again = submit(
        &server,
        json!({"type": "train", "name": "ward6", "dataset": "renders/r96/manifest.csv",
               "activate": "if_better", "seed": 3, "no_white_references_only": true}),
    )
    .await;
    let done = wait_for(&server, again["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"]["model"]["version"], 3);
    assert_eq!(done["result"]["activated"], false, "{done}");
    assert_eq!(classified_version(&server).await, "2");
    // Publishing did not make version 3 the registry's active version.
    let registry =
        reflectance_core::model::registry::Registry::new(server.state.config.models.clone());
    assert_eq!(registry.active("ward6").unwrap(), 2);

    // Roll back, and delete.
    let answer = send(
        &server.admin,
        authed(post_json(
            "/admin/v1/models/ward6/versions/1/activate",
            &json!({}),
        )),
    )
    .await;
    assert_eq!(
        answer.status,
        200,
        "{}",
        String::from_utf8_lossy(&answer.body)
    );
    assert_eq!(
        answer.json(),
        json!({"name": "ward6", "version": 1, "previous": 2, "persisted": true})
    );
    assert_eq!(classified_version(&server).await, "1");
    assert_eq!(registry.active("ward6").unwrap(), 1);
    let delete = |v: &str| {
        authed(
            Request::delete(format!("/admin/v1/models/ward6/versions/{v}"))
                .body(Body::empty())
                .unwrap(),
        )
    };
    send(&server.admin, delete("1"))
        .await
        .problem(409, "version-active");
    assert_eq!(send(&server.admin, delete("3")).await.status, 204);
    send(&server.admin, delete("3"))
        .await
        .problem(404, "version-not-found");
    send(&server.admin, delete("x"))
        .await
        .problem(404, "version-not-found");
    let activate = |v: &str| {
        authed(post_json(
            &format!("/admin/v1/models/ward6/versions/{v}/activate"),
            &json!({}),
        ))
    };
    send(&server.admin, activate("9"))
        .await
        .problem(404, "version-not-found");
    send(&server.admin, activate("-1"))
        .await
        .problem(404, "version-not-found");
    send(
        &server.admin,
        authed(post_json(
            "/admin/v1/models/nope/versions/1/activate",
            &json!({}),
        )),
    )
    .await
    .problem(404, "model-not-found");

    // Cross-validation on a feature table.
    let table = fixture().dir.join("table.csv");
    let extractor = reflectance_core::features::Extractor::new(Default::default()).unwrap();
    let manifest =
        reflectance_core::dataset::read_manifest(&data.join("renders/r96/manifest.csv")).unwrap();
    reflectance_core::dataset::extract_manifest(&extractor, &manifest, &Default::default())
        .unwrap()
        .write(&data.join("table.csv"))
        .unwrap();
    let _ = table;
    let cv = submit(
        &server,
        json!({"type": "cross_validate", "table": "table.csv", "classifier": "nn"}),
    )
    .await;
    let done = wait_for(&server, cv["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"]["cv"]["classifier"], "nn");
    assert!(done["result"].get("model").is_none());

    // The Ward-parameter estimate, cross-validated the same way.
    let estimate = submit(
        &server,
        json!({"type": "cross_validate", "table": "table.csv", "ward_classes": "classes.json"}),
    )
    .await;
    let done = wait_for(&server, estimate["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let report = &done["result"]["estimate"];
    assert_eq!(report["n"], done["result"]["images"], "{done}");
    // The same figures as the command line's estimate on the same table, to the bit.
    let cli = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(["cv", "--features", "hand6", "--table"])
        .arg(data.join("table.csv"))
        .args(["--estimate", "--ward-classes"])
        .arg(data.join("classes.json"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        cli.status.success(),
        "{}",
        String::from_utf8_lossy(&cli.stderr)
    );
    let cli: Value = serde_json::from_slice(&cli.stdout).unwrap();
    assert_eq!(
        report, &cli,
        "the job's estimate against the command line's"
    );
    assert!(
        report["half_widths"]["rho_d"].as_f64().unwrap() > 0.0,
        "{done}"
    );
    assert!(done["result"].get("cv").is_none());
    // The regression's options are the command line's, with the same figures.
    let ridge = submit(
        &server,
        json!({"type": "cross_validate", "table": "table.csv", "ward_classes": "classes.json",
               "regressor": "ridge", "ridge_features": 40, "ridge_lambda": 0.1}),
    )
    .await;
    let done = wait_for(&server, ridge["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let cli = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(["cv", "--features", "hand6", "--table"])
        .arg(data.join("table.csv"))
        .args(["--estimate", "--ward-classes"])
        .arg(data.join("classes.json"))
        .args([
            "--regressor",
            "ridge",
            "--ridge-features",
            "40",
            "--ridge-lambda",
            "0.1",
        ])
        .arg("--json")
        .output()
        .unwrap();
    let cli: Value = serde_json::from_slice(&cli.stdout).unwrap();
    assert_eq!(done["result"]["estimate"], cli);
    assert_ne!(
        done["result"]["estimate"], *report,
        "the ridge is not the trees"
    );
    for bad in [
        json!({"type": "cross_validate", "table": "table.csv", "ward_classes": "classes.json",
               "ridge_lambda": 0}),
        json!({"type": "train", "name": "ward6", "table": "table.csv",
               "estimator_features": "hand6"}),
        json!({"type": "train", "name": "ward6", "table": "table.csv",
               "estimator_table": "table.csv", "estimator_classes": "classes.json",
               "estimator_features": "hand7"}),
    ] {
        send(&server.admin, authed(post_json("/admin/v1/jobs", &bad)))
            .await
            .problem(422, "invalid-job");
    }
    let missing =
        json!({"type": "cross_validate", "table": "table.csv", "ward_classes": "none.json"});
    send(&server.admin, authed(post_json("/admin/v1/jobs", &missing)))
        .await
        .problem(422, "invalid-path");

    // A model trained with an estimator beside its classifier.
    let with_estimator = submit(
        &server,
        json!({"type": "train", "name": "ward6", "table": "table.csv", "activate": "never",
               "cross_validate": false, "estimator_table": "table.csv",
               "estimator_classes": "classes.json"}),
    )
    .await;
    let done = wait_for(&server, with_estimator["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"]["estimate"]["n"], done["result"]["images"]);
    assert!(
        done["result"]["model"]["version"].as_u64().is_some(),
        "{done}"
    );
    let half = json!({"type": "train", "name": "ward6", "table": "table.csv",
                      "estimator_table": "table.csv"});
    let refused = send(&server.admin, authed(post_json("/admin/v1/jobs", &half))).await;
    refused.problem(422, "invalid-job");
    assert!(
        refused.json()["detail"]
            .as_str()
            .unwrap()
            .contains("both or neither")
    );

    // Extraction extensions: log-domain and radial features named by the set, a working radius.
    let log = submit(
        &server,
        json!({"type": "cross_validate", "dataset": "renders/r96/manifest.csv",
               "features": "hand6+log+radial", "working_radius": 40}),
    )
    .await;
    let done = wait_for(&server, log["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"]["cv"]["features"], "hand6+log+radial");
    let bad = json!({"type": "cross_validate", "dataset": "renders/r96/manifest.csv", "working_radius": 3});
    send(&server.admin, authed(post_json("/admin/v1/jobs", &bad)))
        .await
        .problem(422, "invalid-job");

    let list = send(&server.admin, authed(get("/admin/v1/jobs?state=succeeded")))
        .await
        .json();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 8);
    assert_eq!(list["jobs"][0]["id"], log["id"], "newest first");
    let list = send(&server.admin, authed(get("/admin/v1/jobs?state=failed")))
        .await
        .json();
    assert_eq!(list["jobs"], json!([]));
    send(&server.admin, authed(get("/admin/v1/jobs?state=bogus")))
        .await
        .problem(422, "invalid-field");
    send(&server.admin, authed(get("/admin/v1/jobs/nope")))
        .await
        .problem(404, "job-not-found");
}

/// A render slow enough to observe and cancel (12 images of 384 px).
fn slow_render(out: &str) -> Value {
    json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": out, "size": 384})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancellation_and_the_bounded_queue() {
    let (server, _) = admin_server("cancel", 1, 1);
    let a = submit(&server, slow_render("slow/a")).await;
    let a_id = a["id"].as_str().unwrap();
    let running = wait_for(&server, a_id, &["running"]).await;
    let stage = running["progress"]["stage"].as_str().unwrap();
    assert!(["starting", "render"].contains(&stage), "{running}");
    // One waiting job fills the queue; the next is refused.
    let b = submit(&server, slow_render("slow/b")).await;
    let full = send(
        &server.admin,
        authed(post_json("/admin/v1/jobs", &slow_render("slow/c"))),
    )
    .await;
    full.problem(429, "job-queue-full");
    assert!(full.header("retry-after").is_some());

    // A queued job is cancelled at once.
    let b_id = b["id"].as_str().unwrap();
    let cancel = |id: &str| {
        authed(post_json(
            &format!("/admin/v1/jobs/{id}/cancel"),
            &json!({}),
        ))
    };
    let answer = send(&server.admin, cancel(b_id)).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.json()["state"], "cancelled");
    // A running one stops between images.
    let answer = send(&server.admin, cancel(a_id)).await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.json()["cancel_requested"], true);
    let done = wait_for(&server, a_id, TERMINAL).await;
    assert_eq!(done["state"], "cancelled", "{done}");
    assert!(done["progress"]["done"].as_u64().unwrap() < 12, "{done}");
    send(&server.admin, cancel(a_id))
        .await
        .problem(409, "job-finished");
    send(&server.admin, cancel("nope"))
        .await
        .problem(404, "job-not-found");
    // The worker is free again.
    let c = submit(&server, json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": "small", "size": 72})).await;
    let done = wait_for(&server, c["id"].as_str().unwrap(), TERMINAL).await;
    assert_eq!(done["state"], "succeeded", "{done}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn finished_jobs_beyond_the_history_are_forgotten() {
    let (server, data) = admin_server_with("history", |cfg| {
        cfg.workers = 1;
        cfg.job_queue = 4;
        cfg.job_history = 2;
    });
    let id = |doc: &Value| doc["id"].as_str().unwrap().to_string();
    let running = id(&submit(&server, slow_render("slow/h")).await);
    wait_for(&server, &running, &["running"]).await;
    let mut queued = Vec::new();
    for k in 0..3 {
        queued.push(id(
            &submit(&server, slow_render(&format!("slow/q{k}"))).await
        ));
    }
    let cancel = |id: &str| {
        authed(post_json(
            &format!("/admin/v1/jobs/{id}/cancel"),
            &json!({}),
        ))
    };
    for q in &queued {
        assert_eq!(send(&server.admin, cancel(q)).await.status, 200);
    }
    let status = |id: &str| {
        let server = &server;
        let id = id.to_string();
        async move {
            send(&server.admin, authed(get(&format!("/admin/v1/jobs/{id}"))))
                .await
                .status
        }
    };
    let file = |id: &str| data.join("jobs").join(format!("{id}.json"));
    // Three finished, two kept: the first cancelled is forgotten, in memory and on disk.
    assert_eq!(status(&queued[0]).await, 404);
    assert!(!file(&queued[0]).exists());
    assert_eq!(status(&queued[1]).await, 200);
    assert_eq!(status(&queued[2]).await, 200);
    // The running job finishes last, so the next oldest finish goes.
    assert_eq!(send(&server.admin, cancel(&running)).await.status, 200);
    wait_for(&server, &running, TERMINAL).await;
    assert_eq!(status(&queued[1]).await, 404);
    assert!(!file(&queued[1]).exists());
    assert!(file(&queued[2]).exists() && file(&running).exists());
    let list = send(&server.admin, authed(get("/admin/v1/jobs")))
        .await
        .json();
    let ids: Vec<&str> = list["jobs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids.len(), 2, "{list}");
    assert!(ids.contains(&queued[2].as_str()) && ids.contains(&running.as_str()));

    // A restart with a shorter history forgets the excess at once.
    drop(server);
    let mut cfg = config(&models_copy("history-restart-models"));
    cfg.admin_token = Some(TOKEN.into());
    cfg.jobs_dir = data.join("jobs");
    cfg.data_dir = data.clone();
    cfg.job_history = 1;
    let again = start(cfg);
    let list = send(&again.admin, authed(get("/admin/v1/jobs")))
        .await
        .json();
    assert_eq!(list["jobs"].as_array().unwrap().len(), 1, "{list}");
    let records = std::fs::read_dir(data.join("jobs"))
        .unwrap()
        .filter(|e| {
            let path = e.as_ref().unwrap().path();
            path.extension().is_some_and(|x| x == "json")
        })
        .count();
    assert_eq!(records, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn job_paths_and_parameters_are_checked() {
    let (server, data) = admin_server("paths", 1, 4);
    let outside = data.parent().unwrap().join("secret.csv");
    std::fs::write(&outside, "path,class,illumination\n").unwrap();
    std::os::unix::fs::symlink(&outside, data.join("link.csv")).unwrap();
    std::os::unix::fs::symlink(data.parent().unwrap(), data.join("up")).unwrap();
    for dataset in [
        "../secret.csv",
        "/etc/passwd",
        "http://example.com/m.csv",
        "file:///etc/passwd",
        "link.csv",
        "up/secret.csv",
        "missing.csv",
        "",
    ] {
        let answer = send(
            &server.admin,
            authed(post_json(
                "/admin/v1/jobs",
                &json!({"type": "train", "name": "x", "dataset": dataset}),
            )),
        )
        .await;
        answer.problem(422, "invalid-path");
    }
    // A manifest inside the data directory whose rows point outside it fails the job.
    std::fs::write(
        data.join("evil.csv"),
        "path,class,illumination\n../secret.csv,a,b\n",
    )
    .unwrap();
    // So does one whose normal map or mask lies outside it.
    std::fs::write(data.join("in.png"), b"not read").unwrap();
    std::fs::write(
        data.join("evil_normals.csv"),
        "path,class,illumination,normals\nin.png,a,b,../secret.csv\n",
    )
    .unwrap();
    std::fs::write(
        data.join("evil_mask.csv"),
        "path,class,illumination,mask\nin.png,a,b,/etc/passwd\n",
    )
    .unwrap();
    for (manifest, what) in [
        ("evil.csv", "image"),
        ("evil_normals.csv", "normals"),
        ("evil_mask.csv", "mask"),
    ] {
        let evil = submit(
            &server,
            json!({"type": "cross_validate", "dataset": manifest}),
        )
        .await;
        let done = wait_for(&server, evil["id"].as_str().unwrap(), TERMINAL).await;
        assert_eq!(done["state"], "failed");
        let error = done["error"].as_str().unwrap();
        assert!(
            error.contains("outside the data directory")
                && error.contains(&format!("manifest line 2 {what}")),
            "{done}"
        );
    }
    for out in ["../out", "up/out", "/tmp/out"] {
        let job =
            json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": out});
        send(&server.admin, authed(post_json("/admin/v1/jobs", &job)))
            .await
            .problem(422, "invalid-path");
    }
    std::fs::write(data.join("m.csv"), "path,class,illumination\n").unwrap();
    for (job, slug) in [
        (
            json!({"type": "train", "name": "Bad Name", "dataset": "m.csv"}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "activte": "always"}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "features": "auto0"}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "classifier": "tree"}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "c": -1}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "table": "m.csv"}),
            "invalid-job",
        ),
        (json!({"type": "train", "name": "x"}), "invalid-job"),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "activate": "if_better", "cross_validate": false}),
            "invalid-job",
        ),
        (
            json!({"type": "train", "name": "x", "dataset": "m.csv", "activate": "sometimes"}),
            "invalid-job",
        ),
        (
            json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": "o", "size": 8}),
            "invalid-job",
        ),
        (json!({"type": "bake"}), "invalid-job"),
        (json!([1, 2]), "invalid-job"),
    ] {
        send(&server.admin, authed(post_json("/admin/v1/jobs", &job)))
            .await
            .problem(422, slug);
    }
    let not_json = Request::post("/admin/v1/jobs")
        .header("content-type", "application/json")
        .body(Body::from("{"))
        .unwrap();
    send(&server.admin, authed(not_json))
        .await
        .problem(400, "malformed-request");
    let no_type = Request::post("/admin/v1/jobs")
        .body(Body::from("{}"))
        .unwrap();
    send(&server.admin, authed(no_type))
        .await
        .problem(415, "unsupported-media-type");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_version_is_refused_and_the_old_one_keeps_serving() {
    let (server, _) = admin_server("corrupt", 1, 4);
    let models = server.state.config.models.clone();
    // Version 2: a copy of version 1 with one byte of a number changed.
    let text = std::fs::read_to_string(models.join("ward6/1/model.json")).unwrap();
    std::fs::create_dir_all(models.join("ward6/2")).unwrap();
    let at = text.find("\"version\":1").unwrap();
    let mut fixed = text.clone();
    fixed.replace_range(at..at + 11, "\"version\":2");
    let k = fixed.find("\"scaler\"").unwrap() + 40;
    let digit = fixed[k..].find(|c: char| c.is_ascii_digit()).unwrap() + k;
    let d = fixed.as_bytes()[digit];
    let replacement = if d == b'9' { "8" } else { "9" };
    fixed.replace_range(digit..digit + 1, replacement);
    std::fs::write(models.join("ward6/2/model.json"), fixed).unwrap();
    let failures = || {
        let text = reflectance::metrics_text();
        text.lines()
            .find(|l| l.starts_with("reflectance_model_load_failures_total{model=\"ward6\"}"))
            .and_then(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    let before = failures();
    let answer = send(
        &server.admin,
        authed(post_json(
            "/admin/v1/models/ward6/versions/2/activate",
            &json!({}),
        )),
    )
    .await;
    let doc = answer.problem(422, "invalid-model");
    assert!(
        doc["detail"].as_str().unwrap().contains("checksum"),
        "{doc}"
    );
    assert_eq!(failures(), before + 1.0);
    assert_eq!(classified_version(&server).await, "1");
    let versions = send(
        &server.admin,
        authed(get("/admin/v1/models/ward6/versions")),
    )
    .await
    .json();
    assert_eq!(versions["active"], 1);
    assert_eq!(versions["versions"][1]["valid"], false);
    assert!(
        versions["versions"][1]["error"]
            .as_str()
            .unwrap()
            .contains("checksum")
    );
    // A specific version that does not load is refused on the data plane too.
    let (image, _, white) = &fixture().held_out[0];
    let white = white.to_string();
    let answer = send(
        &server.data,
        post_multipart(
            "/v1/models/ward6/classify?version=2",
            &[("image", Part::File(image)), ("white", Part::Text(&white))],
        ),
    )
    .await;
    answer.problem(422, "invalid-model");
}

// ---- the real binary: start-up checks, restart after a crash, graceful shutdown ----

/// One HTTP/1.1 exchange over a fresh connection: (status, body).
fn http(port: u16, method: &str, path: &str, body: Option<&Value>) -> Option<(u16, Value)> {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .ok()?;
    let payload = body
        .map(|b| serde_json::to_vec(b).unwrap())
        .unwrap_or_default();
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        payload.len()
    )
    .ok()?;
    stream.write_all(&payload).ok()?;
    let mut text = String::new();
    stream.read_to_string(&mut text).ok()?;
    let status = text.split_whitespace().nth(1)?.parse().ok()?;
    let body = text.split_once("\r\n\r\n")?.1;
    Some((status, serde_json::from_str(body).unwrap_or(Value::Null)))
}

struct Process(std::process::Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn(models: &Path, data: &Path, port: u16, admin_port: u16) -> Process {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "serve",
            "--models",
            models.to_str().unwrap(),
            "--default-model",
            "ward6",
        ])
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(["--admin-listen", &format!("127.0.0.1:{admin_port}")])
        .args(["--data-dir", data.to_str().unwrap(), "--log-format", "json"])
        .env("REFLECTANCE_ADMIN_TOKEN", TOKEN)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let process = Process(child);
    let deadline = Instant::now() + Duration::from_secs(30);
    while http(port, "GET", "/health/ready", None).map(|(s, _)| s) != Some(200) {
        assert!(Instant::now() < deadline, "server did not become ready");
        std::thread::sleep(Duration::from_millis(20));
    }
    process
}

#[test]
fn a_job_interrupted_by_a_restart_is_failed_and_sigterm_stops_cleanly() {
    let data = data_dir("restart");
    let models = models_copy("restart-models");
    let (port, admin_port) = (free_port(), free_port());
    let first = spawn(&models, &data, port, admin_port);
    let (status, doc) = http(
        admin_port,
        "POST",
        "/admin/v1/jobs",
        Some(&slow_render("slow")),
    )
    .unwrap();
    assert_eq!(status, 202, "{doc}");
    let id = doc["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let (_, doc) = http(admin_port, "GET", &format!("/admin/v1/jobs/{id}"), None).unwrap();
        if doc["state"] == "running" {
            break;
        }
        assert!(Instant::now() < deadline, "{doc}");
        std::thread::sleep(Duration::from_millis(20));
    }
    drop(first); // SIGKILL: the job never finishes.

    let second = spawn(&models, &data, port, admin_port);
    let (status, doc) = http(admin_port, "GET", &format!("/admin/v1/jobs/{id}"), None).unwrap();
    assert_eq!(status, 200);
    assert_eq!(doc["state"], "failed", "{doc}");
    assert_eq!(doc["error"], "interrupted");

    // The container health check: 0 when ready, non-zero when nothing answers.
    let bin = env!("CARGO_BIN_EXE_reflectance");
    let check = |addr: String| {
        std::process::Command::new(bin)
            .args(["healthcheck", "--addr", &addr])
            .output()
            .unwrap()
            .status
            .success()
    };
    assert!(check(format!("127.0.0.1:{port}")));
    assert!(!check(format!("127.0.0.1:{}", free_port())));
    // Without --addr it checks where `serve` listens (REFLECTANCE_LISTEN), on loopback.
    let from_listen = |listen: String| {
        std::process::Command::new(bin)
            .arg("healthcheck")
            .env("REFLECTANCE_LISTEN", listen)
            .env_remove("REFLECTANCE_HEALTHCHECK_ADDR")
            .output()
            .unwrap()
            .status
            .success()
    };
    assert!(from_listen(format!("0.0.0.0:{port}")));
    assert!(!from_listen(format!("0.0.0.0:{}", free_port())));

    // SIGTERM: readiness goes away, the process exits 0.
    let mut second = second;
    let pid = second.0.id().to_string();
    assert!(
        std::process::Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .unwrap()
            .success()
    );
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = second.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "no exit after SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}");
}

#[test]
fn refuses_a_public_admin_address_without_a_token() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "serve",
            "--models",
            concat!(env!("CARGO_MANIFEST_DIR"), "/models"),
            "--admin-listen",
            "0.0.0.0:0",
        ])
        .env_remove("REFLECTANCE_ADMIN_TOKEN")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("not a loopback address"), "{stderr}");
    // A folder that does not exist, or holds no default model, stops the server with a
    // reason before it claims to listen.
    let empty = temp_dir("no_default_model");
    let empty = empty.to_str().unwrap();
    for (folder, reason) in [
        ("nowhere", "there is no model folder nowhere"),
        (empty, "default model \"ward6\""),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
            .args(["serve", "--models", folder, "--listen"])
            .arg(format!("127.0.0.1:{}", free_port()))
            .env_remove("REFLECTANCE_ADMIN_TOKEN")
            .output()
            .unwrap();
        assert!(!out.status.success());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(reason), "{stderr}");
        assert!(!stderr.contains("listening"), "{stderr}");
    }
}

/// A train job's progress as server-sent events: its real stages with their units (the
/// classifier's calibration folds, the prediction sets, the cross-validation's folds), each
/// event a job record, ending with `end` and the finished job.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_jobs_progress_streams_as_server_sent_events() {
    let (server, data) = admin_server("job-events", 1, 4);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(
        root.join("tests/fixtures/learn/table.csv"),
        data.join("table.csv"),
    )
    .unwrap();
    let job = submit(
        &server,
        json!({"type": "train", "name": "streamed", "table": "table.csv", "features": "hand6"}),
    )
    .await;
    let id = job["id"].as_str().unwrap();
    let answer = send(
        &server.admin,
        authed(get(&format!("/admin/v1/jobs/{id}/events"))),
    )
    .await;
    assert_eq!(answer.status, 200);
    assert_eq!(answer.header("content-type"), Some("text/event-stream"));
    let text = String::from_utf8(answer.body.clone()).unwrap();
    let mut events: Vec<(String, Value)> = Vec::new();
    for block in text.split("\n\n").filter(|b| b.contains("data:")) {
        let field = |name: &str| {
            block
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .map(|v| v.trim().to_string())
        };
        let data = serde_json::from_str(&field("data:").unwrap()).unwrap();
        events.push((field("event:").unwrap(), data));
    }
    let (last, done) = events.last().unwrap();
    assert_eq!(last, "end", "{text}");
    assert_eq!(done["state"], "succeeded", "{done}");
    assert!(
        events[..events.len() - 1]
            .iter()
            .all(|(e, _)| e == "progress")
    );
    // The stages in order, each counting real units (a stage is "0 of 0" only as it begins).
    let stages: Vec<&str> = events
        .iter()
        .map(|(_, r)| r["progress"]["stage"].as_str().unwrap())
        .collect();
    let first = |stage: &str| stages.iter().position(|s| *s == stage);
    let (fit, sets, cv) = (
        first("fit"),
        first("prediction_sets"),
        first("cross_validate"),
    );
    assert!(fit < sets && sets < cv && fit.is_some(), "{stages:?}");
    for (_, record) in &events {
        let p = &record["progress"];
        assert!(
            p["done"].as_u64().unwrap() <= p["total"].as_u64().unwrap(),
            "{p}"
        );
    }
    let fit: Vec<&Value> = events
        .iter()
        .map(|(_, r)| &r["progress"])
        .filter(|p| p["stage"] == "fit")
        .collect();
    let last = fit.last().unwrap();
    assert!(
        last["total"].as_u64().unwrap() >= 2,
        "the fit counts its folds: {fit:?}"
    );
    assert_eq!(last["done"], last["total"], "{fit:?}");
    assert!(fit.len() >= 3, "the fit's folds one by one: {fit:?}");
    // A finished job's stream: its end at once. An unknown job: 404.
    let again = send(
        &server.admin,
        authed(get(&format!("/admin/v1/jobs/{id}/events"))),
    )
    .await;
    assert!(String::from_utf8_lossy(&again.body).starts_with("event: end"));
    send(&server.admin, authed(get("/admin/v1/jobs/nope/events")))
        .await
        .problem(404, "job-not-found");
}
