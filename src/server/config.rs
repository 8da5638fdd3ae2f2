//! `reflectance serve` configuration: clap flags, each with a `REFLECTANCE_*` environment
//! equivalent (DESIGN.md §6 fixes the first flags; new ones are only ever added).

use crate::cli::LimitArgs;
use crate::image::decode::Limits;
use clap::{Args, ValueEnum};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Log line format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    /// JSON lines, or human-readable text when stderr is a terminal.
    Auto,
    Json,
    Text,
}

#[derive(Args, Debug, Clone)]
pub struct ServeArgs {
    /// Model registry folder (`<DIR>/<name>/<version>/model.json`); may be read-only.
    #[arg(long, env = "REFLECTANCE_MODELS", default_value = "models")]
    pub models: PathBuf,
    /// Model answering `POST /v1/classify`.
    #[arg(long, env = "REFLECTANCE_DEFAULT_MODEL", default_value = "ward6")]
    pub default_model: String,
    /// Data-plane address (classification, models, health, metrics).
    #[arg(long, env = "REFLECTANCE_LISTEN", default_value = "0.0.0.0:8080")]
    pub listen: SocketAddr,
    /// Admin-plane address (jobs, registry); served only when a token is configured.
    #[arg(
        long,
        env = "REFLECTANCE_ADMIN_LISTEN",
        default_value = "127.0.0.1:8081"
    )]
    pub admin_listen: SocketAddr,
    /// File holding the admin bearer token (surrounding whitespace ignored). The token may
    /// also be given in the REFLECTANCE_ADMIN_TOKEN environment variable.
    #[arg(long, env = "REFLECTANCE_ADMIN_TOKEN_FILE")]
    pub admin_token_file: Option<PathBuf>,
    /// Folder that admin jobs read datasets from and write renderings into; job paths are
    /// relative to it and may not leave it.
    #[arg(long, env = "REFLECTANCE_DATA_DIR", default_value = "data")]
    pub data_dir: PathBuf,
    /// Folder of the persisted job records (default `<data-dir>/jobs`).
    #[arg(long, env = "REFLECTANCE_JOBS_DIR")]
    pub jobs_dir: Option<PathBuf>,
    /// Job worker threads (train, cross_validate, render), off the request runtime.
    #[arg(long, env = "REFLECTANCE_WORKERS", default_value_t = 1)]
    pub workers: usize,
    /// Jobs that may wait for a worker; beyond this `POST /admin/v1/jobs` answers 429.
    #[arg(long, env = "REFLECTANCE_JOB_QUEUE", default_value_t = 16)]
    pub job_queue: usize,
    /// Finished job records kept (in memory and in the jobs folder); the oldest finished
    /// beyond this are forgotten.
    #[arg(long, env = "REFLECTANCE_JOB_HISTORY", default_value_t = 1000)]
    pub job_history: usize,
    /// Threads that decode images and compute features (default: the number of CPUs).
    #[arg(long, env = "REFLECTANCE_CPU_THREADS")]
    pub cpu_threads: Option<usize>,
    /// Classification requests admitted at once (running or waiting for a CPU thread);
    /// beyond this requests are shed at once with 429 and Retry-After.
    #[arg(long, env = "REFLECTANCE_MAX_INFLIGHT", default_value_t = 64)]
    pub max_inflight: usize,
    /// Largest request body in bytes.
    #[arg(long, env = "REFLECTANCE_BODY_LIMIT", default_value_t = 16 * 1024 * 1024)]
    pub body_limit: usize,
    /// Per-request time limit in seconds (answered with 408).
    #[arg(long, env = "REFLECTANCE_REQUEST_TIMEOUT", default_value_t = 30.0)]
    pub request_timeout: f64,
    /// Seconds a connection may take to send a request's headers, or stay idle between
    /// requests, before it is closed (slow or stalled clients cannot hold connections).
    #[arg(long, env = "REFLECTANCE_HEADER_TIMEOUT", default_value_t = 10.0)]
    pub header_timeout: f64,
    /// On SIGTERM/SIGINT: seconds to let in-flight requests finish before stopping.
    #[arg(long, env = "REFLECTANCE_SHUTDOWN_GRACE", default_value_t = 30.0)]
    pub shutdown_grace: f64,
    /// Seconds between turning not-ready and closing the listeners on shutdown, so that
    /// load balancers stop sending traffic first.
    #[arg(long, env = "REFLECTANCE_DRAIN_DELAY", default_value_t = 0.0)]
    pub drain_delay: f64,
    /// Non-active model versions kept loaded for `?version=` requests.
    #[arg(long, env = "REFLECTANCE_MODEL_CACHE", default_value_t = 4)]
    pub model_cache: usize,
    /// Log format.
    #[arg(long, env = "REFLECTANCE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Auto)]
    pub log_format: LogFormat,
    /// Log filter: a level (`info`) or per-target directives (`warn,reflectance=debug`).
    #[arg(long, env = "REFLECTANCE_LOG", default_value = "info")]
    pub log: String,
    #[command(flatten)]
    pub limits: LimitArgs,
}

