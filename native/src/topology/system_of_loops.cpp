// Greedy system of loops and its refinement into simple loops that meet only
// at the base vertex (docs/method.md §2.2).
//
// Refinement, in our own construction. The greedy loops are
// sigma_k = path(x, a_k) + (a_k, b_k) + path(b_k, x) along the shortest-path
// tree T; they share the tree paths T' = union of path(x, a_k), path(x, b_k).
// A thin neighbourhood U of T' is a disk, so the 4g "half loops" from x to the
// generator edges can be redrawn inside U as 4g arcs that fan out from x and
// never meet again. We realise U's collar explicitly: walk around T' once
// (its Euler tour, starting in one corner of x); every non-T' edge leaving a
// vertex of T' is a "slot" that the arcs still travelling cross at distinct
// points near that vertex, in nested order (the arc that leaves the collar
// last runs innermost). At the slot of a generator edge the outermost arc
// leaves: its endpoint is the outermost split point on that edge, and the
// middle piece of the generator edge closes the loop. Inside each input face
// the arc pieces are straight chords between split points (a chord joining
// two points of the same edge gets one bend point inside the face), and the
// pieces of the face are triangulated. Everything afterwards (tree, cut tree,
// generators, word) is recomputed on the refined mesh from the loops, and the
// result is verified.
#include "surfmap/topology/system_of_loops.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <cmath>
#include <functional>
#include <memory>
#include <limits>
#include <numeric>
#include <set>
#include <string>
#include <utility>

#include <Eigen/Dense>

#include "surfmap/error.h"
#include "surfmap/topology/cut_mesh.h"

#include "../mesh/dijkstra.h"

namespace surfmap {
namespace {

// Breadth-first spanning tree of the faces from face 0, crossing only the
// edges `crossable(e)` allows. parent[f] is the halfedge of f through which
// it was reached (inside f, pointing back at its parent face), -1 for face 0
// and for faces not reached. Returns the number of faces reached.
template <class Crossable>
int dual_bfs_tree(const Connectivity& conn, const Crossable& crossable, std::vector<int>& parent) {
  const int nf = conn.num_faces();
  parent.assign(nf, -1);
  std::vector<char> seen(nf, 0);
  std::vector<int> queue{0};
  seen[0] = 1;
  for (size_t i = 0; i < queue.size(); ++i) {
    const int f = queue[i];
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (!crossable(conn.edge(h))) continue;
      const int nbr = Connectivity::face(conn.twin(h));
      if (seen[nbr]) continue;
      seen[nbr] = 1;
      parent[nbr] = conn.twin(h);
      queue.push_back(nbr);
    }
  }
  return static_cast<int>(queue.size());
}

struct UnionFind {
  std::vector<int> p;
  explicit UnionFind(int n) : p(n) { std::iota(p.begin(), p.end(), 0); }
  int find(int a) {
    while (p[a] != a) a = p[a] = p[p[a]];
    return a;
  }
  bool unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    p[a] = b;
    return true;
  }
};

std::vector<double> edge_lengths(const TriMesh& mesh, const Connectivity& conn) {
  std::vector<double> len(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e)
    len[e] = (mesh.V.row(conn.edge_vertex(e, 0)) - mesh.V.row(conn.edge_vertex(e, 1))).norm();
  return len;
}

/// Dijkstra distances from x by edge weights `len` (#E).
std::vector<double> dijkstra_distances(const Connectivity& conn, const std::vector<double>& len, int x) {
  detail::DijkstraOptions options;
  options.want_parents = false;
  detail::DijkstraResult r;
  detail::dijkstra(conn.num_vertices(), detail::rotation_arcs(conn, [&](int h) { return len[conn.edge(h)]; }), {x},
                   options, r);
  return std::move(r.distance);
}

int default_base_vertex(const TriMesh& mesh, const Connectivity& conn) {
  // Among the vertices nearest the centroid, the one of highest valence: a
  // central base point keeps the loops short, and a high valence gives the
  // 4g arcs that leave x room to fan out.
  const int nv = mesh.num_vertices();
  const Eigen::RowVector3d c = mesh.V.colwise().mean();
  std::vector<std::pair<double, int>> d(nv);
  for (int v = 0; v < nv; ++v) d[v] = {(mesh.V.row(v) - c).squaredNorm(), v};
  const int k = std::min(nv, 64);
  std::partial_sort(d.begin(), d.begin() + k, d.end());
  int best = d[0].second, best_val = -1;
  for (int i = 0; i < k; ++i) {
    const int val = conn.valence(d[i].second);
    if (val > best_val) {
      best_val = val;
      best = d[i].second;
    }
  }
  return best;
}

// The greedy homotopy basis on one mesh.
struct Greedy {
  std::vector<int> parent_he;       // per vertex: halfedge parent -> v (-1 at x)
  std::vector<char> in_tree;        // per edge
  std::vector<int> dual_parent_he;  // per face
  std::vector<int> generators;      // edges, sorted by loop length
  std::vector<int> gen_halfedge;    // per generator: halfedge a -> b (loop direction)
  std::vector<std::vector<int>> loops;
};

/// Dijkstra over the faces, crossing only edges with `crossable[e]`, each
/// step weighted by `step[e]`; returns distances (infinity: not reached) and
/// fills parent (the edge crossed last, -1 at the start and unreached).
std::vector<double> dual_dijkstra(const Connectivity& conn, const std::vector<char>& crossable,
                                  const std::vector<double>& step, int start, std::vector<int>& parent) {
  auto across_edges = [&](int f, auto&& visit) {
    for (int k = 0; k < 3; ++k) {
      const int e = conn.edge(3 * f + k);
      if (crossable[e]) visit(e, Connectivity::face(conn.twin(3 * f + k)), step[e]);
    }
  };
  detail::DijkstraResult r;
  detail::dijkstra(conn.num_faces(), across_edges, {start}, {}, r);
  parent = std::move(r.parent_arc);
  return std::move(r.distance);
}

/// The shallow cut tree (SystemOfLoopsOptions::edge_weights given): the dual
/// edges not crossing T, as a shortest-path tree from the centre face of that
/// dual graph (double sweep), steps weighted by the mean perimeter of the two
/// faces / 3. Marks in_dual; the rest of the non-tree edges are generators.
void shallow_cut_tree(const Connectivity& conn, const std::vector<double>& len, const std::vector<char>& in_tree,
                      std::vector<char>& in_dual) {
  const int nf = conn.num_faces(), ne = conn.num_edges();
  std::vector<char> crossable(ne, 0);
  std::vector<double> perimeter(nf, 0.0), step(ne, 0.0);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) perimeter[f] += len[conn.edge(3 * f + k)];
  for (int e = 0; e < ne; ++e) {
    crossable[e] = !in_tree[e];
    const int h = conn.edge_halfedge(e);
    step[e] = (perimeter[Connectivity::face(h)] + perimeter[Connectivity::face(conn.twin(h))]) / 6.0;
  }
  std::vector<int> parent;
  auto farthest = [](const std::vector<double>& d) {
    int best = 0;
    for (int f = 0; f < static_cast<int>(d.size()); ++f)
      if (std::isfinite(d[f]) && d[f] > d[best]) best = f;
    return best;
  };
  const int a = farthest(dual_dijkstra(conn, crossable, step, 0, parent));
  const std::vector<double> da = dual_dijkstra(conn, crossable, step, a, parent);
  const int b = farthest(da);
  // The face of the a-b path nearest its middle.
  int root = b;
  for (int f = b; f != a && parent[f] >= 0;) {
    if (std::abs(da[f] - 0.5 * da[b]) < std::abs(da[root] - 0.5 * da[b])) root = f;
    const int h = conn.edge_halfedge(parent[f]);
    f = Connectivity::face(h) == f ? Connectivity::face(conn.twin(h)) : Connectivity::face(h);
  }
  dual_dijkstra(conn, crossable, step, root, parent);
  in_dual.assign(ne, 0);
  for (int f = 0; f < nf; ++f)
    if (parent[f] >= 0) in_dual[parent[f]] = 1;
}

