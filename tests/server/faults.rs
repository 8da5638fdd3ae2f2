//! Crash safety with the real binary: SIGKILL while a training job publishes a version and
//! while a version is being activated, then a restart on the same registry and data
//! directory. The crash windows are made deterministic with the test-only
//! `REFLECTANCE_TEST_PAUSE` (see `util::durable::test_pause`): the process sleeps at the named
//! point and the test kills it there once the point is observably reached. Also: start-up
//! when the active version does not load (fallback to the newest version that does).

use crate::common;

use common::server::{Part, TOKEN, copy_dir, free_port, multipart, temp_dir};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

pub(crate) struct Reply {
    pub(crate) status: u16,
    head: String,
    pub(crate) body: Vec<u8>,
}

impl Reply {
    pub(crate) fn json(&self) -> Value {
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
pub(crate) fn exchange(
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
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nAuthorization: Bearer {TOKEN}\r\n\
         Content-Type: {content_type}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    )
    .ok()?;
    stream.write_all(body).ok()?;
    read_reply(&mut stream)
}

/// A response: up to its `Content-Length` when it has one (a peer may keep the connection
/// open despite `Connection: close`), else to the end of the stream.
fn read_reply(stream: &mut std::net::TcpStream) -> Option<Reply> {
    let mut raw = Vec::new();
    let mut chunk = [0u8; 16384];
    loop {
        if let Some(reply) = parse_reply(&raw, false) {
            return Some(reply);
        }
        match stream.read(&mut chunk).ok()? {
            0 => return parse_reply(&raw, true),
            n => raw.extend_from_slice(&chunk[..n]),
        }
    }
}

/// The response in `raw`, once complete (or `at_end` of the stream).
fn parse_reply(raw: &[u8], at_end: bool) -> Option<Reply> {
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let reply = Reply {
        status: head.split_whitespace().nth(1)?.parse().ok()?,
        head,
        body: raw[split + 4..].to_vec(),
    };
    let length = reply.header("content-length").and_then(|n| n.parse().ok());
    let complete = at_end || length.is_some_and(|n: usize| reply.body.len() >= n);
    complete.then_some(reply)
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

pub(crate) struct Server {
    child: std::process::Child,
    pub(crate) port: u16,
    admin: u16,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// SIGTERM, and the process must exit within `limit`.
    fn terminate_within(mut self, limit: Duration) {
        let pid = self.child.id() as libc::pid_t;
        // SAFETY: signalling our own child process.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
        let deadline = Instant::now() + limit;
        while self.child.try_wait().unwrap().is_none() {
            assert!(
                Instant::now() < deadline,
                "SIGTERM did not stop the server within {limit:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The disk "has room again": lift the soft `RLIMIT_FSIZE` of the running process.
    fn lift_file_size_limit(&self) {
        let limit = libc::rlimit {
            rlim_cur: libc::RLIM_INFINITY,
            rlim_max: libc::RLIM_INFINITY,
        };
        // SAFETY: our own child; the limit is a plain struct.
        let rc = unsafe {
            libc::prlimit(
                self.child.id() as libc::pid_t,
                libc::RLIMIT_FSIZE,
                &limit,
                std::ptr::null_mut(),
            )
        };
        assert_eq!(rc, 0, "{}", std::io::Error::last_os_error());
    }

    /// SIGKILL: no cleanup of any kind runs.
    fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

/// How to start a server beyond its folders.
#[derive(Default)]
struct Launch<'a> {
    /// `REFLECTANCE_TEST_PAUSE`.
    pause: Option<&'a str>,
    /// More `serve` flags.
    args: &'a [&'a str],
    /// `RLIMIT_FSIZE` in bytes (the soft limit; [`Server::lift_file_size_limit`] lifts it):
    /// a write past it fails with EFBIG, as on a full disk.
    file_size_limit: Option<u64>,
    /// Folders the server sees read-only: a read-only bind mount in a mount namespace of
    /// its own when the tests run as root (whom permissions do not stop), else `chmod a-w`.
    read_only: Vec<PathBuf>,
}

pub(crate) fn spawn(base: &Path, pause: Option<&str>) -> Server {
    launch(
        base,
        Launch {
            pause,
            ..Launch::default()
        },
    )
}

fn launch(base: &Path, how: Launch) -> Server {
    use std::os::unix::process::CommandExt;
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
        .args(how.args)
        .env("REFLECTANCE_ADMIN_TOKEN", TOKEN)
        .env_remove("REFLECTANCE_TEST_PAUSE");
    if how.file_size_limit.is_some() {
        // The log would be cut by the limit too.
        command.stderr(std::process::Stdio::null());
    } else {
        command.stderr(log);
    }
    if let Some(pause) = how.pause {
        command.env("REFLECTANCE_TEST_PAUSE", pause);
    }
    let by = read_only_by();
    if by != ReadOnlyBy::Mount {
        for dir in &how.read_only {
            set_writable(dir, false);
        }
    }
    let drop_override = by == ReadOnlyBy::PermissionsWithoutOverride && !how.read_only.is_empty();
    let read_only: Vec<std::ffi::CString> = how
        .read_only
        .iter()
        .filter(|_| by == ReadOnlyBy::Mount)
        .map(|p| std::ffi::CString::new(p.as_os_str().as_encoded_bytes()).unwrap())
        .collect();
    let file_size_limit = how.file_size_limit;
    // SAFETY: between fork and exec only async-signal-safe calls (signal, setrlimit,
    // unshare, mount), on memory prepared before the fork.
    unsafe {
        command.pre_exec(move || {
            let check = |rc: libc::c_int| {
                if rc == 0 {
                    Ok(())
                } else {
                    Err(std::io::Error::last_os_error())
                }
            };
            if let Some(bytes) = file_size_limit {
                // A write past the limit then fails with EFBIG instead of killing the process.
                libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
                let limit = libc::rlimit {
                    rlim_cur: bytes,
                    rlim_max: libc::RLIM_INFINITY,
                };
                check(libc::setrlimit(libc::RLIMIT_FSIZE, &limit))?;
            }
            if drop_override {
                // Root ignores write bits through CAP_DAC_OVERRIDE: the server is exec'd
                // without it (a capability gone from the bounding set is not regained).
                check(libc::prctl(
                    libc::PR_CAPBSET_DROP,
                    CAP_DAC_OVERRIDE,
                    0,
                    0,
                    0,
                ))?;
            }
            if !read_only.is_empty() {
                let none = std::ptr::null();
                check(libc::unshare(libc::CLONE_NEWNS))?;
                check(libc::mount(
                    none,
                    c"/".as_ptr(),
                    none,
                    libc::MS_REC | libc::MS_PRIVATE,
                    std::ptr::null(),
                ))?;
                for dir in &read_only {
                    let flags = libc::MS_BIND | libc::MS_REC;
                    check(libc::mount(
                        dir.as_ptr(),
                        dir.as_ptr(),
                        none,
                        flags,
                        std::ptr::null(),
                    ))?;
                    let flags = libc::MS_REMOUNT | libc::MS_BIND | libc::MS_RDONLY;
                    check(libc::mount(
                        none,
                        dir.as_ptr(),
                        none,
                        flags,
                        std::ptr::null(),
                    ))?;
                }
            }
            Ok(())
        });
    }
    let server = Server {
        child: command.spawn().expect("the server starts"),
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

const CAP_DAC_OVERRIDE: libc::c_ulong = 1;

/// How a server is kept from writing into folders.
#[derive(Clone, Copy, PartialEq, Debug)]
enum ReadOnlyBy {
    /// A read-only bind mount, in a mount namespace of the server's own (as root).
    Mount,
    /// The write bits removed (not root: they bind).
    Permissions,
    /// The write bits removed, and root's capability to ignore them dropped for the server:
    /// as root where namespaces are refused (a container without CAP_SYS_ADMIN), or with
    /// `REFLECTANCE_TEST_NO_NAMESPACES` set to try this path.
    PermissionsWithoutOverride,
}

fn read_only_by() -> ReadOnlyBy {
    use std::os::unix::process::CommandExt;
    static CHOICE: std::sync::OnceLock<ReadOnlyBy> = std::sync::OnceLock::new();
    *CHOICE.get_or_init(|| {
        // SAFETY: geteuid cannot fail.
        if unsafe { libc::geteuid() } != 0 {
            return ReadOnlyBy::Permissions;
        }
        if std::env::var_os("REFLECTANCE_TEST_NO_NAMESPACES").is_some() {
            return ReadOnlyBy::PermissionsWithoutOverride;
        }
        let mut probe = std::process::Command::new("true");
        // SAFETY: unshare is async-signal-safe.
        unsafe {
            probe.pre_exec(|| match libc::unshare(libc::CLONE_NEWNS) {
                0 => Ok(()),
                _ => Err(std::io::Error::last_os_error()),
            });
        }
        match probe.status() {
            Ok(status) if status.success() => ReadOnlyBy::Mount,
            _ => ReadOnlyBy::PermissionsWithoutOverride,
        }
    })
}

/// Add or remove the write permission of a folder and everything in it.
fn set_writable(dir: &Path, writable: bool) {
    use std::os::unix::fs::PermissionsExt;
    for entry in std::fs::read_dir(dir).unwrap().map(Result::unwrap) {
        if entry.file_type().unwrap().is_dir() {
            set_writable(&entry.path(), writable);
        }
    }
    let mut permissions = std::fs::metadata(dir).unwrap().permissions();
    let mode = permissions.mode();
    permissions.set_mode(if writable {
        mode | 0o200
    } else {
        mode & !0o222
    });
    std::fs::set_permissions(dir, permissions).unwrap();
}

pub(crate) fn wait_until(limit: Duration, what: &str, mut ok: impl FnMut() -> bool) {
    let deadline = Instant::now() + limit;
    while !ok() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A registry holding a copy of the shipped `ward6` version 1, and a data directory with
/// the fixture feature table.
pub(crate) fn setup(name: &str) -> PathBuf {
    let base = temp_dir(name);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // Version 1 alone: the faults below start from a registry of one version.
    copy_dir(&root.join("models/ward6/1"), &base.join("models/ward6/1"));
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

fn activate(admin: u16, version: u32) -> Reply {
    let path = format!("/admin/v1/models/ward6/versions/{version}/activate");
    json_call(admin, "POST", &path, None)
}

fn job_state(admin: u16, id: &str) -> Value {
    json_call(admin, "GET", &format!("/admin/v1/jobs/{id}"), None).json()
}

#[test]
fn sigkill_while_a_training_job_publishes() {
    let base = setup("crash-publish");
    let server = spawn(&base, Some("publish=60000"));
    assert_eq!(classify(server.port), 1);
    let id = accepted(server.admin, &train_job("always"));
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
    let id = accepted(server.admin, &train_job("always"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
    assert_eq!(classify(server.port), 2);
}

#[test]
fn sigkill_while_a_version_is_activated() {
    let base = setup("crash-activate");
    let server = spawn(&base, Some("activate=60000"));
    // Version 2, published but not activated (the served version 1 is pinned in ACTIVE).
    let id = accepted(server.admin, &train_job("never"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
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
    let reply = activate(server.admin, 2);
    assert_eq!(reply.status, 200, "{}", reply.json());
    assert_eq!(classify(server.port), 2);
    server.kill();
    let server = spawn(&base, None);
    assert_eq!(classify(server.port), 2);
}

/// What an operator sees of a fresh server: where it listens, every metric family at zero,
/// and logs without Rust debug text, also after an activation and a finished job.
#[test]
fn a_fresh_server_says_where_it_listens_and_exports_its_metrics_at_zero() {
    let base = setup("fresh");
    let server = spawn(&base, None);
    let metrics = String::from_utf8(json_call(server.port, "GET", "/metrics", None).body).unwrap();
    for family in [
        "reflectance_requests_shed_total 0",
        "reflectance_job_record_write_failures_total 0",
        "reflectance_job_queue_depth 0",
        "reflectance_jobs{state=\"failed\"} 0",
        "reflectance_model_load_failures_total{model=\"ward6\"} 0",
        "reflectance_model_fallbacks_total{model=\"ward6\"} 0",
        "reflectance_stage_duration_seconds_count{stage=\"predict\"} 0",
        "reflectance_model_active_version{model=\"ward6\"} 1",
    ] {
        assert!(metrics.contains(family), "{family} missing:\n{metrics}");
    }
    assert_eq!(activate(server.admin, 1).status, 200);
    let id = accepted(server.admin, &train_job("never"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
    let (port, admin) = (server.port, server.admin);
    server.terminate_within(Duration::from_secs(30));
    let log = std::fs::read_to_string(base.join("server.log")).unwrap();
    let listening =
        format!("listening on http://127.0.0.1:{port}, admin on http://127.0.0.1:{admin}");
    assert!(log.contains(&listening), "{log}");
    let mut requests = Vec::new();
    for line in log.lines() {
        let event: Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {line}"));
        let fields = event["fields"].as_object().unwrap();
        if fields["message"] == "request" {
            assert!(
                fields["request_id"].is_string() && fields["ms"].is_f64(),
                "{line}"
            );
            requests.push(format!(
                "{} {} {}",
                fields["method"], fields["path"], fields["status"]
            ));
        }
        for (name, value) in fields {
            let text = value.to_string();
            assert!(
                !text.contains("Some(") && text != "\"None\"" && text != "\"\"",
                "{name} = {text}: Rust debug text or an empty field in {line}"
            );
        }
    }
    // One access-log line per request, none for the metrics scrape.
    let activated = "\"POST\" \"/admin/v1/models/ward6/versions/1/activate\" 200";
    assert!(requests.iter().any(|r| r == activated), "{requests:?}");
    assert!(
        !requests.iter().any(|r| r.contains("/metrics")),
        "{requests:?}"
    );
}

#[test]
fn start_up_falls_back_to_the_newest_version_that_loads() {
    use reflectance::ServerConfig as Config;
    use reflectance::{build_state, load_models};
    let base = setup("fallback");
    let models = base.join("models");
    // The model has a name of its own: the counters checked below are process-wide, and
    // other tests of this binary count ward6's.
    let registry = reflectance_core::model::registry::Registry::new(&models);
    let mut model = registry.load("ward6", 1).unwrap();
    model.name = "fallback".into();
    assert_eq!(registry.publish(&mut model, &[]).unwrap().0, 1);
    // Versions 2 (truncated file, newest) and 3 (a copy of 1: stored under the wrong
    // version number) do not load; ACTIVE names 3.
    copy_dir(&models.join("fallback/1"), &models.join("fallback/2"));
    let file = models.join("fallback/2/model.json");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    copy_dir(&models.join("fallback/1"), &models.join("fallback/3"));
    std::fs::write(models.join("fallback/ACTIVE"), "3\n").unwrap();
    // A second model with no loadable version at all.
    copy_dir(&models.join("fallback/2"), &models.join("broken/1"));

    let mut config = Config::new(&models, "fallback");
    config.cpu_threads = 1;
    let state = build_state(config).unwrap();
    load_models(&state).expect("served from version 1");
    assert_eq!(state.models.active("fallback").unwrap().version(), 1);
    assert!(!state.models.is_served("broken"));
    // The registry's record is left alone.
    assert_eq!(
        std::fs::read_to_string(models.join("fallback/ACTIVE")).unwrap(),
        "3\n"
    );
    // One fallback, after the two versions that failed to load.
    let metrics = reflectance::metrics_text();
    let count = |family: &str| {
        let key = format!("{family}{{model=\"fallback\"}} ");
        let line = metrics.lines().find(|l| l.starts_with(&key));
        line.and_then(|l| l[key.len()..].parse::<f64>().ok())
    };
    assert_eq!(
        count("reflectance_model_fallbacks_total"),
        Some(1.0),
        "{metrics}"
    );
    assert_eq!(
        count("reflectance_model_load_failures_total"),
        Some(2.0),
        "{metrics}"
    );

    // The default model with no loadable version stops the start-up with a reason.
    let mut config = Config::new(&models, "broken");
    config.cpu_threads = 1;
    let state = build_state(config).unwrap();
    let error = load_models(&state).unwrap_err();
    assert!(
        matches!(error, reflectance::StartError::DefaultNotServed { .. }),
        "{error:?}"
    );
    let error = error.to_string();
    assert!(error.contains("\"broken\""), "{error}");
    assert!(error.contains("no other version loads"), "{error}");
}

/// A data directory that render jobs can use: four tiny probes and three classes.
fn add_render_inputs(base: &Path) {
    common::server::write_probes(&base.join("data/probes"));
    std::fs::write(base.join("data/classes.json"), common::server::CLASSES_JSON).unwrap();
}

fn render_job(out: &str) -> Value {
    json!({"type": "render", "probes": "probes", "classes": "classes.json", "out": out,
           "size": 71})
}

/// What one client of the stress test saw.
#[derive(Default)]
struct Tally {
    calls: usize,
    /// Calls not answered within the per-call limit.
    unanswered: Vec<String>,
    /// Answers with a 5xx status.
    server_errors: Vec<String>,
    slowest: Duration,
}

impl Tally {
    /// One call: `None` when it did not answer in time.
    fn call(&mut self, what: &str, f: impl FnOnce() -> Option<Reply>) -> Option<Reply> {
        let start = Instant::now();
        let reply = f();
        self.calls += 1;
        self.slowest = self.slowest.max(start.elapsed());
        match &reply {
            None => self.unanswered.push(what.to_string()),
            Some(r) if r.status >= 500 => self.server_errors.push(format!(
                "{what}: {} {}",
                r.status,
                String::from_utf8_lossy(&r.body)
            )),
            Some(_) => {}
        }
        reply
    }
}

/// Every call of the stress test must answer within this (the independent check's limit).
const CALL_LIMIT: Duration = Duration::from_secs(10);

fn admin_call(port: u16, method: &str, path: &str, body: Option<&Value>) -> Option<Reply> {
    let bytes = body
        .map(|b| serde_json::to_vec(b).unwrap())
        .unwrap_or_default();
    exchange(port, method, path, "application/json", &bytes, CALL_LIMIT)
}

/// Many admin clients submitting, listing, getting, cancelling and activating at once, a
/// bounded number of calls each, while a data-plane client checks liveness. A watchdog
/// fails the test (instead of hanging) when the clients do not finish in time.
#[test]
fn concurrent_admin_calls_never_stop_the_service() {
    let base = setup("stress");
    add_render_inputs(&base);
    let server = launch(
        &base,
        Launch {
            args: &["--workers", "1", "--job-queue", "8"],
            ..Launch::default()
        },
    );
    let (port, admin) = (server.port, server.admin);
    const ROUNDS: usize = 120;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (done_tx, done_rx) = std::sync::mpsc::channel::<(String, Tally)>();
    let mut clients = Vec::new();
    let mut client = |name: String, work: Box<dyn FnOnce(&mut Tally) + Send>| {
        let done = done_tx.clone();
        clients.push(std::thread::spawn(move || {
            let mut tally = Tally::default();
            work(&mut tally);
            let _ = done.send((name, tally));
        }));
    };
    for k in 0..4 {
        client(
            format!("submitter {k}"),
            Box::new(move |t| {
                for i in 0..ROUNDS {
                    let job = render_job(&format!("out{k}-{i}"));
                    let reply = t.call("submit", || {
                        admin_call(admin, "POST", "/admin/v1/jobs", Some(&job))
                    });
                    if let Some(id) =
                        reply.and_then(|r| r.json()["id"].as_str().map(str::to_string))
                    {
                        t.call("get", || {
                            admin_call(admin, "GET", &format!("/admin/v1/jobs/{id}"), None)
                        });
                    }
                }
            }),
        );
    }
    for k in 0..4 {
        client(
            format!("canceller {k}"),
            Box::new(move |t| {
                for _ in 0..ROUNDS {
                    let state = if k % 2 == 0 { "queued" } else { "running" };
                    let listed = t.call("list", || {
                        admin_call(admin, "GET", &format!("/admin/v1/jobs?state={state}"), None)
                    });
                    let ids: Vec<String> = listed
                        .map(|r| r.json())
                        .and_then(|doc| {
                            doc["jobs"].as_array().map(|jobs| {
                                jobs.iter()
                                    .filter_map(|j| j["id"].as_str().map(str::to_string))
                                    .collect()
                            })
                        })
                        .unwrap_or_default();
                    for id in ids.iter().take(3) {
                        t.call("cancel", || {
                            admin_call(admin, "POST", &format!("/admin/v1/jobs/{id}/cancel"), None)
                        });
                    }
                }
            }),
        );
    }
    client(
        "activator".into(),
        Box::new(move |t| {
            for _ in 0..ROUNDS / 2 {
                t.call("activate", || {
                    admin_call(
                        admin,
                        "POST",
                        "/admin/v1/models/ward6/versions/1/activate",
                        None,
                    )
                });
                t.call("versions", || {
                    admin_call(admin, "GET", "/admin/v1/models/ward6/versions", None)
                });
            }
        }),
    );
    let live = stop.clone();
    client(
        "data plane".into(),
        Box::new(move |t| {
            while !live.load(std::sync::atomic::Ordering::SeqCst) {
                t.call("live", || {
                    exchange(port, "GET", "/health/live", "text/plain", b"", CALL_LIMIT)
                });
                std::thread::sleep(Duration::from_millis(20));
            }
        }),
    );
    drop(done_tx);

    // The watchdog: the admin clients must all finish well within this.
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut tallies = Vec::new();
    while tallies.len() < 9 {
        let left = deadline.saturating_duration_since(Instant::now());
        match done_rx.recv_timeout(left) {
            Ok(done) => tallies.push(done),
            Err(_) => {
                server.kill();
                panic!(
                    "the admin clients did not finish within 60 s (finished: {:?}): the server hung",
                    tallies.iter().map(|(n, _)| n).collect::<Vec<_>>()
                );
            }
        }
    }
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    tallies.push(
        done_rx
            .recv_timeout(Duration::from_secs(30))
            .expect("the data-plane client ends"),
    );
    for handle in clients {
        handle.join().unwrap();
    }
    for (name, tally) in &tallies {
        eprintln!("{name}: {} calls, slowest {:?}", tally.calls, tally.slowest);
        assert!(
            tally.unanswered.is_empty(),
            "{name}: unanswered within {CALL_LIMIT:?}: {:?}",
            tally.unanswered
        );
        assert!(
            tally.server_errors.is_empty(),
            "{name}: 5xx: {:?}",
            tally.server_errors
        );
        assert!(tally.calls > 0, "{name} made no call");
    }
    // Nothing is stuck: every job ends (the rest are cancelled), and SIGTERM still stops
    // the process promptly.
    for job in json_call(admin, "GET", "/admin/v1/jobs", None).json()["jobs"]
        .as_array()
        .unwrap()
    {
        if job["state"] == "queued" || job["state"] == "running" {
            json_call(
                admin,
                "POST",
                &format!("/admin/v1/jobs/{}/cancel", job["id"].as_str().unwrap()),
                None,
            );
        }
    }
    wait_until(Duration::from_secs(60), "every job finished", || {
        json_call(admin, "GET", "/admin/v1/jobs", None).json()["jobs"]
            .as_array()
            .unwrap()
            .iter()
            .all(|j| j["state"] != "queued" && j["state"] != "running")
    });
    assert_eq!(classify(port), 1);
    server.terminate_within(Duration::from_secs(15));
}

/// Hidden (temporary) entries anywhere below `dir`.
fn hidden_entries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().map(Result::unwrap) {
        let path = entry.path();
        if entry.file_name().to_string_lossy().starts_with('.') {
            found.push(path.clone());
        }
        if path.is_dir() {
            found.extend(hidden_entries(&path));
        }
    }
    found
}

fn submit(admin: u16, job: &Value) -> Reply {
    json_call(admin, "POST", "/admin/v1/jobs", Some(job))
}

/// Submit a job that must be accepted; returns its id.
fn accepted(admin: u16, job: &Value) -> String {
    let reply = submit(admin, job);
    assert_eq!(reply.status, 202, "{}", reply.json());
    reply.json()["id"].as_str().unwrap().to_string()
}

/// Wait for a job to end; returns its record.
fn finished(admin: u16, id: &str) -> Value {
    let mut doc = Value::Null;
    wait_until(Duration::from_secs(90), "the job's end", || {
        doc = job_state(admin, id);
        !matches!(doc["state"].as_str(), Some("queued" | "running"))
    });
    doc
}

/// Assert a problem document of `status` and type slug.
fn assert_problem(reply: &Reply, status: u16, slug: &str) -> Value {
    let doc = reply.json();
    assert_eq!(reply.status, status, "{doc}");
    assert_eq!(
        reply.header("content-type").as_deref(),
        Some("application/problem+json")
    );
    assert_eq!(
        doc["type"],
        format!("urn:reflectance:problem:{slug}"),
        "{doc}"
    );
    doc
}

#[test]
fn a_full_disk_refuses_job_records_and_takes_them_again_once_there_is_room() {
    let base = setup("full-records");
    add_render_inputs(&base);
    let server = launch(
        &base,
        Launch {
            file_size_limit: Some(256),
            ..Launch::default()
        },
    );
    let reply = submit(server.admin, &render_job("renders"));
    let doc = assert_problem(&reply, 507, "insufficient-storage");
    assert!(
        doc["detail"].as_str().unwrap().contains("job record"),
        "{doc}"
    );
    // Nothing half-made: no job, no record file, no temporary file; serving goes on.
    let jobs = json_call(server.admin, "GET", "/admin/v1/jobs", None).json();
    assert_eq!(jobs["jobs"], json!([]), "{jobs}");
    let jobs_dir = base.join("data/jobs");
    assert_eq!(std::fs::read_dir(&jobs_dir).unwrap().count(), 0);
    assert!(!base.join("data/renders").exists());
    assert_eq!(classify(server.port), 1);
    // Room again: the same server takes the job and runs it.
    server.lift_file_size_limit();
    let id = accepted(server.admin, &render_job("renders"));
    let doc = finished(server.admin, &id);
    assert_eq!(doc["state"], "succeeded", "{doc}");
    assert_eq!(doc["result"]["render"]["images"], 12, "{doc}");
}

/// An uncompressed tar of `members`.
fn tar_of(members: &[(&str, &[u8])]) -> Vec<u8> {
    let mut builder = tar::Builder::new(Vec::new());
    for (name, data) in members {
        let mut header = tar::Header::new_gnu();
        header.set_size(data.len() as u64);
        header.set_mode(0o644);
        builder.append_data(&mut header, name, *data).unwrap();
    }
    builder.into_inner().unwrap()
}

fn upload_dataset(admin: u16, archive: &[u8]) -> Reply {
    let (content_type, body) = multipart(&[
        ("name", Part::Text("mine")),
        ("archive", Part::File(archive)),
    ]);
    exchange(
        admin,
        "POST",
        "/admin/v1/datasets",
        &content_type,
        &body,
        Duration::from_secs(20),
    )
    .expect("an answer")
}

#[test]
fn a_full_disk_during_an_upload_answers_507_and_leaves_nothing() {
    let base = setup("full-upload");
    let server = launch(
        &base,
        Launch {
            file_size_limit: Some(64 * 1024),
            ..Launch::default()
        },
    );
    // The archive itself does not fit; then an archive that fits, but not unpacked.
    let big = vec![7u8; 100_000];
    let members: &[(&str, &[u8])] = &[
        ("manifest.csv", b"path,class,illumination\n"),
        ("a.pfm", &big),
    ];
    for archive in [tar_of(members), gzip(&tar_of(members))] {
        let doc = assert_problem(
            &upload_dataset(server.admin, &archive),
            507,
            "insufficient-storage",
        );
        let detail = doc["detail"].as_str().unwrap();
        assert!(
            detail.contains("archive") || detail.contains("a.pfm"),
            "{doc}"
        );
        let datasets = base.join("data/datasets");
        let left: Vec<_> = std::fs::read_dir(datasets.join(".incoming"))
            .map(|d| d.map(|e| e.unwrap().path()).collect())
            .unwrap_or_default();
        assert!(left.is_empty(), "{left:?}");
        assert!(!datasets.join("mine").exists());
    }
    assert_eq!(classify(server.port), 1);
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

#[test]
fn a_full_disk_while_a_version_is_written_fails_the_job_and_keeps_serving() {
    let base = setup("full-model");
    // Job records (a few KiB) fit; a model file (≈ 200 KiB) does not.
    let server = launch(
        &base,
        Launch {
            file_size_limit: Some(64 * 1024),
            ..Launch::default()
        },
    );
    let id = accepted(server.admin, &train_job("always"));
    let doc = finished(server.admin, &id);
    assert_eq!(doc["state"], "failed", "{doc}");
    let error = doc["error"].as_str().unwrap();
    assert!(error.contains("cannot publish a new version"), "{error}");
    assert!(error.contains("File too large"), "{error}");
    // No partial version, and the active one still answers.
    assert!(hidden_entries(&base.join("models")).is_empty());
    assert_eq!(entries(&base), ["1", "ACTIVE"]);
    assert_eq!(classify(server.port), 1);
    let versions = json_call(server.admin, "GET", "/admin/v1/models/ward6/versions", None).json();
    assert_eq!(
        versions["versions"].as_array().unwrap().len(),
        1,
        "{versions}"
    );
    // Room again: the same job succeeds without a restart.
    server.lift_file_size_limit();
    let id = accepted(server.admin, &train_job("always"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
    assert_eq!(classify(server.port), 2);
}

#[test]
fn a_read_only_registry_fails_training_clearly_and_keeps_serving() {
    let base = setup("ro-registry");
    let models = base.join("models");
    let server = launch(
        &base,
        Launch {
            read_only: vec![models.clone()],
            ..Launch::default()
        },
    );
    let id = accepted(server.admin, &train_job("always"));
    let doc = finished(server.admin, &id);
    assert_eq!(doc["state"], "failed", "{doc}");
    let error = doc["error"].as_str().unwrap();
    assert!(
        error.contains("cannot publish a new version")
            && (error.contains("Read-only file system") || error.contains("Permission denied")),
        "{error}"
    );
    assert_eq!(entries(&base), ["1"]);
    assert_eq!(classify(server.port), 1);
    // An activation holds in memory and says that it could not be recorded.
    let reply = activate(server.admin, 1);
    assert_eq!(reply.status, 200, "{}", reply.json());
    assert_eq!(reply.json()["persisted"], false, "{}", reply.json());
    set_writable(&models, true);
}

#[test]
fn a_read_only_data_dir_refuses_jobs_clearly_and_keeps_serving() {
    let base = setup("ro-data");
    add_render_inputs(&base);
    let data = base.join("data");
    std::fs::create_dir_all(data.join("jobs")).unwrap();
    // Job records in the read-only folder: the submission is refused, with the reason.
    let server = launch(
        &base,
        Launch {
            read_only: vec![data.clone()],
            ..Launch::default()
        },
    );
    let doc = assert_problem(
        &submit(server.admin, &train_job("never")),
        503,
        "storage-unavailable",
    );
    assert!(
        doc["detail"].as_str().unwrap().contains("job record"),
        "{doc}"
    );
    assert_problem(
        &upload_dataset(server.admin, &tar_of(&[("manifest.csv", b"path\n")])),
        503,
        "storage-unavailable",
    );
    assert_eq!(classify(server.port), 1);
    drop(server);
    // Job records elsewhere: a render into the read-only folder fails as a job, clearly.
    std::fs::create_dir_all(base.join("jobs")).unwrap();
    let jobs_dir = base.join("jobs").display().to_string();
    let server = launch(
        &base,
        Launch {
            read_only: vec![data.clone()],
            args: &["--jobs-dir", &jobs_dir],
            ..Launch::default()
        },
    );
    let id = accepted(server.admin, &render_job("renders"));
    let doc = finished(server.admin, &id);
    set_writable(&data, true);
    assert_eq!(doc["state"], "failed", "{doc}");
    let error = doc["error"].as_str().unwrap();
    assert!(
        error.contains("Read-only file system") || error.contains("Permission denied"),
        "{error}"
    );
    assert_eq!(classify(server.port), 1);
}

#[test]
fn the_models_folder_removed_or_replaced_while_serving() {
    let base = setup("models-gone");
    let models = base.join("models");
    let server = launch(&base, Launch::default());
    std::fs::remove_dir_all(&models).unwrap();
    // The active version is in memory: classification goes on.
    assert_eq!(classify(server.port), 1);
    let reply = json_call(server.admin, "GET", "/admin/v1/models/ward6/versions", None);
    assert_problem(&reply, 404, "model-not-found");
    let reply = activate(server.admin, 1);
    assert_problem(&reply, 404, "model-not-found");
    // A folder put back with other versions is what the registry shows from then on;
    // the served version changes only when one is activated.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    copy_dir(&root.join("models/ward6/1"), &models.join("ward6/1"));
    copy_dir(&root.join("models/ward6/1"), &models.join("ward6/2"));
    let file = models.join("ward6/2/model.json");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replacen("\"version\":1", "\"version\":2", 1)).unwrap();
    let versions = json_call(server.admin, "GET", "/admin/v1/models/ward6/versions", None).json();
    assert_eq!(versions["active"], 1, "{versions}");
    assert_eq!(
        versions["versions"].as_array().unwrap().len(),
        2,
        "{versions}"
    );
    assert_eq!(classify(server.port), 1);
    // Version 2's checksum no longer matches its edited file: refused, 1 keeps serving.
    let reply = activate(server.admin, 2);
    assert_problem(&reply, 422, "invalid-model");
    assert_eq!(classify(server.port), 1);
    // Training publishes into the new folder.
    let id = accepted(server.admin, &train_job("always"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
    assert_eq!(classify(server.port), 3);
}

#[test]
fn sigkill_during_a_render_job_then_a_resubmission_resumes() {
    let base = setup("render-kill");
    add_render_inputs(&base);
    let server = launch(
        &base,
        Launch {
            pause: Some("render-image=300"),
            ..Launch::default()
        },
    );
    let id = accepted(server.admin, &render_job("renders"));
    let out = base.join("data/renders");
    let done = || {
        std::fs::read_dir(&out).map_or(0, |d| {
            d.filter(|e| {
                e.as_ref()
                    .is_ok_and(|e| e.file_name().to_string_lossy().ends_with(".pfm"))
            })
            .count()
        })
    };
    wait_until(Duration::from_secs(30), "some images", || done() >= 2);
    server.kill();
    let before = done();
    assert!(before < 12, "the job finished before the kill");
    assert!(!out.join("manifest.csv").exists());

    let server = launch(&base, Launch::default());
    assert_eq!(job_state(server.admin, &id)["error"], "interrupted");
    let id = accepted(server.admin, &render_job("renders"));
    let doc = finished(server.admin, &id);
    assert_eq!(doc["state"], "succeeded", "{doc}");
    let render = &doc["result"]["render"];
    assert_eq!(render["images"], 12, "{doc}");
    assert!(
        render["skipped"].as_u64().unwrap() >= before as u64,
        "{doc}"
    );
    assert_eq!(
        render["rendered"].as_u64().unwrap() + render["skipped"].as_u64().unwrap(),
        12
    );
    // The resumed data set is the one an uninterrupted run makes, byte for byte.
    let id = accepted(server.admin, &render_job("again"));
    assert_eq!(finished(server.admin, &id)["state"], "succeeded");
    for entry in std::fs::read_dir(base.join("data/again"))
        .unwrap()
        .map(Result::unwrap)
    {
        let name = entry.file_name();
        assert_eq!(
            std::fs::read(entry.path()).unwrap(),
            std::fs::read(out.join(&name)).unwrap(),
            "{name:?}"
        );
    }
    assert!(hidden_entries(&out).is_empty());
}

/// Send the head and half the body of a request, then drop the connection.
fn abandon_upload(port: u16, path: &str, content_type: &str, body: &[u8]) {
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        stream,
        "POST {path} HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\n\
         Content-Type: {content_type}\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .unwrap();
    stream.write_all(&body[..body.len() / 2]).unwrap();
    stream.flush().unwrap();
    std::thread::sleep(Duration::from_millis(100));
}

#[test]
fn clients_that_disconnect_mid_upload_leave_nothing_behind() {
    let base = setup("disconnect");
    add_render_inputs(&base);
    let server = launch(&base, Launch::default());
    let png = common::sphere_png(400, 180.0);
    let (content_type, body) =
        multipart(&[("image", Part::File(&png)), ("white", Part::Text("0.8"))]);
    let job = serde_json::to_vec(&render_job("renders")).unwrap();
    for _ in 0..20 {
        abandon_upload(server.port, "/v1/classify", &content_type, &body);
        abandon_upload(server.admin, "/admin/v1/jobs", "application/json", &job);
    }
    assert_eq!(classify(server.port), 1);
    let jobs = json_call(server.admin, "GET", "/admin/v1/jobs", None).json();
    assert_eq!(jobs["jobs"], json!([]), "{jobs}");
    assert!(!base.join("data/renders").exists());
    let metrics = exchange(
        server.port,
        "GET",
        "/metrics",
        "text/plain",
        b"",
        CALL_LIMIT,
    )
    .unwrap();
    let text = String::from_utf8_lossy(&metrics.body);
    // (Readiness answers 503 while the models load: the test waits on it.)
    let server_errors: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("reflectance_http_requests_total") && l.contains("status=\"5"))
        .filter(|l| !l.contains("route=\"/health/ready\""))
        .collect();
    assert!(server_errors.is_empty(), "{server_errors:?}");
    let live = exchange(
        server.port,
        "GET",
        "/health/live",
        "text/plain",
        b"",
        CALL_LIMIT,
    );
    assert_eq!(live.map(|r| r.status), Some(200));
}
