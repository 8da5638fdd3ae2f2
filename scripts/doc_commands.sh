#!/usr/bin/env bash
# Run the commands of README.md and docs/*.md as written, against live servers.
#
#   scripts/doc_commands.sh                      # README.md, then docs/*.md in name order
#   scripts/doc_commands.sh docs/service.md      # only the files named
#   REFLECTANCE_BIN=/path/to/reflectance scripts/doc_commands.sh   # test a given binary
#   DOC_COMMANDS_SLOW=1 scripts/doc_commands.sh  # also the long blocks (hours)
#   scripts/doc_commands.sh --list               # list every code block and its tag
#
# Nothing beside the repository is needed: CI runs this from a copy of the repository with no
# ../shared next to it (.ci/run). Only DOC_COMMANDS_SLOW=1 needs ../shared/data/probes.
#
# Conventions (also in docs/development.md, "Documentation commands"):
#
# * ```sh blocks are executed; ```text, ```json (and ```console, ```yaml) blocks are shown,
#   not run: outputs, illustrations, and the few commands that act outside the repository
#   (cargo install, docker, pip install, regenerating committed fixtures), which the text
#   says are not run here. A fence without a language is an error.
# * Each file runs in one bash process, from the repository root, with `set -euo pipefail`,
#   its ```sh blocks in order (variables and functions carry over between the blocks of a
#   file, not between files), with target/release first on PATH.
# * A command line (after optional VAR=value assignments) that starts a server —
#   `reflectance serve …`, `./target/release/reflectance serve …` or
#   `cargo run --release -- serve …` — is started in the background in its own process
#   group; the script waits until GET /health/ready answers 200 on the port of its
#   `--listen` (default 8080), refuses to start it when that port is already taken, and
#   stops it (SIGTERM, then SIGKILL) when the file is done, fails or is interrupted.
# * ```sh slow blocks (re-training the shipped models, full renders, benches, soak, fuzz)
#   run only with DOC_COMMANDS_SLOW=1; the text says how long they take.
# * Build and test commands (`cargo test`, `cargo bench`, …, any cargo command but
#   `cargo build` and `cargo run --release --`) run only with DOC_COMMANDS_SLOW=1: they are
#   what CI runs anyway, and run from here they would nest the test suite.
# * REFLECTANCE_BIN=/path/to/reflectance: `reflectance`, `./target/release/reflectance`
#   and `cargo run --release --` all run that binary, and cargo commands are skipped (no
#   build at all). Without it, target/release/reflectance must exist (`cargo build --release`).
# * A ```json expect block right after a ```sh block is that block's expected output: the
#   block's whole standard output (or its last line) must be JSON, hold every key the
#   expected one shows with the same values (numbers to the digits shown: 0.912 matches
#   0.9117966…; lists of the same length), whatever the volatile keys (request_id,
#   timing_ms, id, created, started, finished) hold and whatever else it holds.
# * A ```text expect block right after a ```sh block is that block's whole standard output,
#   line by line: as many lines, each the same, where `…` stands for any run of characters
#   (what varies: a score, a time).
# * Commands write only under data/ (ignored by git) or /tmp, never into tracked files.
#   Blocks are idempotent, so running twice works: render resumes, training writes the
#   next version, tests read versions from answers rather than assuming numbers.
#
# Needs: bash, python3, curl, jq (installed with apt-get when missing and run as root),
# setsid, perl, tritonclient (docs/service.md's client example), and the ports 8080, 8081,
# 8090, 8091, 8092 and 8001 free.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
HELPER="$ROOT/scripts/doc_commands/docblocks.py"

FILES=("$@")
if [ "${1:-}" = "--list" ]; then
  python3 "$HELPER" list README.md docs/*.md
  exit
fi
[ ${#FILES[@]} -eq 0 ] && FILES=(README.md docs/*.md)

die() { echo "doc_commands: $*" >&2; exit 1; }
export DOC_COMMANDS_SLOW=${DOC_COMMANDS_SLOW:-0}

# README.md and docs/ need nothing beside the repository (the light probes and class files
# they read are shipped in data/probes and data/classes); only the slow blocks read the full
# probe set of the project's development data, ../shared.
if [ "$DOC_COMMANDS_SLOW" = 1 ] && ! [ -d ../shared/data/probes ]; then
  die "DOC_COMMANDS_SLOW=1: the slow blocks need ../shared/data/probes (the 70 light probes) beside the repository"
fi
command -v curl >/dev/null || die "curl is needed"
command -v setsid >/dev/null || die "setsid (util-linux) is needed"
if ! command -v jq >/dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "== installing jq" >&2
    apt-get update -qq >/dev/null && apt-get install -y -qq jq >/dev/null
  else
    die "jq is needed (the admin examples read job ids with it)"
  fi
fi

WORK=$(mktemp -d "${TMPDIR:-/tmp}/doc_commands.XXXXXX")
SERVERS_FILE="$WORK/servers"
: >"$SERVERS_FILE"
stop_servers() {
  # Process groups of servers still running (each file's own trap normally stopped them).
  local pgid
  while read -r pgid; do
    kill -TERM -- "-$pgid" 2>/dev/null || true
  done <"$SERVERS_FILE"
  sleep 0.2
  while read -r pgid; do
    kill -KILL -- "-$pgid" 2>/dev/null || true
  done <"$SERVERS_FILE"
}
cleanup() {
  stop_servers
  rm -rf "$WORK"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

if [ -n "${REFLECTANCE_BIN:-}" ]; then
  [ -x "$REFLECTANCE_BIN" ] || die "REFLECTANCE_BIN=$REFLECTANCE_BIN is not an executable"
  REFLECTANCE_BIN=$(cd "$(dirname "$REFLECTANCE_BIN")" && pwd)/$(basename "$REFLECTANCE_BIN")
  export REFLECTANCE_BIN
  echo "== binary: $REFLECTANCE_BIN (cargo commands are skipped)"
else
  [ -x target/release/reflectance ] \
    || die "target/release/reflectance is missing: run cargo build --release, or set REFLECTANCE_BIN"
  echo "== binary: target/release/reflectance"
fi
export PATH="$ROOT/target/release:$PATH"
export DOC_ROOT="$ROOT" DOC_SERVERS="$SERVERS_FILE"

START=$SECONDS
n=0
passed=0
skipped=0
for file in "${FILES[@]}"; do
  [ -f "$file" ] || die "no such file: $file"
  out="$WORK/$n"
  mkdir -p "$out"
  counts=$(python3 "$HELPER" script "$file" "$out") || die "cannot read the blocks of $file"
  read -r to_run to_skip <<<"$counts"
  echo
  echo "==================== $file ($to_run blocks to run, $to_skip slow ones skipped)"
  t0=$SECONDS
  DOC_OUT="$out" DOC_FILE="$file" bash -c '
    set -euo pipefail
    source "$DOC_ROOT/scripts/doc_commands/helpers.sh"
    cd "$DOC_ROOT"
    source "$DOC_OUT/run.sh"
  ' || die "$file failed (see above)"
  echo "==================== $file: ok in $((SECONDS - t0)) s"
  n=$((n + 1))
  passed=$((passed + to_run))
  skipped=$((skipped + to_skip))
done
echo
echo "doc_commands: ${#FILES[@]} files in $((SECONDS - START)) s"
echo "doc_commands: $passed passed, 0 failed, $skipped skipped"
