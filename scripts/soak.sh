#!/usr/bin/env bash
# Soak and overload test of the release server on loopback (docs/design.md §5, issue 6).
#
#   scripts/soak.sh                        # 10 minutes of mixed traffic, then 30 s of overload
#   MINUTES=2 OVERLOAD_SECONDS=10 scripts/soak.sh
#
# Starts `reflectance serve` on a copy of the shipped models (ward6, ward11) with an admin
# token and a data directory holding a tiny rendered dataset (4 synthetic probes × 3
# classes, 64 px). Then, minute by minute, wrk sends a fixed mix of valid, invalid and
# oversized requests over CONNECTIONS connections (scripts/soak/mixed.lua) while an admin
# loop runs jobs back to back (cross-validation of the tiny dataset; every third, a train
# job of a model `soak` activated at once: hot swaps under load). Each minute prints the
# status counts, p50/p99 latency and the server's RSS. The overload phase then opens
# 4 × CONNECTIONS connections against --max-inflight = CONNECTIONS: the excess must be
# refused at once with 429, not queued until a timeout (a curl probe times single requests
# during it). Meanwhile ADMIN_CLIENTS (4) concurrent admin clients submit small render
# jobs, cancel them, list, read and activate (scripts/soak/admin_chaos.py). Success: no
# 5xx, RSS growth ≤ 10 % after the first minute, stable p99, every admin job of the loop
# succeeded (the first failure is printed), and no concurrent admin call took over 10 s.
# The job history is bounded at JOB_HISTORY (200) records, so that it is full within the
# first minute and RSS after it measures leaks, not the history filling up (at the
# default 1000 it took four minutes: +12 %, then flat).
# Exits non-zero when a criterion fails.
set -euo pipefail
cd "$(dirname "$0")/.."

MINUTES=${MINUTES:-10}
CONNECTIONS=${CONNECTIONS:-8}
MAX_INFLIGHT=${MAX_INFLIGHT:-$CONNECTIONS}
OVERLOAD_SECONDS=${OVERLOAD_SECONDS:-30}
PORT=${PORT:-18090}
ADMIN_PORT=${ADMIN_PORT:-18091}
TOKEN=soak-token-$(date +%s)-0123456789

for tool in wrk curl; do
  if ! command -v "$tool" >/dev/null; then
    echo "== installing $tool" >&2
    apt-get update -qq >/dev/null && apt-get install -y -qq "$tool" >/dev/null
  fi
done

echo "== building (release)" >&2
cargo build --release -q
BIN=${CARGO_TARGET_DIR:-target}/release/reflectance

