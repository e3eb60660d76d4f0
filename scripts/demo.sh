#!/usr/bin/env bash
# The main job: maps the shipped genus-2 sample pair in Blender (headless),
# saves a .blend and renders PNGs into $1 (default: <repo>/demo_out).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${SURFMAP_BUILD_DIR:-$repo/build}"
out="${1:-$repo/demo_out}"
bash "$repo/scripts/build.sh"
mkdir -p "$out"
SURFMAP_PYTHONPATH="$build/python" \
  blender -b --factory-startup --python-exit-code 1 --python "$repo/samples/demo.py" -- --out "$out"
echo "surfmap demo: results in $out"
ls -1 "$out"
