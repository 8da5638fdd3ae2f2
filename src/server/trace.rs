//! Traces: W3C Trace Context in, OpenTelemetry spans out.
//!
//! Every request gets a trace context: the client's `traceparent` (and `tracestate`) when it
//! sends a valid one, else a new trace. Its trace id is in the request's log line. With
//! `OTEL_EXPORTER_OTLP_ENDPOINT` (or `OTEL_EXPORTER_OTLP_TRACES_ENDPOINT`) set, the request's
//! span (kind server, the client's span as parent) and its stages' spans (decode, locate,
//! features, classify, estimate) are exported over OTLP/HTTP as protobuf: queued without
//! waiting (a full queue drops the span), sent in batches by one thread, dropped and counted
//! when the collector does not take them. Unset, nothing is queued or built.
//!
//! The standard variables: `OTEL_SERVICE_NAME` (default `reflectance`),
//! `OTEL_TRACES_SAMPLER` (`parentbased_always_on` by default; `always_on`, `always_off`,
//! `traceidratio`, `parentbased_always_off`, `parentbased_traceidratio`),
//! `OTEL_TRACES_SAMPLER_ARG` (the ratio), `OTEL_BSP_SCHEDULE_DELAY` (ms, 5000),
//! `OTEL_BSP_MAX_QUEUE_SIZE` (2048), `OTEL_BSP_MAX_EXPORT_BATCH_SIZE` (512),
//! `OTEL_EXPORTER_OTLP_TIMEOUT` (ms, 10000). Only `http://` endpoints (a collector beside the
//! service, as in Kubernetes); the messages are OTLP's own (`opentelemetry-proto`).

use super::metrics;
use axum::http::HeaderMap;
use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::OnceLock;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::time::{Duration, Instant, SystemTime};

mod otlp;

tokio::task_local! {
    /// The current request's trace context, set by the middleware around every request.
    pub static CURRENT: Context;
}

/// A request's place in its trace.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Context {
    pub trace_id: [u8; 16],
    /// The request's own span.
    pub span_id: [u8; 8],
    /// The client's span, when it sent one.
    pub parent: Option<[u8; 8]>,
    pub sampled: bool,
    pub tracestate: String,
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// `N` bytes from 2·N lowercase hex digits; all-zero ids are invalid.
fn unhex<const N: usize>(text: &str) -> Option<[u8; N]> {
    let valid = text.len() == 2 * N && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'));
    let mut out = [0u8; N];
    for (i, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(text.get(2 * i..2 * i + 2)?, 16).ok()?;
    }
    (valid && out.iter().any(|&b| b != 0)).then_some(out)
}

/// A `traceparent` header's (trace id, parent span id, sampled), per W3C Trace Context:
/// version 00 exactly, a later version by its first four fields.
fn parse_traceparent(value: &str) -> Option<([u8; 16], [u8; 8], bool)> {
    let mut fields = value.trim().split('-');
    let version = fields.next()?;
    let (trace, span, flags) = (fields.next()?, fields.next()?, fields.next()?);
    let rest = fields.next();
    match version {
        "00" if rest.is_none() => {}
        "ff" => return None,
        v if unhex::<1>(v).is_some() && v > "00" => {}
        _ => return None,
    }
    let flags = unhex::<1>(flags)
        .map(|f| f[0])
        .or((flags == "00").then_some(0))?;
    Some((unhex(trace)?, unhex(span)?, flags & 1 == 1))
}

