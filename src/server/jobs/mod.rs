//! Admin jobs (`train`, `cross_validate`, `render`): a bounded queue in front of a fixed
//! pool of worker threads, off the request runtime, with cooperative cancellation and
//! progress, and a persisted record per job.
//!
//! **Records are atomic JSON files**, one per job (`<jobs-dir>/<id>.json`, written with
//! [`crate::fsutil::write_atomic`]: temporary file, fsync, rename). Jobs are rare and their
//! records change a few times a second at most, so an embedded database would buy nothing
//! but build time (SQLite or sqlx) and a second storage format; a rename is crash-safe, a
//! reader never sees a partial record, and the files are easy to inspect. On start-up,
//! records left `queued` or `running` by a previous process become `failed` with the error
//! `"interrupted"`.

pub mod paths;
mod run;

use super::error::{ApiError, Kind};
use super::metrics;
use super::state::ModelStore;
use crate::fsutil::write_atomic;
use crate::image_io::Limits;
use crate::progress::Observer;
use paths::DataDir;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};
use utoipa::ToSchema;

pub use run::{CvResult, FoldResult, JobResult, ModelRef, RenderResult};

/// What to do with a trained version.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Activate {
    /// Publish only (the active version stays).
    #[default]
    Never,
    /// Activate the new version.
    Always,
    /// Activate when its cross-validated accuracy is higher than the active version's
    /// stored one (or when the model has no active version).
    IfBetter,
}

/// Where the labelled data of a `train` or `cross_validate` job come from: exactly one of
/// `dataset` (a manifest; features are extracted first) or `table` (a feature table written
/// by `reflectance features --out`), relative to the data directory.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LearnParams {
    /// Manifest CSV relative to the data directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Feature table CSV relative to the data directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<String>,
    /// hand6, hand2, mean1, all, auto<N>, pca<N>, or a comma-separated list of names.
    #[serde(default = "default_features")]
    #[schema(default = "hand6")]
    pub features: String,
    /// svm, nn, knn5 or chance.
    #[serde(default = "default_classifier")]
    #[schema(default = "svm")]
    pub classifier: String,
    /// SVM C.
    #[serde(default = "default_c")]
    #[schema(default = 100.0)]
    pub c: f64,
    /// SVM γ (default 1 / number of classifier inputs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Choose C and γ by inner leave-one-illumination-out CV.
    #[serde(default)]
    pub grid: bool,
    #[serde(default = "default_seed")]
    #[schema(default = 1)]
    pub seed: u64,
    /// With `dataset`: also extract the log-domain features (`log.*`; implied by feature
    /// sets that name them, such as `hand6+log`).
    #[serde(default)]
    pub log_features: bool,
    /// With `dataset`: also extract the radial changes (`radial.*`; implied by feature sets
    /// that name them, such as `hand6+log+radial`).
    #[serde(default)]
    pub radial_features: bool,
    /// With `dataset`: also extract the orientation dependencies (`dep.*`; implied by
    /// feature sets that name them, such as `hand6+log+radial+dep`).
    #[serde(default)]
    pub dependency_features: bool,
    /// With `dataset`: reduce spheres larger than this radius (px, ≥ 32) before extraction;
    /// recorded in the model so that serving does the same.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub working_radius: Option<f64>,
}

fn default_features() -> String {
    "hand6".into()
}
fn default_classifier() -> String {
    "svm".into()
}
fn default_c() -> f64 {
    100.0
}
fn default_seed() -> u64 {
    1
}
fn default_size() -> usize {
    256
}
fn default_true() -> bool {
    true
}

