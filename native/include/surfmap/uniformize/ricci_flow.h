#pragma once
// Discrete Ricci flow / discrete uniformization metric (docs/method.md
// §2.4). Finds conformal factors u (one per vertex) such that the conformally
// changed metric has the wanted angle defect K_i = 2π − Σθ_i at every vertex:
// flat (Euclidean background, genus 1 and punctured spheres) or curvature −1
// (hyperbolic background, genus >= 2).
//
// Schemes:
//  * VertexScaling (default; discrete Yamabe flow of a convex energy):
//      Euclidean   l̃_ij = e^{(u_i+u_j)/2} l_ij
//      Hyperbolic  sinh(l̃_ij/2) = e^{(u_i+u_j)/2} l_ij/2   (l_ij: the input,
//                  Euclidean, lengths; i.e. the initial hyperbolic metric has
//                  sinh(l_hyp/2) = l/2). The energy is convex in u; triangles
//                  that violate the triangle inequality during the solve use
//                  the extended (C¹, convex) energy with angles (π, 0, 0).
//  * InversiveDistance (the paper's Bowers–Stephenson circle packing):
//      r_i = r⁰_i e^{u_i} (Euclidean) or tanh(r_i/2) = tanh(r⁰_i/2) e^{u_i}
//      (hyperbolic) with initial radii r⁰_i = 1/3 of the shortest edge at i
//      (hyperbolic: of the initial hyperbolic lengths, sinh(l_hyp/2) = l/2)
//      and the inversive distances I_ij fixed from these initial circles;
//      Euclidean   l² = r_i² + r_j² + 2 r_i r_j I_ij
//      Hyperbolic  cosh l = cosh r_i cosh r_j + I_ij sinh r_i sinh r_j.
//
// Methods: Newton with line search on a sparse Hessian (default), or the
// paper's explicit flow du/dt = K_target − K (for comparison). Newton:
// Jacobian dK/du by the chain rule through the law of cosines (Euclidean
// vertex scaling: the cotangent Laplacian / 2), CHOLMOD Cholesky reused as a
// conjugate-gradient preconditioner across steps, backtracking on |K − K*|₂,
// a Levenberg shift only when a step fails; flat gauge: u_0 stays 0.
//
// With fixed connectivity a solution need not exist (crumpled slivers, long
// CAD triangles: the minimiser of the extended energy has degenerate
// triangles); then converged = false with the face named. Setting
// options.intrinsic_delaunay gives a metric on a flipped triangulation
// instead (see RicciFlowResult::faces).
//
// Usage by the layout / CLI / Python code: call ricci_flow(conn, edge_lengths(mesh, conn),
// Background::Euclidean or ::Hyperbolic); check `converged` (never true with
// a wrong metric: degenerate triangles or NaNs give converged=false and a
// message naming the face); use result.edge_lengths (#E, in Connectivity's
// edge order) as the intrinsic metric to lay out. Errors in the inputs
// (wrong sizes, non-positive lengths, targets violating Gauss–Bonnet) throw
// InputError; a progress callback returning false throws Cancelled.
#include <array>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// Flat (genus 1, and the punctured sphere) or curvature −1 (genus >= 2).
enum class Background { Euclidean, Hyperbolic };
/// VertexScaling = discrete Yamabe (default); InversiveDistance = the paper's circle packing.
enum class RicciScheme { VertexScaling, InversiveDistance };
/// Newton with line search (default); the paper's explicit flow du/dt = K_target − K.
enum class RicciMethod { Newton, GradientFlow };