fn random_bytes<const N: usize>() -> [u8; N] {
    static SEED: OnceLock<u64> = OnceLock::new();
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
    let seed = *SEED.get_or_init(|| {
        let nanos = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        nanos ^ u64::from(std::process::id()).rotate_left(40)
    });
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut rng =
        reflectance_core::util::rng::Rng::new(seed ^ n.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    let mut out = [0u8; N];
    for chunk in out.chunks_mut(8) {
        let word = rng.next_u64().to_le_bytes();
        chunk.copy_from_slice(&word[..chunk.len()]);
    }
    if out.iter().all(|&b| b == 0) {
        out[0] = 1;
    }
    out
}

impl Context {
    /// The request's context from its headers: the client's trace, or a new one.
    pub fn of_request(headers: &HeaderMap) -> Context {
        let parent = headers
            .get("traceparent")
            .and_then(|v| v.to_str().ok())
            .and_then(parse_traceparent);
        let tracestate = match parent {
            Some(_) => headers
                .get_all("tracestate")
                .iter()
                .filter_map(|v| v.to_str().ok())
                .collect::<Vec<_>>()
                .join(","),
            None => String::new(),
        };
        let sampler = exporter().map(|e| e.sampler);
        let (trace_id, parent, sampled) = match parent {
            Some((trace, span, sampled)) => (trace, Some(span), sampled),
            None => (random_bytes(), None, false),
        };
        let sampled = sampler.is_some_and(|s| s.samples(&trace_id, parent.map(|_| sampled)));
        Context {
            trace_id,
            span_id: random_bytes(),
            parent,
            sampled,
            tracestate,
        }
    }

    pub fn trace_id_hex(&self) -> String {
        hex(&self.trace_id)
    }

    /// This request's span as W3C Trace Context writes it (`traceparent`'s form): the
    /// answer's `traceresponse` header (Trace Context Level 2), so a client finds its trace.
    pub fn traceparent(&self) -> String {
        let flags = u8::from(self.sampled);
        format!(
            "00-{}-{}-{flags:02x}",
            hex(&self.trace_id),
            hex(&self.span_id)
        )
    }
}

/// `OTEL_TRACES_SAMPLER` and its argument.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sampler {
    /// Follow the client's sampled flag when it sends one.
    parent_based: bool,
    /// The share of new traces kept, by trace id.
    ratio: f64,
}

impl Sampler {
    fn from_env(name: Option<&str>, arg: Option<&str>) -> Sampler {
        let ratio = arg
            .and_then(|a| a.trim().parse::<f64>().ok())
            .filter(|r| (0.0..=1.0).contains(r))
            .unwrap_or(1.0);
        let (parent_based, ratio) = match name.unwrap_or("parentbased_always_on").trim() {
            "always_on" => (false, 1.0),
            "always_off" => (false, 0.0),
            "traceidratio" => (false, ratio),
            "parentbased_always_off" => (true, 0.0),
            "parentbased_traceidratio" => (true, ratio),
            _ => (true, 1.0),
        };
        Sampler {
            parent_based,
            ratio,
        }
    }

    /// Whether a trace is recorded: as its parent says (parent-based, with a parent), else
    /// the trace id's last 8 bytes below the ratio (the W3C random part).
    fn samples(self, trace_id: &[u8; 16], parent_sampled: Option<bool>) -> bool {
        if let (true, Some(sampled)) = (self.parent_based, parent_sampled) {
            return sampled;
        }
        let mut low = [0u8; 8];
        low.copy_from_slice(&trace_id[8..]);
        let draw = u64::from_be_bytes(low) >> 11;
        (draw as f64) < self.ratio * (1u64 << 53) as f64
    }
}

/// A finished span, waiting for export.
#[derive(Clone, Debug)]
pub struct Span {
    pub trace_id: [u8; 16],
    pub span_id: [u8; 8],
    pub parent: Option<[u8; 8]>,
    pub tracestate: String,
    pub name: std::borrow::Cow<'static, str>,
    pub server: bool,
    pub start: SystemTime,
    pub end: SystemTime,
    pub attributes: Vec<(&'static str, Value)>,
    pub error: bool,
}

/// An attribute's value.
#[derive(Clone, Debug)]
pub enum Value {
    Text(String),
    Int(i64),
}

struct Exporter {
    queue: SyncSender<Span>,
    sampler: Sampler,
}

static EXPORTER: OnceLock<Option<Exporter>> = OnceLock::new();

fn exporter() -> Option<&'static Exporter> {
    EXPORTER.get().and_then(Option::as_ref)
}

