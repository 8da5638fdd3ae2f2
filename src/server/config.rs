//! The server's configuration: a plain struct with its defaults and the rules it must keep
//! ([`Config::check`], which the server applies at start however the struct was built). The
//! command line (`reflectance serve`, `src/cli/serve.rs`) builds it from flags and
//! environment.

use crate::archive::ArchiveLimits;
use reflectance_core::decode::Limits;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// The defaults of the configuration, in one place: `Config::new` and the command line's
/// flags both use them.
pub mod defaults {
    pub const MODELS: &str = "models";
    pub const DEFAULT_MODEL: &str = "ward6";
    pub const LISTEN: &str = "0.0.0.0:8080";
    pub const ADMIN_LISTEN: &str = "127.0.0.1:8081";
    pub const DATA_DIR: &str = "data";
    /// Under the data directory.
    pub const JOBS_SUBDIR: &str = "jobs";
    pub const WORKERS: usize = 1;
    pub const JOB_QUEUE: usize = 16;
    pub const JOB_HISTORY: usize = 1000;
    pub const MAX_INFLIGHT: usize = 64;
    pub const BODY_LIMIT: usize = 16 * 1024 * 1024;
    pub const REQUEST_TIMEOUT_S: f64 = 30.0;
    pub const HEADER_TIMEOUT_S: f64 = 10.0;
    pub const SHUTDOWN_GRACE_S: f64 = 30.0;
    pub const DRAIN_DELAY_S: f64 = 0.0;
    pub const MODEL_CACHE: usize = 4;
    /// Seconds between two looks at the registry (0: never, the registry is read at start).
    pub const POLL_INTERVAL_S: f64 = 0.0;
    pub const LOG: &str = "info";
    /// Dataset uploads (`POST /admin/v1/datasets`): the archive's size in bytes, its
    /// unpacked size, its members, and the time the whole upload may take.
    pub const DATASET_MAX_ARCHIVE: u64 = 1 << 30;
    pub const DATASET_MAX_UNPACKED: u64 = 4 << 30;
    pub const DATASET_MAX_MEMBERS: usize = 10_000;
    pub const DATASET_TIMEOUT_S: f64 = 900.0;
    /// Under the data directory.
    pub const DATASETS_SUBDIR: &str = "datasets";
    /// The shortest admin token accepted.
    pub const MIN_TOKEN_LEN: usize = 16;
}

/// Log line format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// JSON lines, or human-readable text when stderr is a terminal.
    Auto,
    Json,
    Text,
}

/// What a dataset upload may be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DatasetLimits {
    /// Bytes of the uploaded archive.
    pub archive_bytes: u64,
    pub archive: ArchiveLimits,
    /// The whole upload: receiving, unpacking and checking every image.
    pub timeout: Duration,
}

impl Default for DatasetLimits {
    fn default() -> DatasetLimits {
        DatasetLimits {
            archive_bytes: defaults::DATASET_MAX_ARCHIVE,
            archive: ArchiveLimits {
                members: defaults::DATASET_MAX_MEMBERS,
                unpacked_bytes: defaults::DATASET_MAX_UNPACKED,
            },
            timeout: Duration::from_secs_f64(defaults::DATASET_TIMEOUT_S),
        }
    }
}

/// The validated configuration the server runs with. Its `Debug` output redacts the admin
/// token, so that logging a configuration can never leak it.
#[derive(Clone)]
pub struct Config {
    pub models: PathBuf,
    pub default_model: String,
    pub listen: SocketAddr,
    pub admin_listen: SocketAddr,
    /// The Open Inference Protocol's gRPC service (`None`: off).
    pub grpc_listen: Option<SocketAddr>,
    /// `None`: the admin plane is off.
    pub admin_token: Option<String>,
    pub data_dir: PathBuf,
    pub jobs_dir: PathBuf,
    pub workers: usize,
    pub job_queue: usize,
    pub job_history: usize,
    pub cpu_threads: usize,
    pub max_inflight: usize,
    pub body_limit: usize,
    pub request_timeout: Duration,
    pub header_timeout: Duration,
    pub shutdown_grace: Duration,
    pub drain_delay: Duration,
    pub model_cache: usize,
    /// How often the registry is looked at for new, changed or removed versions (`None`:
    /// never; the models are loaded at start and change by admin activation only).
    pub poll_interval: Option<Duration>,
    pub limits: Limits,
    pub datasets: DatasetLimits,
    pub log_format: LogFormat,
    pub log: String,
}

