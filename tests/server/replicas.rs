//! Many replicas on one registry (`serve --poll-interval`): two real `serve` processes watch
//! one registry folder while a third process publishes versions as `train` writes them, under
//! a load loop; a corrupt version and a half-written folder are never served. In-process,
//! one look at the registry at a time (`ModelStore::poll`) and the answers of the real
//! router: a new version is served, compared rather than reloaded; a broken one leaves the
//! previous one serving and is tried again only once its file changes; a folder being
//! written is never loaded; a removed version stops being served once the requests on it
//! finish.

use crate::common;

use super::faults::{exchange, wait_until};
use common::server::{
    Part, config, free_port, get as request, models_copy, multipart, send, start, temp_dir,
};
use reflectance_core::model::registry::Registry;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A `serve` process on `models` (data plane only), killed when dropped.
struct Replica {
    child: std::process::Child,
    port: u16,
}

impl Drop for Replica {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn replica(models: &Path, log: &Path, poll: &str) -> Replica {
    let port = free_port();
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .unwrap();
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args(["serve", "--default-model", "demo", "--log-format", "json"])
        .arg("--models")
        .arg(models)
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(["--poll-interval", poll, "--cpu-threads", "1"])
        .env_remove("REFLECTANCE_ADMIN_TOKEN")
        .stderr(log)
        .spawn()
        .expect("the server starts");
    let replica = Replica { child, port };
    wait_until(Duration::from_secs(30), "replica ready", || {
        get(port, "/health/ready").is_some_and(|(status, _)| status == 200)
    });
    replica
}

fn get(port: u16, path: &str) -> Option<(u16, Vec<u8>)> {
    exchange(port, "GET", path, "text/plain", b"", Duration::from_secs(5))
        .map(|r| (r.status, r.body))
}

/// The version a replica's `/v1/models/demo` says it serves.
fn serving(port: u16) -> u32 {
    let (_, body) = get(port, "/v1/models/demo").expect("model detail");
    let detail: serde_json::Value = serde_json::from_slice(&body).unwrap();
    detail["active_version"].as_u64().unwrap() as u32
}

/// A counter of a replica's `/metrics` (0 when absent).
fn counter(port: u16, series: &str) -> u64 {
    let (_, body) = get(port, "/metrics").expect("metrics");
    let text = String::from_utf8(body).unwrap();
    text.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' '))
        .map_or(0, |n| n.trim().parse().unwrap())
}

/// `reflectance_model_load_failures_total{model="demo"}` of a replica.
fn load_failures(port: u16) -> u64 {
    counter(
        port,
        "reflectance_model_load_failures_total{model=\"demo\"}",
    )
}

/// Wait until every replica has looked at the registry twice more (the first look may
/// have begun before the change).
fn two_more_looks(ports: &[u16]) {
    let polls = |port| counter(port, "reflectance_registry_polls_total");
    let before: Vec<u64> = ports.iter().map(|&p| polls(p)).collect();
    wait_until(Duration::from_secs(10), "two looks at the registry", || {
        ports.iter().zip(&before).all(|(&p, &n)| polls(p) >= n + 2)
    });
}

/// `reflectance train` publishing the next version of `demo` and activating it, as a
/// third process (the admin instance's job does the same).
fn train(models: &Path) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_reflectance"))
        .args([
            "train",
            "--table",
            "tests/fixtures/learn/table.csv",
            "--features",
            "hand6",
        ])
        .args([
            "--name",
            "demo",
            "--no-cv",
            "--activate",
            "always",
            "--models",
        ])
        .arg(models)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    common::assert_success(&out);
}

/// Write `bytes` to `path` as a registry writer must: a temporary file renamed into place.
fn write_atomically(path: &Path, bytes: &[u8]) {
    let temporary = path.with_extension("tmp-test");
    std::fs::write(&temporary, bytes).unwrap();
    std::fs::rename(&temporary, path).unwrap();
}

/// What each request of a load loop got: its replica's port, and the version that
/// answered or why it failed.
type Seen = Arc<Mutex<Vec<(u16, Result<u32, String>)>>>;

struct Traffic {
    stop: Arc<AtomicBool>,
    seen: Seen,
    threads: Vec<std::thread::JoinHandle<()>>,
}

