//! Shared state: readiness, the model store ([`super::store`]), the job system, and the CPU
//! pool that keeps decoding and feature extraction off the async runtime.

use super::config::Config;
use super::error::{ApiError, Kind};
use super::jobs::JobManager;
use super::metrics;
pub use super::store::ModelStore;
pub use reflectance_core::inference::LoadedModel;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

/// Life cycle of the process, as `/health/ready` reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    Loading = 0,
    Ready = 1,
    Draining = 2,
}

#[derive(Debug, Default)]
pub struct Readiness(AtomicU8);

impl Readiness {
    pub fn get(&self) -> Phase {
        match self.0.load(Ordering::Acquire) {
            0 => Phase::Loading,
            1 => Phase::Ready,
            _ => Phase::Draining,
        }
    }
    pub fn set(&self, phase: Phase) {
        self.0.store(phase as u8, Ordering::Release);
    }
}

/// A fixed pool of threads for decoding and feature extraction, in front of which a
/// semaphore admits at most `max_inflight` requests: the next one is shed at once (429).
pub struct CpuPool {
    pool: rayon::ThreadPool,
    admission: Arc<Semaphore>,
}

impl CpuPool {
    pub fn new(
        threads: usize,
        max_inflight: usize,
    ) -> Result<CpuPool, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("reflectance-cpu-{i}"))
            .build()?;
        Ok(CpuPool {
            pool,
            admission: Arc::new(Semaphore::new(max_inflight)),
        })
    }

    /// A place in the pool's queue, or 429 when the service is saturated.
    pub fn admit(&self) -> Result<OwnedSemaphorePermit, ApiError> {
        self.admit_many(1)
    }

    /// `n` places at once (a batch counts as `n` requests), or 429.
    pub fn admit_many(&self, n: usize) -> Result<OwnedSemaphorePermit, ApiError> {
        let n = u32::try_from(n).unwrap_or(u32::MAX);
        self.admission
            .clone()
            .try_acquire_many_owned(n)
            .map_err(|_| {
                metrics::shed();
                ApiError::new(
                    Kind::Overloaded,
                    "too many requests in progress; retry shortly",
                )
                .retry_after(1)
            })
    }

    /// Requests admitted now.
    pub fn inflight(&self, max: usize) -> usize {
        max - self.admission.available_permits()
    }

    /// Run `work` on the pool (first come, first served) holding `permit` until it ends.
    pub async fn run<T: Send + 'static>(
        &self,
        permit: OwnedSemaphorePermit,
        work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        self.spawn(permit, work).await
    }

    /// Queue `work` on the pool now; its result when awaited.
    pub fn spawn<T, F>(
        &self,
        permit: OwnedSemaphorePermit,
        work: F,
    ) -> impl Future<Output = Result<T, ApiError>> + use<T, F>
    where
        T: Send + 'static,
        F: FnOnce() -> Result<T, ApiError> + Send + 'static,
    {
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.pool.spawn_fifo(move || {
            let running = reflectance_core::util::parallel::Running::start();
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work))
                .unwrap_or_else(|panic| {
                    let what = panic
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| panic.downcast_ref::<String>().cloned())
                        .unwrap_or_default();
                    Err(ApiError::internal(format!("panic in CPU work: {what}")))
                });
            drop((running, permit));
            let _ = tx.send(result);
        });
        async move {
            rx.await
                .unwrap_or_else(|_| Err(ApiError::internal("CPU task lost")))
        }
    }
}

/// Everything the handlers share.
pub struct AppState {
    pub config: Config,
    pub models: Arc<ModelStore>,
    pub readiness: Readiness,
    pub cpu: CpuPool,
    pub jobs: Option<Arc<JobManager>>,
    /// With the admin plane: the uploaded datasets.
    pub datasets: Option<Arc<super::datasets::DatasetStore>>,
    pub started: std::time::Instant,
}

pub type SharedState = Arc<AppState>;
