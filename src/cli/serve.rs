//! `reflectance serve` and `reflectance healthcheck`.

use super::{CliError, CliResult, LimitArgs};
use crate::archive::ArchiveLimits;
use crate::server::config::{self, Config, DatasetLimits, LogFormat, defaults};
use clap::Args;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::time::Duration;

/// `reflectance serve`'s flags, each with a `REFLECTANCE_*` environment equivalent
/// (docs/design.md §6: the first flags are fixed; new ones are only ever added).
#[derive(Args, Debug, Clone)]
pub struct ServeArgs {
    /// Model registry folder (`<DIR>/<name>/<version>/model.json`); may be read-only.
    #[arg(long, env = "REFLECTANCE_MODELS", default_value = defaults::MODELS)]
    pub models: PathBuf,
    /// Model answering `POST /v1/classify`.
    #[arg(long, env = "REFLECTANCE_DEFAULT_MODEL", default_value = defaults::DEFAULT_MODEL)]
    pub default_model: String,
    /// Data-plane address (classification, models, health, metrics).
    #[arg(long, env = "REFLECTANCE_LISTEN", default_value = defaults::LISTEN)]
    pub listen: SocketAddr,
    /// Admin-plane address (jobs, registry); served only when a token is configured.
    #[arg(
        long,
        env = "REFLECTANCE_ADMIN_LISTEN",
        default_value = defaults::ADMIN_LISTEN
    )]
    pub admin_listen: SocketAddr,
    /// Address of the Open Inference Protocol's gRPC service (`inference.GRPCInferenceService`;
    /// off unless given, e.g. 0.0.0.0:8001).
    #[arg(long, env = "REFLECTANCE_GRPC_LISTEN")]
    pub grpc_listen: Option<SocketAddr>,
    /// File holding the admin bearer token (surrounding whitespace ignored). The token may
    /// also be given in the REFLECTANCE_ADMIN_TOKEN environment variable.
    #[arg(long, env = "REFLECTANCE_ADMIN_TOKEN_FILE")]
    pub admin_token_file: Option<PathBuf>,
    /// Folder that admin jobs read datasets from and write renderings into; job paths are
    /// relative to it and may not leave it.
    #[arg(long, env = "REFLECTANCE_DATA_DIR", default_value = defaults::DATA_DIR)]
    pub data_dir: PathBuf,
    /// Folder of the persisted job records (default `<data-dir>/jobs`).
    #[arg(long, env = "REFLECTANCE_JOBS_DIR")]
    pub jobs_dir: Option<PathBuf>,
    /// Job worker threads (train, cross_validate, render), off the request runtime.
    #[arg(long, env = "REFLECTANCE_WORKERS", default_value_t = defaults::WORKERS)]
    pub workers: usize,
    /// Jobs that may wait for a worker; beyond this `POST /admin/v1/jobs` answers 429.
    #[arg(long, env = "REFLECTANCE_JOB_QUEUE", default_value_t = defaults::JOB_QUEUE)]
    pub job_queue: usize,
    /// Finished job records kept (in memory and in the jobs folder); the oldest finished
    /// beyond this are forgotten.
    #[arg(long, env = "REFLECTANCE_JOB_HISTORY", default_value_t = defaults::JOB_HISTORY)]
    pub job_history: usize,
    /// Threads that decode images and compute features (default: the number of CPUs).
    #[arg(long, env = "REFLECTANCE_CPU_THREADS")]
    pub cpu_threads: Option<usize>,
    /// Classification requests admitted at once (running or waiting for a CPU thread);
    /// beyond this requests are shed at once with 429 and Retry-After.
    #[arg(long, env = "REFLECTANCE_MAX_INFLIGHT", default_value_t = defaults::MAX_INFLIGHT)]
    pub max_inflight: usize,
    /// Largest request body in bytes.
    #[arg(long, env = "REFLECTANCE_BODY_LIMIT", default_value_t = defaults::BODY_LIMIT)]
    pub body_limit: usize,
    /// Per-request time limit in seconds (answered with 408).
    #[arg(long, env = "REFLECTANCE_REQUEST_TIMEOUT", default_value_t = defaults::REQUEST_TIMEOUT_S)]
    pub request_timeout: f64,
    /// Seconds a connection may take to send a request's headers, or stay idle between
    /// requests, before it is closed (slow or stalled clients cannot hold connections).
    #[arg(long, env = "REFLECTANCE_HEADER_TIMEOUT", default_value_t = defaults::HEADER_TIMEOUT_S)]
    pub header_timeout: f64,
    /// On SIGTERM/SIGINT: seconds to let in-flight requests finish before stopping.
    #[arg(long, env = "REFLECTANCE_SHUTDOWN_GRACE", default_value_t = defaults::SHUTDOWN_GRACE_S)]
    pub shutdown_grace: f64,
    /// Seconds between turning not-ready and closing the listeners on shutdown, so that
    /// load balancers stop sending traffic first.
    #[arg(long, env = "REFLECTANCE_DRAIN_DELAY", default_value_t = defaults::DRAIN_DELAY_S)]
    pub drain_delay: f64,
    /// Non-active model versions kept loaded for `?version=` requests.
    #[arg(long, env = "REFLECTANCE_MODEL_CACHE", default_value_t = defaults::MODEL_CACHE)]
    pub model_cache: usize,
    /// Seconds between two looks at the model registry: a new `ACTIVE` or latest version is
    /// loaded (checked as an activation is) and swapped in, a removed one stops being served;
    /// 0 (the default) reads the registry at start only.
    #[arg(long, env = "REFLECTANCE_POLL_INTERVAL", default_value_t = defaults::POLL_INTERVAL_S)]
    pub poll_interval: f64,
    /// Log format.
    #[arg(long, env = "REFLECTANCE_LOG_FORMAT", value_enum, default_value_t = LogFormat::Auto)]
    pub log_format: LogFormat,
    /// Log filter: a level (`info`) or per-target directives (`warn,reflectance=debug`).
    #[arg(long, env = "REFLECTANCE_LOG", default_value = defaults::LOG)]
    pub log: String,
    #[command(flatten)]
    pub limits: LimitArgs,
    /// Largest dataset archive accepted by `POST /admin/v1/datasets`, in bytes.
    #[arg(long, env = "REFLECTANCE_DATASET_MAX_ARCHIVE", default_value_t = defaults::DATASET_MAX_ARCHIVE)]
    pub dataset_max_archive: u64,
    /// Largest unpacked size of a dataset archive, in bytes.
    #[arg(long, env = "REFLECTANCE_DATASET_MAX_UNPACKED", default_value_t = defaults::DATASET_MAX_UNPACKED)]
    pub dataset_max_unpacked: u64,
    /// Most members (files and folders) a dataset archive may hold.
    #[arg(long, env = "REFLECTANCE_DATASET_MAX_MEMBERS", default_value_t = defaults::DATASET_MAX_MEMBERS)]
    pub dataset_max_members: usize,
    /// Seconds a dataset upload may take: receiving, unpacking and checking every image
    /// (answered with 408).
    #[arg(long, env = "REFLECTANCE_DATASET_TIMEOUT", default_value_t = defaults::DATASET_TIMEOUT_S)]
    pub dataset_timeout: f64,
}