/// Sorts the generator candidates (loop length, edge) by decreasing length,
/// ties by increasing edge: the order of the comparator
/// `a.first > b.first || (a.first == b.first && a.second < b.second)`, by a
/// stable radix sort of the lengths' bit patterns (non-negative doubles
/// order as their bits; `order` comes in increasing edge order, which the
/// stable passes keep among equal lengths). Issue 19: a third of the cost of
/// std::sort here, the same order.
void sort_by_decreasing_length(std::vector<std::pair<double, int>>& order) {
  const size_t n = order.size();
  std::vector<std::pair<std::uint64_t, int>> a(n), b(n);
  for (size_t i = 0; i < n; ++i) {
    std::uint64_t bits;
    std::memcpy(&bits, &order[i].first, sizeof bits);
    a[i] = {~bits, static_cast<int>(i)};  // ascending ~bits = descending length
  }
  std::vector<size_t> count(1 << 16);
  for (int shift = 0; shift < 64; shift += 16) {
    std::fill(count.begin(), count.end(), 0);
    for (const auto& item : a) ++count[(item.first >> shift) & 0xffff];
    size_t sum = 0;
    for (size_t& c : count) {
      const size_t here = c;
      c = sum;
      sum += here;
    }
    for (const auto& item : a) b[count[(item.first >> shift) & 0xffff]++] = item;
    a.swap(b);
  }
  std::vector<std::pair<double, int>> sorted(n);
  for (size_t i = 0; i < n; ++i) sorted[i] = order[a[i].second];
  order.swap(sorted);
}

}  // namespace

GreedyGraph::GreedyGraph(const TriMesh& mesh, const Connectivity& conn) : GreedyGraph(conn, edge_lengths(mesh, conn)) {}

GreedyGraph::GreedyGraph(const Connectivity& conn, std::vector<double> lengths)
    : num_vertices(conn.num_vertices()), num_edges(conn.num_edges()), length(std::move(lengths)) {
  if (static_cast<int>(length.size()) != num_edges)
    throw InputError("greedy graph: " + std::to_string(length.size()) + " edge lengths for " +
                     std::to_string(num_edges) + " edges");
  first_out.resize(num_vertices + 1);
  out_head.reserve(2 * static_cast<size_t>(num_edges));
  out_halfedge.reserve(2 * static_cast<size_t>(num_edges));
  out_length.reserve(2 * static_cast<size_t>(num_edges));
  for (int v = 0; v < num_vertices; ++v) {
    first_out[v] = static_cast<int>(out_head.size());
    const int start = conn.vertex_halfedge(v);
    if (start < 0) continue;
    int h = start;
    do {
      out_head.push_back(conn.head(h));
      out_halfedge.push_back(h);
      out_length.push_back(length[conn.edge(h)]);
      h = conn.rotate_ccw(h);
    } while (h != start);
  }
  first_out[num_vertices] = static_cast<int>(out_head.size());
  edge_faces.resize(2 * static_cast<size_t>(num_edges));
  for (int e = 0; e < num_edges; ++e) {
    const int h = conn.edge_halfedge(e);
    edge_faces[2 * e] = Connectivity::face(h);
    edge_faces[2 * e + 1] = Connectivity::face(conn.twin(h));
  }
}