/// One classification loop per replica, each request on a fresh connection.
fn traffic(ports: &[u16]) -> Traffic {
    let stop = Arc::new(AtomicBool::new(false));
    let seen = Arc::new(Mutex::new(Vec::new()));
    let png = common::sphere_png(200, 90.0);
    let threads = ports
        .iter()
        .map(|&port| {
            let (stop, seen, png) = (stop.clone(), seen.clone(), png.clone());
            std::thread::spawn(move || {
                let (content_type, body) = multipart(&[
                    ("image", Part::File(&png)),
                    ("white", Part::Text("0.8")),
                    ("cx", Part::Text("99.5")),
                    ("cy", Part::Text("99.5")),
                    ("r", Part::Text("90")),
                ]);
                while !stop.load(Ordering::Relaxed) {
                    let reply = exchange(
                        port,
                        "POST",
                        "/v1/classify",
                        &content_type,
                        &body,
                        Duration::from_secs(20),
                    );
                    let outcome = match reply {
                        Some(r) if r.status == 200 => {
                            let version = r.json()["model"]["version"].as_u64().unwrap_or(0);
                            Ok(version as u32)
                        }
                        Some(r) => Err(format!(
                            "{}: {}",
                            r.status,
                            String::from_utf8_lossy(&r.body)
                        )),
                        None => Err("no answer".into()),
                    };
                    seen.lock().unwrap().push((port, outcome));
                }
            })
        })
        .collect();
    Traffic {
        stop,
        seen,
        threads,
    }
}

impl Traffic {
    /// Stop, and check every request was answered and no replica went back to an older
    /// version; returns how many requests were made.
    fn finish(self) -> usize {
        self.stop.store(true, Ordering::Relaxed);
        for thread in self.threads {
            thread.join().unwrap();
        }
        let seen = self.seen.lock().unwrap();
        let failures: Vec<_> = seen.iter().filter(|(_, r)| r.is_err()).collect();
        assert!(
            failures.is_empty(),
            "{} failed: {:?}",
            failures.len(),
            &failures[..failures.len().min(3)]
        );
        for port in seen
            .iter()
            .map(|(p, _)| *p)
            .collect::<std::collections::BTreeSet<_>>()
        {
            let versions: Vec<u32> = seen
                .iter()
                .filter(|(p, _)| *p == port)
                .filter_map(|(_, r)| r.as_ref().ok().copied())
                .collect();
            assert!(
                versions.is_sorted(),
                "replica {port} went back: {versions:?}"
            );
        }
        seen.len()
    }
}

