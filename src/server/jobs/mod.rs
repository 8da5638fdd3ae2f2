//! Admin jobs (`train`, `cross_validate`, `render`): a bounded queue in front of a fixed
//! pool of worker threads, off the request runtime, with cooperative cancellation and
//! progress, and a persisted record per job.
//!
//! **Records are atomic JSON files**, one per job (`<jobs-dir>/<id>.json`, written with
//! [`reflectance_core::util::durable::write_atomic`]: temporary file, fsync, rename). Jobs are rare and their
//! records change a few times a second at most, so an embedded database would buy nothing
//! but build time (SQLite or sqlx) and a second storage format; a rename is crash-safe, a
//! reader never sees a partial record, and the files are easy to inspect. On start-up,
//! records left `queued` or `running` by a previous process become `failed` with the error
//! `"interrupted"`.

pub(crate) mod paths;
mod run;
mod types;

use super::metrics;
use crate::server::store::ModelStore;
use paths::DataDir;
use reflectance_core::decode::Limits;
use reflectance_core::util::durable::write_atomic;
use reflectance_core::util::progress::Observer;
use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub use run::{JobError, JobResult};
pub use types::{JobProgress, JobRecord, JobRequest, JobState, LearnParams};

pub use reflectance_core::model::publish::Activate;

/// Whether `rel`, a path relative to the data directory, is `folder` or inside it.
fn is_under(rel: &str, folder: &Path) -> bool {
    let rel: PathBuf = Path::new(rel)
        .components()
        .filter(|c| *c != std::path::Component::CurDir)
        .collect();
    rel.starts_with(folder)
}

/// Everything about the jobs that changes, behind one lock ([`JobManager::state`]).
struct Jobs {
    records: BTreeMap<String, JobRecord>,
    /// Jobs waiting for a worker, first in first out; a job cancelled while waiting leaves
    /// at once.
    waiting: VecDeque<String>,
    /// Cancellation flags of unfinished jobs (a running job polls its own).
    cancel: HashMap<String, Arc<AtomicBool>>,
    /// Ids of finished records, oldest finish first; beyond `history` they are forgotten.
    finished: VecDeque<String>,
    /// Records whose latest state could not be written (e.g. a full disk); every later
    /// write tries them again.
    unsaved: BTreeSet<String>,
    /// False once shutting down.
    open: bool,
}

impl Jobs {
    fn counts(&self) -> Vec<(&'static str, usize)> {
        JobState::ALL
            .iter()
            .map(|s| {
                (
                    s.as_str(),
                    self.records.values().filter(|r| r.state == *s).count(),
                )
            })
            .collect()
    }

    /// Count a record as finished; returns the oldest finished ones beyond `history`,
    /// forgotten here (their files are for the caller to remove).
    fn retire(&mut self, id: &str, history: usize) -> Vec<String> {
        self.cancel.remove(id);
        self.finished.push_back(id.to_string());
        let excess = self.finished.len().saturating_sub(history);
        let forgotten: Vec<String> = self.finished.drain(..excess).collect();
        for old in &forgotten {
            self.records.remove(old);
            self.unsaved.remove(old);
        }
        forgotten
    }
}

/// The job system: records, queue and workers.
///
/// **Locking.** All job state is behind the one `state` mutex, held only for memory
/// updates: no I/O, no other lock taken inside it. Record files are written outside it,
/// under `disk`, which serializes the writers; each write takes the record's *latest*
/// state from `state` at that moment, so a file never goes back in time however the
/// writers interleave. The only nesting is `disk` → `state`. Handlers call the blocking
/// methods from `spawn_blocking`, so a slow disk never holds a runtime thread.
pub struct JobManager {
    dir: PathBuf,
    data: DataDir,
    limits: Limits,
    models: Arc<ModelStore>,
    capacity: usize,
    history: usize,
    state: Mutex<Jobs>,
    /// Workers wait on it for a queued job (with `state`).
    wake: Condvar,
    disk: Mutex<()>,
    workers: Mutex<Vec<std::thread::JoinHandle<()>>>,
    /// Every change of a record, for the job's event streams (sent only while one listens).
    changes: tokio::sync::broadcast::Sender<JobRecord>,
}