namespace {

/// `graph`: the mesh's neighbours and edge lengths (SystemOfLoopsOptions::
/// edge_weights, or 3D lengths); `shallow`: the dual shortest-path T*
/// (with edge weights).
Greedy greedy_basis(const Connectivity& conn, const GreedyGraph& graph, int x, int genus, bool shallow) {
  const int nv = conn.num_vertices(), nf = conn.num_faces(), ne = conn.num_edges();
  const std::vector<double>& len = graph.length;
  Greedy g;
  // Dijkstra shortest-path tree T from x (each vertex's neighbours in the
  // order of its rotation, as the graph lists them).
  auto out_arcs = [&](int v, auto&& visit) {
    for (int q = graph.first_out[v]; q < graph.first_out[v + 1]; ++q)
      visit(graph.out_halfedge[q], graph.out_head[q], graph.out_length[q]);
  };
  detail::DijkstraResult tree;
  detail::dijkstra(nv, out_arcs, {x}, {}, tree);
  const std::vector<double>& dist = tree.distance;
  g.parent_he = std::move(tree.parent_arc);
  g.in_tree.assign(ne, 0);
  for (int v = 0; v < nv; ++v)
    if (g.parent_he[v] >= 0) g.in_tree[conn.edge(g.parent_he[v])] = 1;
  for (int v = 0; v < nv; ++v)
    if (!std::isfinite(dist[v])) throw InputError("vertex " + std::to_string(v) + " is not connected to the base vertex");
  // Maximum spanning tree T* of the dual graph of the non-tree edges, each
  // weighted by the length of its loop sigma(e) (the greedy homotopy basis).
  std::vector<std::pair<double, int>> order;
  order.reserve(ne);
  for (int e = 0; e < ne; ++e)
    if (!g.in_tree[e])
      order.push_back({dist[conn.edge_vertex(e, 0)] + dist[conn.edge_vertex(e, 1)] + len[e], e});
  sort_by_decreasing_length(order);
  UnionFind uf(nf);
  std::vector<char> in_dual(ne, 0);
  std::vector<std::pair<double, int>> gens;
  if (shallow) {
    shallow_cut_tree(conn, len, g.in_tree, in_dual);
    for (const auto& [w, e] : order)
      if (!in_dual[e]) gens.push_back({w, e});
  } else {
    for (const auto& [w, e] : order) {
      if (uf.unite(graph.edge_faces[2 * e], graph.edge_faces[2 * e + 1]))
        in_dual[e] = 1;
      else
        gens.push_back({w, e});
    }
  }
  if (static_cast<int>(gens.size()) != 2 * genus)
    throw SolveError("system of loops: found " + std::to_string(gens.size()) +
                     " generator edges, expected 2g = " + std::to_string(2 * genus));
  std::sort(gens.begin(), gens.end());
  // Dual tree parents by BFS over T* from face 0.
  if (dual_bfs_tree(conn, [&](int e) { return in_dual[e] != 0; }, g.dual_parent_he) != nf)
    throw SolveError("system of loops: the cut tree does not span all faces");
  for (const auto& [w, e] : gens) {
    const int h = conn.edge_halfedge(e);
    g.generators.push_back(e);
    g.gen_halfedge.push_back(h);
    std::vector<int> up;  // a, parent(a), ..., x
    for (int v = conn.tail(h); v != x; v = conn.tail(g.parent_he[v])) up.push_back(v);
    up.push_back(x);
    std::vector<int> loop(up.rbegin(), up.rend());
    for (int v = conn.head(h); v != x; v = conn.tail(g.parent_he[v])) loop.push_back(v);
    loop.push_back(x);
    g.loops.push_back(std::move(loop));
  }
  return g;
}

// Reads the cyclic boundary word of the disk obtained by cutting along the
// edges with cut[e]: walking the boundary with the disk on the left
// (counter-clockwise), every halfedge with letter[h] != 0 contributes it.
std::vector<int> boundary_letters(const Connectivity& conn, const std::vector<char>& cut,
                                  const std::vector<int>& letter, int start_h) {
  std::vector<int> word;
  int num_cut = 0;
  for (char c : cut) num_cut += c ? 1 : 0;
  int h = start_h, steps = 0;
  do {
    if (letter[h]) word.push_back(letter[h]);
    int o = Connectivity::next(h);
    while (!cut[conn.edge(o)]) o = Connectivity::next(conn.twin(o));
    h = o;
    if (++steps > 2 * num_cut) break;
  } while (h != start_h);
  if (steps != 2 * num_cut)
    throw SolveError("system of loops: cutting along the loops does not give one disk (boundary walk of " +
                     std::to_string(steps) + " edges, expected " + std::to_string(2 * num_cut) + ")");
  return word;
}

void check_word(const std::vector<int>& word, int genus) {
  std::vector<int> count(4 * genus + 1, 0);
  bool ok = static_cast<int>(word.size()) == 4 * genus;
  for (int l : word) {
    if (l == 0 || std::abs(l) > 2 * genus) {
      ok = false;
      break;
    }
    ++count[l + 2 * genus];
  }
  for (int l = -2 * genus; ok && l <= 2 * genus; ++l)
    if (l != 0 && count[l + 2 * genus] != 1) ok = false;
  if (!ok) throw SolveError("system of loops: the boundary word is not a 4g-gon schema");
}

std::string word_to_text(const std::vector<int>& word) {
  std::string s;
  for (int l : word) {
    const int k = std::abs(l) - 1;
    if (!s.empty()) s += ' ';
    s += (k % 2 == 0 ? 'a' : 'b');
    s += std::to_string(k / 2 + 1);
    if (l < 0) s += "^-1";
  }
  return s;
}

// ---------------------------------------------------------------------------
// Refinement.

struct NewVertex {
  int face;            // input face containing it
  Eigen::Vector3d bc;  // barycentric coordinates there
  int edge = -1;       // input edge for edge points
  double t = 0;        // parameter from edge_vertex(edge, 0)
  // Bend points: the chord's side k of the face, midpoint and span along it.
  int bend_side = -1;
  double bend_mid = 0, bend_span = 0;
};

// Barycentric coordinates of a bend point: the apex of a symmetric tent over
// its chord, of height eta = slope * span / 2 (in units of the face's
// barycentric coordinate of the opposite corner). Tents on one side of a face
// whose slopes grow with their spans are nested without touching, also when
// they share an endpoint (the arcs leaving x); eta <= span keeps the apex
// inside the face.
Eigen::Vector3d bend_bc(int k, double mid, double span, double slope) {
  const double eta = std::min(slope, 1.2) * 0.5 * span;
  Eigen::Vector3d c;
  c[k] = 1 - mid - 0.5 * eta;
  c[(k + 1) % 3] = mid - 0.5 * eta;
  c[(k + 2) % 3] = eta;
  return c;
}

struct Refiner {
  const TriMesh& mesh;
  const Connectivity& conn;
  int n_in;
  std::vector<NewVertex> nv;  // vertices n_in, n_in+1, ...
  std::vector<std::vector<std::pair<double, int>>> edge_points;  // per input edge
  std::vector<std::vector<std::vector<int>>> face_chords;       // per input face
  std::vector<std::vector<int>> face_interior;                  // per input face

  Refiner(const TriMesh& m, const Connectivity& c)
      : mesh(m),
        conn(c),
        n_in(m.num_vertices()),
        edge_points(c.num_edges()),
        face_chords(c.num_faces()),
        face_interior(c.num_faces()) {}

  int add_edge_point(int e, double t) {
    const int h = conn.edge_halfedge(e);  // runs from edge_vertex(e,0) to (e,1)
    NewVertex p;
    p.face = Connectivity::face(h);
    p.bc.setZero();
    p.bc[h % 3] = 1 - t;
    p.bc[(h + 1) % 3] = t;
    p.edge = e;
    p.t = t;
    nv.push_back(p);
    const int id = n_in + static_cast<int>(nv.size()) - 1;
    edge_points[e].push_back({t, id});
    return id;
  }

  int add_interior(int f, const Eigen::Vector3d& bc) {
    NewVertex p;
    p.face = f;
    p.bc = bc;
    nv.push_back(p);
    const int id = n_in + static_cast<int>(nv.size()) - 1;
    face_interior[f].push_back(id);
    return id;
  }

  // Barycentric coordinates of vertex `id` in face f (which must contain it).
  Eigen::Vector3d local_bc(int f, int id) const {
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    if (id < n_in) {
      bool found = false;
      for (int k = 0; k < 3; ++k)
        if (conn.faces()(f, k) == id) b[k] = 1, found = true;
      if (!found) throw SolveError("system of loops: internal error, vertex " + std::to_string(id) + " not on face " + std::to_string(f));
      return b;
    }
    const NewVertex& p = nv[id - n_in];
    if (p.edge < 0) {
      if (p.face != f) throw SolveError("system of loops: internal error, interior point not in face " + std::to_string(f));
      return p.bc;
    }
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (conn.edge(h) != p.edge) continue;
      const double s = conn.tail(h) == conn.edge_vertex(p.edge, 0) ? p.t : 1 - p.t;
      b[k] = 1 - s;
      b[(k + 1) % 3] = s;
      return b;
    }
    throw SolveError("system of loops: internal error, split point not on face " + std::to_string(f));
  }

  // Adds the chord P -> Q inside face f and returns the vertices appended to
  // the arc (the bend point if any, then Q).
  std::vector<int> add_chord(int f, int P, int Q) {
    const Eigen::Vector3d bp = local_bc(f, P), bq = local_bc(f, Q);
    std::vector<int> chord{P};
    for (int k = 0; k < 3; ++k) {
      const int o = (k + 2) % 3;
      if (bp[o] != 0 || bq[o] != 0) continue;
      // Both on edge k (corner k -> corner k+1): a straight chord would lie
      // on the edge, so it bends at a point inside the face (first guess: a
      // tent; triangulate_face flattens the tents if they fold a triangle).
      const double sp = bp[(k + 1) % 3], sq = bq[(k + 1) % 3];
      const double span = std::abs(sq - sp), mid = 0.5 * (sp + sq);
      const Eigen::Vector3d c = bend_bc(k, mid, span, 1.0);
      const int id = add_interior(f, c);
      nv.back().bend_side = k;
      nv.back().bend_mid = mid;
      nv.back().bend_span = span;
      chord.push_back(id);
      break;
    }
    chord.push_back(Q);
    face_chords[f].push_back(chord);
    return std::vector<int>(chord.begin() + 1, chord.end());
  }

