#pragma once
// A start for the harmonic solve of one class of a genus >= 2 map that
// needs no development of the source in one chart (issue 13): every source
// vertex at the target vertex nearest to it in 3D (its position in the
// target's cut disk), the sheets chosen along a breadth-first tree of the
// solver's edges so that every tree edge's element is the shortest side
// word joining the two copies. For a pair that overlays (a remeshed copy, a
// plate onto another triangulation of itself) the start is then the overlay
// map itself, and in the overlay's class every edge starts a few target
// edges long instead of as long as its deck element moves the origin (the
// genus-11 plate: 41 .. 70 units from the origin, where Newton stalled at
// 800 times the optimum energy). The tree fixes every vertex's deck up to
// one element at the root: the conjugator D with D L D^-1 = M for the loops
// the edges off the tree close (L the class's element of the loop, M the
// snapped map's), found from the fixed points of two such pairs and read
// as a side word by reducing D(0) into the polygon. When the class is not
// the snapped map's (no such D: its lengths differ), the edges off the tree
// come out long and the origin start (lower energy) is kept. Internal to
// src/map/hyperbolic_map.cpp.
#include <complex>
#include <vector>

#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

struct SnappedStart {
  std::vector<std::complex<double>> z;  ///< #V points of the target's cut disk
  std::vector<Word> deck;               ///< #V vertex decks (side words), as solve_with_decks reads them
  /// E at this start and at the origin start (every vertex at 0, no decks),
  /// and the longest start edge of each (hyperbolic units).
  double energy = 0, origin_energy = 0;
  double longest_edge = 0, origin_longest_edge = 0;
  /// Whether this start is the better one: lower energy than the origin's
  /// and no edge longer than the origin's longest (the start-edge limit of
  /// the solve, HyperbolicHarmonicOptions::max_start_edge_size, must not
  /// refuse a class the origin start would solve).
  bool better() const { return energy < origin_energy && longest_edge <= origin_longest_edge; }
};

class SnappedStartBuilder {
 public:
  /// `layout`/`group`: the target's hyperbolic cut disk and deck group; the
  /// first target.num_vertices() vertices of the layout's mesh are the
  /// target's own (as every uniformized target keeps them).
  SnappedStartBuilder(const TriMesh& source, const TriMesh& target, const DiskLayout& layout, const DeckGroup& group,
                      const FundamentalPolygon& polygon);
  /// The start for the solver edges `edges` of one class (#V = source vertices).
  SnappedStart operator()(const std::vector<WeightedEdge>& edges) const;

 private:
  const DeckGroup& group_;
  const FundamentalPolygon& polygon_;
  std::vector<int> nearest_;                              ///< #V source: target vertex
  std::vector<std::vector<std::complex<double>>> copies_;  ///< per target vertex: its disk copies
  std::vector<Word> short_words_;                          ///< side words of length <= 2 (and the empty word)
  std::vector<hyperbolic::Mobius> short_elements_;
};

}  // namespace surfmap::detail