/// Whether spans are exported (the OTLP endpoint is set and valid).
pub fn enabled() -> bool {
    exporter().is_some()
}

/// Where and how to send spans, from the standard environment.
#[derive(Clone, Debug, PartialEq)]
struct Settings {
    host: String,
    port: u16,
    path: String,
    service: String,
    delay: Duration,
    queue: usize,
    batch: usize,
    timeout: Duration,
}

fn env(name: &str) -> Option<String> {
    std::env::var(name).ok().filter(|v| !v.trim().is_empty())
}

fn millis(name: &str, default: u64) -> Duration {
    Duration::from_millis(
        env(name)
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or(default),
    )
}

fn count(name: &str, default: usize) -> usize {
    env(name)
        .and_then(|v| v.trim().parse().ok())
        .filter(|&n| n > 0)
        .unwrap_or(default)
}

/// The exporter's settings (`None`: no endpoint), or why the endpoint is refused.
fn settings() -> Result<Option<Settings>, String> {
    let (url, signal_path) = match (
        env("OTEL_EXPORTER_OTLP_TRACES_ENDPOINT"),
        env("OTEL_EXPORTER_OTLP_ENDPOINT"),
    ) {
        (Some(url), _) => (url, false),
        (None, Some(url)) => (url, true),
        (None, None) => return Ok(None),
    };
    let Some(rest) = url.trim().strip_prefix("http://") else {
        return Err(format!(
            "{url:?}: only http:// OTLP endpoints are supported (a collector beside the service)"
        ));
    };
    let (authority, path) = rest.split_once('/').map_or((rest, ""), |(a, p)| (a, p));
    let (host, port) = match authority.rsplit_once(':') {
        Some((h, p)) => (h, p.parse().map_err(|_| format!("{url:?}: bad port"))?),
        None => (authority, 80),
    };
    // The base endpoint gets the signal's path (OTLP: `v1/traces` under it).
    let base = path.trim_end_matches('/');
    let path = match (signal_path, base.is_empty()) {
        (true, true) => "/v1/traces".to_string(),
        (true, false) => format!("/{base}/v1/traces"),
        (false, _) => format!("/{path}"),
    };
    Ok(Some(Settings {
        host: host.trim_matches(['[', ']']).to_string(),
        port,
        path,
        service: env("OTEL_SERVICE_NAME").unwrap_or_else(|| "reflectance".into()),
        delay: millis("OTEL_BSP_SCHEDULE_DELAY", 5000),
        queue: count("OTEL_BSP_MAX_QUEUE_SIZE", 2048),
        batch: count("OTEL_BSP_MAX_EXPORT_BATCH_SIZE", 512),
        timeout: millis("OTEL_EXPORTER_OTLP_TIMEOUT", 10_000),
    }))
}

/// Start exporting when the environment names an endpoint (once per process).
pub fn init_from_env() {
    EXPORTER.get_or_init(|| {
        let settings = match settings() {
            Ok(Some(s)) => s,
            Ok(None) => return None,
            Err(why) => {
                tracing::warn!(%why, "traces are not exported");
                return None;
            }
        };
        let sampler = Sampler::from_env(
            env("OTEL_TRACES_SAMPLER").as_deref(),
            env("OTEL_TRACES_SAMPLER_ARG").as_deref(),
        );
        let (queue, spans) = std::sync::mpsc::sync_channel(settings.queue);
        tracing::info!(endpoint = %format!("http://{}:{}{}", settings.host, settings.port, settings.path),
            service = %settings.service, "exporting traces over OTLP/HTTP");
        let spawned = std::thread::Builder::new()
            .name("reflectance-otlp".into())
            .spawn(move || export_loop(&settings, &spans));
        spawned.ok().map(|_| Exporter { queue, sampler })
    });
}

