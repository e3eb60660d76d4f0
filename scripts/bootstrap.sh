#!/usr/bin/env bash
# Installs the Debian 12 packages surfmap needs (when run as root), or prints
# the exact apt-get line to run. Idempotent: does nothing when all are there.
set -euo pipefail

PACKAGES=(
  cmake g++ make pkg-config
  libeigen3-dev libopenmesh-dev pybind11-dev python3-dev python3-numpy python3-pytest
  libgtest-dev libbenchmark-dev libsuitesparse-dev libtbb-dev nlohmann-json3-dev libcli11-dev
  libopenblas0-pthread
  blender zip
  clang libclang-rt-14-dev
)
# clang, libclang-rt-14-dev: libFuzzer and the sanitizers for scripts/fuzz.sh
# (the build itself uses g++).
# libopenblas0-pthread: an optimised BLAS/LAPACK for CHOLMOD's supernodal
# factorisations (the Newton solves, the Ricci flow): installing it makes it
# libblas.so.3 / liblapack.so.3 through update-alternatives (priority 100
# against 10 for the reference BLAS that libsuitesparse-dev pulls in), so
# nothing needs relinking. `update-alternatives --display
# libblas.so.3-x86_64-linux-gnu` shows which one is used; bench_map prints it.

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

line="apt-get install -y --no-install-recommends ${missing[*]}"
if [ "$(id -u)" -ne 0 ]; then
  echo "surfmap: missing Debian packages. Run as root:" >&2
  echo "  apt-get update && $line" >&2
  exit 1
fi
echo "surfmap: installing missing Debian packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
