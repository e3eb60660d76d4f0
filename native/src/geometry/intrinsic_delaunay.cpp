#include "surfmap/geometry/intrinsic_delaunay.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <string>

#include "surfmap/error.h"

namespace surfmap {
namespace {

// cot of the angle opposite side a in a triangle with sides a, b, c.
double cot_opposite(double a, double b, double c) {
  const double s = 0.5 * (a + b + c);
  const double area2 = s * (s - a) * (s - b) * (s - c);
  const double area = std::sqrt(std::max(area2, 0.0));
  if (area <= 0.0) return (b * b + c * c - a * a) >= 0 ? 1e300 : -1e300;
  return (b * b + c * c - a * a) / (4.0 * area);
}

double angle_opposite(double a, double b, double c) {
  const double cosv = std::clamp((b * b + c * c - a * a) / (2.0 * b * c), -1.0, 1.0);
  return std::acos(cosv);
}

// A mutable halfedge triangulation that allows multi-edges: twins are stored,
// never derived from vertex pairs.
struct Mesh {
  RowMatrixX3i F;
  std::vector<int> twin, edge_of, edge_he;
  std::vector<double> length;
  std::vector<std::vector<int>> path;  // along edge_he[e]
  const Connectivity* original;

  static int next(int h) { return 3 * (h / 3) + (h % 3 + 1) % 3; }
  static int prev(int h) { return 3 * (h / 3) + (h % 3 + 2) % 3; }
  int tail(int h) const { return F(h / 3, h % 3); }
  int head(int h) const { return F(h / 3, (h % 3 + 1) % 3); }
  double len(int h) const { return length[edge_of[h]]; }

