//! Prometheus metrics (`GET /metrics`). Request counts and latencies are recorded by the
//! middleware for every response (labels: matched route template, method, status); stage
//! durations by the classification path; model and job state where they change.

use metrics::{counter, gauge, histogram};
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};
use std::sync::OnceLock;

const LATENCY_BUCKETS: &[f64] = &[
    0.0005, 0.001, 0.002, 0.004, 0.008, 0.016, 0.032, 0.064, 0.128, 0.256, 0.512, 1.0, 2.0, 5.0,
    10.0, 30.0,
];

/// The process-wide recorder (installed once; every server in the process shares it).
pub fn handle() -> &'static PrometheusHandle {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    HANDLE.get_or_init(|| {
        let builder = PrometheusBuilder::new()
            .set_buckets_for_metric(Matcher::Suffix("_seconds".into()), LATENCY_BUCKETS)
            .expect("non-empty buckets");
        let recorder = builder.build_recorder();
        let handle = recorder.handle();
        if metrics::set_global_recorder(recorder).is_err() {
            tracing::warn!("a metrics recorder was already installed; /metrics will be empty");
        }
        describe();
        register_at_zero();
        gauge!("reflectance_build_info", "version" => env!("CARGO_PKG_VERSION")).set(1.0);
        spawn_upkeep(handle.clone());
        handle
    })
}

/// Histogram samples wait in per-metric buffers until upkeep folds them into the buckets;
/// without it, a server nobody scrapes grows by every sample it records (measured by
/// `scripts/soak.sh`: +3 MiB a minute at 1200 requests/s).
fn spawn_upkeep(handle: PrometheusHandle) {
    let spawned = std::thread::Builder::new()
        .name("reflectance-metrics".into())
        .spawn(move || {
            loop {
                std::thread::sleep(std::time::Duration::from_secs(5));
                handle.run_upkeep();
            }
        });
    if let Err(e) = spawned {
        tracing::warn!(error = %e, "cannot start metrics upkeep; memory grows until /metrics is scraped");
    }
}

fn describe() {
    use metrics::{describe_counter, describe_gauge, describe_histogram};
    describe_counter!(
        "reflectance_http_requests_total",
        "HTTP requests by matched route, method and status"
    );
    describe_histogram!(
        "reflectance_http_request_duration_seconds",
        "HTTP request latency by matched route, method and status"
    );
    describe_gauge!(
        "reflectance_http_requests_in_flight",
        "HTTP requests being handled"
    );
    describe_histogram!(
        "reflectance_stage_duration_seconds",
        "Classification stage durations (decode, features, predict)"
    );
    describe_counter!(
        "reflectance_requests_shed_total",
        "Classification requests refused with 429 because the CPU pool was saturated"
    );
    describe_gauge!(
        "reflectance_model_active_version",
        "Active (served) version of each model"
    );
    describe_counter!(
        "reflectance_model_load_failures_total",
        "Model versions refused at load, activation or a look at the registry (schema, checksum, self-test, I/O)"
    );
    describe_gauge!(
        "reflectance_model_loaded_timestamp_seconds",
        "When this process loaded the served version of each model (Unix time; 0: not served)"
    );
    describe_counter!(
        "reflectance_registry_polls_total",
        "Looks at the registry (--poll-interval) completed"
    );
    describe_counter!(
        "reflectance_registry_poll_failures_total",
        "Looks at the registry (--poll-interval) that could not read it; the served versions stay"
    );
    describe_counter!(
        "reflectance_model_fallbacks_total",
        "Models served from an older version because the active one did not load at start-up"
    );
    describe_gauge!("reflectance_jobs", "Admin jobs by state");
    describe_counter!(
        "reflectance_job_record_write_failures_total",
        "Job record writes that failed (full or read-only disk); they are retried"
    );
    describe_gauge!(
        "reflectance_job_queue_depth",
        "Admin jobs waiting for a worker"
    );
    describe_counter!(
        "reflectance_trace_spans_exported_total",
        "Spans the OTLP collector took (OTEL_EXPORTER_OTLP_ENDPOINT)"
    );
    describe_counter!(
        "reflectance_trace_spans_dropped_total",
        "Spans dropped: the export queue was full, or the collector did not take them"
    );
}

