#!/usr/bin/env bash
# Validate the Kubernetes manifests of deploy/kubernetes/ offline (docs/deployment.md,
# "Validating the manifests"):
#
#   scripts/validate_manifests.sh                 # deploy/kubernetes
#   scripts/validate_manifests.sh DIR             # another folder of manifests
#   REFLECTANCE_BIN=target/release/reflectance scripts/validate_manifests.sh
#   KUBERNETES_VERSION=1.35.0 scripts/validate_manifests.sh
#
# 1. Schema: every manifest (not the kustomization.yaml files, which are no Kubernetes
#    objects) against the JSON schemas of Kubernetes $KUBERNETES_VERSION, strictly: an
#    unknown or misspelt field fails. The validator is kubernetes-validate from PyPI, pinned
#    below; it bundles the schemas of every Kubernetes version it knows, so validation
#    needs no network. It is installed once into a virtual environment under
#    ${XDG_CACHE_HOME:-$HOME/.cache}/reflectance (the first run needs PyPI; later runs reuse
#    it and take about a second).
# 2. Consistency: scripts/check_manifests.py (selectors, ports, probe paths against
#    openapi.yaml, shards against the merge, the restricted security settings, …; with
#    REFLECTANCE_BIN also the subcommands and flags, an offline run of the training Jobs
#    and of the serving container).
#
# Exit status: 0 when both pass, non-zero otherwise.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DIR=${1:-$ROOT/deploy/kubernetes}

# The pins: the validator's release, and the Kubernetes version whose schemas it checks
# against (the oldest the manifests support: backoffLimitPerIndex is GA from 1.33).
VALIDATOR_VERSION=1.37.0
KUBERNETES_VERSION=${KUBERNETES_VERSION:-1.33.0}

CACHE=${XDG_CACHE_HOME:-$HOME/.cache}/reflectance
VENV=$CACHE/kubernetes-validate-$VALIDATOR_VERSION
PYTHON=${PYTHON:-python3}

die() { echo "validate_manifests: $*" >&2; exit 1; }
[ -d "$DIR" ] || die "no folder $DIR"

installed() {
  "$VENV/bin/python" -c 'import kubernetes_validate, yaml' 2>/dev/null \
    && [ "$(cat "$VENV/.pinned" 2>/dev/null)" = "kubernetes-validate==$VALIDATOR_VERSION" ]
}
if ! installed; then
  command -v "$PYTHON" >/dev/null || die "$PYTHON is needed"
  mkdir -p "$CACHE"
  # One install at a time; .pinned is written last, so an interrupted install is redone.
  exec 9>"$CACHE/.kubernetes-validate.lock"
  flock 9
  if ! installed; then
    echo "== installing kubernetes-validate $VALIDATOR_VERSION into $VENV" >&2
    rm -rf "$VENV"
    "$PYTHON" -m venv "$VENV" \
      || die "cannot create a virtual environment ($PYTHON -m venv; on Debian: apt-get install python3-venv)"
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "kubernetes-validate==$VALIDATOR_VERSION" \
      || die "cannot install kubernetes-validate $VALIDATOR_VERSION from PyPI"
    echo "kubernetes-validate==$VALIDATOR_VERSION" > "$VENV/.pinned"
  fi
  exec 9>&-
fi

mapfile -t FILES < <(find "$DIR" -type f \( -name '*.yaml' -o -name '*.yml' \) \
  ! -name kustomization.yaml ! -name kustomization.yml | LC_ALL=C sort)
[ ${#FILES[@]} -gt 0 ] || die "no manifests under $DIR"

echo "== schema: ${#FILES[@]} files against Kubernetes $KUBERNETES_VERSION (kubernetes-validate $VALIDATOR_VERSION, strict)"
# It only warns about a kind or apiVersion it has no schema for (a typo such as
# autoscaling/v3, or a custom resource): here that fails too.
status=0
report=$("$VENV/bin/python" -m kubernetes_validate --strict --quiet -k "$KUBERNETES_VERSION" "${FILES[@]}" 2>&1) \
  || status=$?
[ -z "$report" ] || printf '%s\n' "$report"
[ "$status" -eq 0 ] || die "schema validation failed (above)"
! grep -q '^WARN' <<<"$report" || die "no schema for a kind or apiVersion above: not a Kubernetes $KUBERNETES_VERSION object"
echo "validate_manifests: every document of ${#FILES[@]} files is valid"

# What `kubectl apply -k` would send: each kustomization rendered (offline: kubectl's
# built-in kustomize needs no cluster) and validated the same way.
if command -v kubectl >/dev/null; then
  mapfile -t KUSTOMIZATIONS < <(find "$DIR" -type f -name kustomization.yaml -printf '%h\n' | LC_ALL=C sort)
  RENDERED=$(mktemp -d)
  trap 'rm -rf "$RENDERED"' EXIT
  for k in "${KUSTOMIZATIONS[@]}"; do
    out="$RENDERED/$(printf '%s' "${k#"$DIR"}" | tr '/' '_')_.yaml"
    kubectl kustomize "$k" >"$out" 2>"$RENDERED/stderr" \
      || { cat "$RENDERED/stderr" >&2; die "kubectl kustomize ${k#"$ROOT"/} failed"; }
    # The images must all have been replaced by the kustomization's `images`.
    ! grep -En '^ *image: reflectance(:|$)' "$out" \
      || die "${k#"$ROOT"/}: an image is left unreplaced (add it to images:)"
  done
  echo "== kustomize: ${#KUSTOMIZATIONS[@]} kustomizations rendered (kustomize $(kubectl version --client 2>/dev/null | sed -n "s/^Kustomize Version: //p")), each validated as above"
  status=0
  report=$("$VENV/bin/python" -m kubernetes_validate --strict --quiet -k "$KUBERNETES_VERSION" "$RENDERED"/*_.yaml 2>&1) \
    || status=$?
  [ -z "$report" ] || printf '%s\n' "$report"
  [ "$status" -eq 0 ] && ! grep -q '^WARN' <<<"$report" || die "a rendered kustomization is not valid (above)"
elif [ -n "${REFLECTANCE_REQUIRE_KUBECTL:-}" ]; then
  die "REFLECTANCE_REQUIRE_KUBECTL is set but kubectl is not found: the kustomizations cannot be rendered"
else
  echo "validate_manifests: kubectl not found: the kustomizations are checked but not rendered" >&2
fi

echo "== consistency (scripts/check_manifests.py)"
"$VENV/bin/python" "$ROOT/scripts/check_manifests.py" "$DIR"
