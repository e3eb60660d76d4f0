// Uniformization metric with exact refinement when the fixed-connectivity
// flow is infeasible (uniformize/feasible_metric.h).
#include "surfmap/uniformize/feasible_metric.h"

#include <algorithm>
#include <map>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/exact_refinement.h"

namespace surfmap {
namespace {

/// A point of the input surface as a combination of input vertices (at most
/// a handful of non-zero weights). Split points are affine combinations of
/// two such points, so the weights, and the zeros among them, stay exact.
using Combination = std::map<int, double>;

Combination combination_of(const TriMesh& input, int face, const Eigen::RowVector3d& bary) {
  Combination c;
  for (int k = 0; k < 3; ++k)
    if (bary[k] != 0) c[input.F(face, k)] += bary[k];
  return c;
}

/// The input face holding the combination (all its vertices with weight >
/// tolerance are corners), with barycentrics; faces around the vertices of
/// largest weight are the candidates.
int face_of(const TriMesh& input, const Connectivity& ic, const Combination& c, Eigen::RowVector3d* bary) {
  int best = -1;
  double best_weight = -1;
  for (const auto& [v, w] : c) {
    if (w <= 1e-14) continue;
    for (int h : ic.outgoing(v)) {
      const int f = Connectivity::face(h);
      double captured = 0;
      Eigen::RowVector3d b = Eigen::RowVector3d::Zero();
      for (int k = 0; k < 3; ++k) {
        const auto it = c.find(input.F(f, k));
        if (it != c.end()) b[k] = it->second, captured += it->second;
      }
      if (captured > best_weight) best_weight = captured, best = f, *bary = b;
    }
  }
  if (best >= 0) *bary /= bary->sum();
  return best;
}

/// loops.mesh refined at `max_angle`, the loops carried through the splits,
/// origins converted to the input mesh, trees and word rebuilt.
SystemOfLoops refined_loops(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& loops,
                            double max_angle, int* splits) {
  ExactRefinementOptions ro;
  ro.max_angle_deg = max_angle;
  const ExactRefinementResult r = refine_obtuse_triangles(loops.mesh, ro);
  *splits = r.splits;
  SystemOfLoops s = loops;
  s.mesh = r.mesh;
  const int nv0 = loops.mesh.num_vertices(), nv = s.mesh.num_vertices();
  std::vector<Combination> comb(nv);
  for (int v = 0; v < nv0; ++v) comb[v] = combination_of(input, loops.origin_face[v], loops.origin_barycentric.row(v));
  // Refined faces lie inside loops-mesh faces, which lie inside input faces.
  if (loops.face_origin.size() == static_cast<size_t>(loops.mesh.num_faces())) {
    s.face_origin.resize(s.mesh.num_faces());
    for (int f = 0; f < s.mesh.num_faces(); ++f) s.face_origin[f] = loops.face_origin[r.face_origin[f]];
  }
  s.origin_face.resize(nv);
  s.origin_barycentric.conservativeResize(nv, 3);
  std::vector<char> on_loop(nv, 0);
  for (const auto& L : s.loops)
    for (int v : L) on_loop[v] = 1;
  for (const auto& sp : r.split_log) {
    Combination c = comb[sp.a];
    for (auto& [v, w] : c) w *= 1 - sp.t;
    for (const auto& [v, w] : comb[sp.b]) c[v] += sp.t * w;
    comb[sp.m] = c;
    Eigen::RowVector3d b = Eigen::RowVector3d::Zero();
    s.origin_face[sp.m] = face_of(input, ic, c, &b);
    if (s.origin_face[sp.m] < 0) throw SolveError("exact refinement: a split point lies on no input face");
    s.origin_barycentric.row(sp.m) = b;
    // A split loop edge: the new vertex joins the loop between its ends.
    if (!on_loop[sp.a] || !on_loop[sp.b]) continue;
    for (auto& L : s.loops)
      for (size_t i = 0; i + 1 < L.size(); ++i)
        if ((L[i] == sp.a && L[i + 1] == sp.b) || (L[i] == sp.b && L[i + 1] == sp.a)) {
          L.insert(L.begin() + static_cast<long>(i) + 1, sp.m);
          on_loop[sp.m] = 1;
          break;
        }
  }
  rebuild_system_of_loops(s);
  return s;
}

}  // namespace

FeasibleMetricResult feasible_metric(const TriMesh& input, const SystemOfLoops& loops, Background background,
                                     const FeasibleMetricOptions& options) {
  FeasibleMetricResult res;
  res.loops = loops;
  {
    const Connectivity conn(loops.mesh.F, loops.mesh.num_vertices());
    res.flow = ricci_flow(conn, edge_lengths(loops.mesh, conn), background, options.flow);
  }
  if (res.flow.converged) return res;
  res.unrefined_failure = res.flow.message;
  const Connectivity ic(input.F, input.num_vertices());
  for (double max_angle : options.refine_max_angles) {
    int splits = 0;
    SystemOfLoops s = refined_loops(input, ic, loops, max_angle, &splits);
    const Connectivity conn(s.mesh.F, s.mesh.num_vertices());
    RicciFlowResult flow;
    try {
      flow = ricci_flow(conn, edge_lengths(s.mesh, conn), background, options.flow);
    } catch (const InputError& e) {  // e.g. an edge of zero length in double precision
      flow.converged = false;
      flow.message = std::string("the refined mesh is unusable: ") + e.what();
    }
    res.loops = std::move(s);
    res.flow = std::move(flow);
    res.refinement_splits = splits;
    res.refinement_max_angle = max_angle;
    if (res.flow.converged) break;
  }
  return res;
}

}  // namespace surfmap