/// Every family whose labels are known in advance is exported from the start, at zero, so
/// that dashboards and alerts see it before the first event (a counter that appears only
/// when it first counts cannot be told from one that is missing).
fn register_at_zero() {
    counter!("reflectance_requests_shed_total").increment(0);
    counter!("reflectance_job_record_write_failures_total").increment(0);
    counter!("reflectance_registry_polls_total").increment(0);
    counter!("reflectance_registry_poll_failures_total").increment(0);
    counter!("reflectance_trace_spans_exported_total").increment(0);
    counter!("reflectance_trace_spans_dropped_total").increment(0);
    gauge!("reflectance_http_requests_in_flight").increment(0.0);
    gauge!("reflectance_job_queue_depth").increment(0.0);
    for state in JOB_STATES {
        gauge!("reflectance_jobs", "state" => state).increment(0.0);
    }
    for stage in STAGES {
        let _registered = histogram!("reflectance_stage_duration_seconds", "stage" => stage);
    }
}

/// The states of the `reflectance_jobs` gauge.
const JOB_STATES: [&str; 5] = ["queued", "running", "succeeded", "failed", "cancelled"];
/// The stages of the `reflectance_stage_duration_seconds` histogram.
const STAGES: [&str; 3] = ["decode", "features", "predict"];

pub fn request(route: &str, method: &str, status: u16, seconds: f64) {
    let labels = [
        ("route", route.to_string()),
        ("method", method.to_string()),
        ("status", status.to_string()),
    ];
    counter!("reflectance_http_requests_total", &labels).increment(1);
    histogram!("reflectance_http_request_duration_seconds", &labels).record(seconds);
}

pub fn in_flight(delta: f64) {
    gauge!("reflectance_http_requests_in_flight").increment(delta);
}

pub fn stage(stage: &'static str, seconds: f64) {
    histogram!("reflectance_stage_duration_seconds", "stage" => stage).record(seconds);
}

pub fn spans_exported(n: u64) {
    counter!("reflectance_trace_spans_exported_total").increment(n);
}

pub fn spans_dropped(n: u64) {
    counter!("reflectance_trace_spans_dropped_total").increment(n);
}

pub fn shed() {
    counter!("reflectance_requests_shed_total").increment(1);
}

pub fn model_active(model: &str, version: u32, loaded: std::time::SystemTime) {
    gauge!("reflectance_model_active_version", "model" => model.to_string())
        .set(f64::from(version));
    let since = loaded
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    gauge!("reflectance_model_loaded_timestamp_seconds", "model" => model.to_string()).set(since);
    // A served model's failure counters exist from the start (see `register_at_zero`).
    counter!("reflectance_model_load_failures_total", "model" => model.to_string()).increment(0);
    counter!("reflectance_model_fallbacks_total", "model" => model.to_string()).increment(0);
}

/// A model with no version left in the registry, no longer served.
pub fn model_removed(model: &str) {
    gauge!("reflectance_model_active_version", "model" => model.to_string()).set(0.0);
    gauge!("reflectance_model_loaded_timestamp_seconds", "model" => model.to_string()).set(0.0);
}

/// A look at the registry completed.
pub fn registry_polled() {
    counter!("reflectance_registry_polls_total").increment(1);
}

/// A look at the registry that could not read it (the served versions stay).
pub fn registry_poll_failure() {
    counter!("reflectance_registry_poll_failures_total").increment(1);
}

pub fn model_load_failure(model: &str) {
    counter!("reflectance_model_load_failures_total", "model" => model.to_string()).increment(1);
}

/// A model served from an older version because its active one did not load at start-up.
pub fn model_fallback(model: &str) {
    counter!("reflectance_model_fallbacks_total", "model" => model.to_string()).increment(1);
}

pub fn jobs(counts: &[(&'static str, usize)], queued: usize) {
    for (state, n) in counts {
        gauge!("reflectance_jobs", "state" => *state).set(*n as f64);
    }
    gauge!("reflectance_job_queue_depth").set(queued as f64);
}

pub fn job_record_unsaved() {
    counter!("reflectance_job_record_write_failures_total").increment(1);
}

/// The exposition text.
pub fn render() -> String {
    let handle = handle();
    handle.run_upkeep();
    handle.render()
}