  std::vector<int> path_of(int h) const {
    const int e = edge_of[h];
    if (h == edge_he[e]) return path[e];
    std::vector<int> p(path[e].rbegin(), path[e].rend());
    for (int& x : p) x = original->twin(x);
    return p;
  }
  // cot of the angle opposite halfedge h inside its face.
  double cot_at(int h) const { return cot_opposite(len(h), len(next(h)), len(prev(h))); }
  double weight(int e) const {
    const int h = edge_he[e];
    return 0.5 * (cot_at(h) + cot_at(twin[h]));
  }
};

}  // namespace

IntrinsicDelaunayResult intrinsic_delaunay(const Connectivity& conn, const Eigen::VectorXd& edge_lengths,
                                           const IntrinsicDelaunayOptions& options) {
  const int ne = conn.num_edges(), nh = conn.num_halfedges();
  if (edge_lengths.size() != ne)
    throw InputError("intrinsic_delaunay: " + std::to_string(edge_lengths.size()) + " edge lengths for " +
                     std::to_string(ne) + " edges");
  Mesh m;
  m.original = &conn;
  m.F = conn.faces();
  m.twin.resize(nh);
  m.edge_of.resize(nh);
  for (int h = 0; h < nh; ++h) {
    m.twin[h] = conn.twin(h);
    m.edge_of[h] = conn.edge(h);
  }
  m.edge_he.resize(ne);
  m.length.resize(ne);
  m.path.resize(ne);
  for (int e = 0; e < ne; ++e) {
    m.edge_he[e] = conn.edge_halfedge(e);
    m.length[e] = edge_lengths[e];
    m.path[e] = {conn.edge_halfedge(e)};
    if (!(edge_lengths[e] > 0) || !std::isfinite(edge_lengths[e]))
      throw InputError("intrinsic_delaunay: edge " + std::to_string(e) + " has length " +
                       std::to_string(edge_lengths[e]));
  }
  for (int f = 0; f < conn.num_faces(); ++f) {
    const double a = m.len(3 * f), b = m.len(3 * f + 1), c = m.len(3 * f + 2);
    if (a >= b + c || b >= a + c || c >= a + b)
      throw InputError("intrinsic_delaunay: face " + std::to_string(f) + " violates the triangle inequality");
  }

  if (options.min_degree < 1) throw InputError("intrinsic_delaunay: min_degree must be at least 1");
  if (!options.keep.empty() && static_cast<int>(options.keep.size()) != ne)
    throw InputError("intrinsic_delaunay: keep needs one entry per edge");
  std::vector<int> degree(conn.num_vertices(), 0);  // edge ends
  for (int h = 0; h < nh; ++h) ++degree[m.tail(h)];
  const int max_flips = options.max_flips > 0 ? options.max_flips : 100 * ne;
  std::deque<int> queue;
  std::vector<char> queued(ne, 1);
  for (int e = 0; e < ne; ++e) queue.push_back(e);
  IntrinsicDelaunayResult out;
  while (!queue.empty() && out.flips < max_flips) {
    const int e = queue.front();
    queue.pop_front();
    queued[e] = 0;
    if (m.weight(e) >= -options.tolerance || (!options.keep.empty() && options.keep[e])) continue;
    // Faces f0 = (i, j, k) with h: i->j and f1 = (j, i, l) with t: j->i.
    const int h = m.edge_he[e], t = m.twin[h];
    const int f0 = h / 3, f1 = t / 3;
    if (f0 == f1) continue;  // an edge inside one face cannot be flipped
    const int hn = Mesh::next(h), hp = Mesh::prev(h), tn = Mesh::next(t), tp = Mesh::prev(t);
    const int i = m.tail(h), j = m.head(h), k = m.head(hn), l = m.head(tn);
    // i == j (a loop) loses two ends at one vertex.
    if (degree[i] - 1 - (i == j) < options.min_degree || degree[j] - 1 - (i == j) < options.min_degree) continue;
    // New length of k-l: unfold the two triangles around vertex i.
    const double a_i = angle_opposite(m.len(hn), m.len(h), m.len(hp)) +
                       angle_opposite(m.len(tp), m.len(t), m.len(tn));
    const double lki = m.len(hp), lil = m.len(tn);
    const double new_len = std::sqrt(std::max(lki * lki + lil * lil - 2 * lki * lil * std::cos(a_i), 0.0));
    if (!(new_len > 0)) continue;
    std::vector<int> new_path = m.path_of(hp);  // k -> i
    const std::vector<int> il = m.path_of(tn);  // i -> l
    new_path.insert(new_path.end(), il.begin(), il.end());
    // Outer halfedges and their data, before rewiring. Inner halfedges keep
    // their direction: k->i and i->l move to f0's sides 0 and 1, l->j and
    // j->k to f1's sides 0 and 1.
    const int inner_old[4] = {hp, tn, tp, hn};
    const int inner_new[4] = {3 * f0 + 0, 3 * f0 + 1, 3 * f1 + 0, 3 * f1 + 1};
    // A side's twin may itself be a side of the quad (i or j of degree 2:
    // the quad is folded, and the flip leaves that vertex of degree 1 inside
    // a face whose two sides are one edge; Bobenko–Springborn's flip
    // algorithm needs these). Such a twin moves with the relabelling.
    int outer[4], edges[4];
    bool owns[4];
    for (int q = 0; q < 4; ++q) {
      outer[q] = m.twin[inner_old[q]];
      for (int r = 0; r < 4; ++r)
        if (outer[q] == inner_old[r]) outer[q] = inner_new[r];
      edges[q] = m.edge_of[inner_old[q]];
      owns[q] = m.edge_he[edges[q]] == inner_old[q];
    }
    if (options.record_flips) {
      IntrinsicFlip rec;
      rec.face0 = f0, rec.face1 = f1, rec.column0 = h % 3, rec.column1 = t % 3;
      rec.i = i, rec.j = j, rec.k = k, rec.l = l;
      const double L[6] = {m.len(hp), m.len(tn), m.len(tp), m.len(hn), m.len(h), new_len};
      std::copy(L, L + 6, rec.lengths);
      out.flip_history.push_back(rec);
    }
    m.F.row(f0) << k, i, l;
    m.F.row(f1) << l, j, k;
    for (int q = 0; q < 4; ++q) {
      m.twin[inner_new[q]] = outer[q];
      m.twin[outer[q]] = inner_new[q];
      m.edge_of[inner_new[q]] = edges[q];
      if (owns[q]) m.edge_he[edges[q]] = inner_new[q];
    }
    m.twin[3 * f0 + 2] = 3 * f1 + 2;
    m.twin[3 * f1 + 2] = 3 * f0 + 2;
    m.edge_of[3 * f0 + 2] = m.edge_of[3 * f1 + 2] = e;
    m.edge_he[e] = 3 * f1 + 2;  // k -> l
    m.path[e] = std::move(new_path);
    m.length[e] = new_len;
    out.flips++;
    --degree[i], --degree[j], ++degree[k], ++degree[l];
    for (int q = 0; q < 4; ++q)
      if (!queued[edges[q]]) queued[edges[q]] = 1, queue.push_back(edges[q]);
  }
  out.delaunay = true;
  out.min_cot_weight = 1e300;
  for (int e = 0; e < ne; ++e) {
    const double w = m.weight(e);
    out.min_cot_weight = std::min(out.min_cot_weight, w);
    if (w >= -options.tolerance) continue;
    out.delaunay = false;
    if (!options.keep.empty() && options.keep[e]) continue;
    const int h = m.edge_he[e], i = m.tail(h), j = m.head(h);
    if (degree[i] - 1 - (i == j) < options.min_degree || degree[j] - 1 - (i == j) < options.min_degree)
      ++out.degree_limited;
  }
  out.F = m.F;
  out.face_edges.resize(m.F.rows(), 3);
  out.face_edge_forward.resize(m.F.rows(), 3);
  for (int h = 0; h < nh; ++h) {
    out.face_edges(h / 3, h % 3) = m.edge_of[h];
    out.face_edge_forward(h / 3, h % 3) = m.edge_he[m.edge_of[h]] == h;
  }
  out.edges.resize(ne);
  for (int e = 0; e < ne; ++e) {
    const int h = m.edge_he[e];
    IntrinsicEdge& ie = out.edges[e];
    ie.i = m.tail(h);
    ie.j = m.head(h);
    ie.length = m.length[e];
    ie.cot_weight = m.weight(e);
    ie.path = m.path[e];
  }
  return out;
}


}  // namespace surfmap