struct RicciFlowOptions {
  RicciScheme scheme = RicciScheme::VertexScaling;
  RicciMethod method = RicciMethod::Newton;
  /// Stop when max_i |K_i − target_i| <= tolerance.
  double tolerance = 1e-10;
  /// When Newton can make no further progress (the floating-point floor of
  /// the angle sums: nearly degenerate triangles, 10⁵ angles per sum) with a
  /// residual <= floor_tolerance, that is a converged result with
  /// stopped_at_floor = true (the residual and floor_estimate are reported),
  /// not a failure. Set it <= tolerance to demand the tolerance strictly.
  double floor_tolerance = 1e-7;
  /// 0: 100 for Newton, 200000 for the flow.
  int max_iterations = 0;
  /// Time step of the explicit flow u += flow_step (K_target − K).
  double flow_step = 0.1;
  /// Vertex scaling only (ignored for inversive distance): keep the
  /// triangulation intrinsically Delaunay during the solve — exact flips of
  /// the input metric first, then Ptolemy flips (docs/uniformization.md;
  /// the same for the hyperbolic metric). A flat / hyperbolic metric then exists for
  /// every mesh and admissible target (no degenerate triangles), but it
  /// lives on the flipped triangulation result.faces / result.edge_vertices,
  /// not on the input edges (check result.flips). Default false: fixed
  /// connectivity, result.edge_lengths in Connectivity's edge order.
  bool intrinsic_delaunay = false;
  /// Threads of the Newton solve's evaluations (default 1; 2: the per-face
  /// angles and Jacobian entries of each evaluation in two halves, summed in
  /// face order as with one, so the result is the same bits).
  int threads = 1;
  /// Called once per iteration with the current max curvature error; return
  /// false to cancel (ricci_flow then throws Cancelled).
  std::function<bool(int iteration, double residual)> progress;
};

/// One edge flip of the intrinsic Delaunay flow (RicciFlowOptions::intrinsic_delaunay),
/// enough to carry points back through it (uniformize/intrinsic_correspondence.h).
/// The quad's corners are slots 0..3 = (k, s, m, t), counter-clockwise; the
/// diagonal s–t becomes k–m. Before: face0's row holds k, s, t from column
/// corner0 on (F(face0, corner0) = k, next s, next t), face1's row m, t, s
/// from column corner1 on. After: face0 = (k, s, m), face1 = (m, t, k). Slots,
/// not vertex ids: after flips a vertex may be two corners of one quad.
struct EdgeFlip {
  int face0 = -1, face1 = -1;
  int corner0 = 0, corner1 = 0;
  /// Base (Penner) lengths l⁰ = the lengths in the u = 0 frame of the sides
  /// k–s, s–m, m–t, t–k, the old diagonal s–t and the new one k–m
  /// (hyperbolic: the chords 2 sinh(l/2)).
  std::array<double, 6> base_lengths{};
  /// True for the metric-preserving flips of the input metric before the
  /// solve (Euclidean: planar unfolding; hyperbolic: hyperbolic unfolding);
  /// false for the Ptolemy flips during the solve.
  bool exact = false;
  /// True for the exact flips of the FINAL metric made after the solve to
  /// make the triangulation simplicial (uniformize/simplicial_flips.h); they
  /// come last in the history, and base_lengths then hold the final metric's
  /// chords (Euclidean lengths; hyperbolic 2 sinh(l/2)).
  bool final_frame = false;
};

