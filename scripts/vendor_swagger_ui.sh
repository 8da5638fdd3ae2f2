#!/usr/bin/env bash
# Re-vendor the API reference viewer served at /docs: swagger-ui-dist from the npm registry,
# at the pinned version, checked against the registry's integrity hash. Only the files /docs
# serves, and the licence texts, are kept (web/vendor/swagger-ui/).
set -euo pipefail
VERSION=5.35.0
INTEGRITY=sha512-U06rpMtW9V3XPGOBeamTUSr0Z09jMX4IJuANpE/EZbAhw0G8CgwrzU4YmXkn/h0wCDNsXdGarTNNHC3sU8yVUQ==
cd "$(dirname "$0")/.."
out=web/vendor/swagger-ui
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "swagger-ui-dist@$VERSION" >/dev/null)
tarball="$work/swagger-ui-dist-$VERSION.tgz"
actual="sha512-$(openssl dgst -sha512 -binary "$tarball" | base64 -w0)"
if [ "$actual" != "$INTEGRITY" ]; then
  echo "integrity mismatch: $actual" >&2
  exit 1
fi
tar -xzf "$tarball" -C "$work"
mkdir -p "$out"
for f in swagger-ui-bundle.js swagger-ui.css LICENSE NOTICE swagger-ui-bundle.js.LICENSE.txt; do
  cp "$work/package/$f" "$out/$f"
done
(cd "$out" && sha256sum swagger-ui-bundle.js swagger-ui.css LICENSE NOTICE swagger-ui-bundle.js.LICENSE.txt) > "$out/SHA256SUMS"
echo "vendored swagger-ui-dist $VERSION into $out"
