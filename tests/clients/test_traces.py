"""Traces against the real binary: a client's W3C `traceparent` reaches the spans the
server exports over OTLP/HTTP, decoded here by OpenTelemetry's own messages
(`opentelemetry-proto`); with the collector gone, requests are answered as before and the
spans are counted as dropped.

    pip install opentelemetry-proto pytest && pytest tests/clients/test_traces.py
"""
import http.server
import os
import pathlib
import re
import socket
import subprocess
import threading
import time
import urllib.request
import uuid

import pytest
from opentelemetry.proto.collector.trace.v1.trace_service_pb2 import ExportTraceServiceRequest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = os.environ.get("BIN", str(ROOT / "target" / "release" / "reflectance"))
FIXTURE = ROOT / "tests" / "fixtures" / "features" / "sphere_rgb8.png"
FIELDS = {"white": "0.8", "cx": "96.5", "cy": "94.25", "r": "85"}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Collector:
    """An OTLP/HTTP receiver: every export request, decoded."""

    def __init__(self):
        self.requests = []
        collector = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self):
                body = self.rfile.read(int(self.headers["Content-Length"]))
                message = ExportTraceServiceRequest()
                message.ParseFromString(body)
                collector.requests.append((self.path, self.headers["Content-Type"], message))
                self.send_response(200)
                self.send_header("Content-Type", "application/x-protobuf")
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args):
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = self.server.server_address[1]
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def spans(self):
        out = []
        for _, _, message in self.requests:
            for resource in message.resource_spans:
                service = {a.key: a.value.string_value for a in resource.resource.attributes}
                for scope in resource.scope_spans:
                    out += [(service, span) for span in scope.spans]
        return out

    def stop(self):
        self.server.shutdown()
        self.server.server_close()


def classify(port, headers=None):
    boundary = uuid.uuid4().hex
    parts = [f'--{boundary}\r\nContent-Disposition: form-data; name="image"; '
             f'filename="s.png"\r\nContent-Type: image/png\r\n\r\n'.encode() + FIXTURE.read_bytes()
             + b"\r\n"]
    parts += [f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"\r\n\r\n{v}\r\n'.encode()
              for k, v in FIELDS.items()]
    body = b"".join(parts) + f"--{boundary}--\r\n".encode()
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}/v1/classify", data=body, method="POST",
        headers={"Content-Type": f"multipart/form-data; boundary={boundary}", **(headers or {})})
    with urllib.request.urlopen(request, timeout=30) as response:
        return response.status, dict(response.headers), response.read()


def metric(port, name):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10) as response:
        text = response.read().decode()
    match = re.search(rf"^{name}(?:{{[^}}]*}})? (\S+)$", text, re.M)
    return float(match.group(1)) if match else None


@pytest.fixture()
def traced(tmp_path):
    collector = Collector()
    port = free_port()
    env = dict(os.environ, OTEL_EXPORTER_OTLP_ENDPOINT=f"http://127.0.0.1:{collector.port}",
               OTEL_SERVICE_NAME="reflectance-test", OTEL_BSP_SCHEDULE_DELAY="100",
               OTEL_EXPORTER_OTLP_TIMEOUT="1000")
    log = open(tmp_path / "server.log", "w+")
    process = subprocess.Popen(
        [BIN, "serve", "--models", str(ROOT / "models"), "--default-model", "ward6",
         "--listen", f"127.0.0.1:{port}", "--log-format", "json"],
        env=env, stderr=log)
    deadline = time.time() + 60
    while True:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/health/ready", timeout=1):
                break
        except Exception:
            if process.poll() is not None or time.time() > deadline:
                raise RuntimeError(open(tmp_path / "server.log").read())
            time.sleep(0.1)
    yield {"port": port, "collector": collector, "log": tmp_path / "server.log"}
    process.terminate()
    process.wait(timeout=30)
    collector.stop()


def wait_for(condition, seconds=5.0):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return False


def test_spans_carry_the_clients_trace(traced):
    trace_id = "4bf92f3577b34da6a3ce929d0e0e4736"
    parent = "00f067aa0ba902b7"
    status, headers, _ = classify(traced["port"], {"traceparent": f"00-{trace_id}-{parent}-01",
                                                   "tracestate": "vendor=abc"})
    assert status == 200
    assert headers["traceresponse"].startswith(f"00-{trace_id}-")
    collector = traced["collector"]
    mine = lambda: [(svc, s) for svc, s in collector.spans() if s.trace_id.hex() == trace_id]
    assert wait_for(lambda: len(mine()) >= 6), [s.name for _, s in collector.spans()]
    path, content_type, _ = collector.requests[0]
    assert path == "/v1/traces" and content_type == "application/x-protobuf"
    spans = {s.name: (svc, s) for svc, s in mine()}
    service, request = spans["POST /v1/classify"]
    assert service["service.name"] == "reflectance-test"
    assert request.kind == 2 and request.parent_span_id.hex() == parent
    assert request.trace_state == "vendor=abc"
    assert headers["traceresponse"] == f"00-{trace_id}-{request.span_id.hex()}-01"
    attributes = {a.key: a.value for a in request.attributes}
    assert attributes["http.response.status_code"].int_value == 200
    # The stages, children of the request's span, in order and inside it.
    stages = [spans[name][1] for name in ("decode", "features", "classify", "estimate")]
    for stage in stages:
        assert stage.parent_span_id == request.span_id and stage.kind == 1
        assert request.start_time_unix_nano <= stage.start_time_unix_nano
        assert stage.start_time_unix_nano <= stage.end_time_unix_nano <= request.end_time_unix_nano
    assert [s.start_time_unix_nano for s in stages] == sorted(s.start_time_unix_nano for s in stages)
    # The request's log line carries the trace id.
    assert wait_for(lambda: trace_id in traced["log"].read_text())

    # Without a traceparent: a new trace, in the log and the answer.
    status, headers, _ = classify(traced["port"])
    new_trace = headers["traceresponse"].split("-")[1]
    assert new_trace != trace_id and wait_for(lambda: new_trace in traced["log"].read_text())
    # A client that does not sample: no spans.
    unsampled = "0af7651916cd43dd8448eb211c80319c"
    classify(traced["port"], {"traceparent": f"00-{unsampled}-b7ad6b7169203331-00"})
    time.sleep(0.5)
    assert not [s for _, s in collector.spans() if s.trace_id.hex() == unsampled]
    assert metric(traced["port"], "reflectance_trace_spans_exported_total") >= 6


def test_a_collector_that_is_gone_costs_nothing_but_the_spans(traced):
    traced["collector"].stop()
    for _ in range(5):
        status, _, body = classify(traced["port"])
        assert status == 200 and b"chrome" in body
    assert wait_for(lambda: (metric(traced["port"], "reflectance_trace_spans_dropped_total") or 0) >= 5)