  Eigen::Vector3d position(int id) const {
    if (id < n_in) return mesh.V.row(id).transpose();
    const NewVertex& p = nv[id - n_in];
    Eigen::Vector3d r = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) r += p.bc[k] * mesh.V.row(mesh.F(p.face, k)).transpose();
    return r;
  }
};

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// Boundary cycle of input face f: its corners with the split points of its
// sides in between, counter-clockwise like the face.
std::vector<int> face_boundary_cycle(const Refiner& R, int f) {
  const Connectivity& conn = R.conn;
  std::vector<int> boundary;
  for (int k = 0; k < 3; ++k) {
    const int h = 3 * f + k;
    boundary.push_back(conn.tail(h));
    const int e = conn.edge(h);
    std::vector<std::pair<double, int>> pts = R.edge_points[e];
    const bool forward = conn.tail(h) == conn.edge_vertex(e, 0);
    std::sort(pts.begin(), pts.end());
    if (!forward) std::reverse(pts.begin(), pts.end());
    for (const auto& pt : pts) boundary.push_back(pt.second);
  }
  return boundary;
}

// Isometric 2D copy of input face f (corner 0 at the origin, corner 1 on
// the x axis); a (nearly) degenerate face (accepted by intake through
// mollification, docs/robustness.md) is laid out from its side lengths
// mollified the same way, or its pieces have no room. pos() places a point
// of the face by its barycentric coordinates, sides() says on which sides
// it lies.
struct FaceChart {
  Refiner& R;
  int f;
  Eigen::Vector2d C[3];
  double eps;  // area tolerance of a folded triangle

  FaceChart(Refiner& refiner, int face) : R(refiner), f(face) {
    Eigen::Vector3d P[3];
    for (int k = 0; k < 3; ++k) P[k] = R.mesh.V.row(R.mesh.F(f, k)).transpose();
    double l01 = (P[1] - P[0]).norm();
    Eigen::Vector2d c2;
    {
      double a = l01, b = (P[2] - P[1]).norm(), c = (P[0] - P[2]).norm();
      const double rel = 1e-4, margin = std::min({a + b - c, b + c - a, c + a - b});
      if (margin < rel * (a + b + c) / 3) {
        const double eps = a + b + c > 0 ? (rel * (a + b + c) / 3 - margin) / (1 - rel) * (1 + 1e-9) : 1.0;
        a += eps, b += eps, c += eps;
        const double x = (a * a + c * c - b * b) / (2 * a);
        l01 = a;
        c2 = Eigen::Vector2d(x, std::sqrt(std::max(c * c - x * x, 0.0)));
      } else {
        const Eigen::Vector3d u = (P[1] - P[0]) / l01;
        c2 = Eigen::Vector2d((P[2] - P[0]).dot(u), ((P[2] - P[0]) - (P[2] - P[0]).dot(u) * u).norm());
      }
    }
    C[0] = Eigen::Vector2d(0, 0);
    C[1] = Eigen::Vector2d(l01, 0);
    C[2] = c2;
    eps = 1e-13 * std::max({l01 * l01, c2.squaredNorm(), (C[1] - c2).squaredNorm()});
  }
  Eigen::Vector2d pos(int id) const {
    const Eigen::Vector3d b = R.local_bc(f, id);
    return Eigen::Vector2d(b[0] * C[0] + b[1] * C[1] + b[2] * C[2]);
  }
  int sides(int id) const {  // bit k: on side k (corner k -> corner k+1)
    const Eigen::Vector3d b = R.local_bc(f, id);
    int m = 0;
    for (int k = 0; k < 3; ++k)
      if (b[(k + 2) % 3] == 0) m |= 1 << k;
    return m;
  }
  // True when a triangle of out[first_tri..] is folded (or flat).
  bool folded(const std::vector<std::array<int, 3>>& out, size_t first_tri) const {
    for (size_t t = first_tri; t < out.size(); ++t)
      if (cross2(pos(out[t][0]), pos(out[t][1]), pos(out[t][2])) <= eps) return true;
    return false;
  }
};

using EdgeSet = std::set<std::pair<int, int>>;
std::pair<int, int> edge_key(int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); }

// Splits the boundary cycle of face f into the pieces its chords cut out
// (each piece a cycle of point ids).
std::vector<std::vector<int>> split_along_chords(const std::vector<int>& boundary,
                                                 const std::vector<std::vector<int>>& chords, int f) {
  std::vector<std::vector<int>> regions{boundary};
  for (const auto& ch : chords) {
    const int A = ch.front(), B = ch.back();
    bool split = false;
    for (size_t r = 0; r < regions.size() && !split; ++r) {
      auto& poly = regions[r];
      const auto ia = std::find(poly.begin(), poly.end(), A), ib = std::find(poly.begin(), poly.end(), B);
      if (ia == poly.end() || ib == poly.end()) continue;
      const size_t i = ia - poly.begin(), j = ib - poly.begin(), n = poly.size();
      std::vector<int> p1, p2;  // p1: A .. B along the polygon, then the chord back
      for (size_t q = i; q != j; q = (q + 1) % n) p1.push_back(poly[q]);
      p1.push_back(B);
      for (size_t q = ch.size() - 2; q >= 1; --q) p1.push_back(ch[q]);
      for (size_t q = j; q != i; q = (q + 1) % n) p2.push_back(poly[q]);
      p2.push_back(A);
      for (size_t q = 1; q + 1 < ch.size(); ++q) p2.push_back(ch[q]);
      poly = std::move(p1);
      regions.push_back(std::move(p2));
      split = true;
    }
    if (!split)
      throw SolveError("system of loops: refinement chord " + std::to_string(A) + " -> " + std::to_string(B) +
                       " crosses another one in face " + std::to_string(f));
  }
  return regions;
}

// Tent slopes of face f's bend points by rank of span on their side (even
// angles between the nested tents), halved on every retry.
void place_tents(Refiner& R, int f, int attempt) {
  for (int side = 0; side < 3; ++side) {
    std::vector<std::pair<double, int>> tents;
    for (int id : R.face_interior[f])
      if (R.nv[id - R.n_in].bend_side == side) tents.push_back({R.nv[id - R.n_in].bend_span, id});
    std::sort(tents.begin(), tents.end());
    for (size_t r = 0; r < tents.size(); ++r) {
      NewVertex& p = R.nv[tents[r].second - R.n_in];
      const double slope = 1.2 * (r + 1.0) / tents.size() * std::pow(0.5, attempt);
      p.bc = bend_bc(side, p.bend_mid, p.bend_span, slope);
    }
  }
}

