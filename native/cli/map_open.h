#pragma once
// `surfmap map` for open surfaces (issue 16, docs/open_surfaces.md): called
// first by cmd_map.cpp; closed pairs return false and take the usual path.
#include <string>
#include <utility>
#include <vector>

namespace surfmap::cli {

struct OpenMapCliArgs {
  std::string src, dst, out, report, correspondence, initial_out;
  bool quiet = false;
  /// --landmarks file (empty: none): 'source_vertex target_vertex' lines.
  std::string landmarks;
  /// --boundary-swap (annuli: source loop 0 -> target loop 1) and
  /// --boundary-pairing (target loop of each source loop, by index).
  bool boundary_swap = false;
  std::vector<int> boundary_pairing;
  /// Through the doubles (surfmap/open_double.py surface_map_open): the
  /// refinement fallback near the boundary (--refine-rings, --refine-levels;
  /// 0 levels: off) and the reflection-aware solve of the half
  /// (--no-reflection-solve turns it off).
  int refine_rings = 4, refine_levels = 2;
  bool reflection_solve = true;
};

/// Landmark pairs, one 'source_vertex target_vertex' per line; blank lines
/// and '#' comments are skipped. Errors name the file and line (cmd_map.cpp).
std::vector<std::pair<int, int>> read_landmarks(const std::string& path);

/// When either mesh has a boundary: validates both (same genus and number of
/// boundary loops, else an InputError naming both), maps disks and annuli
/// (map/open_map.h), writes --out, --report and --correspondence like the
/// closed maps, and returns true. Returns false when both are closed.
bool map_open_pair(const OpenMapCliArgs& args);

}  // namespace surfmap::cli
