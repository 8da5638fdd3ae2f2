#!/usr/bin/env bash
# Mutations of the honest parts (prediction sets, the domain verdict, the estimate's
# intervals, the glTF export, the dataset boundary), applied one at a time to a scratch copy
# of the committed tree, each followed by the tests: a mutation the tests do not fail on
# "survived". Prints one line per mutation with the tests that failed (docs/development.md,
# "Mutations").
#
#   scripts/mutants.sh                      # every mutation, the whole suite (`cargo test --release`)
#   scripts/mutants.sh sets-top1 gltf-swap  # some of them
#   QUICK=1 scripts/mutants.sh              # each against the test targets that guard it
#   scripts/mutants.sh --list               # the mutations
#
# The copy is `git archive HEAD` (uncommitted changes are not in it) in $MUTANTS_DIR/tree
# (default: ../reflectance-mutants beside the repository; its ../shared links to the
# repository's), built in its own target folder ($MUTANTS_DIR/target), seeded once from
# target/release when that exists. A mutation whose text is no longer in the file is
# reported "stale" (the code moved: update the list); one that does not compile "unbuilt".
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
SCRATCH=${MUTANTS_DIR:-$REPO/../reflectance-mutants}
QUICK=${QUICK:-0}

# name | file | text | replacement | quick test arguments (cargo test --release ...)
# Texts are Python string literals (\n for a new line); each must occur exactly once.
MUTATIONS=$(cat <<'EOF'
sets-top1|crates/reflectance-core/src/inference.rs|"            if alike && !set.contains(&k) {\n                set.push(k);\n            }\n        }\n    }\n    Some(set)"|"            if alike && !set.contains(&k) {\n                set.push(k);\n            }\n        }\n    }\n    set.truncate(1);\n    Some(set)"|--test server --test cli
sets-calibrated-top1|crates/reflectance-core/src/inference.rs|"let mut set = head.prediction_sets?.set(probabilities, coverage);"|"let mut set = head.prediction_sets?.set(probabilities, coverage);\n    set.truncate(1);"|--test server --test cli
sets-no-brightness-expansion|crates/reflectance-core/src/inference.rs|"    if !white_given {\n        let classes = &head.classifier.classes;"|"    if false && !white_given {\n        let classes = &head.classifier.classes;"|--test server --test cli
sets-threshold-rank|crates/reflectance-core/src/learn/conformal.rs|"        let n = self.n;\n        let rank = ((n + 1) as f64 * coverage).ceil() as usize;"|"        let n = self.n;\n        let rank = (n as f64 * coverage).floor() as usize;"|--test server --test cli
domain-always-in|crates/reflectance-core/src/learn/domain.rs|"        self.score <= self.threshold && !self.checks.iter().any(CheckResult::broken)"|"        true"|--test server --test cli
domain-bounds-ignored|crates/reflectance-core/src/learn/domain.rs|"        self.score <= self.threshold && !self.checks.iter().any(CheckResult::broken)"|"        self.score <= self.threshold"|--test server --test cli
domain-envelope-ignored|crates/reflectance-core/src/inference.rs|"self.verdict.as_ref().is_none_or(Verdict::in_domain) && self.envelope.is_empty()"|"self.verdict.as_ref().is_none_or(Verdict::in_domain)"|--test server --test cli
estimate-not-widened|crates/reflectance-core/src/inference.rs|"    Some(estimate.holding(parameters))"|"    let _ = parameters.count();\n    Some(estimate)"|--test server --test cli
gltf-swap|src/cli/classify.rs|"        rho_d: chosen.ward.rho_d,\n        rho_s: chosen.ward.rho_s,"|"        rho_d: chosen.ward.rho_s,\n        rho_s: chosen.ward.rho_d,"|--test cli
gltf-swap-mapping|crates/reflectance-core/src/material/gltf.rs|"    let pbr = pbr_of(rho_d, rho_s, alpha);"|"    let pbr = pbr_of(rho_s, rho_d, alpha);"|--test cli --test server
manifest-inside-skipped|crates/reflectance-core/src/dataset/ingest.rs|"    if !is_inside(&entry.path) {"|"    if false && !is_inside(&entry.path) {"|--test server --test cli
archive-dotdot|src/archive.rs|"            \"..\" => return Err(\"'..' is not accepted in a member's path\"),"|"            \"..\" => parts.push(part),"|--test server --lib
archive-bytes-limit|src/archive.rs|"        if written > room {"|"        if false && written > room {"|--test server --lib
EOF
)

if [ "${1:-}" = "--list" ]; then
  cut -d'|' -f1,2 <<<"$MUTATIONS" | tr '|' '\t'
  exit 0
fi
WANTED=("$@")

mkdir -p "$SCRATCH"
rm -rf "$SCRATCH/tree"
mkdir -p "$SCRATCH/tree"
git archive HEAD | tar -x -C "$SCRATCH/tree"
mkdir -p "$SCRATCH/tree/target"  # where the browser test keeps its screenshot
# The tree's ../shared (light probes, classes) is the repository's.
if [ -d "$REPO/../shared" ] && [ ! -e "$SCRATCH/shared" ]; then
  ln -s "$(cd "$REPO/../shared" && pwd)" "$SCRATCH/shared"
fi
export CARGO_TARGET_DIR=$SCRATCH/target
if [ ! -d "$CARGO_TARGET_DIR/release" ] && [ -d target/release ]; then
  echo "seeding $CARGO_TARGET_DIR from target/release" >&2
  mkdir -p "$CARGO_TARGET_DIR"
  cp -r --reflink=auto target/release "$CARGO_TARGET_DIR/release"
fi
LOGS=$SCRATCH/logs
mkdir -p "$LOGS"

# Replace the one occurrence of a Python string literal by another in a file; 3: not found
# exactly once.
apply() {
  python3 - "$1" "$2" "$3" <<'PY'
import ast, sys
path, old, new = sys.argv[1], ast.literal_eval(sys.argv[2]), ast.literal_eval(sys.argv[3])
text = open(path).read()
if text.count(old) != 1:
    sys.exit(3)
open(path, "w").write(text.replace(old, new))
PY
}

printf '%-30s %-9s %s\n' mutation outcome "failed tests"
survivors=0
while IFS='|' read -r name file old new quick; do
  [ -z "$name" ] && continue
  if [ ${#WANTED[@]} -gt 0 ] && [[ ! " ${WANTED[*]} " =~ " $name " ]]; then
    continue
  fi
  target=$SCRATCH/tree/$file
  cp "$target" "$SCRATCH/original"
  if ! apply "$target" "$old" "$new"; then
    printf '%-30s %-9s %s\n' "$name" stale "$file"
    continue
  fi
  args=()
  [ "$QUICK" = 1 ] && read -r -a args <<<"$quick"
  log=$LOGS/$name.log
  set +e
  (cd "$SCRATCH/tree" && cargo test --release "${args[@]}" --no-fail-fast) >"$log" 2>&1
  status=$?
  set -e
  cp "$SCRATCH/original" "$target"
  failed=$(sed -n 's/^test \(.*\) \.\.\. FAILED$/\1/p' "$log" | sort -u | tr '\n' ' ')
  if [ -n "$failed" ]; then
    printf '%-30s %-9s %s\n' "$name" caught "$failed"
  elif [ $status -ne 0 ]; then
    printf '%-30s %-9s %s\n' "$name" unbuilt "(see $log)"
  else
    printf '%-30s %-9s\n' "$name" SURVIVED
    survivors=$((survivors + 1))
  fi
done <<<"$MUTATIONS"
echo "survivors: $survivors (logs in $LOGS)"
[ "$survivors" -eq 0 ]
