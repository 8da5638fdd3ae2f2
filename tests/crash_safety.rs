//! Crash safety with the real binary: SIGKILL while a training job publishes a version and
//! while a version is being activated, then a restart on the same registry and data
//! directory. The crash windows are made deterministic with the test-only
//! `REFLECTANCE_TEST_PAUSE` (see `fsutil::test_pause`): the process sleeps at the named
//! point and the test kills it there once the point is observably reached. Also: start-up
//! when the active version does not load (fallback to the newest version that does).

mod common;

use common::server::{Part, TOKEN, copy_dir, free_port, multipart, temp_dir};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

struct Reply {
    status: u16,
    head: String,
    body: Vec<u8>,
}

impl Reply {
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or(Value::Null)
    }
    fn header(&self, name: &str) -> Option<String> {
        self.head.lines().find_map(|line| {
            let (k, v) = line.split_once(':')?;
            k.eq_ignore_ascii_case(name).then(|| v.trim().to_string())
        })
    }
}

/// One HTTP/1.1 exchange over a fresh connection.
fn exchange(
    port: u16,
    method: &str,
    path: &str,
    content_type: &str,
    body: &[u8],
    timeout: Duration,
) -> Option<Reply> {
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    stream.set_read_timeout(Some(timeout)).ok()?;
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\n\
         Content-Type: {content_type}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    )
    .ok()?;
    stream.write_all(body).ok()?;
    let mut raw = Vec::new();
    stream.read_to_end(&mut raw).ok()?;
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let status = head.split_whitespace().nth(1)?.parse().ok()?;
    Some(Reply {
        status,
        head,
        body: raw[split + 4..].to_vec(),
    })
}

fn json_call(port: u16, method: &str, path: &str, body: Option<&Value>) -> Reply {
    let bytes = body
        .map(|b| serde_json::to_vec(b).unwrap())
        .unwrap_or_default();
    exchange(
        port,
        method,
        path,
        "application/json",
        &bytes,
        Duration::from_secs(20),
    )
    .unwrap_or_else(|| panic!("{method} {path}: no answer"))
}

/// Classify the test sphere; returns the answering version.
fn classify(port: u16) -> u32 {
    let png = common::sphere_png(200, 90.0);
    let (content_type, body) = multipart(&[
        ("image", Part::File(&png)),
        ("white", Part::Text("0.8")),
        ("cx", Part::Text("99.5")),
        ("cy", Part::Text("99.5")),
        ("r", Part::Text("90")),
    ]);
    let reply = exchange(
        port,
        "POST",
        "/v1/classify",
        &content_type,
        &body,
        Duration::from_secs(20),
    )
    .expect("classify answered");
    assert_eq!(
        reply.status,
        200,
        "{}",
        String::from_utf8_lossy(&reply.body)
    );
    reply
        .header("x-model-version")
        .and_then(|v| v.parse().ok())
        .expect("x-model-version")
}

