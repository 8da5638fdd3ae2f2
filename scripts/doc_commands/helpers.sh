# Sourced by scripts/doc_commands.sh into the shell that runs one Markdown file's blocks.
# Environment: DOC_ROOT, DOC_OUT, DOC_FILE, DOC_SERVERS, optional REFLECTANCE_BIN.

__DOC_PGIDS=()
__DOC_WHERE="$DOC_FILE"

if [ -n "${REFLECTANCE_BIN:-}" ]; then
  # A function wins over PATH, so `reflectance` is the given binary even after a block
  # exports PATH="$PWD/target/release:$PATH"; exported for servers started with bash -c.
  reflectance() { "$REFLECTANCE_BIN" "$@"; }
  export -f reflectance
fi

__doc_stop_servers() {
  local pgid i
  for pgid in "${__DOC_PGIDS[@]}"; do
    kill -TERM -- "-$pgid" 2>/dev/null || true
  done
  for pgid in "${__DOC_PGIDS[@]}"; do
    for i in $(seq 100); do
      kill -0 -- "-$pgid" 2>/dev/null || break
      sleep 0.1
    done
    kill -KILL -- "-$pgid" 2>/dev/null || true
  done
  __DOC_PGIDS=()
}

__doc_on_exit() {
  local status=$?
  __doc_stop_servers
  if [ "$status" != 0 ]; then
    echo "doc_commands: FAILED (exit $status) in the block at $__DOC_WHERE" >&2
  fi
  exit "$status"
}
trap __doc_on_exit EXIT
trap 'exit 130' INT TERM

# __doc_block FILE:LINE <<TEXT — announce a block and show its text.
__doc_block() {
  __DOC_WHERE=$1
  echo
  echo "--- $1"
  sed 's/^/$ /'
}

__doc_skip_block() {
  echo
  echo "--- $1: skipped, $2"
}

# On stderr: a skipped command adds nothing to the block's output, which an expect block checks.
__doc_skip_line() {
  echo "(skipped: $1 — $2)" >&2
}

# __doc_serve PORT USES_CARGO COMMAND — start a server in its own process group and wait
# until GET /health/ready answers 200 on PORT.
__doc_serve() {
  local port=$1 uses_cargo=$2 command=$3 log pgid deadline
  if curl -s -o /dev/null --max-time 1 "http://127.0.0.1:$port/"; then
    echo "doc_commands: port $port is already taken; stop what listens there first" >&2
    return 1
  fi
  log="$DOC_OUT/server-$port.log"
  setsid bash -c "$command" >"$log" 2>&1 &
  pgid=$!
  __DOC_PGIDS+=("$pgid")
  echo "$pgid" >>"$DOC_SERVERS"
  # cargo run may have to build first.
  if [ "$uses_cargo" = 1 ]; then deadline=$((SECONDS + 1200)); else deadline=$((SECONDS + 60)); fi
  until [ "$(curl -s -o /dev/null -w '%{http_code}' --max-time 2 "http://127.0.0.1:$port/health/ready")" = 200 ]; do
    if ! kill -0 "$pgid" 2>/dev/null; then
      echo "doc_commands: the server exited; its log:" >&2
      tail -n 20 "$log" >&2
      return 1
    fi
    if [ "$SECONDS" -ge "$deadline" ]; then
      echo "doc_commands: the server on port $port was not ready in time; its log:" >&2
      tail -n 20 "$log" >&2
      return 1
    fi
    sleep 0.2
  done
  echo "(server on port $port ready, in the background; stopped at the end of $DOC_FILE)"
}

# __doc_expect EXPECTED ACTUAL WHERE
__doc_expect() {
  if python3 "$DOC_ROOT/scripts/doc_commands/docblocks.py" check "$1" "$2"; then
    echo "(output matches the expected output at $3)"
  else
    echo "doc_commands: the output differs from the expected output at $3" >&2
    return 1
  fi
}

__doc_file_done() {
  __doc_stop_servers
}
