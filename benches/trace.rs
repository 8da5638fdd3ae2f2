//! What tracing adds to a request (docs/service.md "Traces"): with
//! `OTEL_EXPORTER_OTLP_ENDPOINT` set, each classification parses its `traceparent`, builds
//! its span and its stages' spans, and the exporter thread encodes them into OTLP's
//! protobuf. This is that work, per request, without the queue (one `try_send`) and the
//! network (one connection per batch of 512 spans); compare it with a request's CPU time
//! (`scripts/loadtest.sh`: about 1.6 ms for ward6 on the 2-core VM).

use axum::http::{HeaderMap, HeaderValue};
use divan::Bencher;

fn main() {
    divan::main();
}

#[divan::bench]
fn spans_of_one_request(bencher: Bencher) {
    let mut headers = HeaderMap::new();
    headers.insert(
        "traceparent",
        HeaderValue::from_static("00-4bf92f3577b34da6a3ce929d0e0e4736-00f067aa0ba902b7-01"),
    );
    bencher.bench(|| reflectance::trace_one_request(divan::black_box(&headers)));
}