// Ear clipping of one piece: ears that are geometrically good under the
// current guess first, any combinatorially valid ear next (never three
// points of one side, never a dividing diagonal, never a doubled edge), a
// centre point as the last resort. Appends the triangles to `out`.
void triangulate_piece(const FaceChart& chart, std::vector<int> poly, EdgeSet& edges,
                       std::vector<std::array<int, 3>>& out) {
  Refiner& R = chart.R;
  const double eps = chart.eps;
  while (poly.size() > 3) {
    const size_t n = poly.size();
    double best_q = -std::numeric_limits<double>::infinity();
    size_t best = n;
    for (size_t i = 0; i < n; ++i) {
      const int a = poly[(i + n - 1) % n], b = poly[i], c = poly[(i + 1) % n];
      if (chart.sides(a) & chart.sides(b) & chart.sides(c)) continue;  // three points of one side
      if (chart.sides(a) & chart.sides(c)) continue;                   // dividing diagonal
      if (edges.count(edge_key(a, c))) continue;                       // would double an edge
      const Eigen::Vector2d pa = chart.pos(a), pb = chart.pos(b), pc = chart.pos(c);
      const double area2 = cross2(pa, pb, pc);
      double q = -1;
      if (area2 > eps) {
        bool empty = true;
        for (size_t j = 0; j < n && empty; ++j) {
          if (j == i || j == (i + 1) % n || j == (i + n - 1) % n) continue;
          const Eigen::Vector2d p = chart.pos(poly[j]);
          if (cross2(pa, pb, p) >= -eps && cross2(pb, pc, p) >= -eps && cross2(pc, pa, p) >= -eps) empty = false;
        }
        if (empty) q = area2 / ((pa - pb).squaredNorm() + (pb - pc).squaredNorm() + (pc - pa).squaredNorm());
      }
      if (q > best_q) {
        best_q = q;
        best = i;
      }
    }
    if (best == n) {
      Eigen::Vector3d bc = Eigen::Vector3d::Zero();
      for (int id : poly) bc += R.local_bc(chart.f, id);
      const int c = R.add_interior(chart.f, bc / static_cast<double>(poly.size()));
      for (size_t i = 0; i < n; ++i) out.push_back({poly[i], poly[(i + 1) % n], c});
      poly.clear();
      break;
    }
    const int a = poly[(best + n - 1) % n], c = poly[(best + 1) % n];
    out.push_back({a, poly[best], c});
    edges.insert(edge_key(a, c));
    poly.erase(poly.begin() + best);
  }
  if (poly.size() == 3) out.push_back({poly[0], poly[1], poly[2]});
}

// Places face f's interior (bend and centre) points by a Tutte embedding
// (uniform weights) of the triangles out[first_tri..], the face boundary
// fixed.
void tutte_embed_interior(const FaceChart& chart, const std::vector<std::array<int, 3>>& out, size_t first_tri) {
  Refiner& R = chart.R;
  const auto& inner = R.face_interior[chart.f];
  const int m = static_cast<int>(inner.size());
  std::vector<std::pair<int, int>> local;
  for (int i = 0; i < m; ++i) local.push_back({inner[i], i});
  std::sort(local.begin(), local.end());
  auto index_of = [&](int id) {
    auto it = std::lower_bound(local.begin(), local.end(), std::make_pair(id, -1));
    return (it != local.end() && it->first == id) ? it->second : -1;
  };
  EdgeSet tri_edges;
  for (size_t t = first_tri; t < out.size(); ++t)
    for (int k = 0; k < 3; ++k) tri_edges.insert(edge_key(out[t][k], out[t][(k + 1) % 3]));
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(m, 2);
  for (const auto& [a, b] : tri_edges) {
    const int ia = index_of(a), ib = index_of(b);
    for (int s = 0; s < 2; ++s) {
      const int i = s ? ib : ia, j = s ? ia : ib, other = s ? a : b;
      if (i < 0) continue;
      A(i, i) += 1;
      if (j >= 0)
        A(i, j) -= 1;
      else
        rhs.row(i) += chart.pos(other).transpose();
    }
  }
  const Eigen::MatrixXd X = A.partialPivLu().solve(rhs);
  const Eigen::Vector2d* C = chart.C;
  Eigen::Matrix2d T;
  T.col(0) = C[1] - C[0];
  T.col(1) = C[2] - C[0];
  for (int i = 0; i < m; ++i) {
    const Eigen::Vector2d l = T.inverse() * (X.row(i).transpose() - C[0]);
    R.nv[inner[i] - R.n_in].bc = Eigen::Vector3d(1 - l[0] - l[1], l[0], l[1]);
  }
}

// Triangulates input face f with its split points and chords; appends
// triangles (counter-clockwise, like the face) to `out`. The pieces are
// found combinatorially (chords split the boundary cycle), triangulated
// without ever joining two points of one side of the face, and the interior
// (bend and centre) points are placed by a Tutte embedding if the first
// guess folds a triangle: with the face boundary convex and no such
// "dividing" edge, Tutte/Floater guarantees an embedding.
void triangulate_face(Refiner& R, int f, std::vector<std::array<int, 3>>& out) {
  const std::vector<int> boundary = face_boundary_cycle(R, f);
  const auto& chords = R.face_chords[f];
  if (boundary.size() == 3 && chords.empty()) {
    out.push_back({boundary[0], boundary[1], boundary[2]});
    return;
  }
  const FaceChart chart(R, f);
  EdgeSet edges;
  for (size_t i = 0; i < boundary.size(); ++i) edges.insert(edge_key(boundary[i], boundary[(i + 1) % boundary.size()]));
  for (const auto& ch : chords)
    for (size_t i = 0; i + 1 < ch.size(); ++i) edges.insert(edge_key(ch[i], ch[i + 1]));
  const std::vector<std::vector<int>> regions = split_along_chords(boundary, chords, f);
  // Triangulate every piece; if a triangle folds, flatten the tents and retry.
  const size_t first_tri = out.size(), nv0 = R.nv.size(), ni0 = R.face_interior[f].size();
  const EdgeSet edges0 = edges;
  for (int attempt = 0; attempt < 30; ++attempt) {
    edges = edges0;
    out.resize(first_tri);
    R.nv.resize(nv0);
    R.face_interior[f].resize(ni0);
    place_tents(R, f, attempt);
    for (const auto& poly : regions) triangulate_piece(chart, poly, edges, out);
    if (!chart.folded(out, first_tri)) return;
  }
  tutte_embed_interior(chart, out, first_tri);
  if (chart.folded(out, first_tri))
    throw SolveError("system of loops: could not embed the refined pieces of face " + std::to_string(f));
}

struct Refined {
  TriMesh mesh;
  std::vector<int> origin_face;
  RowMatrixX3d origin_bc;
  std::vector<int> face_origin;  // per refined face, the input face holding it
  std::vector<std::vector<int>> loops;
};

// One step of the Euler tour around T' (refine): a slot (a non-T'
// halfedge leaving a T' vertex; lo = hi = the exits so far) or a T'
// traversal down into a branch (lo..hi: the exits inside it) or back up.
enum TourEventType { SLOT, DOWN, UP };
struct TourEvent {
  int type, h, lo = 0, hi = -1;
};