/// Queue a span; never waits (a full queue drops it, counted).
pub fn record(span: Span) {
    let Some(exporter) = exporter() else { return };
    match exporter.queue.try_send(span) {
        Ok(()) => {}
        Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => metrics::spans_dropped(1),
    }
}

fn export_loop(settings: &Settings, spans: &Receiver<Span>) {
    let mut batch = Vec::with_capacity(settings.batch);
    let mut due = Instant::now() + settings.delay;
    let mut warned: Option<Instant> = None;
    loop {
        let wait = due.saturating_duration_since(Instant::now());
        let closed = match spans.recv_timeout(wait) {
            Ok(span) => {
                batch.push(span);
                false
            }
            Err(RecvTimeoutError::Timeout) => false,
            Err(RecvTimeoutError::Disconnected) => true,
        };
        if batch.len() < settings.batch && Instant::now() < due && !closed {
            continue;
        }
        if !batch.is_empty() {
            let n = batch.len() as u64;
            match send(settings, &otlp::request(&settings.service, &batch)) {
                Ok(()) => metrics::spans_exported(n),
                Err(why) => {
                    metrics::spans_dropped(n);
                    if warned.is_none_or(|t| t.elapsed() > Duration::from_secs(60)) {
                        tracing::warn!(%why, spans = n, "OTLP export failed; spans dropped");
                        warned = Some(Instant::now());
                    }
                }
            }
            batch.clear();
        }
        if closed {
            return;
        }
        due = Instant::now() + settings.delay;
    }
}

/// POST one export request; Ok on a 2xx answer.
fn send(settings: &Settings, body: &[u8]) -> Result<(), String> {
    let address = (settings.host.as_str(), settings.port)
        .to_socket_addrs()
        .map_err(|e| e.to_string())?
        .next()
        .ok_or("the collector's name does not resolve")?;
    let mut stream =
        TcpStream::connect_timeout(&address, settings.timeout).map_err(|e| e.to_string())?;
    stream
        .set_write_timeout(Some(settings.timeout))
        .map_err(|e| e.to_string())?;
    stream
        .set_read_timeout(Some(settings.timeout))
        .map_err(|e| e.to_string())?;
    let head = format!(
        "POST {} HTTP/1.1\r\nHost: {}:{}\r\nContent-Type: application/x-protobuf\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n",
        settings.path,
        settings.host,
        settings.port,
        body.len()
    );
    stream
        .write_all(head.as_bytes())
        .map_err(|e| e.to_string())?;
    stream.write_all(body).map_err(|e| e.to_string())?;
    let mut status = [0u8; 12];
    stream.read_exact(&mut status).map_err(|e| e.to_string())?;
    match &status[9..10] {
        b"2" => Ok(()),
        _ => Err(format!(
            "the collector answered {}",
            String::from_utf8_lossy(&status[9..12])
        )),
    }
}