#[test]
fn replicas_follow_the_registry() {
    let base = temp_dir("replicas");
    let models = base.join("models");
    train(&models);
    train(&models);
    let log = base.join("server.log");
    let replicas = [replica(&models, &log, "1"), replica(&models, &log, "1")];
    let ports: Vec<u16> = replicas.iter().map(|r| r.port).collect();
    assert!(ports.iter().all(|&p| serving(p) == 2));
    let load = traffic(&ports);
    std::thread::sleep(Duration::from_millis(300));

    // Version 3 and its ACTIVE, published by another process: both replicas switch.
    let published = Instant::now();
    train(&models);
    wait_until(
        Duration::from_secs(20),
        "both replicas serve version 3",
        || ports.iter().all(|&p| serving(p) == 3),
    );
    let switched = published.elapsed();
    std::thread::sleep(Duration::from_millis(300));
    let requests = load.finish();
    assert!(requests > 0, "no request during the switch");
    eprintln!(
        "both replicas served version 3 {switched:?} after it was published; {requests} requests, none failed"
    );

    // A corrupt version 4 (its checksum does not match), ACTIVE: refused once, not again.
    let registry = Registry::new(&models);
    let v3 = std::fs::read_to_string(models.join("demo/3/model.json")).unwrap();
    let corrupt =
        v3.replacen("\"version\":3", "\"version\":4", 1)
            .replacen("\"seed\":", "\"seed\":1", 1);
    let staging = models.join("demo/.4.tmp-test");
    std::fs::create_dir_all(&staging).unwrap();
    std::fs::write(staging.join("model.json"), corrupt).unwrap();
    std::fs::rename(&staging, models.join("demo/4")).unwrap();
    write_atomically(&models.join("demo/ACTIVE"), b"4\n");
    assert_eq!(registry.versions("demo").unwrap(), [1, 2, 3, 4]);
    wait_until(
        Duration::from_secs(20),
        "the corrupt version counted",
        || ports.iter().all(|&p| load_failures(p) == 1),
    );
    two_more_looks(&ports);
    for &port in &ports {
        assert_eq!(serving(port), 3);
        assert_eq!(
            load_failures(port),
            1,
            "a refused version is tried again only when its file changes"
        );
    }

    // A half-written version 5 (its folder, no model file yet) named by ACTIVE, and a
    // complete model file in a writer's hidden temporary folder: neither is loaded.
    std::fs::create_dir_all(models.join("demo/5")).unwrap();
    std::fs::write(models.join("demo/5/report.json"), b"{}").unwrap();
    let hidden = models.join("demo/.6.tmp-writer");
    std::fs::create_dir_all(&hidden).unwrap();
    std::fs::write(hidden.join("model.json"), v3.as_bytes()).unwrap();
    write_atomically(&models.join("demo/ACTIVE"), b"5\n");
    two_more_looks(&ports);
    for &port in &ports {
        assert_eq!(serving(port), 3, "a version being written is not served");
        assert_eq!(load_failures(port), 1, "nor tried");
    }

    // The next published version (6: 5's folder is taken) is served by both again.
    std::fs::remove_dir_all(&hidden).unwrap();
    let load = traffic(&ports);
    train(&models);
    wait_until(
        Duration::from_secs(20),
        "both replicas serve version 6",
        || ports.iter().all(|&p| serving(p) == 6),
    );
    load.finish();
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.contains("model loaded from the registry"), "{text}");
    assert!(text.contains("version refused"), "{text}");
}

/// The version `GET /v1/models/ward6` says this server serves, with when it loaded it.
async fn detail(server: &common::server::TestServer) -> (u64, String) {
    let detail = send(&server.data, request("/v1/models/ward6"))
        .await
        .json_of(200);
    let loaded = detail["loaded"].as_str().unwrap().to_string();
    assert!(!detail["replica"].as_str().unwrap().is_empty(), "{detail}");
    (detail["active_version"].as_u64().unwrap(), loaded)
}

/// `model.json` of `ward6` version 1 made into a valid `version`.
fn as_version(registry: &Registry, version: u32) -> Vec<u8> {
    let mut file = registry.load("ward6", 1).unwrap();
    file.version = version;
    file.to_json().unwrap()
}

/// A new newest version (no `ACTIVE`) is served after one look at the registry, and the
/// looks after it compare instead of reloading; `ACTIVE` naming an older version brings
/// it back.
#[tokio::test]
async fn a_published_version_is_served_after_a_look() {
    let models = models_copy("published");
    let server = start(config(&models));
    let store = &server.state.models;
    assert_eq!(detail(&server).await.0, 1);
    assert_eq!(
        store.poll("ward6").unwrap(),
        Default::default(),
        "nothing changed"
    );
    let registry = Registry::new(&models);
    let mut file = registry.load("ward6", 1).unwrap();
    assert_eq!(registry.publish(&mut file, &[]).unwrap().0, 2);
    let polled = store.poll("ward6").unwrap();
    assert_eq!(polled.swapped, [("ward6".to_string(), 2)]);
    let (version, loaded) = detail(&server).await;
    assert_eq!(version, 2);
    assert_eq!(
        store.poll("ward6").unwrap(),
        Default::default(),
        "compared, not reloaded"
    );
    assert_eq!(detail(&server).await, (2, loaded));
    write_atomically(&models.join("ward6/ACTIVE"), b"1\n");
    assert_eq!(
        store.poll("ward6").unwrap().swapped,
        [("ward6".to_string(), 1)]
    );
    assert_eq!(detail(&server).await.0, 1);
}

