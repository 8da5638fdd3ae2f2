#!/usr/bin/env bash
# Every kind of glTF asset the product exports, validated by the Khronos glTF validator
# (npm `gltf-validator`, installed into a temporary folder): the classes of both class
# files (as .gltf and as binary .glb), 200 materials over the whole design's range and its
# corners, coloured (`reflectance gltf`), and the estimates and classes of the shipped models
# on the fixture photographs (`reflectance classify --gltf`, both materials, both formats). `GET /v1/material.gltf` writes the same asset
# (tests/server/api.rs checks that). Fails on any error or warning.
#
#   bash scripts/gltf/check.sh            # with BIN=path/to/reflectance to test a given binary
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${BIN:-target/release/reflectance}
VALIDATOR=gltf-validator@2.0.0-dev.3.10
work=$(mktemp -d "${TMPDIR:-/tmp}/gltf-check.XXXXXX")
trap 'rm -rf "$work"' EXIT

npm install --silent --no-audit --no-fund --prefix "$work/npm" "$VALIDATOR" >/dev/null
for n in 6 11; do
  "$BIN" gltf --classes "../shared/data/classes/classes$n.json" --out "$work/classes$n" >/dev/null
  "$BIN" gltf --classes "../shared/data/classes/classes$n.json" --format glb --out "$work/glb$n" >/dev/null
done
"$BIN" materials --count 200 --seed 3 --out "$work/design.json" >/dev/null
"$BIN" gltf --classes "$work/design.json" --out "$work/design" >/dev/null
mkdir -p "$work/corners"
corner=0
for params in "0 0 0" "1 0 0" "0 1 0" "0 0 1" "0.5 0.5 1" "0 0.04 0.005" "0.2 0.01 0.3"; do
  read -r d s a <<<"$params"
  corner=$((corner + 1))
  "$BIN" gltf --rho-d "$d" --rho-s "$s" --alpha "$a" --out "$work/corners/$corner.gltf" >/dev/null
  "$BIN" gltf --rho-d "$d" --rho-s "$s" --alpha "$a" --colour 0.9,0.4,0.1 --name "c$corner" \
    --out "$work/corners/$corner-colour.glb" >/dev/null
done
mkdir -p "$work/classified"
for model in models/ward6 models/ward11; do
  for image in tests/fixtures/features/sphere_rgb8.png tests/fixtures/features/sphere_gray16.png; do
    out="$work/classified/$(basename "$model")-$(basename "$image" .png).gltf"
    "$BIN" classify "$image" --model "$model" --white 0.8 --gltf "$out" >/dev/null 2>&1
    "$BIN" classify "$image" --model "$model" --white 0.8 --gltf "${out%.gltf}-estimate.glb" \
      --gltf-material estimate >/dev/null 2>&1
    "$BIN" classify "$image" --model "$model" --gltf "${out%.gltf}-nowhite.gltf" >/dev/null 2>&1
  done
done
files=("$work"/*/*.gltf "$work"/*/*.glb)
NODE_PATH="$work/npm/node_modules" node scripts/gltf/validate.js "${files[@]}" > "$work/report.txt" \
  || { grep -v ' 0 errors, 0 warnings' "$work/report.txt"; exit 1; }
echo "gltf: ${#files[@]} assets valid ($(tail -1 "$work/report.txt" | sed 's/.*(//; s/)//'))"
