#pragma once
// The one entry point of the intake fuzzer (scripts/fuzz.sh, libFuzzer) and
// of its corpus replay in CI (tests/test_fuzz_corpus.cpp, any compiler):
// the input's first byte picks the file format, the rest is the file. The
// bytes go through exactly what `surfmap info`, `surfmap map` and Python's
// load_mesh do: read_polygon_soup, inspect, intake, and for a valid mesh the
// solvers' mollified edge lengths.
#include <cstddef>
#include <cstdint>
#include <string>

namespace surfmap::fuzz {

/// Outcome of one input: "ok" or the one-line InputError message.
/// Returns normally for every input the readers and intake handle properly;
/// anything else (another exception type, an empty or multi-line message, a
/// broken invariant of a valid intake result) aborts, which is what the
/// fuzzer and the replay test detect. `scratch_dir` holds the temporary file.
std::string run_intake_input(const uint8_t* data, size_t size, const std::string& scratch_dir);

/// The file extension the first byte selects (".obj", ".off", ".ply", ".stl").
const char* extension_for(uint8_t selector);

}  // namespace surfmap::fuzz
