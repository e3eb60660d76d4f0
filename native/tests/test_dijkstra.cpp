// The one Dijkstra / A* search of the core (src/mesh/dijkstra.h): its
// distances are shortest-path lengths (every arc satisfies the triangle
// inequality, every parent arc is tight), its early stops and bounds give
// the same distance to the target, and a reused result is as a fresh one.
#include "../src/mesh/dijkstra.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"

namespace surfmap::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A jittered genus-2 surface: edge lengths of many different values.
struct Shape {
  TriMesh mesh = samples::jitter(samples::n_hole_torus(2, 40), 0.2, 7);
  Connectivity conn{mesh.F, mesh.num_vertices()};
  double length(int h) const { return (mesh.V.row(conn.head(h)) - mesh.V.row(conn.tail(h))).norm(); }
  auto arcs() const {
    return rotation_arcs(conn, [this](int h) { return length(h); });
  }
  int nv() const { return conn.num_vertices(); }
};

// Options recording parent nodes too (the checks walk them).
DijkstraOptions with_nodes() {
  DijkstraOptions options;
  options.want_parent_nodes = true;
  return options;
}

const Shape& shape() {
  static const Shape s;
  return s;
}

// The properties that make `r` the shortest-path distances from `sources`
// over every vertex: sources at 0, no arc shortens a distance (triangle
// inequality), and each reached vertex's parent arc ends there, starts at
// its parent and adds up to its distance exactly.
void expect_shortest_paths(const Shape& s, const DijkstraResult& r, const std::vector<int>& sources) {
  for (int v : sources) EXPECT_EQ(r.distance[v], 0.0);
  int tight = 0;
  for (int h = 0; h < s.conn.num_halfedges(); ++h) {
    const int a = s.conn.tail(h), b = s.conn.head(h);
    ASSERT_TRUE(std::isfinite(r.distance[a]));
    EXPECT_LE(r.distance[b], r.distance[a] + s.length(h)) << "halfedge " << h;
  }
  for (int v = 0; v < s.nv(); ++v) {
    const int h = r.parent_arc[v];
    if (r.distance[v] == 0.0) continue;
    ASSERT_GE(h, 0) << "vertex " << v;
    EXPECT_EQ(s.conn.head(h), v);
    EXPECT_EQ(s.conn.tail(h), r.parent_node[v]);
    EXPECT_EQ(r.distance[v], r.distance[r.parent_node[v]] + s.length(h));
    ++tight;
  }
  EXPECT_EQ(tight, s.nv() - static_cast<int>(sources.size()));
}

TEST(Dijkstra, DistancesAreShortestPathLengths) {
  const Shape& s = shape();
  DijkstraResult r;
  dijkstra(s.nv(), s.arcs(), {17}, with_nodes(), r);
  expect_shortest_paths(s, r, {17});
  EXPECT_EQ(static_cast<int>(r.settled.size()), s.nv());
  EXPECT_EQ(r.settled.front(), 17);
  for (size_t i = 1; i < r.settled.size(); ++i) EXPECT_LE(r.distance[r.settled[i - 1]], r.distance[r.settled[i]]);
  // Several sources: each vertex's distance is the least of the single-source ones.
  const std::vector<int> sources = {3, 400, s.nv() - 1};
  DijkstraResult multi;
  dijkstra(s.nv(), s.arcs(), sources, with_nodes(), multi);
  expect_shortest_paths(s, multi, sources);
  std::vector<DijkstraResult> single(sources.size());
  for (size_t k = 0; k < sources.size(); ++k) dijkstra(s.nv(), s.arcs(), {sources[k]}, with_nodes(), single[k]);
  for (int v = 0; v < s.nv(); ++v) {
    double least = kInf;
    for (const DijkstraResult& one : single) least = std::min(least, one.distance[v]);
    EXPECT_NEAR(multi.distance[v], least, 1e-12 * (1 + least));
  }
}

TEST(Dijkstra, EarlyStopGivesTheSameDistanceToTheTarget) {
  const Shape& s = shape();
  DijkstraResult full;
  dijkstra(s.nv(), s.arcs(), {5}, with_nodes(), full);
  for (int target : {5, 6, 1000, s.nv() / 2, s.nv() - 1}) {
    DijkstraOptions to = with_nodes();
    to.target = target;
    DijkstraResult r;
    dijkstra(s.nv(), s.arcs(), {5}, to, r);
    EXPECT_TRUE(r.reached_target);
    EXPECT_EQ(r.settled.back(), target);
    EXPECT_EQ(r.distance[target], full.distance[target]) << "target " << target;
    // The parents' path adds up to that distance.
    double along = 0;
    for (int h : arcs_back_to_source(r, target)) along += s.length(h);
    EXPECT_NEAR(along, r.distance[target], 1e-12 * (1 + along));
    if (target != 5) EXPECT_LT(r.settled.size(), full.settled.size());
  }
}

TEST(Dijkstra, AStarWithTheStraightLineFindsTheSameDistance) {
  const Shape& s = shape();
  DijkstraResult full;
  dijkstra(s.nv(), s.arcs(), {11}, with_nodes(), full);
  for (int target : {12, 900, s.nv() - 3}) {
    DijkstraOptions to = with_nodes();
    to.target = target;
    DijkstraResult r;
    auto straight = [&](int v) { return (s.mesh.V.row(v) - s.mesh.V.row(target)).norm(); };
    dijkstra(s.nv(), s.arcs(), {11}, to, r, straight);
    ASSERT_TRUE(r.reached_target);
    EXPECT_NEAR(r.distance[target], full.distance[target], 1e-12 * full.distance[target]);
    EXPECT_LE(r.settled.size(), full.settled.size());
    // A bound below the straight line to the target stops before it.
    DijkstraOptions short_of = to;
    short_of.max_key = 0.99 * straight(11);
    dijkstra(s.nv(), s.arcs(), {11}, short_of, r, straight);
    EXPECT_FALSE(r.reached_target);
  }
}

