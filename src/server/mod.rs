//! `reflectance serve`: the classification service (docs/design.md §5).
//!
//! * [`config`] — flags and environment;
//! * [`state`] — readiness, the model store (atomic hot swap), the CPU pool;
//! * [`router`] — the two planes and the middleware;
//! * [`handlers`] — one module per area;
//! * [`error`] — the one place errors become HTTP statuses and problem+json;
//! * [`listener`] — the accept loop and its header deadline;
//! * [`datasets`] — uploaded datasets under the data directory;
//! * [`grpc`] — the Open Inference Protocol's gRPC service, on its own port;
//! * [`trace`] — W3C Trace Context and OpenTelemetry spans over OTLP;
//! * [`auth`], [`metrics`], [`jobs`], [`openapi`].

pub(crate) mod auth;
pub mod config;
pub(crate) mod datasets;
pub(crate) mod error;
pub(crate) mod grpc;
pub(crate) mod handlers;
pub(crate) mod jobs;
pub mod listener;
pub mod metrics;
pub mod openapi;
pub mod router;
pub mod state;
pub(crate) mod store;
pub mod trace;

use config::{Config, LogFormat};
use state::{AppState, CpuPool, ModelStore, Phase, Readiness, SharedState};
use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant;

/// Why the server cannot start (or stopped at start): the command line prints it and exits 1.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error("default model {name:?} is not in {registry} (it holds: {holds})")]
    NoDefaultModel {
        name: String,
        registry: String,
        holds: String,
    },
    #[error("default model {name:?} in {registry} cannot be served: {reason}")]
    DefaultNotServed {
        name: String,
        registry: String,
        reason: String,
    },
    #[error(transparent)]
    Registry(#[from] reflectance_core::model::registry::RegistryError),
    #[error("the model registry: {0}")]
    Models(reflectance_core::model::registry::RegistryError),
    #[error(transparent)]
    Config(#[from] config::InvalidConfig),
    #[error("cannot start the runtime: {0}")]
    Runtime(std::io::Error),
    #[error("cannot listen on {address}: {source}")]
    Listen {
        address: SocketAddr,
        source: std::io::Error,
    },
    #[error("cannot start the CPU pool: {0}")]
    CpuPool(#[from] rayon::ThreadPoolBuildError),
    #[error(transparent)]
    Jobs(#[from] jobs::OpenError),
}

/// Build the shared state: clean the registry's staging leftovers, start the job system
/// (when the admin plane is on) and the CPU pool. Models are not loaded yet (the server
/// reports `loading`); call [`load_models`].
pub fn build_state(config: Config) -> Result<SharedState, StartError> {
    config.check()?;
    let _ = metrics::handle();
    let registry = reflectance_core::model::registry::Registry::new(&config.models);
    match registry.clean_staging() {
        Ok(0) => {}
        Ok(n) => tracing::info!(removed = n, "removed staging leftovers from the registry"),
        Err(e) => tracing::warn!(error = %e, "could not clean the registry's staging leftovers"),
    }
    let models = Arc::new(ModelStore::new(registry, config.model_cache));
    let datasets = if config.admin_enabled() {
        Some(Arc::new(datasets::DatasetStore::open(
            &config.data_dir,
            config.datasets,
        )))
    } else {
        None
    };
    let jobs = if config.admin_enabled() {
        Some(jobs::JobManager::start(
            &config.jobs_dir,
            &config.data_dir,
            config.limits,
            models.clone(),
            config.workers,
            config.job_queue,
            config.job_history,
        )?)
    } else {
        None
    };
    let cpu = CpuPool::new(config.cpu_threads, config.max_inflight)?;
    Ok(Arc::new(AppState {
        config,
        models,
        readiness: Readiness::default(),
        cpu,
        jobs,
        datasets,
        started: Instant::now(),
    }))
}

/// Load every model's active version (blocking); the default model must load. Marks the
/// state ready.
pub fn load_models(state: &AppState) -> Result<(), StartError> {
    let failed = state.models.load_all().map_err(StartError::Models)?;
    for (name, reason) in &failed {
        tracing::error!(model = %name, %reason, "model not served: its active version does not load");
    }
    let default = &state.config.default_model;
    if !state.models.is_served(default) {
        let reason = failed
            .iter()
            .find(|(n, _)| n == default)
            .map_or("it is not in the registry".to_string(), |(_, r)| r.clone());
        return Err(StartError::DefaultNotServed {
            name: default.clone(),
            registry: state.config.models.display().to_string(),
            reason,
        });
    }
    for model in state.models.all_active() {
        tracing::info!(
            model = model.name(),
            version = model.version(),
            "model loaded"
        );
    }
    state.readiness.set(Phase::Ready);
    Ok(())
}

fn init_logging(config: &Config) {
    use std::io::IsTerminal;
    use tracing_subscriber::filter::{LevelFilter, Targets};
    use tracing_subscriber::prelude::*;
    let filter: Targets = config
        .log
        .parse()
        .or_else(|_| {
            config
                .log
                .parse::<LevelFilter>()
                .map(|l| Targets::new().with_default(l))
        })
        .unwrap_or_else(|_| Targets::new().with_default(LevelFilter::INFO));
    let json = match config.log_format {
        LogFormat::Json => true,
        LogFormat::Text => false,
        LogFormat::Auto => !std::io::stderr().is_terminal(),
    };
    let registry = tracing_subscriber::registry().with(filter);
    let result = if json {
        registry
            .with(
                tracing_subscriber::fmt::layer()
                    .json()
                    .with_current_span(false)
                    .with_writer(std::io::stderr),
            )
            .try_init()
    } else {
        registry
            .with(
                tracing_subscriber::fmt::layer()
                    .with_ansi(std::io::stderr().is_terminal())
                    .with_writer(std::io::stderr),
            )
            .try_init()
    };
    let _ = result;
}

/// Resolves on SIGTERM or SIGINT.
async fn termination() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
}

/// The bound listeners: the data plane, and the admin plane and gRPC when they are on.
pub struct Listeners {
    pub data: tokio::net::TcpListener,
    pub admin: Option<tokio::net::TcpListener>,
    pub grpc: Option<tokio::net::TcpListener>,
}

/// Serve every listener until `shutdown` resolves, then drain: readiness turns 503, after
/// `drain_delay` the listeners close and in-flight requests get up to `shutdown_grace` to
/// finish; running jobs are asked to stop.
pub async fn serve(
    state: SharedState,
    listeners: Listeners,
    shutdown: impl Future<Output = ()> + Send + 'static,
) {
    let Listeners { data, admin, grpc } = listeners;
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let signal = |mut rx: tokio::sync::watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|stop| *stop).await;
    };
    let header_timeout = state.config.header_timeout;
    let data_task = tokio::spawn(listener::serve_plane(
        data,
        router::data_router(state.clone()),
        header_timeout,
        signal(stop_rx.clone()),
    ));
    let admin_task = admin.map(|admin| {
        tokio::spawn(listener::serve_plane(
            admin,
            router::admin_router(state.clone()),
            header_timeout,
            signal(stop_rx.clone()),
        ))
    });
    let grpc_task =
        grpc.map(|grpc| tokio::spawn(grpc::serve(state.clone(), grpc, signal(stop_rx.clone()))));
    if let Some(every) = state.config.poll_interval {
        tokio::spawn(watch_registry(
            state.clone(),
            every,
            signal(stop_rx.clone()),
        ));
    }
    shutdown.await;
    tracing::info!("shutting down: draining");
    state.readiness.set(Phase::Draining);
    tokio::time::sleep(state.config.drain_delay).await;
    let _ = stop_tx.send(true);
    if let Some(jobs) = &state.jobs {
        jobs.shutdown();
    }
    let grace = state.config.shutdown_grace;
    let drained = tokio::time::timeout(grace, async {
        let _ = data_task.await;
        if let Some(task) = admin_task {
            let _ = task.await;
        }
        if let Some(task) = grpc_task
            && let Ok(Err(e)) = task.await
        {
            tracing::warn!(error = %e, "the gRPC server stopped with an error");
        }
    })
    .await;
    if drained.is_err() {
        tracing::warn!("in-flight requests did not finish within the shutdown grace period");
    }
    if let Some(jobs) = state.jobs.clone() {
        let _ = tokio::task::spawn_blocking(move || jobs.join(grace)).await;
    }
    tracing::info!("stopped");
}