/// The validated configuration the server runs with. Its `Debug` output redacts the admin
/// token, so that logging a configuration can never leak it.
#[derive(Clone)]
pub struct Config {
    pub models: PathBuf,
    pub default_model: String,
    pub listen: SocketAddr,
    pub admin_listen: SocketAddr,
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
    pub limits: Limits,
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
            .field("limits", &self.limits)
            .field("log_format", &self.log_format)
            .field("log", &self.log)
            .finish()
    }
}

impl Config {
    /// Defaults for a registry folder (the same as the flags' defaults); for tests and
    /// embedding.
    pub fn new(models: impl Into<PathBuf>, default_model: &str) -> Config {
        let data_dir = PathBuf::from("data");
        Config {
            models: models.into(),
            default_model: default_model.to_string(),
            listen: "0.0.0.0:8080".parse().expect("valid address"),
            admin_listen: "127.0.0.1:8081".parse().expect("valid address"),
            admin_token: None,
            jobs_dir: data_dir.join("jobs"),
            data_dir,
            workers: 1,
            job_queue: 16,
            job_history: 1000,
            cpu_threads: default_cpu_threads(),
            max_inflight: 64,
            body_limit: 16 * 1024 * 1024,
            request_timeout: Duration::from_secs(30),
            header_timeout: Duration::from_secs(10),
            shutdown_grace: Duration::from_secs(30),
            drain_delay: Duration::ZERO,
            model_cache: 4,
            limits: Limits::default(),
            log_format: LogFormat::Auto,
            log: "info".into(),
        }
    }

    /// Whether the admin plane is served.
    pub fn admin_enabled(&self) -> bool {
        self.admin_token.is_some()
    }
}

fn default_cpu_threads() -> usize {
    std::thread::available_parallelism().map_or(2, |n| n.get())
}

fn seconds(what: &str, value: f64) -> Result<Duration, String> {
    if (0.0..1e9).contains(&value) {
        Ok(Duration::from_secs_f64(value))
    } else {
        Err(format!(
            "{what} must be a number of seconds ≥ 0, not {value}"
        ))
    }
}

fn positive_seconds(what: &str, value: f64) -> Result<Duration, String> {
    match seconds(what, value)? {
        d if d.is_zero() => Err(format!("{what} must be > 0")),
        d => Ok(d),
    }
}

impl ServeArgs {
    /// Validate the flags and read the admin token (`env_token`: REFLECTANCE_ADMIN_TOKEN).
    pub fn into_config(self, env_token: Option<String>) -> Result<Config, String> {
        let token = match (&self.admin_token_file, env_token) {
            (Some(path), _) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| format!("admin token file {}: {e}", path.display()))?;
                Some(text.trim().to_string())
            }
            (None, Some(token)) => Some(token.trim().to_string()),
            (None, None) => None,
        };
        if token.as_ref().is_some_and(|t| t.len() < 16) {
            return Err("the admin token must be at least 16 characters".into());
        }
        if token.is_none() && !self.admin_listen.ip().is_loopback() {
            return Err(format!(
                "--admin-listen {} is not a loopback address and no admin token is configured \
                 (--admin-token-file or REFLECTANCE_ADMIN_TOKEN)",
                self.admin_listen
            ));
        }
        if !crate::model::registry::valid_name(&self.default_model) {
            return Err(format!(
                "invalid --default-model {:?} (use 1–64 of a-z, 0-9, '_' and '-')",
                self.default_model
            ));
        }
        let positive = |what: &str, n: usize| {
            if n == 0 {
                Err(format!("{what} must be at least 1"))
            } else {
                Ok(n)
            }
        };
        let jobs_dir = self
            .jobs_dir
            .clone()
            .unwrap_or_else(|| self.data_dir.join("jobs"));
        let request_timeout = positive_seconds("--request-timeout", self.request_timeout)?;
        let header_timeout = positive_seconds("--header-timeout", self.header_timeout)?;
        Ok(Config {
            models: self.models,
            default_model: self.default_model,
            listen: self.listen,
            admin_listen: self.admin_listen,
            admin_token: token,
            data_dir: self.data_dir,
            jobs_dir,
            workers: positive("--workers", self.workers)?,
            job_queue: positive("--job-queue", self.job_queue)?,
            job_history: positive("--job-history", self.job_history)?,
            cpu_threads: positive(
                "--cpu-threads",
                self.cpu_threads.unwrap_or_else(default_cpu_threads),
            )?,
            max_inflight: positive("--max-inflight", self.max_inflight)?,
            body_limit: positive("--body-limit", self.body_limit)?,
            request_timeout,
            header_timeout,
            shutdown_grace: seconds("--shutdown-grace", self.shutdown_grace)?,
            drain_delay: seconds("--drain-delay", self.drain_delay)?,
            model_cache: self.model_cache,
            limits: self.limits.limits(),
            log_format: self.log_format,
            log: self.log,
        })
    }
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
}
