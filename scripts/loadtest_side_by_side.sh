#!/usr/bin/env bash
# The shipped models and the fixture model under the same load, measured alternately in one
# run (so that a noisy machine slows them alike), as one Markdown table.
#
#   scripts/loadtest_side_by_side.sh
#   BASELINE=/tmp/base/target/release/reflectance scripts/loadtest_side_by_side.sh
#   ROUNDS=3 DURATION=30s scripts/loadtest_side_by_side.sh
#
# BASELINE adds the fixture model served by another build (for example an older commit
# built in a worktree), and the ratios are taken against it; without it, against this
# build's fixture model. Each row is the median of ROUNDS runs (default 2) of
# scripts/loadtest.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
ROUNDS=${ROUNDS:-2}
export DURATION=${DURATION:-20s}

cargo build --release -q
CURRENT=${CARGO_TARGET_DIR:-target}/release/reflectance
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

# name|binary|registry (empty: the script's fixture model)|model
configs=()
[ -n "${BASELINE:-}" ] && configs+=("fixture hand6, baseline build|$BASELINE||ward6")
configs+=("fixture hand6|$CURRENT||ward6")
configs+=("shipped ward6|$CURRENT|models|ward6")
configs+=("shipped ward11|$CURRENT|models|ward11")

for round in $(seq 1 "$ROUNDS"); do
  for i in "${!configs[@]}"; do
    IFS='|' read -r name bin registry model <<<"${configs[$i]}"
    echo "== round $round/$ROUNDS: $name" >&2
    BIN=$bin MODELS=$registry MODEL=$model scripts/loadtest.sh >"$OUT/$i.$round" 2>/dev/null
  done
done

python3 - "$OUT" "$ROUNDS" "${configs[@]}" <<'PY'
import re, statistics, sys
out, rounds, configs = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
def read(path):
    text = open(path).read()
    rps = float(re.search(r"Requests/sec:\s+([\d.]+)", text).group(1))
    p99 = re.search(r"99%\s+([\d.]+)(us|ms|s)\b", text)
    scale = {"us": 1e-3, "ms": 1.0, "s": 1e3}[p99.group(2)]
    rss = int(re.search(r"server peak RSS: (\d+) MiB", text).group(1))
    return rps, float(p99.group(1)) * scale, rss
rows = []
for i, config in enumerate(configs):
    runs = [read(f"{out}/{i}.{r}") for r in range(1, rounds + 1)]
    rows.append((config.split("|")[0], runs))
reference = statistics.median(r[0] for r in rows[0][1])
print("| model | requests/s (each run) | p99 (each run) | peak RSS | × " + rows[0][0] + " |")
print("|---|---|---|---|---|")
for name, runs in rows:
    rps = statistics.median(r[0] for r in runs)
    print(f"| {name} | {' / '.join(f'{r[0]:.0f}' for r in runs)} | "
          f"{' / '.join(f'{r[1]:.1f} ms' for r in runs)} | {max(r[2] for r in runs)} MiB | "
          f"{rps / reference:.2f} |")
PY