/// Changes a slow event stream may fall behind by before it reads the record afresh.
const CHANGES_BUFFERED: usize = 1024;

/// Why the job system refuses a request (`server::error` maps it to HTTP).
#[derive(Debug, thiserror::Error)]
pub enum ManagerError {
    /// The job itself: its parameters or paths.
    #[error(transparent)]
    Refused(Box<JobError>),
    #[error("the job system is shutting down")]
    ShuttingDown,
    #[error("the job queue is full; retry when running jobs have finished")]
    QueueFull,
    /// Its record cannot be written.
    #[error(transparent)]
    Persist(#[from] PersistError),
    #[error("unknown job {0:?}")]
    UnknownJob(String),
    /// Cancelling a job that has ended.
    #[error("job {id} has already {}", state.as_str())]
    Finished { id: String, state: JobState },
}

impl From<JobError> for ManagerError {
    fn from(e: JobError) -> ManagerError {
        ManagerError::Refused(Box::new(e))
    }
}

/// A record file that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write the job record {path}: {source}")]
pub struct PersistError {
    pub path: String,
    pub source: std::io::Error,
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
    ) -> Result<Arc<JobManager>, OpenError> {
        std::fs::create_dir_all(jobs_dir).map_err(|source| OpenError::JobsDir {
            dir: jobs_dir.display().to_string(),
            source,
        })?;
        let data = DataDir::new(data_dir)?;
        let records = load_records(jobs_dir)?;
        let manager = Arc::new(JobManager {
            dir: jobs_dir.to_path_buf(),
            data,
            limits,
            models,
            capacity,
            history,
            state: Mutex::new(Jobs {
                records,
                waiting: VecDeque::new(),
                cancel: HashMap::new(),
                finished: VecDeque::new(),
                unsaved: BTreeSet::new(),
                open: true,
            }),
            wake: Condvar::new(),
            changes: tokio::sync::broadcast::channel(CHANGES_BUFFERED).0,
            disk: Mutex::new(()),
            workers: Mutex::new(Vec::new()),
        });
        manager.recover();
        let mut handles = Vec::new();
        for i in 0..workers {
            let weak = Arc::downgrade(&manager);
            let handle = std::thread::Builder::new()
                .name(format!("reflectance-job-{i}"))
                .spawn(move || worker(weak))
                .map_err(OpenError::Worker)?;
            handles.push(handle);
        }
        *manager.workers.lock().unwrap_or_else(|e| e.into_inner()) = handles;
        manager.publish_metrics();
        Ok(manager)
    }

    fn lock(&self) -> MutexGuard<'_, Jobs> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn lock_disk(&self) -> MutexGuard<'_, ()> {
        self.disk.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Records a previous process left unfinished become failed ("interrupted").
    fn recover(&self) {
        let now = reflectance_core::model::now_rfc3339();
        let (interrupted, forgotten) = {
            let mut jobs = self.lock();
            let mut interrupted = Vec::new();
            for record in jobs.records.values_mut() {
                if !record.state.is_terminal() {
                    record.state = JobState::Failed;
                    record.error = Some("interrupted".into());
                    record.finished = Some(now.clone());
                    interrupted.push(record.id.clone());
                }
            }
            let mut done: Vec<(String, String)> = jobs
                .records
                .values()
                .map(|r| (r.finished.clone().unwrap_or_default(), r.id.clone()))
                .collect();
            // Finish times have one-second resolution; ids order ties by creation.
            done.sort();
            let mut forgotten = Vec::new();
            for (_, id) in done {
                forgotten.extend(jobs.retire(&id, self.history));
            }
            (interrupted, forgotten)
        };
        for id in &interrupted {
            tracing::warn!(job = %id, "job interrupted by a restart: marked failed");
            self.save(id);
        }
        self.remove_files(&forgotten);
    }

    fn record_path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.json"))
    }

    pub fn data_dir(&self) -> &DataDir {
        &self.data
    }