struct RicciFlowResult {
  bool converged = false;
  int iterations = 0;
  /// max_i |K_i − target_i| of the returned metric.
  double max_curvature_error = 0;
  /// True when the run stopped at the floating-point floor above the
  /// tolerance (but within options.floor_tolerance): converged, with
  /// max_curvature_error the achieved residual.
  bool stopped_at_floor = false;
  /// A priori round-off level of the angle sums at the final metric: max over
  /// vertices of machine epsilon × Σ over the corners of (Σ l²)/(2A) of the
  /// face (the relative round-off of the lengths propagated to the angles;
  /// large for nearly degenerate triangles). Diagnostic only.
  double floor_estimate = 0;
  /// max curvature error before each iteration (and the final one).
  std::vector<double> residual_history;
  /// #V conformal factors (start 0). Euclidean: defined up to a common
  /// constant; the solver keeps u_0 = 0 (Newton) / Σu = 0 (flow).
  Eigen::VectorXd u;
  /// #E final lengths, edge order of Connectivity (Euclidean or hyperbolic lengths).
  Eigen::VectorXd edge_lengths;
  Background background = Background::Euclidean;
  double time_s = 0;
  /// Why it failed, naming the element when there is one; empty on success.
  std::string message;
  /// Edge flips done (only with options.intrinsic_delaunay). The triangulation
  /// the final metric lives on: faces #F x 3 (same vertices), face_edges(f, k)
  /// = edge of the side opposite corner k, edge_vertices #E x 2. With
  /// flips == 0 these are the input faces and Connectivity's edges, and
  /// edge_lengths is indexed like edge_vertices either way.
  int flips = 0;
  /// The flips, in the order they were made (flips entries).
  std::vector<EdgeFlip> flip_history;
  /// Newton: preconditioned conjugate-gradient iterations (steps solved on
  /// an earlier step's factor) and numeric factorisations, over the run.
  int cg_iterations = 0;
  int factorisations = 0;
  /// Newton line-search trial points whose Delaunay flips ran past the
  /// per-pass limit (2 #E + 100): their flips were undone (not in flips or
  /// flip_history) and the step halved, as for an invalid trial metric.
  int rolled_back_trials = 0;
  RowMatrixX3i faces;
  RowMatrixX3i face_edges;
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> edge_vertices;
};

/// mesh: closed, oriented connectivity; edge_lengths: #E positive Euclidean
/// lengths satisfying the triangle inequality (e.g. edge_lengths(mesh, conn)).
/// target_curvature: #V (angle defect 2π − Σθ wanted at each vertex); empty =
/// all zero. Euclidean targets must sum to 2πχ; hyperbolic targets to more
/// than 2πχ (the excess is the hyperbolic area).
RicciFlowResult ricci_flow(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                           Background background, const RicciFlowOptions& options = {},
                           const Eigen::VectorXd& target_curvature = {});

/// The same from the conformal factors u_start (#V) instead of u = 0, e.g. a
/// coarse copy's solution prolonged to this mesh (uniformize/coarse_start.h).
/// The solution is the same within the tolerance (the energy is convex); with
/// intrinsic_delaunay the input is flipped to the Delaunay triangulation of
/// the metric at u_start first. Euclidean: u is shifted so that u_0 = 0.
RicciFlowResult ricci_flow_from(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                Background background, const RicciFlowOptions& options,
                                const Eigen::VectorXd& u_start, const Eigen::VectorXd& target_curvature = {});

/// The linearisation at u, for tests and for callers that need it: the
/// curvatures K (#V, angle defects of the metric given by u) and the Jacobian
/// dK/du (#V x #V, symmetric; the Hessian of the flow's energy). Triangles
/// violating the triangle inequality get angles (π, 0, 0) and contribute
/// nothing to the Jacobian; their count is `degenerate_faces`.
struct RicciLinearization {
  Eigen::VectorXd curvature;
  Eigen::SparseMatrix<double> jacobian;
  Eigen::VectorXd edge_lengths;  ///< #E lengths of the metric at u
  int degenerate_faces = 0;
};
RicciLinearization ricci_linearization(const Connectivity& mesh,
                                       const Eigen::VectorXd& edge_lengths,
                                       Background background, RicciScheme scheme,
                                       const Eigen::VectorXd& u);

/// 3D edge lengths of `mesh`, #E in the edge order of `conn`, intrinsically
/// mollified (geometry/mollify.h, default margin): identical to the Euclidean
/// lengths unless some face is (nearly) degenerate, which then gets a strict
/// triangle inequality (intake reports it as a note).
Eigen::VectorXd edge_lengths(const TriMesh& mesh, const Connectivity& conn);

}  // namespace surfmap
