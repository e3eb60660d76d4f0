#!/usr/bin/env bash
# Configures and builds everything (core, CLI, Python module, tests, add-on zip)
# in $SURFMAP_BUILD_DIR (default: <repo>/build), Release by default.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${SURFMAP_BUILD_DIR:-$repo/build}"
bash "$repo/scripts/bootstrap.sh"
jobs="${SURFMAP_JOBS:-$(nproc)}"
# ccache, when installed, lets several checkouts (worktrees) share compiled
# objects; the build does not depend on it.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # Paths below the checkout are hashed relative to it, so that two worktrees
  # of the same sources hit the same cache entries.
  export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$repo}"
fi
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE="${SURFMAP_BUILD_TYPE:-Release}" -DPython_EXECUTABLE=/usr/bin/python3 "${launcher[@]}" >/dev/null
cmake --build "$build" -j"$jobs"
