#!/usr/bin/env python3
"""An OTLP/HTTP collector stand-in for the load test: takes every export request
(POST /v1/traces), answers 200 at once, and prints how many requests and bytes it took when
stopped; with --decode (and opentelemetry-proto installed) also the spans, which costs the
sink CPU the server on the same machine then lacks.

    python3 scripts/loadtest/otlp_sink.py 4318 &
    OTEL_EXPORTER_OTLP_ENDPOINT=http://127.0.0.1:4318 MODELS=models scripts/loadtest.sh
"""
import http.server
import signal
import sys

ExportTraceServiceRequest = None
if "--decode" in sys.argv:
    from opentelemetry.proto.collector.trace.v1.trace_service_pb2 import ExportTraceServiceRequest

counts = {"requests": 0, "bytes": 0, "spans": 0}


class Handler(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        counts["requests"] += 1
        counts["bytes"] += len(body)
        if ExportTraceServiceRequest is not None:
            message = ExportTraceServiceRequest()
            message.ParseFromString(body)
            counts["spans"] += sum(len(s.spans) for r in message.resource_spans for s in r.scope_spans)
        self.send_response(200)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def log_message(self, *args):
        pass


def main():
    ports = [a for a in sys.argv[1:] if a.isdigit()]
    port = int(ports[0]) if ports else 4318
    server = http.server.ThreadingHTTPServer(("127.0.0.1", port), Handler)

    def stop(*_):
        print(f"otlp_sink: {counts}", file=sys.stderr)
        sys.exit(0)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    server.serve_forever()


if __name__ == "__main__":
    main()
