// Greedy system of loops and its refinement into simple loops that meet only
// at the base vertex (paper §IV-A, DESIGN.md §2.2).
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
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <string>
#include <utility>

#include <Eigen/Dense>

#include "surfmap/error.h"
#include "surfmap/topology/cut_mesh.h"

namespace surfmap {
namespace {

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

Greedy greedy_basis(const TriMesh& mesh, const Connectivity& conn, int x, int genus) {
  const int nv = conn.num_vertices(), nf = conn.num_faces(), ne = conn.num_edges();
  const std::vector<double> len = edge_lengths(mesh, conn);
  Greedy g;
  // Dijkstra shortest-path tree T from x.
  std::vector<double> dist(nv, std::numeric_limits<double>::infinity());
  g.parent_he.assign(nv, -1);
  g.in_tree.assign(ne, 0);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> pq;
  dist[x] = 0;
  pq.push({0.0, x});
  std::vector<char> done(nv, 0);
  while (!pq.empty()) {
    const auto [d, v] = pq.top();
    pq.pop();
    if (done[v]) continue;
    done[v] = 1;
    if (g.parent_he[v] >= 0) g.in_tree[conn.edge(g.parent_he[v])] = 1;
    const int start = conn.vertex_halfedge(v);
    int h = start;
    do {
      const int w = conn.head(h);
      const double nd = d + len[conn.edge(h)];
      if (nd < dist[w]) {
        dist[w] = nd;
        g.parent_he[w] = h;
        pq.push({nd, w});
      }
      h = conn.rotate_ccw(h);
    } while (h != start);
  }
  for (int v = 0; v < nv; ++v)
    if (!done[v]) throw InputError("vertex " + std::to_string(v) + " is not connected to the base vertex");
  // Maximum spanning tree T* of the dual graph of the non-tree edges, each
  // weighted by the length of its loop sigma(e) (Erickson–Whittlesey).
  std::vector<std::pair<double, int>> order;
  order.reserve(ne);
  for (int e = 0; e < ne; ++e)
    if (!g.in_tree[e])
      order.push_back({dist[conn.edge_vertex(e, 0)] + dist[conn.edge_vertex(e, 1)] + len[e], e});
  std::sort(order.begin(), order.end(),
            [](const auto& a, const auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
  UnionFind uf(nf);
  std::vector<char> in_dual(ne, 0);
  std::vector<std::pair<double, int>> gens;
  for (const auto& [w, e] : order) {
    const int h = conn.edge_halfedge(e);
    if (uf.unite(Connectivity::face(h), Connectivity::face(conn.twin(h))))
      in_dual[e] = 1;
    else
      gens.push_back({w, e});
  }
  if (static_cast<int>(gens.size()) != 2 * genus)
    throw SolveError("system of loops: found " + std::to_string(gens.size()) +
                     " generator edges, expected 2g = " + std::to_string(2 * genus));
  std::sort(gens.begin(), gens.end());
  // Dual tree parents by BFS over T* from face 0.
  g.dual_parent_he.assign(nf, -1);
  std::vector<char> fseen(nf, 0);
  std::vector<int> queue{0};
  fseen[0] = 1;
  for (size_t i = 0; i < queue.size(); ++i) {
    const int f = queue[i];
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (!in_dual[conn.edge(h)]) continue;
      const int nbr = Connectivity::face(conn.twin(h));
      if (fseen[nbr]) continue;
      fseen[nbr] = 1;
      g.dual_parent_he[nbr] = conn.twin(h);
      queue.push_back(nbr);
    }
  }
  if (static_cast<int>(queue.size()) != nf) throw SolveError("system of loops: the cut tree does not span all faces");
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
};

struct Refiner {
  const TriMesh& mesh;
  const Connectivity& conn;
  int n_in;
  std::vector<NewVertex> nv;  // vertices n_in, n_in+1, ...
  std::vector<std::vector<std::pair<double, int>>> edge_points;  // per input edge
  std::vector<std::vector<std::vector<int>>> face_chords;       // per input face

  Refiner(const TriMesh& m, const Connectivity& c)
      : mesh(m), conn(c), n_in(m.num_vertices()), edge_points(c.num_edges()), face_chords(c.num_faces()) {}

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

  // Barycentric coordinates of vertex `id` in face f (which must contain it).
  Eigen::Vector3d local_bc(int f, int id) const {
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    if (id < n_in) {
      for (int k = 0; k < 3; ++k)
        if (conn.faces()(f, k) == id) b[k] = 1;
      return b;
    }
    const NewVertex& p = nv[id - n_in];
    if (p.edge < 0) return p.bc;
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
      // on the edge, so bend it into the face. Tent height grows with the
      // square of the chord's span, which keeps nested tents (also tents
      // sharing an endpoint) strictly apart.
      const double sp = bp[(k + 1) % 3], sq = bq[(k + 1) % 3];
      const double span = std::abs(sq - sp), mid = 0.5 * (sp + sq);
      const double eta = 0.8 * span * span;
      NewVertex c;
      c.face = f;
      c.bc[k] = 1 - mid - 0.5 * eta;
      c.bc[(k + 1) % 3] = mid - 0.5 * eta;
      c.bc[o] = eta;
      nv.push_back(c);
      chord.push_back(n_in + static_cast<int>(nv.size()) - 1);
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

bool inside_polygon(const std::vector<int>& poly, const std::vector<Eigen::Vector2d>& pos,
                    const std::function<int(int)>& loc, const Eigen::Vector2d& p) {
  bool in = false;
  const size_t n = poly.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = pos[loc(poly[i])];
    const Eigen::Vector2d& b = pos[loc(poly[j])];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

// Triangulates input face f with its split points and chords; appends
// triangles (counter-clockwise, like the face) to `out`.
void triangulate_face(const Refiner& R, int f, std::vector<std::array<int, 3>>& out) {
  const Connectivity& conn = R.conn;
  // Boundary polygon.
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
  const auto& chords = R.face_chords[f];
  if (boundary.size() == 3 && chords.empty()) {
    out.push_back({boundary[0], boundary[1], boundary[2]});
    return;
  }
  // Local 2D positions of every vertex involved (isometric copy of the face).
  Eigen::Vector3d P[3];
  for (int k = 0; k < 3; ++k) P[k] = R.mesh.V.row(R.mesh.F(f, k)).transpose();
  const double l01 = (P[1] - P[0]).norm();
  const Eigen::Vector3d u = (P[1] - P[0]) / l01;
  const Eigen::Vector2d c2((P[2] - P[0]).dot(u), ((P[2] - P[0]) - (P[2] - P[0]).dot(u) * u).norm());
  const Eigen::Vector2d C[3] = {Eigen::Vector2d(0, 0), Eigen::Vector2d(l01, 0), c2};
  std::vector<int> ids = boundary;
  for (const auto& ch : chords)
    for (size_t i = 1; i + 1 < ch.size(); ++i) ids.push_back(ch[i]);
  std::vector<Eigen::Vector2d> pos;
  std::vector<std::pair<int, int>> index;  // (id, local index), sorted
  for (int id : ids) {
    const Eigen::Vector3d b = R.local_bc(f, id);
    index.push_back({id, static_cast<int>(pos.size())});
    pos.push_back(b[0] * C[0] + b[1] * C[1] + b[2] * C[2]);
  }
  std::sort(index.begin(), index.end());
  auto loc = [&](int id) {
    auto it = std::lower_bound(index.begin(), index.end(), std::make_pair(id, -1));
    return it->second;
  };
  const double scale2 = std::max({l01 * l01, c2.squaredNorm(), (C[1] - c2).squaredNorm()});
  // Split the face into regions along the chords.
  std::vector<std::vector<int>> regions{boundary};
  for (const auto& ch : chords) {
    const int A = ch.front(), B = ch.back();
    const Eigen::Vector2d probe = 0.5 * (pos[loc(ch[0])] + pos[loc(ch[1])]);
    bool split = false;
    for (size_t r = 0; r < regions.size() && !split; ++r) {
      auto& poly = regions[r];
      const auto ia = std::find(poly.begin(), poly.end(), A), ib = std::find(poly.begin(), poly.end(), B);
      if (ia == poly.end() || ib == poly.end()) continue;
      if (!inside_polygon(poly, pos, loc, probe)) continue;
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
                       " does not fit inside face " + std::to_string(f));
  }
  // Ear clipping, best (largest smallest angle) ear first.
  const double eps = 1e-14 * scale2;
  for (auto poly : regions) {
    while (poly.size() > 3) {
      const size_t n = poly.size();
      double best_q = -1;
      size_t best = n;
      for (size_t i = 0; i < n; ++i) {
        const Eigen::Vector2d &a = pos[loc(poly[(i + n - 1) % n])], &b = pos[loc(poly[i])],
                              &c = pos[loc(poly[(i + 1) % n])];
        const double area2 = cross2(a, b, c);
        if (area2 <= eps) continue;
        bool empty = true;
        for (size_t j = 0; j < n && empty; ++j) {
          if (j == i || j == (i + 1) % n || j == (i + n - 1) % n) continue;
          const Eigen::Vector2d& p = pos[loc(poly[j])];
          if (cross2(a, b, p) >= -eps && cross2(b, c, p) >= -eps && cross2(c, a, p) >= -eps) empty = false;
        }
        if (!empty) continue;
        // Quality: area over the sum of squared edge lengths.
        const double q = area2 / ((a - b).squaredNorm() + (b - c).squaredNorm() + (c - a).squaredNorm());
        if (q > best_q) {
          best_q = q;
          best = i;
        }
      }
      if (best == n)
        throw SolveError("system of loops: cannot triangulate a refined piece of face " + std::to_string(f));
      out.push_back({poly[(best + n - 1) % n], poly[best], poly[(best + 1) % n]});
      poly.erase(poly.begin() + best);
    }
    const Eigen::Vector2d &a = pos[loc(poly[0])], &b = pos[loc(poly[1])], &c = pos[loc(poly[2])];
    if (cross2(a, b, c) <= eps)
      throw SolveError("system of loops: degenerate refined triangle in face " + std::to_string(f));
    out.push_back({poly[0], poly[1], poly[2]});
  }
}

struct Refined {
  TriMesh mesh;
  std::vector<int> origin_face;
  RowMatrixX3d origin_bc;
  std::vector<std::vector<int>> loops;
};

Refined refine(const TriMesh& mesh, const Connectivity& conn, const Greedy& g, int x) {
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
  // Euler tour around T': the slots (non-T' halfedges leaving T' vertices),
  // until the last arc has left.
  const int n_arcs = 2 * ng;
  std::vector<int> slots;
  {
    int exits = 0, guard = 0;
    int o = Connectivity::next(h_last);
    while (exits < n_arcs) {
      if (++guard > 4 * conn.num_halfedges()) throw SolveError("system of loops: Euler tour did not close");
      if (tp[conn.edge(o)]) {
        o = Connectivity::next(o);
        continue;
      }
      slots.push_back(o);
      if (gen_of_edge[conn.edge(o)] >= 0) ++exits;
      o = Connectivity::next(conn.twin(o));
    }
  }
  Refiner R(mesh, conn);
  // arc paths by level (level 0 innermost = the arc that exits last).
  std::vector<std::vector<int>> arc(n_arcs, std::vector<int>{x});
  // exit_arc[k][0]: arc ending near the tail of gen_halfedge[k]; [1]: near its head.
  std::vector<std::array<int, 2>> exit_arc(ng, {-1, -1});
  const double Lambda = 0.4;
  int present = n_arcs;
  std::vector<int> prev_points;  // points of the previous slot, by level
  int prev_slot = -1;
  for (int o : slots) {
    const int v = conn.tail(o), e = conn.edge(o);
    std::vector<int> pts(present);
    for (int l = 0; l < present; ++l) {
      const double lambda = Lambda * (l + 1) / present;
      pts[l] = R.add_edge_point(e, v == conn.edge_vertex(e, 0) ? lambda : 1 - lambda);
    }
    const int f = Connectivity::face(o);
    if (prev_slot >= 0 && Connectivity::face(conn.twin(prev_slot)) != f)
      throw SolveError("system of loops: internal error in the Euler tour");
    for (int l = 0; l < present; ++l) {
      const std::vector<int> app = R.add_chord(f, prev_slot < 0 ? x : prev_points[l], pts[l]);
      arc[l].insert(arc[l].end(), app.begin(), app.end());
    }
    const int k = gen_of_edge[e];
    if (k >= 0) {
      --present;  // the outermost arc leaves here
      exit_arc[k][conn.tail(g.gen_halfedge[k]) == v ? 0 : 1] = present;
    }
    prev_points = pts;
    prev_slot = o;
  }
  // Refined faces.
  std::vector<std::array<int, 3>> tris;
  tris.reserve(conn.num_faces() + 4 * R.nv.size());
  for (int f = 0; f < conn.num_faces(); ++f) triangulate_face(R, f, tris);
  Refined out;
  const int n_total = R.n_in + static_cast<int>(R.nv.size());
  out.mesh.V.resize(n_total, 3);
  out.mesh.V.topRows(R.n_in) = mesh.V;
  out.origin_face.resize(n_total);
  out.origin_bc.setZero(n_total, 3);
  {
    // Input vertices: a corner of some face.
    for (int f = 0; f < conn.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int v = mesh.F(f, k);
        out.origin_face[v] = f;
        out.origin_bc.row(v).setZero();
        out.origin_bc(v, k) = 1;
      }
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
  std::vector<char> in_dual(ne, 0);
  s.dual_tree_parent_halfedge.assign(nf, -1);
  std::vector<char> fseen(nf, 0);
  std::vector<int> queue{0};
  fseen[0] = 1;
  for (size_t i = 0; i < queue.size(); ++i) {
    const int f = queue[i];
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (on_loop[conn.edge(h)]) continue;
      const int nbr = Connectivity::face(conn.twin(h));
      if (fseen[nbr]) continue;
      fseen[nbr] = 1;
      in_dual[conn.edge(h)] = 1;
      s.dual_tree_parent_halfedge[nbr] = conn.twin(h);
      queue.push_back(nbr);
    }
  }
  if (static_cast<int>(queue.size()) != nf)
    throw SolveError("system of loops: the loops cut the surface into more than one piece");
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

SystemOfLoops system_of_loops(const TriMesh& mesh, const SystemOfLoopsOptions& options) {
  const Connectivity conn(mesh.F, mesh.num_vertices());
  const int genus = conn.genus();
  if (conn.euler_characteristic() > 0 || genus < 1)
    throw InputError("system of loops: the surface has genus 0 (Euler characteristic " +
                     std::to_string(conn.euler_characteristic()) + "); there are no loops to cut");
  int x = options.base_vertex;
  if (x < 0)
    x = default_base_vertex(mesh, conn);
  else if (x >= mesh.num_vertices())
    throw InputError("system of loops: base vertex " + std::to_string(x) + " is out of range (the mesh has " +
                     std::to_string(mesh.num_vertices()) + " vertices)");
  const Greedy g = greedy_basis(mesh, conn, x, genus);
  SystemOfLoops s;
  s.genus = genus;
  s.base_vertex = x;
  if (!options.refine) {
    s.mesh = mesh;
    const int nv = mesh.num_vertices();
    s.origin_face.assign(nv, -1);
    s.origin_barycentric.setZero(nv, 3);
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
  Refined r = refine(mesh, conn, g, x);
  s.mesh = std::move(r.mesh);
  s.origin_face = std::move(r.origin_face);
  s.origin_barycentric = std::move(r.origin_bc);
  s.loops = std::move(r.loops);
  try {
    finish_from_simple_loops(s);
  } catch (const InputError& e) {
    throw SolveError(std::string("system of loops: the refined mesh is invalid: ") + e.what());
  }
  return s;
}

}  // namespace surfmap
