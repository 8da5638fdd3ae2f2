#!/usr/bin/env bash
# Property-based API testing of both planes against openapi.yaml with Schemathesis (PyPI).
# Starts the release server on a model trained from the fixture table, with the admin plane
# on, and runs every check on both planes. scripts/schemathesis/hooks.py gives valid cases a
# real photograph; scripts/schemathesis/schemathesis.toml lists, per operation and with why,
# the statuses that only content decides. MAX_EXAMPLES (default 320: over 5000 cases on
# each plane) sets the cases per operation and phase.
set -euo pipefail
cd "$(dirname "$0")/.."

command -v st >/dev/null || pip install -q 'schemathesis==4.32.5'
cargo build --release -q
BIN=${CARGO_TARGET_DIR:-target}/release/reflectance
PORT=${PORT:-18090}
ADMIN_PORT=${ADMIN_PORT:-18091}
WORK=$(mktemp -d)
SERVER_PID=
cleanup() {
  [ -n "$SERVER_PID" ] && kill "$SERVER_PID" 2>/dev/null && wait "$SERVER_PID" 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

"$BIN" train --table tests/fixtures/learn/table.csv --features hand6 --models "$WORK/models" \
  --name ward6 >/dev/null 2>&1
TOKEN=schemathesis-token-$RANDOM$RANDOM$RANDOM
echo "$TOKEN" > "$WORK/token"
mkdir -p "$WORK/data"
"$BIN" serve --models "$WORK/models" --default-model ward6 --listen "127.0.0.1:$PORT" \
  --admin-listen "127.0.0.1:$ADMIN_PORT" --admin-token-file "$WORK/token" \
  --data-dir "$WORK/data" --log warn 2>"$WORK/server.log" &
SERVER_PID=$!
for _ in $(seq 1 100); do
  "$BIN" healthcheck --addr "127.0.0.1:$PORT" 2>/dev/null && break
  sleep 0.1
done

export PYTHONPATH="$PWD/scripts/schemathesis${PYTHONPATH:+:$PYTHONPATH}"
export SCHEMATHESIS_HOOKS=hooks
ST=(st --config-file scripts/schemathesis/schemathesis.toml run openapi.yaml --checks all
  --max-examples "${MAX_EXAMPLES:-320}" --seed "${SEED:-1}" --no-color)
echo "== data plane"
"${ST[@]}" --url "http://127.0.0.1:$PORT" --exclude-path-regex '^/admin/'
echo "== admin plane"
"${ST[@]}" --url "http://127.0.0.1:$ADMIN_PORT" --include-path-regex '^/admin/' \
  -H "Authorization: Bearer $TOKEN" --workers 1