/// Every `every`, once the models are loaded, look at the registry and serve what it says
/// ([`store::ModelStore::poll`]), off the runtime's threads, until `stop` resolves.
async fn watch_registry(
    state: SharedState,
    every: std::time::Duration,
    stop: impl Future<Output = ()> + Send,
) {
    tokio::pin!(stop);
    loop {
        tokio::select! {
            () = &mut stop => return,
            () = tokio::time::sleep(every) => {}
        }
        if state.readiness.get() == Phase::Loading {
            continue;
        }
        let looking = state.clone();
        let polled =
            tokio::task::spawn_blocking(move || looking.models.poll(&looking.config.default_model))
                .await;
        match polled {
            Ok(Ok(_)) => {}
            Ok(Err(e)) => {
                metrics::registry_poll_failure();
                tracing::warn!(error = %e, "cannot read the registry: the served versions stay");
            }
            Err(e) => tracing::error!(error = %e, "the look at the registry failed"),
        }
    }
}

/// `reflectance serve`: everything, from configuration to shutdown.
/// (The binary has already tuned the heap for repeated requests: `reflectance_core::util::heap`.)
pub fn run(config: Config) -> Result<(), StartError> {
    init_logging(&config);
    trace::init_from_env();
    // Before claiming to listen: the registry is there and holds the default model (its
    // file is verified while the server already answers, as loading takes a while).
    let registry = reflectance_core::model::registry::Registry::new(&config.models);
    registry
        .active(&config.default_model)
        .map_err(|e| match e {
            reflectance_core::model::registry::RegistryError::UnknownModel(name) => {
                StartError::NoDefaultModel {
                    name,
                    registry: config.models.display().to_string(),
                    holds: registry.names().unwrap_or_default().join(", "),
                }
            }
            other => other.into(),
        })?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("reflectance-io")
        .build()
        .map_err(StartError::Runtime)?;
    runtime.block_on(async move {
        let data = bind(config.listen).await?;
        let admin = match config.admin_enabled() {
            true => Some(bind(config.admin_listen).await?),
            false => None,
        };
        let grpc = match config.grpc_listen {
            Some(address) => Some(bind(address).await?),
            None => None,
        };
        let bound = |listener: &tokio::net::TcpListener, asked| {
            listener.local_addr().unwrap_or(asked)
        };
        let admin_at = admin.as_ref().map(|l| bound(l, config.admin_listen));
        let grpc_at = grpc
            .as_ref()
            .zip(config.grpc_listen)
            .map(|(l, asked)| bound(l, asked));
        let data_at = bound(&data, config.listen);
        // 0.0.0.0 suits a container; on a laptop it opens the port to the network.
        let reach = match data_at.ip().is_unspecified() {
            true => format!(
                " (every network interface: http://localhost:{} here; --listen 127.0.0.1:{} \
                 for this machine only)",
                data_at.port(),
                data_at.port()
            ),
            false => String::new(),
        };
        tracing::info!(
            models = %config.models.display(),
            default_model = %config.default_model,
            "listening on http://{data_at}{reach}{}{}",
            admin_at.map_or(" (admin plane off: no token)".into(), |a| format!(", admin on http://{a}")),
            grpc_at.map_or(String::new(), |g| format!(", Open Inference Protocol gRPC on {g}")),
        );
        let state = build_state(config)?;
        // Listen at once (liveness answers, readiness says "loading"), load meanwhile.
        let loader = state.clone();
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<StartError>();
        tokio::task::spawn_blocking(move || {
            if let Err(e) = load_models(&loader) {
                tracing::error!(error = %e, "cannot start");
                let _ = stop_tx.send(e);
            }
        });
        let failure = Arc::new(std::sync::Mutex::new(None::<StartError>));
        let recorded = failure.clone();
        let shutdown = async move {
            tokio::select! {
                () = termination() => {},
                // A dropped sender means the models loaded: keep serving.
                Ok(reason) = stop_rx => {
                    *recorded.lock().unwrap_or_else(|e| e.into_inner()) = Some(reason);
                }
            }
        };
        serve(state, Listeners { data, admin, grpc }, shutdown).await;
        match failure.lock().unwrap_or_else(|e| e.into_inner()).take() {
            Some(reason) => Err(reason),
            None => Ok(()),
        }
    })
}

async fn bind(address: SocketAddr) -> Result<tokio::net::TcpListener, StartError> {
    tokio::net::TcpListener::bind(address)
        .await
        .map_err(|source| StartError::Listen { address, source })
}