// The Euler tour around T' (tp: its edges) from the corner after h_last
// until all n_arcs arcs have left through generator edges (gen_of_edge >= 0).
std::vector<TourEvent> euler_tour(const Connectivity& conn, const Greedy& g, const std::vector<char>& tp,
                                  const std::vector<int>& gen_of_edge, int h_last, int n_arcs) {
  std::vector<TourEvent> events;
  int exits = 0, guard = 0;
  int o = Connectivity::next(h_last);
  std::vector<size_t> open;
  while (exits < n_arcs) {
    if (++guard > 4 * conn.num_halfedges()) throw SolveError("system of loops: Euler tour did not close");
    if (tp[conn.edge(o)]) {
      const bool down = g.parent_he[conn.head(o)] == o;
      events.push_back({down ? DOWN : UP, o, exits, -1});
      if (down) {
        open.push_back(events.size() - 1);
      } else {
        if (open.empty()) throw SolveError("system of loops: internal error in the Euler tour");
        events[open.back()].hi = exits - 1;  // exits inside that branch
        open.pop_back();
      }
      o = Connectivity::next(o);
      continue;
    }
    events.push_back({SLOT, o, exits, exits});
    if (gen_of_edge[conn.edge(o)] >= 0) ++exits;
    o = Connectivity::next(conn.twin(o));
  }
  for (size_t i : open) events[i].hi = n_arcs - 1;
  return events;
}

// The refined mesh (every input face triangulated with its split points and
// chords), each vertex's origin on the input mesh, and the loops: generator
// k's two arcs (exit_arc[k]) joined.
Refined assemble_refined(Refiner& R, const TriMesh& mesh, const Connectivity& conn,
                         const std::vector<std::vector<int>>& arc, const std::vector<std::array<int, 2>>& exit_arc) {
  const int ng = static_cast<int>(exit_arc.size());
  // Refined faces.
  std::vector<std::array<int, 3>> tris;
  tris.reserve(conn.num_faces() + 4 * R.nv.size());
  Refined out;
  out.face_origin.reserve(conn.num_faces() + 4 * R.nv.size());
  for (int f = 0; f < conn.num_faces(); ++f) {
    triangulate_face(R, f, tris);
    out.face_origin.resize(tris.size(), f);
  }
  const int n_total = R.n_in + static_cast<int>(R.nv.size());
  out.mesh.V.resize(n_total, 3);
  out.mesh.V.topRows(R.n_in) = mesh.V;
  out.origin_face.resize(n_total);
  out.origin_bc.setZero(n_total, 3);
  for (int f = 0; f < conn.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.F(f, k);
      out.origin_face[v] = f;
      out.origin_bc.row(v).setZero();
      out.origin_bc(v, k) = 1;
    }
  for (int i = 0; i < static_cast<int>(R.nv.size()); ++i) {
    const int id = R.n_in + i;
    out.mesh.V.row(id) = R.position(id).transpose();
    out.origin_face[id] = R.nv[i].face;
    out.origin_bc.row(id) = R.nv[i].bc.transpose();
  }
  out.mesh.F.resize(static_cast<int>(tris.size()), 3);
  for (int i = 0; i < static_cast<int>(tris.size()); ++i)
    for (int k = 0; k < 3; ++k) out.mesh.F(i, k) = tris[i][k];
  for (int k = 0; k < ng; ++k) {
    const auto& a = arc[exit_arc[k][0]];
    const auto& b = arc[exit_arc[k][1]];
    std::vector<int> loop(a.begin(), a.end());
    loop.insert(loop.end(), b.rbegin(), b.rend());
    out.loops.push_back(std::move(loop));
  }
  return out;
}

// shortcut=true: arcs that pass a whole branch of T' cross its root edge
// instead of travelling around it (short loops, few split points);
// shortcut=false: every arc follows the Euler tour (kept as a fallback).
Refined refine(const TriMesh& mesh, const Connectivity& conn, const Greedy& g, int x, bool shortcut) {
  const int ne = conn.num_edges();
  const int ng = static_cast<int>(g.generators.size());
  // T': tree edges on the paths from x to the generator endpoints.
  std::vector<char> tp(ne, 0);
  std::vector<int> gen_of_edge(ne, -1);
  for (int k = 0; k < ng; ++k) {
    gen_of_edge[g.generators[k]] = k;
    const int h = g.gen_halfedge[k];
    for (int v : {conn.tail(h), conn.head(h)})
      for (; v != x && !tp[conn.edge(g.parent_he[v])]; v = conn.tail(g.parent_he[v]))
        tp[conn.edge(g.parent_he[v])] = 1;
  }
  // Start corner: the corner of x (after arriving along a T' edge) with the
  // most edges in it, so the arcs fan out where x has room.
  int h_last = -1, best_spokes = -1;
  for (int t : conn.outgoing(x)) {
    if (!tp[conn.edge(t)]) continue;
    const int h_in = conn.twin(t);
    int spokes = 0;
    for (int o = Connectivity::next(h_in); !tp[conn.edge(o)]; o = Connectivity::next(conn.twin(o))) ++spokes;
    if (spokes > best_spokes) {
      best_spokes = spokes;
      h_last = h_in;
    }
  }
  if (h_last < 0) throw SolveError("system of loops: the base vertex has no tree edge to the generators");
  const int n_arcs = 2 * ng;
  const std::vector<TourEvent> events = euler_tour(conn, g, tp, gen_of_edge, h_last, n_arcs);
  Refiner R(mesh, conn);
  std::vector<std::vector<int>> arc(n_arcs, std::vector<int>{x});
  std::vector<int> cur(n_arcs, x);  // current end point of every arc
  // exit_arc[k][0]: arc ending near the tail of gen_halfedge[k]; [1]: near its head.
  std::vector<std::array<int, 2>> exit_arc(ng, {-1, -1});
  const double Lambda = 0.4;
  int lo = 0, hi = n_arcs - 1;  // arcs present: lo..hi (hi runs innermost)
  struct Parked {
    int lo, hi;
  };
  std::vector<Parked> parked;
  // Points for arcs lo..hi on edge e near vertex v, hi closest to v; chords
  // from the arcs' current ends inside face f.
  auto advance = [&](int e, int v, int f, int a, int b) {
    const int n = b - a + 1;
    for (int k = a; k <= b; ++k) {
      const double lambda = Lambda * (b - k + 1) / n;
      const int p = R.add_edge_point(e, v == conn.edge_vertex(e, 0) ? lambda : 1 - lambda);
      const std::vector<int> app = R.add_chord(f, cur[k], p);
      arc[k].insert(arc[k].end(), app.begin(), app.end());
      cur[k] = p;
    }
  };
  // The arcs leave x one group per face of the start corner (outermost
  // first) instead of all through its first face, so no single face of x
  // has to hold all 4g bends.
  int leading = 0;
  while (leading < static_cast<int>(events.size()) && events[leading].type == SLOT) ++leading;
  int departed = 0;  // arcs < departed have left x
  for (size_t i = 0; i < events.size(); ++i) {
    const TourEvent& ev = events[i];
    const int o = ev.h, v = conn.tail(o), e = conn.edge(o), f = Connectivity::face(o);
    if (ev.type == SLOT) {
      if (lo > hi) continue;
      if (static_cast<int>(i) < leading) {
        const int share = (n_arcs * (static_cast<int>(i) + 1) + leading - 1) / leading;
        departed = std::min(hi + 1, std::max({departed, share, lo + 1}));
      } else {
        departed = hi + 1;
      }
      advance(e, v, f, lo, std::min(hi, departed - 1));
      const int k = gen_of_edge[e];
      if (k >= 0) {
        if (ev.lo != lo) throw SolveError("system of loops: internal error, arcs leave out of order");
        exit_arc[k][conn.tail(g.gen_halfedge[k]) == v ? 0 : 1] = lo;
        ++lo;  // the outermost arc leaves here
      }
    } else if (shortcut && ev.type == DOWN) {
      if (ev.lo != lo || ev.hi < lo || ev.hi > hi)
        throw SolveError("system of loops: internal error, branch arcs out of order");
      // Arcs that pass this whole branch cross its root edge near v.
      if (ev.hi < hi) advance(e, v, f, ev.hi + 1, hi);
      parked.push_back({ev.hi + 1, hi});
      hi = ev.hi;
    } else if (shortcut && ev.type == UP) {
      if (lo <= hi || parked.empty()) throw SolveError("system of loops: internal error, arcs left in a branch");
      lo = parked.back().lo;
      hi = parked.back().hi;
      parked.pop_back();
    }
  }
  for (int k = 0; k < ng; ++k)
    if (exit_arc[k][0] < 0 || exit_arc[k][1] < 0)
      throw SolveError("system of loops: internal error, generator " + std::to_string(k) + " not reached");
  return assemble_refined(R, mesh, conn, arc, exit_arc);
}

