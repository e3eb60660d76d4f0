#include "source_side.h"

#include <algorithm>

#include "../map_support.h"
#include "surfmap/error.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/topology/edge_homotopy.h"

namespace surfmap::detail {

SourceSide build_source_side(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options,
                             bool own_weights, const GreedyGraph* graph, const std::function<bool(double)>& step) {
  // The parts' shares of the side's time, 50k-vertex genus-2 source (session
  // 30): loops 15%, edge words 5%, weights 10%, handle basis 5%, coarse copy 65%.
  auto done = [&](double fraction) {
    if (step && !step(fraction)) throw Cancelled("the source's homotopy data cancelled");
  };
  CoarseSourceOptions cso;
  cso.target_vertices = std::min(options.homotopy.coarse_vertices, source.num_vertices() / 4);
  if (step) cso.keep_going = [&](double sampled) { return step(0.35 + 0.6 * std::min(sampled, 1.0)); };
  SourceSide ss;
  ss.sl = source_loops(source, sc, options, graph);
  done(0.15);
  ss.scs = canonical_schema(ss.sl.word, schema_options(options));
  // Deck elements are computed as words first and multiplied out only when
  // reduced: products like g g^-1 of large SU(1,1) matrices lose digits, and
  // the words of single edges are short (their crossings with the cut).
  std::vector<Word> src_letters;
  for (size_t k = 0; k < ss.scs.letters.size(); ++k) src_letters.push_back({static_cast<int>(k) + 1});
  const GroupOps<Word> free_group{Word{}, [](const Word& u, const Word& v) { return concat(u, v); },
                                  [](const Word& u) { return inverse(u); }};
  ss.edge_word = edge_group_elements(sc, ss.sl.tree_parent_halfedge, ss.sl.dual_tree_parent_halfedge,
                                     ss.sl.generator_edges, loop_first_vertices(ss.sl, sc), src_letters, free_group);
  done(0.2);
  // The energy's triangulation and weights: intrinsic Delaunay, or positive
  // weights on the source's own edges (options.solve.source_weights; the automatic
  // fallback below switches when the user's faces fold).
  ss.idt = own_weights ? positive_edge_weights(sc, edge_lengths(source, sc), {options.solve.own_weights_floor})
                       : delaunay_energy_weights(sc, edge_lengths(source, sc));
  if (!ss.idt.delaunay) throw SolveError("the source's intrinsic Delaunay flips did not finish");
  done(0.3);
  ss.shb = handle_basis(source, ss.sl.loops, ss.scs);
  done(0.35);
  // The ranking level (below): a coarse copy of the source.
  if (options.homotopy.coarse_vertices > 0 && cso.target_vertices >= 500) ss.cs = coarse_source(source, sc, cso);
  done(1);
  return ss;
}

}  // namespace surfmap::detail