/// A job to run, as posted to `POST /admin/v1/jobs`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum JobRequest {
    /// Train a model and publish it as a new version.
    Train {
        /// Model name (a-z, 0-9, '_', '-').
        name: String,
        #[serde(flatten)]
        data: LearnParams,
        #[serde(default)]
        activate: Activate,
        /// Class file with the classes' Ward parameters, relative to the data directory.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        classes: Option<String>,
        /// Store a leave-one-illumination-out CV summary with the model (required by
        /// `activate: if_better`).
        #[serde(default = "default_true")]
        #[schema(default = true)]
        cross_validate: bool,
    },
    /// Leave-one-illumination-out cross-validation.
    CrossValidate {
        #[serde(flatten)]
        data: LearnParams,
    },
    /// Render Ward spheres under light probes into a dataset with a manifest.
    Render {
        /// A folder of `.hdr` probes or a probe list file, relative to the data directory.
        probes: String,
        /// Class file (`{"classes": [{"name", "rho_d", "rho_s", "alpha"}]}`), relative to
        /// the data directory.
        classes: String,
        /// Output folder relative to the data directory (created).
        out: String,
        /// Image size in pixels (71…4096: the sphere's radius, size / 2.2, must be ≥ 32 px).
        #[serde(default = "default_size")]
        #[schema(default = 256, minimum = 71, maximum = 4096)]
        size: usize,
        #[serde(default = "default_seed")]
        #[schema(default = 1)]
        seed: u64,
    },
}

impl JobRequest {
    pub fn kind(&self) -> &'static str {
        match self {
            JobRequest::Train { .. } => "train",
            JobRequest::CrossValidate { .. } => "cross_validate",
            JobRequest::Render { .. } => "render",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 5] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
    ];

    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }

    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
}

/// How far a job is: `done` of `total` units (images or folds) of its current stage
/// (`queued`, `starting`, `features`, `fit`, `cross_validate`, `publish`, `activate`,
/// `render`, `done`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobProgress {
    pub stage: String,
    pub done: usize,
    pub total: usize,
}

/// A job and what became of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobRecord {
    pub id: String,
    pub state: JobState,
    /// The job as submitted (with defaults filled in).
    pub request: JobRequest,
    /// RFC 3339 times.
    pub created: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub finished: Option<String>,
    pub progress: JobProgress,
    /// Whether a cancellation was requested (a running job stops at its next check).
    #[serde(default)]
    pub cancel_requested: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub result: Option<JobResult>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Jobs waiting for a worker, first in first out; a job cancelled while waiting leaves it
/// at once.
struct Queue {
    waiting: VecDeque<String>,
    capacity: usize,
    open: bool,
}

/// The job system: records, queue and workers.
pub struct JobManager {
    dir: PathBuf,
    data: DataDir,
    limits: Limits,
    models: Arc<ModelStore>,
    records: Mutex<BTreeMap<String, JobRecord>>,
    /// Ids of finished records, oldest finish first; beyond `history` they are forgotten.
    finished: Mutex<VecDeque<String>>,
    history: usize,
    cancel: Mutex<HashMap<String, Arc<AtomicBool>>>,
    queue: Mutex<Queue>,
    wake: Condvar,
    workers: Mutex<Vec<std::thread::JoinHandle<()>>>,
}

impl JobManager {
    /// Open the jobs folder (marking records of a previous process that never finished as
    /// failed: "interrupted") and start `workers` threads behind a queue of `capacity`,
    /// keeping the `history` most recently finished records.
    pub fn start(
        jobs_dir: &Path,
        data_dir: &Path,
        limits: Limits,
        models: Arc<ModelStore>,
        workers: usize,
        capacity: usize,
        history: usize,
    ) -> Result<Arc<JobManager>, String> {
        std::fs::create_dir_all(jobs_dir)
            .map_err(|e| format!("jobs directory {}: {e}", jobs_dir.display()))?;
        let data = DataDir::new(data_dir)?;
        let records = load_records(jobs_dir)?;
        let manager = Arc::new(JobManager {
            dir: jobs_dir.to_path_buf(),
            data,
            limits,
            models,
            records: Mutex::new(records),
            finished: Mutex::new(VecDeque::new()),
            history,
            cancel: Mutex::new(HashMap::new()),
            queue: Mutex::new(Queue {
                waiting: VecDeque::new(),
                capacity,
                open: true,
            }),
            wake: Condvar::new(),
            workers: Mutex::new(Vec::new()),
        });
        manager.recover();
        let mut handles = Vec::new();
        for i in 0..workers {
            let weak = Arc::downgrade(&manager);
            let handle = std::thread::Builder::new()
                .name(format!("reflectance-job-{i}"))
                .spawn(move || worker(weak))
                .map_err(|e| format!("cannot start a job worker: {e}"))?;
            handles.push(handle);
        }
        *manager.workers.lock().unwrap_or_else(|e| e.into_inner()) = handles;
        manager.publish_metrics();
        Ok(manager)
    }