impl std::fmt::Debug for Config {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Config")
            .field("models", &self.models)
            .field("default_model", &self.default_model)
            .field("listen", &self.listen)
            .field("admin_listen", &self.admin_listen)
            .field("grpc_listen", &self.grpc_listen)
            .field(
                "admin_token",
                &self.admin_token.as_ref().map(|_| "<redacted>"),
            )
            .field("data_dir", &self.data_dir)
            .field("jobs_dir", &self.jobs_dir)
            .field("workers", &self.workers)
            .field("job_queue", &self.job_queue)
            .field("job_history", &self.job_history)
            .field("cpu_threads", &self.cpu_threads)
            .field("max_inflight", &self.max_inflight)
            .field("body_limit", &self.body_limit)
            .field("request_timeout", &self.request_timeout)
            .field("header_timeout", &self.header_timeout)
            .field("shutdown_grace", &self.shutdown_grace)
            .field("drain_delay", &self.drain_delay)
            .field("model_cache", &self.model_cache)
            .field("poll_interval", &self.poll_interval)
            .field("limits", &self.limits)
            .field("datasets", &self.datasets)
            .field("log_format", &self.log_format)
            .field("log", &self.log)
            .finish()
    }
}

impl Config {
    /// Defaults for a registry folder (the same as the flags' defaults); for tests and
    /// embedding.
    pub fn new(models: impl Into<PathBuf>, default_model: &str) -> Config {
        let data_dir = PathBuf::from(defaults::DATA_DIR);
        let address = |text: &str| text.parse().expect("a default address parses");
        Config {
            models: models.into(),
            default_model: default_model.to_string(),
            listen: address(defaults::LISTEN),
            admin_listen: address(defaults::ADMIN_LISTEN),
            grpc_listen: None,
            admin_token: None,
            jobs_dir: data_dir.join(defaults::JOBS_SUBDIR),
            data_dir,
            workers: defaults::WORKERS,
            job_queue: defaults::JOB_QUEUE,
            job_history: defaults::JOB_HISTORY,
            cpu_threads: default_cpu_threads(),
            max_inflight: defaults::MAX_INFLIGHT,
            body_limit: defaults::BODY_LIMIT,
            request_timeout: Duration::from_secs_f64(defaults::REQUEST_TIMEOUT_S),
            header_timeout: Duration::from_secs_f64(defaults::HEADER_TIMEOUT_S),
            shutdown_grace: Duration::from_secs_f64(defaults::SHUTDOWN_GRACE_S),
            drain_delay: Duration::from_secs_f64(defaults::DRAIN_DELAY_S),
            model_cache: defaults::MODEL_CACHE,
            poll_interval: None,
            limits: Limits::default(),
            datasets: DatasetLimits::default(),
            log_format: LogFormat::Auto,
            log: defaults::LOG.into(),
        }
    }

    /// Whether the admin plane is served.
    pub fn admin_enabled(&self) -> bool {
        self.admin_token.is_some()
    }