WORK=$(mktemp -d)
SERVER_PID=
ADMIN_PID=
CHAOS_PID=
SAMPLER_PID=
cleanup() {
  touch "$WORK/stop"
  for pid in $ADMIN_PID $SAMPLER_PID $CHAOS_PID; do kill "$pid" 2>/dev/null || true; done
  [ -n "$SERVER_PID" ] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

echo "== data: registry copy, tiny rendered dataset, request bodies" >&2
cp -r models "$WORK/models"
mkdir -p "$WORK/data"
python3 scripts/soak/probes.py "$WORK/data/probes"
cat > "$WORK/data/classes.json" <<'JSON'
{"classes": [
  {"name": "matte", "rho_d": 0.8, "rho_s": 0.0, "alpha": 0.0},
  {"name": "chrome", "rho_d": 0.0, "rho_s": 0.75, "alpha": 0.0},
  {"name": "dark", "rho_d": 0.08, "rho_s": 0.0, "alpha": 0.0}]}
JSON
"$BIN" render --probes "$WORK/data/probes" --classes "$WORK/data/classes.json" \
  --out "$WORK/data/tiny" --size 72 >/dev/null 2>&1
python3 scripts/loadtest/sphere_png.py "$WORK/sphere.png"
head -c "$(( $(stat -c %s "$WORK/sphere.png") / 2 ))" "$WORK/sphere.png" > "$WORK/corrupt.png"
head -c 1200000 /dev/urandom > "$WORK/big.bin"

# The token goes through the environment (kept out of argv and the process list).
REFLECTANCE_ADMIN_TOKEN=$TOKEN "$BIN" serve --models "$WORK/models" --default-model ward6 --data-dir "$WORK/data" \
  --listen "127.0.0.1:$PORT" --admin-listen "127.0.0.1:$ADMIN_PORT" \
  --max-inflight "$MAX_INFLIGHT" --body-limit 1048576 --request-timeout 10 \
  --job-history "${JOB_HISTORY:-200}" \
  --log-format json --log warn 2>"$WORK/server.log" &
SERVER_PID=$!
for _ in $(seq 1 200); do
  "$BIN" healthcheck --addr "127.0.0.1:$PORT" 2>/dev/null && break
  sleep 0.1
done
"$BIN" healthcheck --addr "127.0.0.1:$PORT"
AUTH="Authorization: Bearer $TOKEN"

rss_kib() { awk '/VmRSS/ {print $2}' "/proc/$SERVER_PID/status" 2>/dev/null || echo 0; }

# RSS every second: "seconds rss_kib".
( start=$(date +%s)
  while kill -0 "$SERVER_PID" 2>/dev/null; do
    echo "$(( $(date +%s) - start )) $(rss_kib)" >> "$WORK/rss.log"
    sleep 1
  done ) &
SAMPLER_PID=$!

# Admin jobs back to back until told to stop: "kind state".
( n=0
  while [ ! -f "$WORK/stop" ]; do
    n=$((n + 1))
    if [ $((n % 3)) -eq 0 ]; then
      job='{"type": "train", "name": "soak", "dataset": "tiny/manifest.csv", "features": "hand6", "cross_validate": false, "activate": "always"}'
      kind=train
    else
      job='{"type": "cross_validate", "dataset": "tiny/manifest.csv", "features": "hand6"}'
      kind=cross_validate
    fi
    answer=$(curl -sS -H "$AUTH" -H 'content-type: application/json' -d "$job" \
      -w '\n%{http_code}' "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs" || true)
    code=$(tail -1 <<<"$answer")
    if [ "$code" != 202 ]; then echo "$kind submit-$code" >> "$WORK/jobs.log"; sleep 1; continue; fi
    id=$(head -1 <<<"$answer" | python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
    while [ ! -f "$WORK/stop" ]; do
      state=$(curl -sS -H "$AUTH" "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs/$id" \
        | python3 -c 'import json,sys; print(json.load(sys.stdin)["state"])' || echo error)
      case $state in succeeded|failed|cancelled|error) break ;; esac
      sleep 0.5
    done
    echo "$kind $state" >> "$WORK/jobs.log"
    if [ "$state" = failed ]; then
      curl -sS -H "$AUTH" "http://127.0.0.1:$ADMIN_PORT/admin/v1/jobs/$id" >> "$WORK/failed-jobs.log" || true
      echo >> "$WORK/failed-jobs.log"
    fi
  done ) &
ADMIN_PID=$!

# Concurrent admin clients for the whole load phase (issue 17): submitting small render
# jobs, cancelling them, listing, reading and activating, all at once.
REFLECTANCE_ADMIN_TOKEN=$TOKEN python3 scripts/soak/admin_chaos.py "http://127.0.0.1:$ADMIN_PORT" \
  --seconds "$((MINUTES * 60))" --clients "${ADMIN_CLIENTS:-4}" > "$WORK/chaos.txt" 2>&1 &
CHAOS_PID=$!

export IMAGE=$WORK/sphere.png CORRUPT=$WORK/corrupt.png BIG=$WORK/big.bin
printf '%-6s %-8s %-8s %-9s %-9s %-8s %s\n' minute requests rps p50_ms p99_ms rss_MiB statuses
for minute in $(seq 1 "$MINUTES"); do
  out=$WORK/minute-$minute.txt
  wrk -t2 -c"$CONNECTIONS" -d60s -s scripts/soak/mixed.lua "http://127.0.0.1:$PORT" > "$out" 2>&1 || true
  statuses=$(sed -n 's/^statuses: //p' "$out")
  read -r requests rps p50 p99 < <(awk '/^requests:/ {print $2, $4, $6, $8}' "$out")
  rss=$(rss_kib)
  echo "$minute $rss" >> "$WORK/rss-minutes.log"
  echo "$minute ${p99:-0}" >> "$WORK/p99.log"
  echo "$statuses" >> "$WORK/statuses.log"
  printf '%-6s %-8s %-8s %-9s %-9s %-8s %s\n' "$minute" "${requests:-0}" "${rps:-0}" "${p50:-?}" \
    "${p99:-?}" "$(( rss / 1024 ))" "$statuses"
  grep '^socket_errors' "$out" | grep -v 'connect=0 read=0 write=0 timeout=0' || true
done
touch "$WORK/stop"
wait "$ADMIN_PID" 2>/dev/null || true
ADMIN_PID=
chaos=0
wait "$CHAOS_PID" || chaos=$?
cat "$WORK/chaos.txt"

echo "admin jobs during the soak: $(sort "$WORK/jobs.log" | uniq -c | awk '{printf "%s %s=%s; ", $2, $3, $1}')"
if [ -s "$WORK/failed-jobs.log" ]; then
  echo "first failed job: $(head -1 "$WORK/failed-jobs.log")"
fi

echo "== overload: $((4 * CONNECTIONS)) connections for ${OVERLOAD_SECONDS}s against --max-inflight $MAX_INFLIGHT"
( end=$(( $(date +%s) + OVERLOAD_SECONDS - 2 ))
  sleep 2
  while [ "$(date +%s)" -lt "$end" ]; do
    curl -sS -o /dev/null -w '%{http_code} %{time_total}\n' -F image=@"$IMAGE" -F white=0.9 \
      -F cx=127.5 -F cy=127.5 -F r=116 "http://127.0.0.1:$PORT/v1/classify" >> "$WORK/probe.log" || true
  done ) &
PROBE_PID=$!
ONLY_VALID=1 wrk -t2 -c$((4 * CONNECTIONS)) -d"${OVERLOAD_SECONDS}s" -s scripts/soak/mixed.lua \
  "http://127.0.0.1:$PORT" | tee "$WORK/overload.txt" | sed -n '/^statuses/,$p'
wait "$PROBE_PID" || true
python3 - "$WORK/probe.log" <<'PY'
import sys
from collections import defaultdict
times = defaultdict(list)
for line in open(sys.argv[1]):
    code, t = line.split()
    times[code].append(float(t) * 1000)
for code, ts in sorted(times.items()):
    ts.sort()
    pick = lambda q: ts[min(len(ts) - 1, int(q * len(ts)))]
    print(f"probe {code}: n={len(ts)} p50={pick(0.5):.2f} ms p99={pick(0.99):.2f} ms max={ts[-1]:.2f} ms")
PY

echo "== verdict"
fail=0
five=$(tr ' ' '\n' < "$WORK/statuses.log" | awk -F= '$1 >= 500 {s += $2} END {print s + 0}')
over5=$(sed -n 's/^statuses: //p' "$WORK/overload.txt" | tr ' ' '\n' | awk -F= '$1 >= 500 {s += $2} END {print s + 0}')
five=$((five + over5))
shed=$(sed -n 's/^statuses: //p' "$WORK/overload.txt" | tr ' ' '\n' | awk -F= '$1 == 429 {s += $2} END {print s + 0}')
grep -c '"level":"ERROR"' "$WORK/server.log" > "$WORK/errors" || true
echo "5xx responses: $five (server error log lines: $(cat "$WORK/errors"))"
[ "$five" -eq 0 ] || fail=1
python3 - "$WORK/rss-minutes.log" "$WORK/p99.log" <<'PY' || fail=1
import sys
rss = [int(line.split()[1]) for line in open(sys.argv[1])]
p99 = [float(line.split()[1]) for line in open(sys.argv[2])]
base = rss[0] if len(rss) < 2 else rss[1]  # after the first minute's warm-up
peak = max(rss[1:] or rss)
growth = 100.0 * (peak - base) / base
print(f"RSS after warm-up {base / 1024:.1f} MiB, peak {peak / 1024:.1f} MiB, last {rss[-1] / 1024:.1f} MiB: growth {growth:+.1f} %")
print(f"p99 per minute: min {min(p99):.2f} ms, max {max(p99):.2f} ms")
sys.exit(0 if growth <= 10.0 else 1)
PY
echo "overload: $shed requests refused with 429"
[ "$shed" -gt 0 ] || fail=1
succeeded=$(grep -c ' succeeded$' "$WORK/jobs.log" || true)
echo "admin jobs: $succeeded succeeded, $(grep -vc ' succeeded$' "$WORK/jobs.log" || true) did not"
[ "$succeeded" -gt 0 ] && [ ! -s "$WORK/failed-jobs.log" ] || fail=1
[ "$chaos" -eq 0 ] || { echo "concurrent admin clients: a call timed out or got a 5xx"; fail=1; }
[ $fail -eq 0 ] && echo "PASS" || echo "FAIL"
exit $fail
