#include "dijkstra.h"

namespace surfmap::detail {

void prepare_dijkstra(int num_nodes, const DijkstraOptions& options, DijkstraResult& result) {
  const size_t n = static_cast<size_t>(num_nodes);
  result.settled.clear();
  result.heap.clear();
  result.reached_target = false;
  const bool sized = result.distance.size() == n;
  const bool parents_sized = result.parent_arc.size() == n && result.parent_node.size() == n;
  if (options.keep_distances && sized && (parents_sized || !options.want_parents)) return;
  if (sized) {
    // Only what the earlier searches reached differs from a fresh result.
    for (int v : result.reached) {
      result.distance[v] = std::numeric_limits<double>::infinity();
      if (parents_sized) result.parent_arc[v] = result.parent_node[v] = -1;
    }
  } else {
    result.distance.assign(n, std::numeric_limits<double>::infinity());
  }
  if (options.want_parents && !(sized && parents_sized)) {
    result.parent_arc.assign(n, -1);
    result.parent_node.assign(n, -1);
  }
  result.reached.clear();
}

std::vector<int> arcs_back_to_source(const DijkstraResult& result, int node) {
  std::vector<int> arcs;
  for (int v = node; result.parent_arc[v] >= 0; v = result.parent_node[v]) arcs.push_back(result.parent_arc[v]);
  return arcs;
}

}  // namespace surfmap::detail