// Tree, cut tree, generators and word of a system of simple loops meeting
// only at x, recomputed on the mesh that carries them.
void finish_from_simple_loops(SystemOfLoops& s) {
  const Connectivity conn(s.mesh.F, s.mesh.num_vertices());
  const int nv = conn.num_vertices(), nf = conn.num_faces(), ne = conn.num_edges();
  const int x = s.base_vertex, ng = static_cast<int>(s.loops.size());
  std::vector<char> on_loop(ne, 0);
  std::vector<int> vertex_loop(nv, -1);
  std::vector<int> letter(conn.num_halfedges(), 0);
  s.generator_edges.assign(ng, -1);
  for (int k = 0; k < ng; ++k) {
    const auto& L = s.loops[k];
    if (L.size() < 3 || L.front() != x || L.back() != x)
      throw SolveError("system of loops: loop " + std::to_string(k) + " does not start and end at x");
    for (size_t i = 0; i + 1 < L.size(); ++i) {
      const int h = conn.find_halfedge(L[i], L[i + 1]);
      if (h < 0) throw SolveError("system of loops: loop " + std::to_string(k) + " leaves the mesh edges");
      if (on_loop[conn.edge(h)]) throw SolveError("system of loops: loops share an edge");
      on_loop[conn.edge(h)] = 1;
      if (i > 0) {
        if (vertex_loop[L[i]] != -1 || L[i] == x)
          throw SolveError("system of loops: loop " + std::to_string(k) + " is not simple or meets another loop at vertex " +
                           std::to_string(L[i]));
        vertex_loop[L[i]] = k;
      }
      if (i == 0) letter[h] = k + 1;
      if (i + 2 == L.size()) letter[conn.twin(h)] = -(k + 1);
    }
    // Generator: the middle edge of the loop, so both tree halves are short.
    const size_t mid = (L.size() - 1) / 2;
    s.generator_edges[k] = conn.edge(conn.find_halfedge(L[mid], L[mid + 1]));
  }
  // Word: walk the boundary of the disk; every side starts at a copy of x.
  int start = -1;
  for (int h = 0; h < conn.num_halfedges() && start < 0; ++h)
    if (letter[h]) start = h;
  s.word = boundary_letters(conn, on_loop, letter, start);
  check_word(s.word, s.genus);
  s.word_text = word_to_text(s.word);
  // Cut tree T*: spanning tree of the faces, never crossing a loop edge.
  if (dual_bfs_tree(conn, [&](int e) { return !on_loop[e]; }, s.dual_tree_parent_halfedge) != nf)
    throw SolveError("system of loops: the loops cut the surface into more than one piece");
  std::vector<char> in_dual(ne, 0);
  for (int f = 0; f < nf; ++f)
    if (s.dual_tree_parent_halfedge[f] >= 0) in_dual[conn.edge(s.dual_tree_parent_halfedge[f])] = 1;
  // Tree T: the edges T* does not cross, minus the generators; it contains
  // both halves of every loop, so loop k = path(x,a) + generator + path(b,x).
  std::vector<char> gen(ne, 0);
  for (int e : s.generator_edges) gen[e] = 1;
  s.tree_parent_halfedge.assign(nv, -1);
  std::vector<char> vseen(nv, 0);
  std::vector<int> vq{x};
  vseen[x] = 1;
  int tree_edges = 0;
  for (size_t i = 0; i < vq.size(); ++i) {
    const int v = vq[i];
    const int h0 = conn.vertex_halfedge(v);
    int h = h0;
    do {
      const int e = conn.edge(h);
      if (!in_dual[e] && !gen[e]) {
        const int w = conn.head(h);
        if (!vseen[w]) {
          vseen[w] = 1;
          s.tree_parent_halfedge[w] = h;
          vq.push_back(w);
          ++tree_edges;
        }
      }
      h = conn.rotate_ccw(h);
    } while (h != h0);
  }
  int non_dual = 0;
  for (int e = 0; e < ne; ++e) non_dual += (!in_dual[e] && !gen[e]) ? 1 : 0;
  if (static_cast<int>(vq.size()) != nv || tree_edges != non_dual)
    throw SolveError("system of loops: the edges outside the cut tree and the generators are not a spanning tree");
}

}  // namespace

void rebuild_system_of_loops(SystemOfLoops& s) { finish_from_simple_loops(s); }

int metric_centre_vertex(const Connectivity& conn, const std::vector<double>& edge_weights, int samples) {
  const int nv = conn.num_vertices();
  if (static_cast<int>(edge_weights.size()) != conn.num_edges())
    throw InputError("metric_centre_vertex: " + std::to_string(edge_weights.size()) + " edge weights for " +
                     std::to_string(conn.num_edges()) + " edges");
  for (int e = 0; e < conn.num_edges(); ++e)
    if (!(edge_weights[e] > 0) || !std::isfinite(edge_weights[e]))
      throw InputError("metric_centre_vertex: edge " + std::to_string(e) + " has weight " +
                       std::to_string(edge_weights[e]));
  // Farthest-point sampling: lower[v] = max over the sampled points p of
  // d(p, v) <= eccentricity(v); the next sample is the farthest vertex from
  // the current best centre, which raises the bound where it was too low.
  std::vector<double> lower(nv, 0.0);
  auto farthest = [&](const std::vector<double>& d) {
    return static_cast<int>(std::max_element(d.begin(), d.end()) - d.begin());
  };
  int p = farthest(dijkstra_distances(conn, edge_weights, 0));
  for (int s = 0; s < std::max(2, samples); ++s) {
    const std::vector<double> d = dijkstra_distances(conn, edge_weights, p);
    for (int v = 0; v < nv; ++v) {
      if (!std::isfinite(d[v])) throw InputError("metric_centre_vertex: vertex " + std::to_string(v) + " is unreachable");
      lower[v] = std::max(lower[v], d[v]);
    }
    const int centre = static_cast<int>(std::min_element(lower.begin(), lower.end()) - lower.begin());
    p = farthest(dijkstra_distances(conn, edge_weights, centre));
  }
  std::vector<std::pair<double, int>> order(nv);
  for (int v = 0; v < nv; ++v) order[v] = {lower[v], v};
  const int k = std::min(nv, 64);
  std::partial_sort(order.begin(), order.begin() + k, order.end());
  int best = order[0].second, best_val = -1;
  for (int i = 0; i < k; ++i)
    if (conn.valence(order[i].second) > best_val) {
      best_val = conn.valence(order[i].second);
      best = order[i].second;
    }
  return best;
}