    /// Records a previous process left unfinished become failed ("interrupted").
    fn recover(&self) {
        let now = crate::model::now_rfc3339();
        let mut interrupted = Vec::new();
        {
            let mut records = self.records.lock().unwrap_or_else(|e| e.into_inner());
            for record in records.values_mut() {
                if !record.state.is_terminal() {
                    record.state = JobState::Failed;
                    record.error = Some("interrupted".into());
                    record.finished = Some(now.clone());
                    interrupted.push(record.clone());
                }
            }
        }
        for record in interrupted {
            tracing::warn!(job = %record.id, "job interrupted by a restart: marked failed");
            self.persist(&record);
        }
        let mut done: Vec<(String, String)> = self
            .lock_records()
            .values()
            .map(|r| (r.finished.clone().unwrap_or_default(), r.id.clone()))
            .collect();
        // Finish times have one-second resolution; ids order ties by creation.
        done.sort();
        for (_, id) in done {
            self.retire(&id);
        }
    }

    /// Count a record as finished, and forget the oldest finished ones beyond the history.
    fn retire(&self, id: &str) {
        // A job cancelled while queued never reaches a worker, which would drop its flag.
        self.lock_cancel().remove(id);
        let forgotten: Vec<String> = {
            let mut finished = self.finished.lock().unwrap_or_else(|e| e.into_inner());
            finished.push_back(id.to_string());
            let excess = finished.len().saturating_sub(self.history);
            finished.drain(..excess).collect()
        };
        if forgotten.is_empty() {
            return;
        }
        let mut records = self.lock_records();
        for old in forgotten {
            records.remove(&old);
            let path = self.record_path(&old);
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => {
                    tracing::warn!(job = %old, path = %path.display(), error = %e, "cannot remove an old job record")
                }
            }
        }
    }

    fn record_path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.json"))
    }

    pub fn data_dir(&self) -> &DataDir {
        &self.data
    }

    /// Validate and enqueue a job. Blocking (writes its record).
    pub fn submit(&self, request: JobRequest) -> Result<JobRecord, ApiError> {
        run::validate(&request, &self.data)?;
        let id = new_id();
        let record = JobRecord {
            id: id.clone(),
            state: JobState::Queued,
            request,
            created: crate::model::now_rfc3339(),
            started: None,
            finished: None,
            progress: JobProgress {
                stage: "queued".into(),
                done: 0,
                total: 0,
            },
            cancel_requested: false,
            result: None,
            error: None,
        };
        {
            let mut queue = self.lock_queue();
            if !queue.open {
                return Err(
                    ApiError::new(Kind::NotReady, "the job system is shutting down").retry_after(5),
                );
            }
            if queue.waiting.len() >= queue.capacity {
                return Err(ApiError::new(
                    Kind::JobQueueFull,
                    "the job queue is full; retry when running jobs have finished",
                )
                .retry_after(10));
            }
            self.lock_records().insert(id.clone(), record.clone());
            self.lock_cancel()
                .insert(id.clone(), Arc::new(AtomicBool::new(false)));
            // Persisted before a worker can see it, so a record never goes back in time.
            self.persist(&record);
            queue.waiting.push_back(id.clone());
        }
        self.wake.notify_one();
        self.publish_metrics();
        tracing::info!(job = %id, kind = record.request.kind(), "job queued");
        Ok(record)
    }

    pub fn get(&self, id: &str) -> Result<JobRecord, ApiError> {
        self.lock_records()
            .get(id)
            .cloned()
            .ok_or_else(|| ApiError::new(Kind::JobNotFound, format!("unknown job {id:?}")))
    }

    /// Jobs, newest first, optionally in one state.
    pub fn list(&self, state: Option<JobState>) -> Vec<JobRecord> {
        let records = self.lock_records();
        let mut out: Vec<JobRecord> = records
            .values()
            .filter(|r| state.is_none_or(|s| r.state == s))
            .cloned()
            .collect();
        out.sort_by(|a, b| b.created.cmp(&a.created).then(b.id.cmp(&a.id)));
        out
    }

    /// Request cancellation: a queued job is cancelled at once, a running one at its next
    /// check (between images or folds). Blocking (writes the record).
    pub fn cancel(&self, id: &str) -> Result<JobRecord, ApiError> {
        let record = {
            let mut records = self.lock_records();
            let record = records
                .get_mut(id)
                .ok_or_else(|| ApiError::new(Kind::JobNotFound, format!("unknown job {id:?}")))?;
            if record.state.is_terminal() {
                return Err(ApiError::new(
                    Kind::JobFinished,
                    format!("job {id} has already {}", record.state.as_str()),
                ));
            }
            record.cancel_requested = true;
            if record.state == JobState::Queued {
                self.lock_queue().waiting.retain(|q| q != id);
                record.state = JobState::Cancelled;
                record.finished = Some(crate::model::now_rfc3339());
                record.error = Some("cancelled before it started".into());
            }
            record.clone()
        };
        if let Some(flag) = self.lock_cancel().get(id) {
            flag.store(true, Ordering::SeqCst);
        }
        self.persist(&record);
        if record.state.is_terminal() {
            self.retire(id);
        }
        self.publish_metrics();
        tracing::info!(job = %id, "job cancellation requested");
        Ok(record)
    }

    /// Stop taking jobs; running jobs are asked to stop. Idempotent.
    pub fn shutdown(&self) {
        self.lock_queue().open = false;
        self.wake.notify_all();
        for flag in self.lock_cancel().values() {
            flag.store(true, Ordering::SeqCst);
        }
    }

    /// Wait (up to `timeout`) for the workers to finish after [`JobManager::shutdown`].
    pub fn join(&self, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        let handles: Vec<_> = self
            .workers
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain(..)
            .collect();
        for handle in handles {
            while !handle.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(20));
            }
            if handle.is_finished() {
                let _ = handle.join();
            }
        }
    }

    pub fn queue_depth(&self) -> usize {
        self.lock_queue().waiting.len()
    }

    fn lock_queue(&self) -> std::sync::MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The next job, waiting for one; `None` once shut down.
    fn next_job(&self) -> Option<String> {
        let mut queue = self.lock_queue();
        loop {
            if !queue.open {
                return None;
            }
            if let Some(id) = queue.waiting.pop_front() {
                return Some(id);
            }
            queue = self.wake.wait(queue).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn lock_records(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, JobRecord>> {
        self.records.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn lock_cancel(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<AtomicBool>>> {
        self.cancel.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn persist(&self, record: &JobRecord) {
        let path = self.record_path(&record.id);
        let written = serde_json::to_vec_pretty(record)
            .map_err(std::io::Error::other)
            .and_then(|bytes| write_atomic(&path, &bytes));
        if let Err(e) = written {
            tracing::error!(job = %record.id, path = %path.display(), error = %e, "cannot persist job record");
        }
    }

    /// Update a record in memory (and on disk when `persist`).
    fn update(&self, id: &str, persist: bool, f: impl FnOnce(&mut JobRecord)) {
        let record = {
            let mut records = self.lock_records();
            let Some(record) = records.get_mut(id) else {
                return;
            };
            f(record);
            record.clone()
        };
        if persist {
            self.persist(&record);
        }
    }

    fn publish_metrics(&self) {
        let counts: Vec<(&'static str, usize)> = {
            let records = self.lock_records();
            JobState::ALL
                .iter()
                .map(|s| {
                    (
                        s.as_str(),
                        records.values().filter(|r| r.state == *s).count(),
                    )
                })
                .collect()
        };
        metrics::jobs(&counts, self.queue_depth());
    }

    /// Run one job from the queue.
    fn execute(self: &Arc<Self>, id: String) {
        let flag = self.lock_cancel().get(&id).cloned();
        let Some(flag) = flag else { return };
        let request = {
            let mut records = self.lock_records();
            let Some(record) = records.get_mut(&id) else {
                return;
            };
            if record.state != JobState::Queued {
                // Cancelled while queued.
                drop(records);
                self.lock_cancel().remove(&id);
                self.publish_metrics();
                return;
            }
            record.state = JobState::Running;
            record.started = Some(crate::model::now_rfc3339());
            record.progress.stage = "starting".into();
            record.request.clone()
        };
        self.update(&id, true, |_| {});
        self.publish_metrics();
        tracing::info!(job = %id, kind = request.kind(), "job started");
        let observer = JobObserver {
            manager: self.clone(),
            id: id.clone(),
            flag: flag.clone(),
            last_persist: Mutex::new(Instant::now()),
        };
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run::execute(&request, &self.data, &self.limits, &self.models, &observer)
        }))
        .unwrap_or_else(|_| Err(run::Failure::Error("the job panicked".into())));
        let finished = crate::model::now_rfc3339();
        // Trim the history first: whoever sees this job finished sees the trimmed history.
        self.retire(&id);
        self.update(&id, true, |record| {
            record.finished = Some(finished);
            match outcome {
                Ok(result) => {
                    record.state = JobState::Succeeded;
                    record.progress.stage = "done".into();
                    record.result = Some(result);
                }
                Err(run::Failure::Cancelled) => {
                    record.state = JobState::Cancelled;
                    record.error = Some("cancelled".into());
                }
                Err(run::Failure::Error(message)) => {
                    record.state = JobState::Failed;
                    record.error = Some(message);
                }
                Err(run::Failure::Partial(message, result)) => {
                    record.state = JobState::Failed;
                    record.error = Some(message);
                    record.result = Some(*result);
                }
            }
            tracing::info!(job = %record.id, state = record.state.as_str(), error = ?record.error, "job finished");
        });
        self.publish_metrics();
    }
}

fn worker(manager: std::sync::Weak<JobManager>) {
    loop {
        let Some(manager) = manager.upgrade() else {
            return;
        };
        let Some(id) = manager.next_job() else { return };
        manager.execute(id);
    }
}

/// Progress and cancellation of one running job.
struct JobObserver {
    manager: Arc<JobManager>,
    id: String,
    flag: Arc<AtomicBool>,
    last_persist: Mutex<Instant>,
}

/// Progress is written to disk at most this often (and at every stage change).
const PERSIST_EVERY: Duration = Duration::from_millis(500);

impl Observer for JobObserver {
    fn stage(&self, name: &'static str) {
        self.manager.update(&self.id, true, |r| {
            r.progress = JobProgress {
                stage: name.into(),
                done: 0,
                total: 0,
            };
        });
    }

    fn progress(&self, done: usize, total: usize) {
        let persist = {
            let mut last = self.last_persist.lock().unwrap_or_else(|e| e.into_inner());
            if last.elapsed() >= PERSIST_EVERY || done == total {
                *last = Instant::now();
                true
            } else {
                false
            }
        };
        self.manager.update(&self.id, persist, |r| {
            r.progress.done = done;
            r.progress.total = total;
        });
    }

    fn cancelled(&self) -> bool {
        self.flag.load(Ordering::SeqCst)
    }
}

fn load_records(dir: &Path) -> Result<BTreeMap<String, JobRecord>, String> {
    let mut records = BTreeMap::new();
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries.filter_map(|e| e.ok()) {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            // A temporary file of an interrupted write.
            let _ = std::fs::remove_file(&path);
            continue;
        }
        if !name.ends_with(".json") {
            continue;
        }
        let parsed = std::fs::read(&path)
            .map_err(|e| e.to_string())
            .and_then(|b| serde_json::from_slice::<JobRecord>(&b).map_err(|e| e.to_string()));
        match parsed {
            Ok(record) => {
                records.insert(record.id.clone(), record);
            }
            Err(e) => {
                tracing::warn!(path = %path.display(), error = %e, "unreadable job record skipped")
            }
        }
    }
    Ok(records)
}

/// A job id: time-ordered and unique (nanoseconds since the epoch, a process counter).
fn new_id() -> String {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!(
        "{nanos:x}{:04x}{:04x}",
        std::process::id() & 0xffff,
        n & 0xffff
    )
}