    /// The rules a configuration must keep, however it was built (flags, tests, embedding):
    /// [`crate::server::build_state`] refuses a configuration that breaks one.
    pub fn check(&self) -> Result<(), InvalidConfig> {
        if let Some(token) = &self.admin_token
            && token.len() < defaults::MIN_TOKEN_LEN
        {
            return Err(InvalidConfig::ShortToken);
        }
        if self.admin_token.is_none() && !self.admin_listen.ip().is_loopback() {
            return Err(InvalidConfig::OpenAdmin(self.admin_listen));
        }
        if !reflectance_core::model::registry::valid_name(&self.default_model) {
            return Err(InvalidConfig::DefaultModel(self.default_model.clone()));
        }
        let counts = [
            ("--workers", self.workers),
            ("--job-queue", self.job_queue),
            ("--job-history", self.job_history),
            ("--cpu-threads", self.cpu_threads),
            ("--max-inflight", self.max_inflight),
            ("--body-limit", self.body_limit),
            ("--dataset-max-members", self.datasets.archive.members),
        ];
        if let Some((flag, _)) = counts.iter().find(|(_, n)| *n == 0) {
            return Err(InvalidConfig::Zero(flag));
        }
        if self.poll_interval.is_some_and(|d| d.is_zero()) {
            return Err(InvalidConfig::NoTime("--poll-interval"));
        }
        let durations = [
            ("--request-timeout", self.request_timeout),
            ("--header-timeout", self.header_timeout),
            ("--dataset-timeout", self.datasets.timeout),
        ];
        match durations.iter().find(|(_, d)| d.is_zero()) {
            Some((flag, _)) => Err(InvalidConfig::NoTime(flag)),
            None => Ok(()),
        }
    }
}

/// A configuration the server refuses to run with (each names the flag to change).
#[derive(Debug, thiserror::Error)]
pub enum InvalidConfig {
    #[error(
        "the admin token must be at least {} characters",
        defaults::MIN_TOKEN_LEN
    )]
    ShortToken,
    #[error(
        "--admin-listen {0} is not a loopback address and no admin token is configured \
         (--admin-token-file or REFLECTANCE_ADMIN_TOKEN)"
    )]
    OpenAdmin(SocketAddr),
    #[error("invalid --default-model {0:?} (use 1–64 of a-z, 0-9, '_' and '-')")]
    DefaultModel(String),
    #[error("{0} must be at least 1")]
    Zero(&'static str),
    #[error("{0} must be > 0")]
    NoTime(&'static str),
}

/// The number of CPUs (2 when it cannot be told).
pub fn default_cpu_threads() -> usize {
    std::thread::available_parallelism().map_or(2, |n| n.get())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_output_redacts_the_admin_token() {
        let mut config = Config::new("models", "ward6");
        config.admin_token = Some("super-secret-token-0123456789".into());
        let text = format!("{config:?}");
        assert!(!text.contains("super-secret"), "{text}");
        assert!(text.contains("<redacted>"), "{text}");
    }

    #[test]
    fn a_configuration_is_checked_however_it_was_built() {
        let base = || Config::new("models", "ward6");
        assert!(base().check().is_ok());
        let refused = |change: &dyn Fn(&mut Config)| {
            let mut config = base();
            change(&mut config);
            config.check().map_err(|e| e.to_string()).unwrap_err()
        };
        let short = refused(&|c| c.admin_token = Some("fifteen-chars-x".into()));
        assert_eq!(short, "the admin token must be at least 16 characters");
        let open = refused(&|c| c.admin_listen = "0.0.0.0:8081".parse().unwrap());
        assert!(
            open.starts_with("--admin-listen 0.0.0.0:8081 is not a loopback"),
            "{open}"
        );
        let mut open_with_token = base();
        open_with_token.admin_listen = "0.0.0.0:8081".parse().unwrap();
        open_with_token.admin_token = Some("sixteen-chars-xx".into());
        assert!(open_with_token.check().is_ok());
        let name = refused(&|c| c.default_model = "../ward6".into());
        assert!(name.starts_with("invalid --default-model"), "{name}");
        assert_eq!(refused(&|c| c.workers = 0), "--workers must be at least 1");
        assert_eq!(
            refused(&|c| c.datasets.archive.members = 0),
            "--dataset-max-members must be at least 1"
        );
        assert_eq!(
            refused(&|c| c.header_timeout = Duration::ZERO),
            "--header-timeout must be > 0"
        );
        let mut zero = base();
        zero.cpu_threads = 0;
        assert!(matches!(
            crate::server::build_state(zero),
            Err(crate::server::StartError::Config(InvalidConfig::Zero(
                "--cpu-threads"
            )))
        ));
    }
}
