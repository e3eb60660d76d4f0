#pragma once
// Dijkstra's shortest paths over any graph with non-negative arc lengths,
// given by a callable that lists a node's arcs; with a potential (a lower
// bound on the distance still to go) it is A*. The one search of the
// core: the systems of loops (vertex and dual-face trees), the loops'
// projections (A* to the next loop vertex), the snapped start's and the
// per-face charts' image paths, the coarse copies' Voronoi regions, the
// open disk's pole. Internal to the core (native/src).
//
// The order is the one every caller had when each wrote it out: a binary
// min-heap of (key, node) pairs (std::priority_queue's push_heap /
// pop_heap with std::greater), ties to the smaller node; an arc taken only
// when it makes a distance strictly shorter; a node's arcs in the order the
// callable lists them. Stale heap entries are skipped. So the same graph
// listed in the same order gives the same distances, parents and
// settling order, bit for bit.
//
// Not this search: the genus-0 layout's cheapest-first placement
// (uniformize/spherical.cpp, lay_out_flat_disk). A vertex there is offered
// by a face once two of its corners are placed, at the larger of their two
// costs plus the face's own, and the heap's ties go by face and corner:
// no arc of one tail, and its order (which face places a vertex) is part
// of the result.
#include <algorithm>
#include <cstddef>
#include <functional>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "surfmap/mesh/connectivity.h"

namespace surfmap::detail {

struct DijkstraOptions {
  /// Stop as soon as this node is settled (its distance final); -1: settle
  /// every node the sources reach.
  int target = -1;
  /// Record DijkstraResult::parent_arc.
  bool want_parents = true;
  /// Record DijkstraResult::parent_node too (needed by arcs_back_to_source;
  /// off by default: one more array written per improvement, which the
  /// whole-mesh trees, whose arcs name their tails, do without).
  bool want_parent_nodes = false;
  /// Stop before settling a node whose key (its distance, plus its
  /// potential in A*) exceeds this.
  double max_key = std::numeric_limits<double>::infinity();
  /// Stop before settling a node once more than this many nodes hold a
  /// distance (DijkstraResult::num_reached): a search bounded to a
  /// neighbourhood.
  size_t max_reached = std::numeric_limits<size_t>::max();
  /// Start from the distances and parents the result holds from earlier
  /// searches of the same graph: only shorter distances are taken (one more
  /// Voronoi seed grows only its own region). Otherwise the result is reset
  /// first, in time of the nodes the last search reached when its size is
  /// already right and that search did not keep distances (many short
  /// searches of one large graph).
  bool keep_distances = false;
};

struct DijkstraResult {
  /// #nodes: the distance from the nearest source; infinity where not reached.
  std::vector<double> distance;
  /// #nodes (with want_parents): the arc into the node on its shortest path,
  /// as the caller numbers arcs (a halfedge, an edge); -1 at the sources and
  /// where not reached.
  std::vector<int> parent_arc;
  /// #nodes (with want_parent_nodes): that arc's tail; -1 likewise.
  std::vector<int> parent_node;
  /// The nodes settled by the last search, in order (a node's parent before
  /// it). Without a potential each node at most once; in A* a node whose
  /// two heap keys round to the same value may be listed twice.
  std::vector<int> settled;
  /// How many nodes were given a distance since the result was last reset
  /// (sources included).
  size_t num_reached = 0;
  /// Whether the last search stopped at DijkstraOptions::target.
  bool reached_target = false;
  /// The heap's storage, kept between searches; after a search it holds
  /// (with `settled`) every node the search reached: what the next reset
  /// clears.
  std::vector<std::pair<double, int>> heap;
  /// Whether `settled` and `heap` list every node reached since the last
  /// reset (not after a search that kept earlier distances).
  bool lists_hold_reached = false;
};

/// No potential: plain Dijkstra, the key is the distance.
struct NoPotential {
  double operator()(int) const { return 0.0; }
};

/// The arcs of a mesh's vertex graph, for dijkstra(): v's outgoing
/// halfedges h counter-clockwise from conn.vertex_halfedge(v) (the order of
/// Connectivity::outgoing), to conn.head(h), of length `length(h)`.
template <class Length>
auto rotation_arcs(const Connectivity& conn, Length length) {
  return [&conn, length](int v, auto&& visit) {
    const int first = conn.vertex_halfedge(v);
    if (first < 0) return;
    for (int h = first, more = 1; more; h = conn.rotate_ccw(h), more = h != first) visit(h, conn.head(h), length(h));
  };
}

/// Resets `result` for a search of `num_nodes` nodes (see
/// DijkstraOptions::keep_distances).
void prepare_dijkstra(int num_nodes, const DijkstraOptions& options, DijkstraResult& result);

/// The arcs of the shortest path from a source to `node`, last arc first
/// (empty at a source or where not reached; needs want_parent_nodes).
std::vector<int> arcs_back_to_source(const DijkstraResult& result, int node);

/// Shortest paths from `sources` (distance 0 each, pushed in their order)
/// over the graph of `num_nodes` nodes whose arcs out of node v are listed
/// by `for_each_arc(v, visit)`, calling visit(int arc, int head, double
/// length) for each (length >= 0, in a fixed order); into `result` (reused
/// between searches: see DijkstraOptions::keep_distances). With
/// `potential(v)` (a lower bound on the distance from v to the target, no
/// more than an arc's length plus its head's potential): A*, heap keys
/// distance + potential.
template <class ForEachArc, class Potential = NoPotential>
void dijkstra(int num_nodes, const ForEachArc& for_each_arc, const std::vector<int>& sources,
              const DijkstraOptions& options, DijkstraResult& result, const Potential& potential = {}) {
  constexpr bool astar = !std::is_same_v<Potential, NoPotential>;
  prepare_dijkstra(num_nodes, options, result);
  using Item = std::pair<double, int>;
  const std::greater<Item> later;
  // Plain pointers to the arrays of fixed size: the lists that grow (heap,
  // settled) then cannot look to the compiler as if they moved them.
  double* const dist = result.distance.data();
  int* const parent_arc = options.want_parents ? result.parent_arc.data() : nullptr;
  int* const parent_node = options.want_parent_nodes ? result.parent_node.data() : nullptr;
  std::vector<Item>& heap = result.heap;
  size_t reached = result.num_reached;
  auto key = [&](double d, int v) {
    if constexpr (astar) return d + potential(v);
    else return d;
  };
  auto set_distance = [&](int v, double d, int arc, int from) {
    reached += dist[v] == std::numeric_limits<double>::infinity();
    dist[v] = d;
    if (parent_arc) parent_arc[v] = arc;
    if (parent_node) parent_node[v] = from;
    heap.push_back({key(d, v), v});
    std::push_heap(heap.begin(), heap.end(), later);
  };
  for (int s : sources) set_distance(s, 0.0, -1, -1);
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), later);
    const auto [k, v] = heap.back();
    const double d = dist[v];
    if (k > key(d, v)) {  // stale: v was reached by a shorter path since
      heap.pop_back();
      continue;
    }
    // A bound stops the search with v still in the heap (the next reset
    // finds it there); the target is settled at any number reached.
    if (k > options.max_key) break;
    if (v == options.target) {
      heap.pop_back();
      result.settled.push_back(v);
      result.reached_target = true;
      break;
    }
    if (reached > options.max_reached) break;
    heap.pop_back();
    result.settled.push_back(v);
    for_each_arc(v, [&](int arc, int w, double length) {
      const double dw = d + length;
      if (dw < dist[w]) set_distance(w, dw, arc, v);
    });
  }
  result.num_reached = reached;
}

}  // namespace surfmap::detail