    /// Refuse a submission while shutting down or when the queue is full.
    fn admission(&self, jobs: &Jobs) -> Result<(), ManagerError> {
        if !jobs.open {
            return Err(ManagerError::ShuttingDown);
        }
        if jobs.waiting.len() >= self.capacity {
            return Err(ManagerError::QueueFull);
        }
        Ok(())
    }

    /// Validate and enqueue a job. Blocking: its record is on disk before it is queued, so
    /// an accepted job survives a crash (as `interrupted`), and a job whose record cannot
    /// be written (a full or read-only disk) is refused with that reason.
    pub fn submit(&self, request: JobRequest) -> Result<JobRecord, ManagerError> {
        run::validate(&request, &self.data)?;
        self.admission(&self.lock())?;
        let id = new_id();
        let record = JobRecord {
            id: id.clone(),
            state: JobState::Queued,
            request,
            created: reflectance_core::model::now_rfc3339(),
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
            // Nobody else knows the id yet; `disk` is held until the record is queued so
            // that no other write of it can come first.
            let _disk = self.lock_disk();
            self.write(&record)?;
            let mut jobs = self.lock();
            if let Err(refused) = self.admission(&jobs) {
                drop(jobs);
                self.delete(std::slice::from_ref(&id));
                return Err(refused);
            }
            jobs.records.insert(id.clone(), record.clone());
            jobs.cancel
                .insert(id.clone(), Arc::new(AtomicBool::new(false)));
            jobs.waiting.push_back(id.clone());
        }
        self.wake.notify_one();
        self.publish_metrics();
        tracing::info!(job = %id, kind = record.request.kind(), "job queued");
        Ok(record)
    }

    /// A queued or running job that reads or writes inside `folder` (relative to the data
    /// directory), if any.
    pub fn user_of(&self, folder: &Path) -> Option<String> {
        self.lock()
            .records
            .values()
            .filter(|r| !r.state.is_terminal())
            .find(|r| r.request.paths().iter().any(|p| is_under(p, folder)))
            .map(|r| r.id.clone())
    }

    pub fn get(&self, id: &str) -> Result<JobRecord, ManagerError> {
        self.lock()
            .records
            .get(id)
            .cloned()
            .ok_or_else(|| unknown_job(id))
    }

    /// Jobs, newest first, optionally in one state.
    pub fn list(&self, state: Option<JobState>) -> Vec<JobRecord> {
        let mut out: Vec<JobRecord> = self
            .lock()
            .records
            .values()
            .filter(|r| state.is_none_or(|s| r.state == s))
            .cloned()
            .collect();
        out.sort_by(|a, b| b.created.cmp(&a.created).then(b.id.cmp(&a.id)));
        out
    }

    /// Request cancellation: a queued job is cancelled at once, a running one at its next
    /// check (between images or folds). Blocking (writes the record).
    pub fn cancel(&self, id: &str) -> Result<JobRecord, ManagerError> {
        let (record, forgotten) = {
            let mut jobs = self.lock();
            let record = jobs.records.get_mut(id).ok_or_else(|| unknown_job(id))?;
            if record.state.is_terminal() {
                return Err(ManagerError::Finished {
                    id: id.to_string(),
                    state: record.state,
                });
            }
            record.cancel_requested = true;
            let queued = record.state == JobState::Queued;
            if queued {
                record.state = JobState::Cancelled;
                record.finished = Some(reflectance_core::model::now_rfc3339());
                record.error = Some("cancelled before it started".into());
            }
            let record = record.clone();
            self.announce(&record);
            if let Some(flag) = jobs.cancel.get(id) {
                flag.store(true, Ordering::SeqCst);
            }
            let forgotten = if queued {
                jobs.waiting.retain(|q| q != id);
                jobs.retire(id, self.history)
            } else {
                Vec::new()
            };
            (record, forgotten)
        };
        self.save(id);
        self.remove_files(&forgotten);
        self.publish_metrics();
        tracing::info!(job = %id, "job cancellation requested");
        Ok(record)
    }

