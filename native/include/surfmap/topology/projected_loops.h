#pragma once
// The homotopy class "as the two shapes overlap" (DESIGN.md §2.10: handles go
// to the geometrically corresponding handles when two objects are posed
// alike). Both shapes are normalised to the unit box (per-axis bounding-box
// scaling about the box centre); every vertex of each source loop is sent to
// the nearest target vertex, consecutive images are joined by shortest edge
// paths of the target, and the class of each closed image path is read off
// as the product of the target's edge elements (topology/edge_homotopy.h: a
// word in the target's loop letters, based at the target's base vertex up
// to one common conjugation). For a remeshed or jittered copy of a surface
// this is exactly the identity class; for two different shapes in the same
// pose it is the class a nearest-point correspondence induces. When the
// shapes do not overlap well the images jump and the result is refused
// (`ok` false) rather than guessed. The caller still verifies that the
// loop images define an isomorphism (relator image trivial, symplectic
// homology).
#include <string>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"

namespace surfmap {

struct ProjectedLoopsOptions {
  /// Longest edge path (in edges) allowed between the images of two
  /// consecutive loop vertices, relative to the ratio of mean edge lengths
  /// (default 6: images that jump further mean the shapes do not overlap).
  double max_gap_factor = 6.0;
};

struct ProjectedLoopsResult {
  bool ok = false;
  std::string message;
  /// Per source loop: its image's class as a Dehn-reduced word in the
  /// target's loop letters (relator: the target's boundary word).
  std::vector<Word> loop_images;
  /// Longest edge path used to join consecutive images.
  int longest_gap = 0;
};

/// `source`: the mesh of `source_loops` (closed vertex paths); `target`: the
/// target's system of loops (its refined mesh carries the loops);
/// `target_word`: the boundary word used as the target's relator.
ProjectedLoopsResult project_loops(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                   const SystemOfLoops& target, const Word& target_word,
                                   const ProjectedLoopsOptions& options = {});

}  // namespace surfmap
