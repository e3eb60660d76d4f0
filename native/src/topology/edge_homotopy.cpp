#include "surfmap/topology/edge_homotopy.h"

namespace surfmap {

std::vector<int> loop_first_vertices(const SystemOfLoops& s, const Connectivity& c) {
  std::vector<int> first;
  for (size_t k = 0; k < s.loops.size(); ++k) {
    const int e = s.generator_edges[k];
    const int u = c.edge_vertex(e, 0), w = c.edge_vertex(e, 1);
    const auto& L = s.loops[k];
    int found = -1;
    for (size_t q = 0; q + 1 < L.size() && found < 0; ++q)
      if ((L[q] == u && L[q + 1] == w) || (L[q] == w && L[q + 1] == u)) found = L[q];
    if (found < 0) throw SolveError("loop " + std::to_string(k) + " does not pass through its generator edge");
    first.push_back(found);
  }
  return first;
}

}  // namespace surfmap