fn seconds(what: &str, value: f64) -> CliResult<Duration> {
    if (0.0..1e9).contains(&value) {
        Ok(Duration::from_secs_f64(value))
    } else {
        Err(CliError::Invalid(format!(
            "{what} must be a number of seconds ≥ 0, not {value}"
        )))
    }
}

impl ServeArgs {
    /// Validate the flags and read the admin token (`env_token`: REFLECTANCE_ADMIN_TOKEN).
    pub fn into_config(self, env_token: Option<String>) -> CliResult<Config> {
        let token = match (&self.admin_token_file, env_token) {
            (Some(path), _) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| CliError::at(format!("admin token file {}", path.display()), e))?;
                Some(text.trim().to_string())
            }
            (None, Some(token)) => Some(token.trim().to_string()),
            (None, None) => None,
        };
        let jobs_dir = self
            .jobs_dir
            .clone()
            .unwrap_or_else(|| self.data_dir.join(defaults::JOBS_SUBDIR));
        let config = Config {
            models: self.models,
            default_model: self.default_model,
            listen: self.listen,
            admin_listen: self.admin_listen,
            grpc_listen: self.grpc_listen,
            admin_token: token,
            data_dir: self.data_dir,
            jobs_dir,
            workers: self.workers,
            job_queue: self.job_queue,
            job_history: self.job_history,
            cpu_threads: self.cpu_threads.unwrap_or_else(config::default_cpu_threads),
            max_inflight: self.max_inflight,
            body_limit: self.body_limit,
            request_timeout: seconds("--request-timeout", self.request_timeout)?,
            header_timeout: seconds("--header-timeout", self.header_timeout)?,
            shutdown_grace: seconds("--shutdown-grace", self.shutdown_grace)?,
            drain_delay: seconds("--drain-delay", self.drain_delay)?,
            model_cache: self.model_cache,
            poll_interval: Some(seconds("--poll-interval", self.poll_interval)?)
                .filter(|d| !d.is_zero()),
            limits: self.limits.limits(),
            datasets: DatasetLimits {
                archive_bytes: self.dataset_max_archive,
                archive: ArchiveLimits {
                    members: self.dataset_max_members,
                    unpacked_bytes: self.dataset_max_unpacked,
                },
                timeout: seconds("--dataset-timeout", self.dataset_timeout)?,
            },
            log_format: self.log_format,
            log: self.log,
        };
        config.check()?;
        Ok(config)
    }
}

