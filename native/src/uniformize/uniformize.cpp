// One-call uniformization (uniformize.h).
#include "surfmap/uniformize/uniformize.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/feasible_metric.h"

namespace surfmap {
namespace {

std::string fmt(double x) {
  std::ostringstream s;
  s.precision(3);
  s << x;
  return s.str();
}

/// The layout must glue back together; anything else is a failed solve.
void check_layout(const DiskLayout& L, double tolerance) {
  // Positions are compared in coordinates; a metric with curvature error ε
  // shifts copies by about ε times the domain size, so allow a generous
  // multiple of the flow tolerance but never a visible gap.
  const double tol = std::max(1e-6, 1e4 * tolerance);
  if (L.num_flipped > 0)
    throw SolveError("uniformize: " + std::to_string(L.num_flipped) + " triangles are flipped in the layout");
  if (L.max_interior_mismatch > tol)
    throw SolveError("uniformize: the layout does not close up (interior edge mismatch " +
                     fmt(L.max_interior_mismatch) + ")");
  if (L.max_deck_inconsistency > tol)
    throw SolveError("uniformize: the deck maps of a loop disagree along its edges (" +
                     fmt(L.max_deck_inconsistency) + ")");
  // The matrix relation loses digits in proportion to relation_condition
  // (large for long fundamental domains) even when every point glues; only
  // an error beyond that is a failure.
  if (L.product_relation_error > tol * L.relation_condition)
    throw SolveError("uniformize: the generators violate the boundary-word relation (" +
                     fmt(L.product_relation_error) + ", condition " + fmt(L.relation_condition) + ")");
}

}  // namespace

UniformizeResult uniformize(const TriMesh& mesh, const UniformizeOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  UniformizeResult r;
  Connectivity input_conn(mesh.F, mesh.num_vertices());
  r.genus = input_conn.genus();
  RicciFlowOptions flow;
  flow.scheme = options.scheme;
  flow.method = options.method;
  flow.tolerance = options.tolerance;
  flow.max_iterations = options.max_iterations;
  flow.progress = options.progress;

  if (r.genus == 0) {
    r.kind = "spherical";
    SphericalUniformizationOptions so;
    so.removed_vertex = options.base_vertex;
    so.flow = flow;
    r.sphere = spherical_uniformization(mesh, so);
    if (!r.sphere.converged)
      throw SolveError("uniformize: spherical uniformization failed: " +
                       (r.sphere.message.empty() ? std::string("did not converge") : r.sphere.message));
    r.converged = true;
    r.iterations = r.sphere.flow_iterations;
    r.max_curvature_error = r.sphere.max_curvature_error;
    r.area = 4 * M_PI;
    r.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
  }

  SystemOfLoopsOptions lo;
  lo.base_vertex = options.base_vertex;
  r.loops = system_of_loops(mesh, lo);
  const Background bg = r.genus == 1 ? Background::Euclidean : Background::Hyperbolic;
  r.kind = r.genus == 1 ? "flat" : "hyperbolic";
  // Fixed connectivity, refined exactly when that metric does not exist
  // (uniformize/feasible_metric.h).
  FeasibleMetricOptions fo;
  fo.flow = flow;
  FeasibleMetricResult fm = feasible_metric(mesh, r.loops, bg, fo);
  r.loops = std::move(fm.loops);
  r.ricci = std::move(fm.flow);
  r.refinement_splits = fm.refinement_splits;
  const Connectivity conn(r.loops.mesh.F, r.loops.mesh.num_vertices());
  r.iterations = r.ricci.iterations;
  r.max_curvature_error = r.ricci.max_curvature_error;
  r.residual_history = r.ricci.residual_history;
  if (!r.ricci.converged)
    throw SolveError("uniformize: Ricci flow did not converge after " + std::to_string(r.ricci.iterations) +
                     " iterations (max curvature error " + fmt(r.ricci.max_curvature_error) + ")" +
                     (r.ricci.message.empty() ? std::string() : ": " + r.ricci.message));
  r.layout = layout_disk(conn, r.ricci.edge_lengths, bg, r.loops, options.layout);
  check_layout(r.layout, options.tolerance);
  r.area = r.layout.area;
  r.product_relation_error = r.layout.product_relation_error;
  if (r.genus == 1) {
    r.modulus = torus_modulus(r.layout.generator_translations[0], r.layout.generator_translations[1]);
    r.tau = r.modulus.tau;
    r.tau_reduced = r.modulus.tau_reduced;
  } else {
    r.generators = r.layout.generators;
  }
  r.converged = true;
  r.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace surfmap
