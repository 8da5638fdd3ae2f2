#!/usr/bin/env bash
# Fails when a crate of the workspace depends on what its layer may not
# (docs/architecture.md): the core carries no HTTP, async runtime, metrics, OpenAPI (unless
# asked for), plotting or command line, and knows neither the renderer nor the binary; the
# renderer adds nothing of the service's either.
set -euo pipefail
cd "$(dirname "$0")/.."
service='axum|hyper|hyper-util|tokio|tower|tower-http|metrics|metrics-exporter-prometheus|utoipa|plotters|clap|reflectance'
declare -A forbidden=(
  [reflectance-core]="^($service|reflectance-render) "
  [reflectance-render]="^($service) "
)
status=0
for crate in reflectance-core reflectance-render; do
  # Normal dependencies as the crate builds on its own; the first line is the crate itself.
  found=$(cargo tree -p "$crate" -e normal --prefix none --no-dedupe | tail -n +2 \
    | grep -E "${forbidden[$crate]}" | sort -u || true)
  if [ -n "$found" ]; then
    echo "$crate depends on what its layer may not:" >&2
    echo "$found" >&2
    status=1
  else
    echo "$crate: no dependency outside its layer"
  fi
done
exit $status