/// A version whose checksum does not match is refused and the previous one keeps
/// serving; the next looks leave it alone until its file changes, then it is served.
#[tokio::test]
async fn a_broken_version_leaves_the_previous_one_serving() {
    let models = models_copy("broken");
    let server = start(config(&models));
    let store = &server.state.models;
    let registry = Registry::new(&models);
    let good = as_version(&registry, 2);
    let text = String::from_utf8(good.clone()).unwrap();
    let broken = text.replacen("\"seed\":", "\"seed\":1", 1);
    assert_ne!(broken, text);
    let staging = models.join("ward6/.2.tmp-test");
    std::fs::create_dir_all(&staging).unwrap();
    std::fs::write(staging.join("model.json"), broken).unwrap();
    std::fs::rename(&staging, models.join("ward6/2")).unwrap();
    let polled = store.poll("ward6").unwrap();
    assert_eq!(polled.refused, [("ward6".to_string(), 2)]);
    assert!(polled.swapped.is_empty());
    assert_eq!(detail(&server).await.0, 1);
    assert_eq!(
        store.poll("ward6").unwrap(),
        Default::default(),
        "not tried again"
    );
    // Classification still answers, with version 1.
    let fixture = common::sphere_png(200, 90.0);
    let answer = send(
        &server.data,
        common::server::post_multipart(
            "/v1/classify",
            &[
                ("image", Part::File(&fixture)),
                ("white", Part::Text("0.8")),
                ("cx", Part::Text("99.5")),
                ("cy", Part::Text("99.5")),
                ("r", Part::Text("90")),
            ],
        ),
    )
    .await
    .json_of(200);
    assert_eq!(answer["model"]["version"], 1);
    // Its file replaced by a good one: served at the next look.
    write_atomically(&models.join("ward6/2/model.json"), &good);
    assert_eq!(
        store.poll("ward6").unwrap().swapped,
        [("ward6".to_string(), 2)]
    );
    assert_eq!(detail(&server).await.0, 2);
}

/// A version being written — its folder without a model file yet, or a writer's hidden
/// temporary folder — is never loaded, even with `ACTIVE` naming it; once complete, it is.
#[tokio::test]
async fn a_version_being_written_is_never_loaded() {
    let models = models_copy("half");
    let server = start(config(&models));
    let store = &server.state.models;
    let registry = Registry::new(&models);
    std::fs::create_dir_all(models.join("ward6/2")).unwrap();
    std::fs::write(models.join("ward6/2/report.json"), b"{}").unwrap();
    let hidden = models.join("ward6/.3.tmp-writer");
    std::fs::create_dir_all(&hidden).unwrap();
    std::fs::write(hidden.join("model.json"), as_version(&registry, 3)).unwrap();
    write_atomically(&models.join("ward6/ACTIVE"), b"2\n");
    assert_eq!(store.poll("ward6").unwrap(), Default::default());
    write_atomically(&models.join("ward6/ACTIVE"), b"3\n");
    assert_eq!(store.poll("ward6").unwrap(), Default::default());
    assert_eq!(detail(&server).await.0, 1);
    // The writer's rename completes version 3.
    std::fs::rename(&hidden, models.join("ward6/3")).unwrap();
    assert_eq!(
        store.poll("ward6").unwrap().swapped,
        [("ward6".to_string(), 3)]
    );
    assert_eq!(detail(&server).await.0, 3);
}

/// Once the served version's folder is removed, the next look serves the newest left,
/// while a request holding the removed version finishes on it.
#[tokio::test]
async fn a_removed_version_stops_being_served() {
    let models: PathBuf = models_copy("removed");
    let server = start(config(&models));
    let store = &server.state.models;
    let registry = Registry::new(&models);
    let mut file = registry.load("ward6", 1).unwrap();
    let (v2, dir) = registry.publish(&mut file, &[]).unwrap();
    assert_eq!(v2, 2);
    assert_eq!(
        store.poll("ward6").unwrap().swapped,
        [("ward6".to_string(), 2)]
    );
    let held = store.active("ward6").unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let polled = store.poll("ward6").unwrap();
    assert_eq!(polled.swapped, [("ward6".to_string(), 1)]);
    assert_eq!(detail(&server).await.0, 1);
    // The request that held version 2 still has all of it.
    assert_eq!(held.version(), 2);
    assert!(held.file().self_test().is_ok());
}
