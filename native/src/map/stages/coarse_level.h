#pragma once
// The ranking level of the genus >= 2 class ranking (docs/method.md §2.10, ranking in
// docs/method.md): the coarse copy of the source (map/coarse_source.h)
// with every candidate class's deck elements on its edges, products of the
// fine ones along the fine paths. Internal to src/map/hyperbolic_map.cpp.
#include <vector>

#include "class_data.h"
#include "surfmap/map/coarse_source.h"

namespace surfmap::detail {

struct CoarseLevel {
  /// Per class (#classes; empty for a class without homotopy data): the
  /// coarse solver edges (#coarse idt edges) with their elements.
  std::vector<std::vector<WeightedEdge>> class_edges;
  /// For the class search: every coarse solver edge's element as a reduced
  /// word in the source's loop letters (class independent), so a new
  /// class's coarse edges are one substitution per edge (edges_of); empty
  /// when the search will not run.
  std::vector<WeightedEdge> edge_template;
  std::vector<Word> source_word;
  /// The coarse edges of class theta from the template.
  std::vector<WeightedEdge> edges_of(const ClassSpace& space, const GroupMap& theta, const DiskLayout& layout,
                                     const DeckGroup& group) const;
};

/// Builds the coarse level for `data` (#classes; `usable` flags which have
/// data). Sets cs.ok = false (and cs.why) when a coarse face's fine paths are
/// not contractible or the coarse intrinsic Delaunay flips do not finish;
/// then class_edges is empty. `with_search_template`: build edge_template.
CoarseLevel coarse_level(CoarseSource& cs, const Connectivity& sc, const std::vector<Word>& edge_word,
                         const SystemOfLoops& sl, const std::vector<ClassData>& data, const std::vector<char>& usable,
                         const DeckGroup& group, bool with_search_template);

/// Prolongation (coarse solution -> start of the fine solve): a coarse
/// vertex is its fine vertex (same point, same deck); every other fine
/// vertex starts at the image of its region's coarse vertex, with that deck
/// times the element of the tree path to it (the collapsed start has the
/// right global layout; Newton spreads the clusters in a few steps).
/// prolongation_order: the #V fine vertices, parents (cs.parent_halfedge)
/// first.
std::vector<int> prolongation_order(const CoarseSource& cs, const Connectivity& sc);
/// `coarse`: the class's coarse solve (#coarse V); `cd`: its fine data.
/// Fills #V points `z` and side-word decks `deck`.
void prolong(const CoarseSource& cs, const Connectivity& sc, const std::vector<int>& order,
             const HyperbolicHarmonicResult& coarse, const ClassData& cd, const DeckGroup& group,
             std::vector<std::complex<double>>& z, std::vector<Word>& deck);

}  // namespace surfmap::detail
