// System of loops and exact lengths on an intrinsic triangulation
// (uniformize/intrinsic_loops.h).
#include "surfmap/uniformize/intrinsic_loops.h"

#include <algorithm>
#include <array>
#include <memory>
#include <cmath>
#include <string>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap {
namespace {

/// A point of T' as weights on the corners of one face: the faces that
/// contain it are found from its support (vertex, edge or face interior).
struct Support {
  int count = 0;
  std::array<int, 3> vertex{{-1, -1, -1}};
  std::array<double, 3> weight{{0, 0, 0}};
  int face = -1;
};

Support support_of(const RowMatrixX3i& F, int face, const Eigen::RowVector3d& b, double zero) {
  Support s;
  s.face = face;
  const double sum = b.sum();
  for (int k = 0; k < 3; ++k)
    if (b[k] > zero * sum) {
      s.vertex[s.count] = F(face, k);
      s.weight[s.count] = b[k] / sum;
      ++s.count;
    }
  return s;
}

/// Calls visit(g) for the faces of T' containing the point (around its
/// vertex counter-clockwise from the vertex's halfedge, the two sides of its
/// edge, or its face) until visit returns true; returns whether one did.
/// Issue 19: no list per call (two allocations each, ~1400 instructions per
/// point, for every refined edge's ends and every located point).
template <class Visit>
bool any_face_containing(const Support& s, const Connectivity& c, const Visit& visit) {
  if (s.count == 1) {
    const int start = c.vertex_halfedge(s.vertex[0]);
    int h = start;
    do {
      if (visit(Connectivity::face(h))) return true;
      h = c.rotate_ccw(h);
    } while (h != start);
    return false;
  }
  if (s.count == 2) {
    const int h = c.find_halfedge(s.vertex[0], s.vertex[1]);
    return h >= 0 && (visit(Connectivity::face(h)) || visit(Connectivity::face(c.twin(h))));
  }
  return visit(s.face);
}

/// Whether face g of T' is one of those containing the point.
bool face_contains(const Support& s, const Connectivity& c, int g) {
  return any_face_containing(s, c, [g](int x) { return x == g; });
}

/// The point's barycentric coordinates in face g (which contains it).
bool weights_in(const Support& s, const RowMatrixX3i& F, int g, double w[3]) {
  w[0] = w[1] = w[2] = 0;
  for (int i = 0; i < s.count; ++i) {
    int k = 0;
    while (k < 3 && F(g, k) != s.vertex[i]) ++k;
    if (k == 3) return false;
    w[k] += s.weight[i];
  }
  return true;
}

/// Corners of a face in a canonical placement: Euclidean (x, y, 0);
/// hyperbolic on the hyperboloid (t, x, y) with t² − x² − y² = 1.
/// l[k]: side opposite corner k.
std::array<Eigen::Vector3d, 3> place(const double l[3], Background bg) {
  std::array<Eigen::Vector3d, 3> X;
  const double c = l[2], b = l[1], a = l[0];  // c: corner 0 -> 1, b: corner 0 -> 2
  // Angle at corner 0 by the half-angle formula (Euclidean tan(A/2) =
  // sqrt((s−b)(s−c) / (s(s−a))), hyperbolic the same with sinh): accurate
  // for slivers, where the law of cosines cancels.
  const double s = 0.5 * (a + b + c);
  const double sa = std::max(0.0, s - a), sb = std::max(0.0, s - b), sc = std::max(0.0, s - c);
  if (bg == Background::Euclidean) {
    const double A = 2.0 * std::atan2(std::sqrt(sb * sc), std::sqrt(s * sa));
    X[0] = {0, 0, 0};
    X[1] = {c, 0, 0};
    X[2] = {b * std::cos(A), b * std::sin(A), 0};
  } else {
    const double A =
        2.0 * std::atan2(std::sqrt(std::sinh(sb) * std::sinh(sc)), std::sqrt(std::sinh(s) * std::sinh(sa)));
    X[0] = {1, 0, 0};
    X[1] = {std::cosh(c), std::sinh(c), 0};
    X[2] = {std::cosh(b), std::sinh(b) * std::cos(A), std::sinh(b) * std::sin(A)};
  }
  return X;
}

Eigen::Vector3d combine(const std::array<Eigen::Vector3d, 3>& X, const double w[3], Background bg) {
  Eigen::Vector3d p = w[0] * X[0] + w[1] * X[1] + w[2] * X[2];
  if (bg == Background::Hyperbolic) p /= std::sqrt(std::max(1e-300, p[0] * p[0] - p[1] * p[1] - p[2] * p[2]));
  return p;
}

double distance(const Eigen::Vector3d& p, const Eigen::Vector3d& q, Background bg) {
  const Eigen::Vector3d d = p - q;
  if (bg == Background::Euclidean) return d.norm();
  // |p − q|_Lorentz = 2 sinh(dist/2): no cancellation for short distances.
  const double s2 = std::max(0.0, d[1] * d[1] + d[2] * d[2] - d[0] * d[0]);
  return 2.0 * std::asinh(0.5 * std::sqrt(s2));
}

Support support_of_vertex(const SystemOfLoops& loops, const RowMatrixX3i& F, int num_input_vertices, int v) {
  Support s;
  if (v < num_input_vertices) {
    s.count = 1;
    s.vertex[0] = v;
    s.weight[0] = 1;
    s.face = loops.origin_face[v];
  } else {
    s = support_of(F, loops.origin_face[v], loops.origin_barycentric.row(v), 1e-15);
  }
  return s;
}

}  // namespace