pub fn run(args: ServeArgs) -> CliResult {
    let token = std::env::var("REFLECTANCE_ADMIN_TOKEN").ok();
    let config = args.into_config(token)?;
    Ok(crate::server::run(config)?)
}

#[derive(Args, Debug)]
pub struct HealthcheckArgs {
    /// Address of the data plane (default: where `serve` listens, from REFLECTANCE_LISTEN,
    /// with an unspecified address such as 0.0.0.0 checked on loopback).
    #[arg(long, env = "REFLECTANCE_HEALTHCHECK_ADDR")]
    addr: Option<String>,
    /// Path to GET.
    #[arg(long, default_value = "/health/ready")]
    path: String,
    /// Seconds to wait for the answer.
    #[arg(long, default_value_t = 3.0)]
    timeout: f64,
}

/// GET the path over plain HTTP/1.1 (no client library needed in the container).
pub fn healthcheck(args: HealthcheckArgs) -> CliResult {
    let timeout = Duration::from_secs_f64(args.timeout.clamp(0.1, 60.0));
    let listen = std::env::var("REFLECTANCE_LISTEN").ok();
    let addr = args.addr.as_deref().map_or_else(
        || served_address(listen.as_deref().unwrap_or(defaults::LISTEN)),
        |given| {
            given
                .to_socket_addrs()
                .map_err(|e| CliError::at(given, e))?
                .next()
                .ok_or_else(|| CliError::at(given, "no address"))
        },
    )?;
    let mut stream =
        TcpStream::connect_timeout(&addr, timeout).map_err(|e| CliError::at(addr, e))?;
    stream
        .set_read_timeout(Some(timeout))
        .and_then(|()| stream.set_write_timeout(Some(timeout)))
        .map_err(|e| CliError::at(addr, e))?;
    write!(
        stream,
        "GET {} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n",
        args.path
    )
    .map_err(|e| CliError::at(addr, e))?;
    let mut head = [0u8; 64];
    let n = stream.read(&mut head).map_err(|e| CliError::at(addr, e))?;
    let line = String::from_utf8_lossy(&head[..n]);
    let status = line.split_whitespace().nth(1).unwrap_or_default();
    if status == "200" {
        Ok(())
    } else {
        Err(CliError::Invalid(format!(
            "{addr}{} answered {status:?}",
            args.path
        )))
    }
}

/// Where to reach a server listening on `listen`: the same port, on loopback when it
/// listens on every address.
fn served_address(listen: &str) -> CliResult<SocketAddr> {
    let mut addr: SocketAddr = listen
        .parse()
        .map_err(|e| CliError::at(format!("REFLECTANCE_LISTEN {listen:?}"), e))?;
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr {
            SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
            SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
        });
    }
    Ok(addr)
}

#[cfg(test)]
mod tests {
    use super::served_address;

    #[test]
    fn the_health_check_reaches_the_listening_port_on_loopback() {
        let at = |listen| served_address(listen).map_or_else(|e| e.to_string(), |a| a.to_string());
        assert_eq!(at("0.0.0.0:9000"), "127.0.0.1:9000");
        assert_eq!(at("[::]:9000"), "[::1]:9000");
        assert_eq!(at("10.1.2.3:8080"), "10.1.2.3:8080");
        assert!(at("not an address").starts_with("REFLECTANCE_LISTEN \"not an address\": "));
    }
}
