#!/usr/bin/env bash
# Fuzzes the mesh readers (OBJ/OFF/PLY/STL through OpenMesh) and intake with
# libFuzzer, AddressSanitizer and UndefinedBehaviorSanitizer, for SECONDS
# (default 600). Needs Debian's clang and libclang-rt-14-dev, installed here when
# missing and run as root (the normal
# build and CI use g++ and only replay the corpus: test_fuzz_corpus.cpp).
#
#   bash scripts/fuzz.sh 600
#
# Starts from native/tests/fuzz/corpus/{seeds,findings,fuzzed}; new interesting
# inputs collect in $SURFMAP_FUZZ_DIR/corpus (default build-fuzz/corpus), and
# a crash, hang (> 10 s per input), memory blow-up (> 2 GB) or sanitizer
# report stops the run with the input saved in build-fuzz/artifacts/. Fix the
# cause, then copy the input into native/tests/fuzz/corpus/findings/ so CI
# replays it. Exit status 0 only when the whole time passed without a finding.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-600}"
out="${SURFMAP_FUZZ_DIR:-$repo/build-fuzz}"
cxx="${SURFMAP_FUZZ_CXX:-clang++}"
if ! command -v "$cxx" >/dev/null 2>&1 || ! dpkg-query -W -f='${Status}' libclang-rt-14-dev 2>/dev/null | grep -q "install ok installed"; then
  # Only the fuzzer needs clang and its sanitizer runtimes, so bootstrap.sh leaves them out.
  if [ "$(id -u)" -eq 0 ]; then
    echo "fuzz.sh: installing clang libclang-rt-14-dev" >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev >/dev/null
  else
    echo "fuzz.sh: $cxx not found. Run as root: apt-get install clang libclang-rt-14-dev" >&2
    exit 2
  fi
fi
mkdir -p "$out/obj" "$out/corpus" "$out/artifacts" "$out/scratch"
flags=(-std=c++17 -g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
       -I"$repo/native/include" -I"$repo/native/tests" -I/usr/include/eigen3 -DOM_STATIC_BUILD=0)
sources=(native/src/mesh/mesh_io.cpp native/src/mesh/intake.cpp native/src/mesh/connectivity.cpp
         native/src/geometry/mollify.cpp native/tests/fuzz/fuzz_intake.cpp native/tests/fuzz/libfuzzer_main.cpp)
objects=()
for src in "${sources[@]}"; do
  obj="$out/obj/$(basename "${src%.cpp}").o"
  if [ ! -f "$obj" ] || [ "$repo/$src" -nt "$obj" ] || [ -n "$(find "$repo/native/include" "$repo/native/tests/fuzz" -newer "$obj" -name '*.h' | head -1)" ]; then
    echo "fuzz.sh: compiling $src" >&2
    "$cxx" "${flags[@]}" -fsanitize=fuzzer-no-link -c "$repo/$src" -o "$obj"
  fi
  objects+=("$obj")
done
"$cxx" "${flags[@]}" -fsanitize=fuzzer "${objects[@]}" -lOpenMeshCore -o "$out/fuzz_intake"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export SURFMAP_FUZZ_SCRATCH="$out/scratch"
echo "fuzz.sh: fuzzing for $seconds s (corpus $out/corpus)" >&2
"$out/fuzz_intake" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
  -max_len=8192 -dict="$repo/native/tests/fuzz/mesh.dict" -artifact_prefix="$out/artifacts/" \
  -print_final_stats=1 "$out/corpus" "$repo/native/tests/fuzz/corpus/seeds" "$repo/native/tests/fuzz/corpus/findings" \
  "$repo/native/tests/fuzz/corpus/fuzzed"