TEST(Dijkstra, BoundsStopTheSearch) {
  const Shape& s = shape();
  DijkstraResult full;
  dijkstra(s.nv(), s.arcs(), {0}, with_nodes(), full);
  DijkstraOptions near = with_nodes();
  near.max_key = 0.3;
  DijkstraResult r;
  dijkstra(s.nv(), s.arcs(), {0}, near, r);
  int within = 0;
  for (int v = 0; v < s.nv(); ++v) within += full.distance[v] <= 0.3;
  EXPECT_EQ(static_cast<int>(r.settled.size()), within);
  for (int v : r.settled) EXPECT_EQ(r.distance[v], full.distance[v]);
  DijkstraOptions few = with_nodes();
  few.max_reached = 50;
  few.target = s.nv() - 1;
  dijkstra(s.nv(), s.arcs(), {0}, few, r);
  EXPECT_FALSE(r.reached_target);
  EXPECT_GT(r.num_reached, 50u);
  EXPECT_LT(r.num_reached, 50u + 20u);  // the last settled vertex's neighbours at most
}

TEST(Dijkstra, AReusedResultIsAFreshOne) {
  const Shape& s = shape();
  // Earlier searches stopped at a target, at a bound (nodes left in the
  // heap), or keeping distances: the next search is as on a fresh result.
  DijkstraOptions to = with_nodes(), near = with_nodes(), keep = with_nodes();
  to.target = 300;
  near.max_key = 0.2;
  keep.keep_distances = true;
  DijkstraResult fresh;
  dijkstra(s.nv(), s.arcs(), {9}, with_nodes(), fresh);
  for (const DijkstraOptions& before : {to, near, keep}) {
    DijkstraResult reused;
    dijkstra(s.nv(), s.arcs(), {200}, before, reused);
    dijkstra(s.nv(), s.arcs(), {400}, before, reused);
    dijkstra(s.nv(), s.arcs(), {9}, with_nodes(), reused);
    EXPECT_EQ(reused.distance, fresh.distance);
    EXPECT_EQ(reused.parent_arc, fresh.parent_arc);
    EXPECT_EQ(reused.parent_node, fresh.parent_node);
    EXPECT_EQ(reused.settled, fresh.settled);
    EXPECT_EQ(reused.num_reached, fresh.num_reached);
  }
}

TEST(Dijkstra, KeptDistancesGrowOneRegionAtATime) {
  // Voronoi regions seed by seed (keep_distances) are the multi-source
  // search's: each new seed settles exactly the vertices now nearer to it.
  const Shape& s = shape();
  const std::vector<int> seeds = {0, 700, 1500, s.nv() - 1};
  DijkstraOptions keep = with_nodes();
  keep.keep_distances = true;
  DijkstraResult grown;
  std::vector<double> before(s.nv(), kInf);
  for (int seed : seeds) {
    dijkstra(s.nv(), s.arcs(), {seed}, keep, grown);
    int lowered = 0;
    for (int v = 0; v < s.nv(); ++v) {
      EXPECT_LE(grown.distance[v], before[v]);
      lowered += grown.distance[v] < before[v];
    }
    EXPECT_EQ(static_cast<int>(grown.settled.size()), lowered);
    before = grown.distance;
  }
  expect_shortest_paths(s, grown, seeds);
}

TEST(Dijkstra, UnreachedNodesKeepNoDistance) {
  // The dual graph of the shape's faces, crossing only edges between two
  // faces of the first half (by index), steps of 1: the second half is cut
  // off. Reached faces satisfy the triangle inequality across every
  // crossable edge and are one step from their parent; the rest stay
  // infinite and parentless.
  const Shape& s = shape();
  const Connectivity& c = s.conn;
  const int half = c.num_faces() / 2;
  auto first_half = [&](int f, auto&& visit) {
    for (int k = 0; k < 3; ++k) {
      const int g = Connectivity::face(c.twin(3 * f + k));
      if (f < half && g < half) visit(c.edge(3 * f + k), g, 1.0);
    }
  };
  DijkstraResult r;
  dijkstra(c.num_faces(), first_half, {0}, with_nodes(), r);
  int reached = 0;
  for (int f = 0; f < c.num_faces(); ++f) {
    if (!std::isfinite(r.distance[f])) {
      EXPECT_EQ(r.parent_arc[f], -1);
      EXPECT_EQ(r.parent_node[f], -1);
      continue;
    }
    ++reached;
    EXPECT_LT(f, half);
    first_half(f, [&](int, int g, double step) { EXPECT_LE(r.distance[g], r.distance[f] + step); });
    if (f != 0) EXPECT_EQ(r.distance[f], r.distance[r.parent_node[f]] + 1.0);
  }
  EXPECT_GT(reached, 1);
  EXPECT_EQ(reached, static_cast<int>(r.num_reached));
  EXPECT_EQ(reached, static_cast<int>(r.settled.size()));
}

}  // namespace
}  // namespace surfmap::detail