struct Server {
    child: std::process::Child,
    port: u16,
    admin: u16,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// SIGKILL: no cleanup of any kind runs.
    fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

fn spawn(base: &Path, pause: Option<&str>) -> Server {
    let (port, admin) = (free_port(), free_port());
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(base.join("server.log"))
        .unwrap();
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"));
    command
        .args(["serve", "--default-model", "ward6", "--log-format", "json"])
        .arg("--models")
        .arg(base.join("models"))
        .arg("--data-dir")
        .arg(base.join("data"))
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(["--admin-listen", &format!("127.0.0.1:{admin}")])
        .env("REFLECTANCE_ADMIN_TOKEN", TOKEN)
        .env_remove("REFLECTANCE_TEST_PAUSE")
        .stderr(log);
    if let Some(pause) = pause {
        command.env("REFLECTANCE_TEST_PAUSE", pause);
    }
    let server = Server {
        child: command.spawn().unwrap(),
        port,
        admin,
    };
    wait_until(Duration::from_secs(30), "server ready", || {
        exchange(
            port,
            "GET",
            "/health/ready",
            "text/plain",
            b"",
            Duration::from_secs(2),
        )
        .is_some_and(|r| r.status == 200)
    });
    server
}

fn wait_until(limit: Duration, what: &str, mut ok: impl FnMut() -> bool) {
    let deadline = Instant::now() + limit;
    while !ok() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A registry holding a copy of the shipped `ward6` version 1, and a data directory with
/// the fixture feature table.
fn setup(name: &str) -> PathBuf {
    let base = temp_dir(name);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    copy_dir(&root.join("models/ward6"), &base.join("models/ward6"));
    std::fs::create_dir_all(base.join("data")).unwrap();
    std::fs::copy(
        root.join("tests/fixtures/learn/table.csv"),
        base.join("data/table.csv"),
    )
    .unwrap();
    base
}

/// Entries of the model's registry folder (hidden ones included), sorted.
fn entries(base: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(base.join("models/ward6"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn train_job(activate: &str) -> Value {
    json!({"type": "train", "name": "ward6", "table": "table.csv", "features": "hand6",
           "cross_validate": false, "activate": activate})
}

fn job_state(admin: u16, id: &str) -> Value {
    json_call(admin, "GET", &format!("/admin/v1/jobs/{id}"), None).json()
}

#[test]
fn sigkill_while_a_training_job_publishes() {
    let base = setup("crash-publish");
    let server = spawn(&base, Some("publish=60000"));
    assert_eq!(classify(server.port), 1);
    let reply = json_call(
        server.admin,
        "POST",
        "/admin/v1/jobs",
        Some(&train_job("always")),
    );
    assert_eq!(reply.status, 202, "{}", reply.json());
    let id = reply.json()["id"].as_str().unwrap().to_string();
    // The job stages version 2 in a hidden directory and pauses before renaming it.
    wait_until(Duration::from_secs(30), "a staged version", || {
        entries(&base).iter().any(|n| {
            n.starts_with(".2.tmp-")
                && base
                    .join("models/ward6")
                    .join(n)
                    .join("model.json")
                    .is_file()
        })
    });
    let doc = job_state(server.admin, &id);
    assert_eq!(doc["state"], "running", "{doc}");
    assert_eq!(doc["progress"]["stage"], "publish", "{doc}");
    server.kill();
    assert!(
        entries(&base).iter().any(|n| n.starts_with(".2.tmp-")),
        "the crash left the staging directory: {:?}",
        entries(&base)
    );

    let server = spawn(&base, None);
    // Only complete versions are visible: the staging leftover was removed at start-up.
    let names = entries(&base);
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
    assert!(!names.contains(&"2".to_string()), "{names:?}");
    assert_eq!(classify(server.port), 1);
    let doc = job_state(server.admin, &id);
    assert_eq!(doc["state"], "failed", "{doc}");
    assert_eq!(doc["error"], "interrupted", "{doc}");
    let versions = json_call(server.admin, "GET", "/admin/v1/models/ward6/versions", None).json();
    assert_eq!(versions["active"], 1, "{versions}");
    assert_eq!(
        versions["versions"].as_array().unwrap().len(),
        1,
        "{versions}"
    );
    // The registry still takes new versions: the next one is 2.
    let reply = json_call(
        server.admin,
        "POST",
        "/admin/v1/jobs",
        Some(&train_job("always")),
    );
    let id = reply.json()["id"].as_str().unwrap().to_string();
    wait_until(Duration::from_secs(60), "the job's end", || {
        job_state(server.admin, &id)["state"] == "succeeded"
    });
    assert_eq!(classify(server.port), 2);
}

#[test]
fn sigkill_while_a_version_is_activated() {
    let base = setup("crash-activate");
    let server = spawn(&base, Some("activate=60000"));
    // Version 2, published but not activated (the served version 1 is pinned in ACTIVE).
    let reply = json_call(
        server.admin,
        "POST",
        "/admin/v1/jobs",
        Some(&train_job("never")),
    );
    assert_eq!(reply.status, 202, "{}", reply.json());
    let id = reply.json()["id"].as_str().unwrap().to_string();
    wait_until(Duration::from_secs(60), "the training job", || {
        job_state(server.admin, &id)["state"] == "succeeded"
    });
    assert_eq!(
        std::fs::read_to_string(base.join("models/ward6/ACTIVE"))
            .unwrap()
            .trim(),
        "1"
    );
    // Activate 2: it is swapped in memory, then the process pauses before recording it.
    let admin = server.admin;
    let activation = std::thread::spawn(move || {
        exchange(
            admin,
            "POST",
            "/admin/v1/models/ward6/versions/2/activate",
            "application/json",
            b"",
            Duration::from_secs(90),
        )
        .map(|r| r.status)
    });
    wait_until(Duration::from_secs(30), "version 2 serving", || {
        classify(server.port) == 2
    });
    server.kill();
    assert_eq!(activation.join().unwrap(), None, "the client got no answer");

    // The activation was never acknowledged nor recorded: version 1 is still active.
    let server = spawn(&base, None);
    let names = entries(&base);
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
    assert!(names.contains(&"2".to_string()), "{names:?}");
    assert_eq!(classify(server.port), 1);
    // Activating again completes and survives a restart.
    let reply = json_call(
        server.admin,
        "POST",
        "/admin/v1/models/ward6/versions/2/activate",
        None,
    );
    assert_eq!(reply.status, 200, "{}", reply.json());
    assert_eq!(classify(server.port), 2);
    server.kill();
    let server = spawn(&base, None);
    assert_eq!(classify(server.port), 2);
}

#[test]
fn start_up_falls_back_to_the_newest_version_that_loads() {
    use reflectance::server::config::Config;
    use reflectance::server::{build_state, load_models};
    let base = setup("fallback");
    let models = base.join("models");
    // Versions 2 (truncated file, newest) and 3 (a copy of 1: stored under the wrong
    // version number) do not load; ACTIVE names 3.
    copy_dir(&models.join("ward6/1"), &models.join("ward6/2"));
    let file = models.join("ward6/2/model.json");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    copy_dir(&models.join("ward6/1"), &models.join("ward6/3"));
    std::fs::write(models.join("ward6/ACTIVE"), "3\n").unwrap();
    // A second model with no loadable version at all.
    copy_dir(&models.join("ward6/2"), &models.join("broken/1"));

    let mut config = Config::new(&models, "ward6");
    config.cpu_threads = 1;
    let state = build_state(config).unwrap();
    load_models(&state).expect("ward6 is served from version 1");
    assert_eq!(state.models.active("ward6").unwrap().version(), 1);
    assert!(!state.models.is_served("broken"));
    // The registry's record is left alone.
    assert_eq!(
        std::fs::read_to_string(models.join("ward6/ACTIVE")).unwrap(),
        "3\n"
    );
    let metrics = reflectance::server::metrics::render();
    assert!(
        metrics
            .lines()
            .any(|l| l.starts_with("reflectance_model_fallbacks_total{model=\"ward6\"}")),
        "{metrics}"
    );

    // The default model with no loadable version stops the start-up with a reason.
    let mut config = Config::new(&models, "broken");
    config.cpu_threads = 1;
    let state = build_state(config).unwrap();
    let error = load_models(&state).unwrap_err();
    assert!(error.contains("\"broken\""), "{error}");
    assert!(error.contains("no other version loads"), "{error}");
}
