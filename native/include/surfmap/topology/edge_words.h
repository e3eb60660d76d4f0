#pragma once
// Free-group words of single edges of a system of loops, one edge at a time.
//
// edge_group_elements (edge_homotopy.h) gives every edge of the mesh its
// element by peeling the whole cut tree T* once: O(#E) words, with a cache
// miss per face. A loop projection onto the mesh's own loops (another cut of
// the source: map/stages/source_cuts.h) only reads the edges along a few
// loops, ~1% of them, and that peel was a third of each cut's cost (issue 19).
//
// The same words, read from the cut disk D (the faces glued along T*, cut
// along T and the generator edges): the faces below a T* edge e (on its
// child side) form a sub-disk bounded by e and one arc of the boundary of D,
// and every face relation there holds exactly in the free group (only the
// root face's does not), so e's element is the inverse of the product of the
// boundary arc's elements: tree halfedges the identity, generator halfedges
// their letters. D's boundary carries only 4g letters, so each edge costs the
// two rotations that find its arc's ends. The words are reduced free-group
// words, hence equal to edge_group_elements' (a test compares every edge).
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"

namespace surfmap {

class CutDiskEdgeWords {
 public:
  /// `conn`: Connectivity(loops.mesh.F) (kept by reference, as `loops`).
  /// Throws SolveError when the trees are inconsistent with the mesh (the
  /// boundary of D is not one cycle through every cut halfedge).
  CutDiskEdgeWords(const SystemOfLoops& loops, const Connectivity& conn);
  /// The word of edge e for the orientation conn.edge_halfedge(e), the
  /// generator letters 1..2g as edge_group_elements with loop values {k}.
  /// Memoized: not safe to call from two threads at once.
  const Word& operator()(int e) const;

 private:
  int arc_start(int h) const;
  const Connectivity& conn_;
  const std::vector<int>& dual_parent_;
  std::vector<int> letter_;  ///< per halfedge: its generator letter (0: none)
  std::vector<char> cut_;    ///< per edge: in T or a generator edge
  std::vector<int> pos_;     ///< per halfedge: position on D's boundary walk (-1: off it)
  std::vector<std::pair<int, int>> letters_;  ///< (position, letter), in walk order
  int length_ = 0;                            ///< halfedges on D's boundary
  mutable std::vector<Word> cache_;
  mutable std::vector<char> done_;
};

}  // namespace surfmap
