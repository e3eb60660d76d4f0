#pragma once
// A start for the Ricci flow's Newton solve from a coarse copy (issue 19:
// multilevel start). The conformal factor u of the uniformizing metric is,
// away from the mesh's own discretisation, a smooth function on the surface,
// so the solution on a few-thousand-vertex copy of the mesh gives u's
// large-scale part. The copy: seeds are the vertices, in index order, more
// than R edges from every earlier seed; each vertex belongs to the region of
// its nearest seed (Dijkstra over the 3D edge lengths); a coarse face stands
// for every fine triangle with corners in three regions, and the copy is used
// only when these faces form a closed oriented surface of the mesh's Euler
// characteristic (else R is lowered). (map/coarse_source.h builds the
// ranking's copy by farthest-point sampling, with fine paths for its edges:
// ~0.3 s of CPU on a 56k mesh, a third of the flow this start shortens.)
// The solution is prolonged to the mesh: a seed takes its coarse vertex's u,
// the other vertices their region's, smoothed by Gauss–Seidel sweeps of the
// mesh's graph Laplacian with the seeds held. Newton from there only corrects
// the small-scale part, and the one factorisation of its first step is of a
// Hessian close to the final one, so the later steps' conjugate gradients on
// it need fewer iterations.
//
// The start changes where Newton begins, not what it converges to: the
// flow's energy is convex and its solution unique (hyperbolic; flat: up to a
// constant), so the metric is the same within the flow's tolerance.
#include <string>

#include <Eigen/Core>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct CoarseStartOptions {
  /// About how many vertices the coarse copy has (default 3000; the seeds'
  /// spacing R is chosen for it); <= 0: no coarse start.
  int coarse_vertices = 3000;
  /// Meshes with fewer vertices (or fewer than 4 coarse_vertices) start from
  /// u = 0 (default 20000: below that the whole flow costs about what the
  /// coarse copy and its solve cost).
  int min_vertices = 20000;
  /// Curvature tolerance of the coarse solve (default 1e-6: the prolonged u
  /// is further than that from the fine solution anyway).
  double coarse_tolerance = 1e-6;
  /// Gauss–Seidel sweeps smoothing the prolonged u (default 10: the regions
  /// of a 3000-vertex copy of a 56k mesh are 2-3 edges across).
  int smoothing_sweeps = 10;
  /// Threads of the coarse copy's flow's evaluations (RicciFlowOptions::
  /// threads, default 1; 2: the same bits, in two halves).
  int threads = 1;
};

struct CoarseStart {
  /// False: no start (the reason in `why`); the flow then starts from u = 0.
  bool ok = false;
  std::string why;
  /// #V conformal factors on the mesh (ricci_flow_from's u_start).
  Eigen::VectorXd u;
  /// The coarse copy's vertices and its flow's Newton iterations and flips.
  int coarse_vertices = 0;
  int coarse_iterations = 0;
  int coarse_flips = 0;
  /// Seconds: the coarse copy, its flow, the prolongation; and all of it.
  double copy_seconds = 0, flow_seconds = 0, prolong_seconds = 0, seconds = 0;
};

/// `mesh`, `conn`: a closed mesh (genus >= 1) and its connectivity. Never
/// throws for a mesh the coarse copy or its flow cannot handle: ok = false.
CoarseStart coarse_conformal_start(const TriMesh& mesh, const Connectivity& conn, Background background,
                                   const CoarseStartOptions& options = {});

/// Whether ricci_flow_from_checked started from u_start, and why.
struct CheckedStart {
  /// False: the run started from u = 0 (the run ricci_flow makes, bit for bit).
  bool start_used = false;
  /// The energy's slopes φ'(0) = g(0)·u_start and φ'(1) = g(u_start)·u_start
  /// along the segment (see ricci_flow_from_checked), and the max curvature
  /// error at u = 0 (the flow's residual_history[0] is the chosen start's).
  double slope_at_zero = 0, slope_at_start = 0, residual_at_zero = 0;
};

struct CheckedFlow {
  RicciFlowResult flow;
  CheckedStart start;
};

/// ricci_flow_from (Newton) with the start checked first (session 18: the
/// coarse start is worse than u = 0 on irregular meshes: 13 Newton steps
/// instead of 7 on a 32508-vertex CAD teapot, 14 instead of 6 on a 50085-vertex
/// CAD hand). The flow's energy E is convex with gradient g = K − target
/// (Hessian dK/du), so along the segment u(t) = t u_start its slope
/// φ'(t) = g(u(t))·u_start grows with t (E is C¹, flips included). The start
/// is used when the segment runs downhill from u = 0 (φ'(0) < 0) and is at
/// most `overshoot` |φ'(0)| uphill at u_start (φ'(1)): the energy's minimum
/// along the segment, by the secant of φ', then lies at t >= 1 / (1 +
/// overshoot). Measured (docs/benchmarks.md, session 18): φ'(1) / |φ'(0)| =
/// 0.0005-0.005 on the smooth meshes where the start saves Newton steps, 0.25
/// and 0.33 on the CAD meshes where it costs them: a start whose scale is off
/// (the coarse copy's hop-ball regions on long thin triangles) overshoots its
/// own line's minimum. Otherwise the run starts from u = 0, after every flip
/// made towards u_start is undone from a copy of the triangulation: the run
/// ricci_flow makes, bit for bit. Costs one evaluation at u = 0 more (the
/// input pass has made the triangulation Delaunay there). Throws as
/// ricci_flow_from.
CheckedFlow ricci_flow_from_checked(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                    Background background, const RicciFlowOptions& options,
                                    const Eigen::VectorXd& u_start, double overshoot = 0.05);

}  // namespace surfmap