    /// Stop taking jobs; running jobs are asked to stop. Idempotent.
    pub fn shutdown(&self) {
        {
            let mut jobs = self.lock();
            jobs.open = false;
            for flag in jobs.cancel.values() {
                flag.store(true, Ordering::SeqCst);
            }
        }
        self.wake.notify_all();
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

    /// The next job, marked running, with its request and cancellation flag; waits for
    /// one; `None` once shut down.
    fn next_job(&self) -> Option<(String, JobRequest, Arc<AtomicBool>)> {
        let mut jobs = self.lock();
        loop {
            if !jobs.open {
                return None;
            }
            while let Some(id) = jobs.waiting.pop_front() {
                let Some(flag) = jobs.cancel.get(&id).cloned() else {
                    continue;
                };
                let queued = jobs.records.get_mut(&id);
                let Some(record) = queued.filter(|r| r.state == JobState::Queued) else {
                    continue;
                };
                record.state = JobState::Running;
                record.started = Some(reflectance_core::model::now_rfc3339());
                record.progress.stage = "starting".into();
                self.announce(record);
                return Some((id, record.request.clone(), flag));
            }
            jobs = self.wake.wait(jobs).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Write one record file (the caller holds `disk`).
    fn write(&self, record: &JobRecord) -> Result<(), PersistError> {
        let path = self.record_path(&record.id);
        serde_json::to_vec_pretty(record)
            .map_err(std::io::Error::other)
            .and_then(|bytes| write_atomic(&path, &bytes))
            .map_err(|source| PersistError {
                path: path.display().to_string(),
                source,
            })
    }

    /// Write the latest state of `id`, and of every record a failed write left unsaved.
    /// A failure is logged and retried at the next write: the record in memory stays
    /// right, and a restart marks a job whose final state never reached the disk as
    /// interrupted.
    fn save(&self, id: &str) {
        let _disk = self.lock_disk();
        let pending: Vec<JobRecord> = {
            let mut jobs = self.lock();
            let mut ids = std::mem::take(&mut jobs.unsaved);
            ids.insert(id.to_string());
            ids.iter()
                .filter_map(|id| jobs.records.get(id).cloned())
                .collect()
        };
        let failed: Vec<String> = pending
            .iter()
            .filter_map(|record| match self.write(record) {
                Ok(()) => None,
                Err(e) => {
                    tracing::error!(job = %record.id, error = %e, "job record not saved; will retry");
                    metrics::job_record_unsaved();
                    Some(record.id.clone())
                }
            })
            .collect();
        if !failed.is_empty() {
            let mut jobs = self.lock();
            for id in failed {
                if jobs.records.contains_key(&id) {
                    jobs.unsaved.insert(id);
                }
            }
        }
    }

    /// Delete the files of forgotten records.
    fn remove_files(&self, ids: &[String]) {
        if !ids.is_empty() {
            let _disk = self.lock_disk();
            self.delete(ids);
        }
    }

    /// Delete record files (the caller holds `disk`).
    fn delete(&self, ids: &[String]) {
        for id in ids {
            let path = self.record_path(id);
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => {
                    tracing::warn!(job = %id, path = %path.display(), error = %e, "cannot remove an old job record")
                }
            }
        }
    }

    /// Update a record in memory (and on disk when `persist`).
    /// Every change of a record from now on (what `GET /admin/v1/jobs/{id}/events` reads).
    pub fn subscribe(&self) -> tokio::sync::broadcast::Receiver<JobRecord> {
        self.changes.subscribe()
    }

    fn announce(&self, record: &JobRecord) {
        if self.changes.receiver_count() > 0 {
            let _ = self.changes.send(record.clone());
        }
    }

    fn update(&self, id: &str, persist: bool, f: impl FnOnce(&mut JobRecord)) {
        {
            let mut jobs = self.lock();
            let Some(record) = jobs.records.get_mut(id) else {
                return;
            };
            f(record);
            self.announce(record);
        }
        if persist {
            self.save(id);
        }
    }

    fn publish_metrics(&self) {
        let (counts, queued) = {
            let jobs = self.lock();
            (jobs.counts(), jobs.waiting.len())
        };
        metrics::jobs(&counts, queued);
    }

    /// Run one job taken from the queue.
    fn execute(self: &Arc<Self>, id: String, request: JobRequest, flag: Arc<AtomicBool>) {
        self.save(&id);
        self.publish_metrics();
        tracing::info!(job = %id, kind = request.kind(), "job started");
        let observer = JobObserver {
            manager: self.clone(),
            id: id.clone(),
            flag,
            last_persist: Mutex::new(Instant::now()),
        };
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run::execute(&request, &self.data, &self.limits, &self.models, &observer)
        }))
        .unwrap_or_else(|_| Err(JobError::Panicked.into()));
        self.conclude(&id, outcome);
        self.publish_metrics();
    }

    /// Record how a job ended. The final record is on disk, and the records the history
    /// forgets are gone from it, before anyone can see the job finished: `disk` is held
    /// throughout, so no other write comes between.
    fn conclude(&self, id: &str, outcome: Result<JobResult, run::Failure>) {
        let _disk = self.lock_disk();
        let Some(mut record) = self.lock().records.get(id).cloned() else {
            return;
        };
        finish(&mut record, reflectance_core::model::now_rfc3339(), outcome);
        let state = record.state.as_str();
        match &record.error {
            Some(error) => tracing::info!(job = %id, state, %error, "job finished"),
            None => tracing::info!(job = %id, state, "job finished"),
        }
        let mut saved = self.write(&record).is_ok();
        let (forgotten, latest) = {
            let mut jobs = self.lock();
            let latest = jobs.records.get_mut(id).map(|current| {
                let mut latest = record.clone();
                // A cancellation may have been asked for meanwhile.
                latest.cancel_requested |= current.cancel_requested;
                *current = latest.clone();
                self.announce(&latest);
                latest
            });
            (jobs.retire(id, self.history), latest)
        };
        if let Some(latest) = latest.filter(|latest| !saved || *latest != record) {
            saved = self.write(&latest).is_ok();
        }
        if !saved {
            metrics::job_record_unsaved();
            tracing::error!(job = %id, "the final job record was not saved; will retry");
            let mut jobs = self.lock();
            if jobs.records.contains_key(id) {
                jobs.unsaved.insert(id.to_string());
            }
        }
        self.delete(&forgotten);
    }
}

