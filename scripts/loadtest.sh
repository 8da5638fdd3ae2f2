#!/usr/bin/env bash
# Load test of POST /v1/classify: a 256×256 PNG sphere (with white and circle), 32
# connections, wrk; or a photograph of your own (PHOTO). Prints requests/s, latency
# percentiles and the server's peak RSS.
#
#   scripts/loadtest.sh                 # 20 s, 32 connections, 2 wrk threads
#   ROUTES="v1 v2 v1 v2" scripts/loadtest.sh   # also the same request as Open Inference
#                                       # Protocol binary tensor data (POST /v2/models/M/infer),
#                                       # alternating, on one server
#   DURATION=60s CONNECTIONS=64 scripts/loadtest.sh
#   MODELS=models scripts/loadtest.sh   # a registry with ward6 (default: train one from the fixture table)
#   MODELS=models MODEL=ward11 scripts/loadtest.sh   # any model of the registry
#   BIN=/elsewhere/reflectance scripts/loadtest.sh     # another build (no build here)
#   PHOTO=photo.jpg scripts/loadtest.sh # a photograph instead (a phone's JPEG): the sphere
#                                       # located by the server, or given by CIRCLE="cx cy r";
#                                       # WHITE=v adds a white reference; 2 connections and a
#                                       # 60 s timeout unless set
set -euo pipefail
cd "$(dirname "$0")/.."

DURATION=${DURATION:-20s}
if [ -n "${PHOTO:-}" ]; then
  [ -f "$PHOTO" ] || { echo "PHOTO=$PHOTO: no such file" >&2; exit 2; }
  CONNECTIONS=${CONNECTIONS:-2}
  TIMEOUT=${TIMEOUT:-60s}
else
  CONNECTIONS=${CONNECTIONS:-32}
  TIMEOUT=${TIMEOUT:-2s}
fi
# wrk needs a connection per thread.
THREADS=${THREADS:-$(( CONNECTIONS < 2 ? CONNECTIONS : 2 ))}
PORT=${PORT:-18080}
MODEL=${MODEL:-ward6}
ROUTES=${ROUTES:-v1}

if ! command -v wrk >/dev/null; then
  echo "== installing wrk" >&2
  apt-get update -qq >/dev/null && apt-get install -y -qq wrk >/dev/null
fi

if [ -z "${BIN:-}" ]; then
  echo "== building (release)" >&2
  cargo build --release -q
  BIN=${CARGO_TARGET_DIR:-target}/release/reflectance
fi

WORK=$(mktemp -d)
SERVER_PID=
SAMPLER_PID=
cleanup() {
  [ -n "$SAMPLER_PID" ] && kill "$SAMPLER_PID" 2>/dev/null || true
  [ -n "$SERVER_PID" ] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

if [ -n "${MODELS:-}" ]; then
  REGISTRY=$MODELS
else
  REGISTRY=$WORK/models
  "$BIN" train --table tests/fixtures/learn/table.csv --features hand6 --classifier svm \
    --models "$REGISTRY" --name "$MODEL" --no-cv >/dev/null
fi
if [ -n "${PHOTO:-}" ]; then
  IMAGE=$PHOTO
  case $PHOTO in
    *.png | *.PNG) IMAGE_TYPE=image/png ;;
    *) IMAGE_TYPE=image/jpeg ;;
  esac
  FIELDS=
  if [ -n "${CIRCLE:-}" ]; then
    read -r cx cy r <<<"$CIRCLE"
    FIELDS="cx=$cx cy=$cy r=$r"
  fi
  [ -n "${WHITE:-}" ] && FIELDS="white=$WHITE $FIELDS"
  how=located
  [ -n "${CIRCLE:-}" ] && how="circle given"
  DESCRIPTION="$(basename "$PHOTO") ($(du -k "$PHOTO" | cut -f1) KiB, $how)"
else
  IMAGE=$WORK/sphere.png
  IMAGE_TYPE=image/png
  FIELDS="white=0.9 cx=127.5 cy=127.5 r=116"
  DESCRIPTION="256×256 PNG"
  python3 scripts/loadtest/sphere_png.py "$IMAGE"
fi
export IMAGE IMAGE_TYPE FIELDS

"$BIN" serve --models "$REGISTRY" --default-model "$MODEL" --listen "127.0.0.1:$PORT" \
  --log-format json --log warn 2>"$WORK/server.log" &
SERVER_PID=$!
for _ in $(seq 1 100); do
  "$BIN" healthcheck --addr "127.0.0.1:$PORT" 2>/dev/null && break
  sleep 0.1
done
"$BIN" healthcheck --addr "127.0.0.1:$PORT"

# One request first: the answer must be a classification.
form=(-F "image=@$IMAGE;type=$IMAGE_TYPE")
for field in $FIELDS; do form+=(-F "$field"); done
curl -fsS "${form[@]}" "http://127.0.0.1:$PORT/v1/classify" | head -c 300 >&2 || true
echo >&2

# Peak resident memory of the server while under load.
( peak=0
  while kill -0 "$SERVER_PID" 2>/dev/null; do
    rss=$(awk '/VmRSS/ {print $2}' "/proc/$SERVER_PID/status" 2>/dev/null || echo 0)
    [ "${rss:-0}" -gt "$peak" ] && peak=$rss && echo "$peak" > "$WORK/rss"
    sleep 0.2
  done ) &
SAMPLER_PID=$!

for route in $ROUTES; do
  case $route in
    v1) script=classify.lua url=/v1/classify ;;
    v2) script=v2_infer.lua url=/v2/models/$MODEL/infer ;;
    *) echo "unknown route $route (v1 or v2)" >&2; exit 2 ;;
  esac
  echo "== wrk: $CONNECTIONS connections, $THREADS threads, $DURATION, $DESCRIPTION → POST $url" >&2
  wrk -t"$THREADS" -c"$CONNECTIONS" -d"$DURATION" --timeout "$TIMEOUT" --latency \
    -s "scripts/loadtest/$script" "http://127.0.0.1:$PORT$url"
done

echo "server peak RSS: $(( $(cat "$WORK/rss" 2>/dev/null || echo 0) / 1024 )) MiB"