SystemOfLoops system_of_loops(const TriMesh& mesh, const SystemOfLoopsOptions& options) {
  return system_of_loops(mesh, Connectivity(mesh.F, mesh.num_vertices()), options);
}

namespace {

/// system_of_loops after the greedy basis g at base vertex x: the loops as
/// they are (options.refine false) or refined into simple ones.
SystemOfLoops from_greedy(const TriMesh& mesh, const Connectivity& conn, const Greedy& g, int x, int genus,
                          const SystemOfLoopsOptions& options) {
  SystemOfLoops s;
  s.genus = genus;
  s.base_vertex = x;
  if (!options.refine) {
    s.mesh = mesh;
    const int nv = mesh.num_vertices();
    s.origin_face.assign(nv, -1);
    s.origin_barycentric.setZero(nv, 3);
    s.face_origin.resize(mesh.num_faces());
    for (int f = 0; f < mesh.num_faces(); ++f) s.face_origin[f] = f;
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        s.origin_face[mesh.F(f, k)] = f;
        s.origin_barycentric.row(mesh.F(f, k)).setZero();
        s.origin_barycentric(mesh.F(f, k), k) = 1;
      }
    s.tree_parent_halfedge = g.parent_he;
    s.dual_tree_parent_halfedge = g.dual_parent_he;
    s.generator_edges = g.generators;
    s.loops = g.loops;
    // Word of the cut graph T + generators: tree edges read as identity.
    std::vector<char> cut(conn.num_edges(), 0);
    for (int e = 0; e < conn.num_edges(); ++e) cut[e] = g.in_tree[e];
    std::vector<int> letter(conn.num_halfedges(), 0);
    for (int k = 0; k < static_cast<int>(g.generators.size()); ++k) {
      cut[g.generators[k]] = 1;
      letter[g.gen_halfedge[k]] = k + 1;
      letter[conn.twin(g.gen_halfedge[k])] = -(k + 1);
    }
    s.word = boundary_letters(conn, cut, letter, g.gen_halfedge[0]);
    check_word(s.word, genus);
    s.word_text = word_to_text(s.word);
    return s;
  }
  // The short construction first; the full Euler-tour construction (longer
  // loops, more split points, but the simplest geometry) if it fails.
  std::string first_error;
  for (const bool shortcut : {options.shortcut_branches, false}) {
    try {
      Refined r = refine(mesh, conn, g, x, shortcut);
      SystemOfLoops t = s;
      t.mesh = std::move(r.mesh);
      t.origin_face = std::move(r.origin_face);
      t.origin_barycentric = std::move(r.origin_bc);
      t.face_origin = std::move(r.face_origin);
      t.loops = std::move(r.loops);
      finish_from_simple_loops(t);
      t.shortcut_used = shortcut;
      return t;
    } catch (const Error& e) {
      if (!shortcut) {
        throw SolveError(std::string("system of loops: refinement failed: ") + e.what() +
                         (first_error.empty() ? "" : " (shortcut construction: " + first_error + ")"));
      }
      first_error = e.what();
    }
  }
  return s;
}

}  // namespace

SystemOfLoops system_of_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoopsOptions& options,
                             const GreedyGraph* graph) {
  const int genus = conn.genus();
  if (conn.euler_characteristic() > 0 || genus < 1)
    throw InputError("system of loops: the surface has genus 0 (Euler characteristic " +
                     std::to_string(conn.euler_characteristic()) + "); there are no loops to cut");
  const std::vector<double>& weights = options.edge_weights;
  if (!weights.empty()) {
    if (static_cast<int>(weights.size()) != conn.num_edges())
      throw InputError("system of loops: " + std::to_string(weights.size()) + " edge weights for " +
                       std::to_string(conn.num_edges()) + " edges");
    for (int e = 0; e < conn.num_edges(); ++e)
      if (!(weights[e] > 0) || !std::isfinite(weights[e]))
        throw InputError("system of loops: edge " + std::to_string(e) + " has weight " + std::to_string(weights[e]));
  }
  int x = options.base_vertex;
  if (x < 0)
    x = weights.empty() ? default_base_vertex(mesh, conn) : metric_centre_vertex(conn, weights);
  else if (x >= mesh.num_vertices())
    throw InputError("system of loops: base vertex " + std::to_string(x) + " is out of range (the mesh has " +
                     std::to_string(mesh.num_vertices()) + " vertices)");
  // The neighbours and lengths of the greedy basis: the caller's graph of
  // this mesh (3D lengths), else built here.
  std::unique_ptr<GreedyGraph> own;
  if (!weights.empty()) {
    own = std::make_unique<GreedyGraph>(conn, weights);
  } else if (!graph) {
    own = std::make_unique<GreedyGraph>(mesh, conn);
  } else if (graph->num_vertices != conn.num_vertices() || graph->num_edges != conn.num_edges()) {
    throw InputError("system of loops: the greedy graph has " + std::to_string(graph->num_vertices) + " vertices and " +
                     std::to_string(graph->num_edges) + " edges, the mesh " + std::to_string(conn.num_vertices()) +
                     " and " + std::to_string(conn.num_edges()));
  }
  const GreedyGraph& g = own ? *own : *graph;
  return from_greedy(mesh, conn, greedy_basis(conn, g, x, genus, !weights.empty()), x, genus, options);
}

SystemOfLoops refine_system_of_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoops& unrefined,
                                     const SystemOfLoopsOptions& options) {
  const int nv = mesh.num_vertices(), ne = conn.num_edges();
  const int genus = conn.genus();
  if (genus < 1 || unrefined.mesh.num_vertices() != nv || unrefined.mesh.F != mesh.F ||
      static_cast<int>(unrefined.tree_parent_halfedge.size()) != nv ||
      static_cast<int>(unrefined.dual_tree_parent_halfedge.size()) != conn.num_faces() ||
      static_cast<int>(unrefined.generator_edges.size()) != 2 * genus || unrefined.genus != genus)
    throw InputError("refine_system_of_loops: the loops are not an unrefined system of loops of this mesh");
  // The greedy basis as system_of_loops found it (greedy_basis): T from the
  // tree parents, T* from the dual parents, each generator's loop direction
  // the edge's own halfedge.
  Greedy g;
  g.parent_he = unrefined.tree_parent_halfedge;
  g.in_tree.assign(ne, 0);
  for (int v = 0; v < nv; ++v)
    if (g.parent_he[v] >= 0) g.in_tree[conn.edge(g.parent_he[v])] = 1;
  g.dual_parent_he = unrefined.dual_tree_parent_halfedge;
  g.generators = unrefined.generator_edges;
  for (int e : g.generators) g.gen_halfedge.push_back(conn.edge_halfedge(e));
  g.loops = unrefined.loops;
  SystemOfLoopsOptions refined = options;
  refined.refine = true;
  return from_greedy(mesh, conn, g, unrefined.base_vertex, genus, refined);
}

}  // namespace surfmap