FacePoint intrinsic_face_point(const SystemOfLoops& loops, const RowMatrixX3i& F, const Connectivity& tc,
                               int num_input_vertices, int rf, const Eigen::Vector3d& b) {
  std::array<Support, 3> sup;
  for (int k = 0; k < 3; ++k) sup[k] = support_of_vertex(loops, F, num_input_vertices, loops.mesh.F(rf, k));
  // The first face around corner 0's point that holds all three points.
  FacePoint p;
  any_face_containing(sup[0], tc, [&](int g) {
    if (!face_contains(sup[1], tc, g) || !face_contains(sup[2], tc, g)) return false;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      double w[3];
      if (!weights_in(sup[k], F, g, w)) return false;
      for (int q = 0; q < 3; ++q) sum[q] += b[k] * w[q];
    }
    p.face = g;
    p.barycentric = sum;
    return true;
  });
  if (p.face >= 0) return p;
  throw SolveError("refined face " + std::to_string(rf) + " lies in no single face of the intrinsic triangulation");
}

std::vector<double> metric_edge_weights(const RicciFlowResult& flow, const Connectivity& tc) {
  // Halfedge 3f + k runs from corner k to corner k + 1: the side opposite
  // corner k + 2 (flow.face_edges(f, k) is the side opposite corner k).
  std::vector<double> w(tc.num_edges(), 0.0);
  for (int f = 0; f < flow.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) w[tc.edge(3 * f + k)] = flow.edge_lengths[flow.face_edges(f, (k + 2) % 3)];
  return w;
}

IntrinsicLoops intrinsic_loops(const TriMesh& input, const RicciFlowResult& flow, Background background,
                               const SystemOfLoopsOptions& options_in, bool loops_in_metric) {
  const RowMatrixX3i& F = flow.faces;
  if (F.rows() == 0 || flow.face_edges.rows() != F.rows())
    throw InputError("intrinsic_loops: the flow result has no triangulation");
  TriMesh tm;
  tm.V = input.V;
  tm.F = F;
  std::unique_ptr<Connectivity> ct;
  try {
    ct = std::make_unique<Connectivity>(F, input.num_vertices());
  } catch (const InputError& e) {
    throw SolveError(std::string("the intrinsic triangulation is not simplicial (") + e.what() + ")");
  }
  SystemOfLoopsOptions options = options_in;
  if (loops_in_metric) options.edge_weights = metric_edge_weights(flow, *ct);
  IntrinsicLoops out;
  out.loops = system_of_loops(tm, *ct, options);
  const TriMesh& R = out.loops.mesh;
  const int nv = R.num_vertices();
  if (static_cast<int>(out.loops.origin_face.size()) != nv)
    throw SolveError("intrinsic_loops: the loops' mesh has no origins");
  std::vector<Support> sup(nv);
  for (int v = 0; v < nv; ++v) sup[v] = support_of_vertex(out.loops, F, input.num_vertices(), v);
  out.conn = std::make_shared<const Connectivity>(R.F, nv);
  const Connectivity& rc = *out.conn;
  out.lengths.resize(rc.num_edges());
  for (int e = 0; e < rc.num_edges(); ++e) {
    const int a = rc.edge_vertex(e, 0), b = rc.edge_vertex(e, 1);
    // The first face around a's point that also holds b's.
    int g = -1;
    any_face_containing(sup[a], *ct, [&](int x) {
      if (!face_contains(sup[b], *ct, x)) return false;
      g = x;
      return true;
    });
    double wa[3], wb[3];
    if (g < 0 || !weights_in(sup[a], F, g, wa) || !weights_in(sup[b], F, g, wb))
      throw SolveError("intrinsic_loops: refined edge " + std::to_string(e) + " (" + std::to_string(a) + ", " +
                       std::to_string(b) + ") lies in no single face of the intrinsic triangulation");
    double l[3];
    for (int k = 0; k < 3; ++k) l[k] = flow.edge_lengths[flow.face_edges(g, k)];
    int side = -1;  // an edge of T' itself: its length exactly
    if (sup[a].count == 1 && sup[b].count == 1)
      for (int k = 0; k < 3; ++k)
        if (wa[k] == 0 && wb[k] == 0) side = k;
    if (side >= 0) {
      out.lengths[e] = l[side];
    } else {
      const auto X = place(l, background);
      out.lengths[e] = distance(combine(X, wa, background), combine(X, wb, background), background);
    }
    if (!(out.lengths[e] > 0) || !std::isfinite(out.lengths[e]))
      throw SolveError("intrinsic_loops: refined edge " + std::to_string(e) + " has length " +
                       std::to_string(out.lengths[e]));
  }
  return out;
}

}  // namespace surfmap