/// The span of one request (from `started`, ending now), when its trace is sampled.
pub fn request_span(
    context: &Context,
    name: String,
    started: SystemTime,
    attributes: Vec<(&'static str, Value)>,
    error: bool,
) {
    if context.sampled && enabled() {
        record(server_span(context, name, started, attributes, error));
    }
}

fn server_span(
    context: &Context,
    name: String,
    started: SystemTime,
    attributes: Vec<(&'static str, Value)>,
    error: bool,
) -> Span {
    Span {
        trace_id: context.trace_id,
        span_id: context.span_id,
        parent: context.parent,
        tracestate: context.tracestate.clone(),
        name: name.into(),
        server: true,
        start: started,
        end: SystemTime::now(),
        attributes,
        error,
    }
}

/// Spans of a request's stages, children of its span, laid end to end from `start`:
/// `(name, milliseconds)`, those of 0 ms left out.
pub fn stage_spans(context: &Context, start: SystemTime, stages: &[(&'static str, f64)]) {
    if context.sampled && enabled() {
        stages_of(context, start, stages)
            .into_iter()
            .for_each(record);
    }
}

fn stages_of(context: &Context, start: SystemTime, stages: &[(&'static str, f64)]) -> Vec<Span> {
    let mut at = start;
    let mut spans = Vec::with_capacity(stages.len());
    for &(name, ms) in stages {
        let end = at + Duration::from_secs_f64(ms.max(0.0) / 1e3);
        if ms > 0.0 {
            spans.push(Span {
                trace_id: context.trace_id,
                span_id: random_bytes(),
                parent: Some(context.span_id),
                tracestate: String::new(),
                name: name.into(),
                server: false,
                start: at,
                end,
                attributes: Vec::new(),
                error: false,
            });
        }
        at = end;
    }
    spans
}

/// What tracing adds to one classification, but the queue and the network: the context of
/// a request with `traceparent`, its span and its stages' spans, and their export request
/// (`benches/trace.rs`).
pub fn one_request_encoded(headers: &HeaderMap) -> Vec<u8> {
    let context = Context::of_request(headers);
    let now = SystemTime::now();
    let attributes = vec![
        ("http.request.method", Value::Text("POST".into())),
        ("http.route", Value::Text("/v1/classify".into())),
        ("http.response.status_code", Value::Int(200)),
    ];
    let mut spans = vec![server_span(
        &context,
        "POST /v1/classify".into(),
        now,
        attributes,
        false,
    )];
    let stages = [
        ("decode", 0.3),
        ("features", 1.0),
        ("classify", 0.2),
        ("estimate", 0.1),
    ];
    spans.extend(stages_of(&context, now, &stages));
    otlp::request("reflectance", &spans)
}

/// The current request's context (`None` outside a request).
pub fn current() -> Option<Context> {
    CURRENT.try_with(Clone::clone).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The W3C specification's own example, and what it refuses.
    #[test]
    fn traceparent_headers_parse_as_the_specification_says() {
        let (trace, span, sampled) =
            parse_traceparent("00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01").unwrap();
        assert_eq!(hex(&trace), "4bf92f3577b34da6a3ce929d0e0e4736");
        assert_eq!(hex(&span), "00f067aa0ba902b7");
        assert!(sampled);
        let unsampled = "00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-00";
        assert!(!parse_traceparent(unsampled).unwrap().2);
        // A later version: its first four fields, whatever follows.
        let later = "cc-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01-what-the-future-holds";
        assert!(parse_traceparent(later).is_some());
        for bad in [
            "00-00000000000000000000000000000000-00f067aa0ba902b7-01",
            "00-4bf92f3577b34da6a3ce929d0e0e4736-0000000000000000-01",
            "00-4BF92F3577B34DA6A3CE929D0E0E4736-00f067aa0ba902b7-01",
            "00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01-extra",
            "ff-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01",
            "00-4bf92f3577b34da6a3ce929d0e0e473-00f067aa0ba902b7-01",
            "00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7",
            "",
        ] {
            assert!(parse_traceparent(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn the_sampler_follows_the_parent_and_the_ratio() {
        let default = Sampler::from_env(None, None);
        let id = [7u8; 16];
        assert!(default.samples(&id, None));
        assert!(!default.samples(&id, Some(false)));
        let none = Sampler::from_env(Some("parentbased_traceidratio"), Some("0"));
        assert!(!none.samples(&id, None) && none.samples(&id, Some(true)));
        // A ratio keeps about its share of random trace ids.
        let half = Sampler::from_env(Some("traceidratio"), Some("0.5"));
        let kept = (0..4000)
            .filter(|_| half.samples(&random_bytes(), Some(false)))
            .count();
        assert!((1800..2200).contains(&kept), "{kept}");
    }
}
