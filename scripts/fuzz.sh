#!/usr/bin/env bash
# Run the cargo-fuzz targets of fuzz/ on the stable toolchain, one after the other, and
# print executions, executions/s and coverage per target.
#
#   scripts/fuzz.sh                          # every target, 600 s each
#   SECONDS_PER_TARGET=60 scripts/fuzz.sh model_file
#   PARALLEL=2 scripts/fuzz.sh               # two targets at a time
#
# Stable Rust has no `-Z` flags, so cargo fuzz runs with RUSTC_BOOTSTRAP=1 (its
# instrumentation flags need it) and without a sanitizer (`-s none`: ASan's runtime is a
# nightly component); panics, aborts, timeouts and out-of-memory are still caught.
# Crashes land in fuzz/artifacts/<target>/; corpora in fuzz/corpus/<target>/ (ignored by git).
set -euo pipefail
cd "$(dirname "$0")/.."

SECONDS_PER_TARGET=${SECONDS_PER_TARGET:-600}
PARALLEL=${PARALLEL:-1}
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=(decode_features multipart_router model_file archive_unpack)

command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
export RUSTC_BOOTSTRAP=1
python3 scripts/fuzz/seeds.py
(cd fuzz && cargo fuzz build -s none --release)
mkdir -p fuzz/logs

run() {
  local target=$1
  (cd fuzz && cargo fuzz run -s none --release "$target" -- \
     -max_total_time="$SECONDS_PER_TARGET" -timeout=20 -rss_limit_mb=4096 \
     -max_len=600000 -print_final_stats=1) >"fuzz/logs/$target.log" 2>&1 || true
}

summary() {
  local target=$1 log=fuzz/logs/$1.log
  local last execs rate
  last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  echo "$target: executions ${execs:-?}, ${rate:-?} exec/s; last status: ${last:-none}"
  if grep -qE 'panicked|deadly signal|ERROR: libFuzzer' "$log"; then
    echo "  CRASH: see $log and fuzz/artifacts/$target/"
  fi
}

running=0
for target in "${TARGETS[@]}"; do
  echo "== fuzzing $target for ${SECONDS_PER_TARGET}s" >&2
  run "$target" &
  running=$((running + 1))
  if [ "$running" -ge "$PARALLEL" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait || true
for target in "${TARGETS[@]}"; do summary "$target"; done
