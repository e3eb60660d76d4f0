#!/usr/bin/env bash
# Runs every test: C++ (GoogleTest via ctest), Python (pytest on the module)
# and Blender (blender -b). Installs what is missing and builds first.
# Exit status is non-zero if any test fails.
set -uo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${SURFMAP_BUILD_DIR:-$repo/build}"
bash "$repo/scripts/build.sh" || { echo "surfmap: build failed"; exit 1; }
results="$build/test-results"
rm -rf "$results" && mkdir -p "$results"
status=0

echo "== C++ tests (ctest)"
(cd "$build" && ctest -j2 --output-on-failure --timeout 900 --output-junit "$results/ctest.xml") || status=1

echo "== Python tests (pytest)"
SURFMAP_PYTHONPATH="$build/python" /usr/bin/python3 -m pytest -q -p no:cacheprovider \
  --junitxml="$results/pytest.xml" "$repo/native/tests/python" || status=1

echo "== Blender tests (blender -b)"
SURFMAP_PYTHONPATH="$build/python" SURFMAP_TEST_RESULTS="$results/blender.json" \
  blender -b --factory-startup --python-exit-code 1 --python "$repo/blender_tests/run_all.py" || status=1

/usr/bin/python3 "$repo/scripts/summarize_tests.py" "$results" || status=1
exit $status
