#!/usr/bin/env python3
"""Concurrent admin traffic for the soak (issue 17): CLIENTS threads, for SECONDS, each
submitting small render jobs, listing queued jobs and cancelling them, reading jobs and
model versions, and activating a model version, in a random order (seeded per client).

Every call must answer within LIMIT seconds and never with a 5xx. Prints one line per
operation (count, statuses, slowest) and exits non-zero when a call timed out or got a
5xx. Only the Python standard library is used.

    REFLECTANCE_ADMIN_TOKEN=... admin_chaos.py http://127.0.0.1:8081 --seconds 30
"""

import argparse
import json
import os
import random
import threading
import time
import urllib.error
import urllib.request
from collections import defaultdict

LIMIT = 10.0


class Tally:
    def __init__(self):
        self.lock = threading.Lock()
        self.statuses = defaultdict(lambda: defaultdict(int))
        self.slowest = defaultdict(float)
        self.failures = []

    def record(self, op, status, seconds, detail=""):
        with self.lock:
            self.statuses[op][status] += 1
            self.slowest[op] = max(self.slowest[op], seconds)
            if status == "timeout" or (isinstance(status, int) and status >= 500):
                self.failures.append(f"{op}: {status} after {seconds:.2f} s {detail[:200]}")


def call(base, token, tally, op, method, path, body=None):
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(base + path, data=data, method=method)
    request.add_header("Authorization", f"Bearer {token}")
    if data is not None:
        request.add_header("Content-Type", "application/json")
    start = time.monotonic()
    try:
        with urllib.request.urlopen(request, timeout=LIMIT) as response:
            payload = response.read()
            tally.record(op, response.status, time.monotonic() - start)
            return json.loads(payload or b"null")
    except urllib.error.HTTPError as e:
        tally.record(op, e.code, time.monotonic() - start, e.read().decode(errors="replace"))
    except (TimeoutError, urllib.error.URLError, ConnectionError) as e:
        tally.record(op, "timeout", time.monotonic() - start, str(e))
    return None


def client(index, args, token, tally, deadline):
    rng = random.Random(index)
    submitted = []
    while time.monotonic() < deadline:
        op = rng.choice(["submit", "submit", "list", "cancel", "cancel", "get", "activate", "versions"])
        if op == "submit":
            job = {"type": "render", "probes": args.probes, "classes": args.classes,
                   "out": f"chaos/{index}", "size": 72}
            answer = call(args.admin, token, tally, op, "POST", "/admin/v1/jobs", job)
            if answer:
                submitted.append(answer["id"])
        elif op == "list":
            call(args.admin, token, tally, op, "GET", "/admin/v1/jobs?state=queued")
        elif op == "cancel" and submitted:
            # The newest job: most likely still queued or running.
            job = submitted.pop()
            call(args.admin, token, tally, op, "POST", f"/admin/v1/jobs/{job}/cancel")
        elif op == "get" and submitted:
            call(args.admin, token, tally, op, "GET", f"/admin/v1/jobs/{rng.choice(submitted)}")
        elif op == "activate":
            call(args.admin, token, tally, op, "POST",
                 f"/admin/v1/models/{args.model}/versions/{args.version}/activate")
        elif op == "versions":
            call(args.admin, token, tally, op, "GET", f"/admin/v1/models/{args.model}/versions")
        time.sleep(rng.uniform(0.0, args.pause))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("admin", help="admin plane base URL")
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--clients", type=int, default=4)
    parser.add_argument("--probes", default="probes", help="render jobs' probes (data-dir relative)")
    parser.add_argument("--classes", default="classes.json")
    parser.add_argument("--model", default="ward6")
    parser.add_argument("--version", type=int, default=1)
    parser.add_argument("--pause", type=float, default=0.05, help="largest pause between calls (s)")
    args = parser.parse_args()
    token = os.environ["REFLECTANCE_ADMIN_TOKEN"]
    tally = Tally()
    deadline = time.monotonic() + args.seconds
    threads = [threading.Thread(target=client, args=(i, args, token, tally, deadline))
               for i in range(args.clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for op in sorted(tally.statuses):
        counts = " ".join(f"{s}={n}" for s, n in sorted(tally.statuses[op].items(), key=str))
        print(f"admin {op}: {counts}; slowest {tally.slowest[op] * 1000:.0f} ms")
    for failure in tally.failures[:5]:
        print(f"admin failure: {failure}")
    print(f"admin calls failed (timeout > {LIMIT:.0f} s or 5xx): {len(tally.failures)}")
    raise SystemExit(1 if tally.failures else 0)


if __name__ == "__main__":
    main()