fn unknown_job(id: &str) -> ManagerError {
    ManagerError::UnknownJob(id.to_string())
}

/// Record how a job ended.
fn finish(record: &mut JobRecord, finished: String, outcome: Result<JobResult, run::Failure>) {
    record.finished = Some(finished);
    match outcome {
        Ok(result) => {
            record.state = JobState::Succeeded;
            // Complete: the last stage's units, or one for a stage without any (publish).
            let units = record.progress.total.max(1);
            record.progress = JobProgress {
                stage: "done".into(),
                done: units,
                total: units,
            };
            record.result = Some(result);
        }
        Err(run::Failure::Cancelled) => {
            record.state = JobState::Cancelled;
            record.error = Some("cancelled".into());
        }
        Err(run::Failure::Error(e)) => {
            record.state = JobState::Failed;
            record.error = Some(e.to_string());
        }
        Err(run::Failure::Partial(e, result)) => {
            record.state = JobState::Failed;
            record.error = Some(e.to_string());
            record.result = Some(*result);
        }
    }
}

fn worker(manager: std::sync::Weak<JobManager>) {
    loop {
        let Some(manager) = manager.upgrade() else {
            return;
        };
        let Some((id, request, flag)) = manager.next_job() else {
            return;
        };
        manager.execute(id, request, flag);
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

/// Why the job system cannot start: its folders, or its workers.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    #[error("jobs directory {dir}: {source}")]
    JobsDir { dir: String, source: std::io::Error },
    #[error(transparent)]
    DataDir(#[from] paths::PathError),
    #[error("cannot start a job worker: {0}")]
    Worker(std::io::Error),
}

fn load_records(dir: &Path) -> Result<BTreeMap<String, JobRecord>, OpenError> {
    let mut records = BTreeMap::new();
    let entries = std::fs::read_dir(dir).map_err(|source| OpenError::JobsDir {
        dir: dir.display().to_string(),
        source,
    })?;
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
pub(crate) fn new_id() -> String {
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
