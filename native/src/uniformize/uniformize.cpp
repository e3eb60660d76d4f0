// One-call uniformization (uniformize.h).
#include "surfmap/uniformize/uniformize.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/feasible_metric.h"
#include "surfmap/uniformize/intrinsic_loops.h"
#include "surfmap/uniformize/simplicial_flips.h"

namespace surfmap {

using detail::seconds_since;

namespace {

std::string fmt(double x) {
  std::ostringstream s;
  s.precision(3);
  s << x;
  return s.str();
}

}  // namespace

double gluing_tolerance(const DiskLayout& L, double residual) {
  const double scale = std::sqrt(std::max(L.area, 0.0));
  return std::max(1e-6, 1e4 * residual) * scale + 1e3 * L.coordinate_roundoff;
}

double vertex_holonomy_tolerance(double residual) { return 1e-8 + 1e2 * residual; }

namespace {

/// The checks in per-face charts (DiskLayout::max_vertex_holonomy,
/// num_flipped_local), which hold for every layout of a converged metric,
/// wherever its faces lie.
void check_local(const DiskLayout& L, double residual) {
  if (L.num_flipped_local > 0)
    throw SolveError("uniformize: " + std::to_string(L.num_flipped_local) +
                     " triangles are flipped or folded over a neighbour in their per-face charts");
  const double tol = vertex_holonomy_tolerance(residual);
  if (!(L.max_vertex_holonomy <= tol))
    throw SolveError("uniformize: the transitions around a vertex do not close up (holonomy " +
                     fmt(L.max_vertex_holonomy) + ", tolerance " + fmt(tol) + ")");
}

/// The layout must glue back together; anything else is a failed solve.
/// Gluing gaps are judged relative to the layout's scale (DiskLayout::
/// gluing_tolerance): a metric with curvature error ε shifts copies by about
/// ε times the domain size, and coordinates far out in the Poincaré disk
/// carry round-off of coordinate_roundoff. A flipped triangle is always a
/// failure (a converged metric never has one).
void check_single_chart(const DiskLayout& L, double residual) {
  const double tol = gluing_tolerance(L, residual);
  if (L.num_flipped > 0)
    throw SolveError("uniformize: " + std::to_string(L.num_flipped) + " triangles are flipped in the layout");
  // Interior gaps, like deck gaps, are judged beyond the round-off of the
  // charts that place the two copies (DiskLayout::max_interior_excess).
  if (L.max_interior_excess > tol)
    throw SolveError("uniformize: the layout does not close up (interior edge mismatch " +
                     fmt(L.max_interior_mismatch) + ", tolerance " + fmt(tol) + " plus chart round-off up to " +
                     fmt(L.interior_roundoff) + ")");
  // Deck gaps are judged beyond the round-off of evaluating the side
  // pairing at each point (DiskLayout::max_deck_excess): near |z| = 1 that
  // round-off alone exceeds any fixed tolerance (genus 11: 2e-4).
  if (L.max_deck_excess > tol)
    throw SolveError("uniformize: the deck maps of a loop disagree along its edges (" +
                     fmt(L.max_deck_inconsistency) + ", tolerance " + fmt(tol) + " at layout scale " +
                     fmt(std::sqrt(L.area)) + " plus evaluation round-off up to " + fmt(L.deck_roundoff) + ")");
  if (L.max_corner_inconsistency > tol * L.corner_condition)
    throw SolveError("uniformize: the side pairings do not carry the base corner to the polygon's corners (" +
                     fmt(L.max_corner_inconsistency) + ", condition " + fmt(L.corner_condition) + ")");
  // The matrix relation loses digits in proportion to relation_condition
  // (large for long fundamental domains) even when every point glues; only
  // an error beyond that is a failure.
  if (L.product_relation_error > tol * L.relation_condition)
    throw SolveError("uniformize: the generators violate the boundary-word relation (" +
                     fmt(L.product_relation_error) + ", condition " + fmt(L.relation_condition) + ")");
}

}  // namespace

/// All checks of a layout (docs/robustness.md "High genus"). The per-face checks always; then the
/// single chart's. A hyperbolic layout with faces its coordinates cannot resolve (DiskLayout::
/// num_unresolved: a domain reaching 37 .. 73 from the centre puts corners where 1 − |z| is below
/// double resolution) is never held by the single chart, even when its checks pass: whether the
/// slivers out there turn over is decided by round-off (the genus-13 plate: 2, 1 or none flipped as
/// the flow's angles were computed one way or another, with the metric the same to 1e-12), and the
/// single chart's readers (location, the harmonic map) refuse such a layout anyway (map_support.cpp
/// require_single_chart). Its failure is then the coordinates', not the metric's: the per-face
/// checks decide, provided no triangle taller than its corners' round-off is flipped. Returns true
/// when the single chart passed (UniformizeResult::single_chart), false with `why` set to its
/// failure otherwise.
bool check_layout(const DiskLayout& L, double residual, std::string* why) {
  check_local(L, residual);
  const bool unresolved = L.background == Background::Hyperbolic && L.num_unresolved > 0;
  try {
    check_single_chart(L, residual);
    if (!unresolved) return true;
    throw SolveError("uniformize: " + std::to_string(L.num_unresolved) +
                     " triangles are below the round-off of the layout's coordinates (layout radius " +
                     fmt(L.layout_radius) + ")");
  } catch (const SolveError& e) {
    if (!unresolved) throw;
    if (L.num_flipped_above_roundoff > 0)
      throw SolveError("uniformize: " + std::to_string(L.num_flipped_above_roundoff) +
                       " triangles taller than their coordinates' round-off are flipped in the layout");
    if (why) *why = e.what();
    return false;
  }
}

namespace {

/// A hyperbolic layout held by per-face charts only, laid out again on the
/// same loops centred on the domain's 1-centre instead of the Karcher mean
/// of its corners (LayoutOptions::minimax_centre); kept when the single
/// chart holds it then, or when still per-face only but more compact (fewer
/// triangles below the round-off). Layouts the single chart holds are not
/// touched, so their results stay as they were. The genus-13 CAD plate: 36.8
/// -> 28.0 from the centre, 505 -> 20 unresolved triangles, still per-face
/// charts (2 slivers below their round-off flipped; issue 13).
void recentre_on_minimax(double residual, Background background, const LayoutOptions& layout_options,
                         LoopsLayout& r) {
  if (background != Background::Hyperbolic || r.single_chart || r.layout.genus == 0 || !layout_options.recentre ||
      layout_options.minimax_centre)
    return;
  // No centre is nearer than half the domain's diameter to every corner: when
  // the layout's radius is already within one unit of half a lower bound on
  // it (two sweeps over the faces' charts, distances read off the matrices),
  // laying out again cannot gain (the plates of genus 16 and up: 38 of 76,
  // 55.5 of 111).
  const std::vector<hyperbolic::Mobius>& chart = r.layout.face_charts;
  auto farthest = [&](int from, double& d) {
    const hyperbolic::Mobius inv = chart[from].inverse();
    int best = from;
    d = 0;
    for (size_t f = 0; f < chart.size(); ++f) {
      const double df = (inv * chart[f]).displacement_of_origin();
      if (df > d) d = df, best = static_cast<int>(f);
    }
    return best;
  };
  double diameter = 0;
  if (chart.empty()) return;
  farthest(farthest(0, diameter), diameter);
  if (r.layout.layout_radius < diameter / 2 + 1.0) return;
  LayoutOptions lo = layout_options;
  lo.minimax_centre = true;
  try {
    const Connectivity conn(r.loops.mesh.F, r.loops.mesh.num_vertices());
    DiskLayout layout = layout_disk(conn, r.lengths, background, r.loops, lo);
    std::string why;
    const bool single = check_layout(layout, residual, &why);  // throws when per-face charts fail too
    // Held by the single chart now, or still by per-face charts only but
    // more compact (fewer triangles below the coordinates' round-off).
    if (!single && layout.layout_radius >= r.layout.layout_radius) return;
    r.layout = std::move(layout);
    r.single_chart = single;
    r.single_chart_failure = why;
  } catch (const SolveError&) {
    // the Karcher-centred layout stays (it passed its per-face checks)
  }
}

}  // namespace

LoopsLayout lay_out_loops(const TriMesh& mesh, const RicciFlowResult& flow, Background background,
                          const SystemOfLoopsOptions& loop_options, SystemOfLoops loops, Eigen::VectorXd lengths,
                          std::string loop_metric, bool may_switch, const LayoutOptions& layout_options,
                          double crowded_roundoff) {
  const double residual = flow.max_curvature_error;
  LoopsLayout r;
  r.loops = std::move(loops);
  r.lengths = std::move(lengths);
  r.loop_metric = std::move(loop_metric);
  std::string embedding_failure;
  try {
    const Connectivity conn(r.loops.mesh.F, r.loops.mesh.num_vertices());
    r.layout = layout_disk(conn, r.lengths, background, r.loops, layout_options);
    r.single_chart = check_layout(r.layout, residual, &r.single_chart_failure);
    if (may_switch && !r.single_chart)
      embedding_failure = "checked in per-face charts only (" + r.single_chart_failure + ")";
    else if (may_switch && r.layout.coordinate_roundoff > crowded_roundoff)
      embedding_failure = "coordinate round-off " + fmt(r.layout.coordinate_roundoff);
  } catch (const SolveError& e) {
    if (!may_switch) throw;
    embedding_failure = e.what();
    r.layout = DiskLayout{};
  }
  if (embedding_failure.empty()) {
    recentre_on_minimax(residual, background, layout_options, r);
    return r;
  }
  const bool embedding_ok = r.layout.genus > 0;
  try {
    IntrinsicLoops il = intrinsic_loops(mesh, flow, background, loop_options, true);
    DiskLayout layout = layout_disk(*il.conn, il.lengths, background, il.loops, layout_options);
    std::string why;
    const bool single = check_layout(layout, residual, &why);
    // A layout the single chart holds beats one it does not; then the
    // more compact one (coordinate round-off grows like e^radius).
    const bool better = single != r.single_chart ? single
                                                 : layout.coordinate_roundoff < r.layout.coordinate_roundoff;
    if (!embedding_ok || better) {
      r.layout = std::move(layout);
      r.loops = std::move(il.loops);
      r.lengths = std::move(il.lengths);
      r.loop_metric = "metric (embedding loops: " + embedding_failure + ")";
      r.single_chart = single;
      r.single_chart_failure = why;
    }
  } catch (const SolveError& e) {
    if (!embedding_ok) throw SolveError(embedding_failure + "; on loops shortest in the metric: " + e.what());
  }
  recentre_on_minimax(residual, background, layout_options, r);
  return r;
}

namespace {

/// uniformize() for one metric (options.metric: IntrinsicDelaunay, or
/// Automatic read as it, or FixedConnectivity); any failure is a SolveError.
UniformizeResult uniformize_one_metric(const TriMesh& mesh, const UniformizeOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  UniformizeResult r;
  Connectivity input_conn(mesh.F, mesh.num_vertices());
  r.genus = input_conn.genus();
  RicciFlowOptions flow;
  flow.scheme = options.scheme;
  flow.method = options.method;
  flow.tolerance = options.tolerance;
  flow.max_iterations = options.max_iterations;
  flow.floor_tolerance = options.floor_tolerance;
  flow.progress = options.progress;

  if (r.genus == 0) {
    r.kind = "spherical";
    SphericalUniformizationOptions so;
    so.removed_vertex = options.base_vertex;
    so.flow = flow;
    so.intrinsic_delaunay = options.metric != UniformizationMetric::FixedConnectivity;
    r.sphere = spherical_uniformization(mesh, so);
    if (!r.sphere.converged)
      throw SolveError("uniformize: spherical uniformization failed: " +
                       (r.sphere.message.empty() ? std::string("did not converge") : r.sphere.message));
    r.converged = true;
    r.iterations = r.sphere.flow_iterations;
    r.max_curvature_error = r.sphere.max_curvature_error;
    r.stopped_at_floor = r.sphere.stopped_at_floor;
    r.edge_flips = r.sphere.edge_flips + r.sphere.ring_flips;
    r.area = 4 * M_PI;
    r.time_s = seconds_since(t0);
    return r;
  }

  SystemOfLoopsOptions lo;
  lo.base_vertex = options.base_vertex;
  const Background bg = r.genus == 1 ? Background::Euclidean : Background::Hyperbolic;
  r.kind = r.genus == 1 ? "flat" : "hyperbolic";
  Eigen::VectorXd lengths;  // the metric on r.loops.mesh, edge order of its Connectivity
  bool intrinsic_loops_failed = false;
  const bool flips = options.metric != UniformizationMetric::FixedConnectivity &&
                     options.scheme == RicciScheme::VertexScaling && options.method == RicciMethod::Newton;
  if (flips) {
    // Default: Newton with Ptolemy flips on the input's vertices (a metric
    // always exists), loops on the intrinsic triangulation
    // (uniformize/intrinsic_loops.h).
    r.metric = "intrinsic Delaunay";
    flow.intrinsic_delaunay = true;
    r.ricci = ricci_flow(input_conn, edge_lengths(mesh, input_conn), bg, flow);
    r.edge_flips = r.ricci.flips;
    if (r.ricci.converged && !is_simplicial(r.ricci)) {
      // T' is a Δ-complex (loops or double edges after Ptolemy flips): exact
      // flips of the final metric make it simplicial without changing the
      // metric (uniformize/simplicial_flips.h).
      const SimplicialFlipsResult sf = make_simplicial(r.ricci);
      r.edge_flips = r.ricci.flips;
      r.metric += " (" + std::to_string(sf.loop_edges) + " loop and " + std::to_string(sf.multiple_edges) +
                  " multiple edges of T' removed by " + std::to_string(sf.flips) + " exact flips of the final metric" +
                  (sf.simplicial ? "" : ", not all") + ")";
    }
    if (r.ricci.converged) {
      try {
        const bool in_metric = options.loops == LoopMetric::Metric && r.genus >= 2;
        IntrinsicLoops il = intrinsic_loops(mesh, r.ricci, bg, lo, in_metric);
        r.loop_metric = in_metric ? "metric" : "embedding";
        r.loops = std::move(il.loops);
        lengths = std::move(il.lengths);
      } catch (const SolveError& e) {
        // T' not simplicial (rare): the fixed-connectivity path below.
        r.metric = std::string("fixed connectivity (intrinsic loops failed: ") + e.what() + ")";
        intrinsic_loops_failed = true;
        r.edge_flips = 0;  // the metric laid out is the fixed one
      }
    }
  }
  if (lengths.size() == 0 && (!flips || r.ricci.converged)) {
    r.loops = system_of_loops(mesh, lo);
    if (!flips) r.metric = "fixed connectivity";
    // Fixed connectivity, refined exactly when that metric does not exist
    // (uniformize/feasible_metric.h) unless the refinement is switched off.
    FeasibleMetricOptions fo;
    fo.flow = flow;
    fo.flow.intrinsic_delaunay = false;
    // The fallback after the flip path's loops failed is refined whenever
    // the fixed metric does not exist: that is why the flips were needed
    // (issue 13: the genus-3 CAD plate's flipped triangulation has a double
    // edge, and its unrefined fixed metric has 12 degenerate faces).
    if (!options.fixed_connectivity_refinement && !intrinsic_loops_failed) fo.refine_max_angles.clear();
    FeasibleMetricResult fm = feasible_metric(mesh, r.loops, bg, fo);
    r.loops = std::move(fm.loops);
    r.ricci = std::move(fm.flow);
    r.refinement_splits = fm.refinement_splits;
    lengths = r.ricci.edge_lengths;
    r.loop_metric = "embedding";
  }
  r.iterations = r.ricci.iterations;
  r.max_curvature_error = r.ricci.max_curvature_error;
  r.stopped_at_floor = r.ricci.stopped_at_floor;
  r.floor_estimate = r.ricci.floor_estimate;
  r.residual_history = r.ricci.residual_history;
  if (!r.ricci.converged)
    throw SolveError("uniformize: Ricci flow did not converge after " + std::to_string(r.ricci.iterations) +
                     " iterations (max curvature error " + fmt(r.ricci.max_curvature_error) + ")" +
                     (r.ricci.message.empty() ? std::string() : ": " + r.ricci.message));
  // The layout on the loops found above; Automatic, genus >= 2, flip path:
  // again on loops shortest in the metric when it fails or crowds |z| = 1.
  const bool may_switch = options.loops == LoopMetric::Automatic && r.genus >= 2 && r.loop_metric == "embedding" &&
                          flips && !intrinsic_loops_failed;
  LoopsLayout laid = lay_out_loops(mesh, r.ricci, bg, lo, std::move(r.loops), std::move(lengths),
                                   std::move(r.loop_metric), may_switch, options.layout, options.crowded_roundoff);
  r.loops = std::move(laid.loops);
  lengths = std::move(laid.lengths);
  r.layout = std::move(laid.layout);
  r.loop_metric = std::move(laid.loop_metric);
  r.single_chart = laid.single_chart;
  r.layout_checks = r.single_chart ? "single chart"
                                   : "per-face charts (the single chart's coordinates cannot resolve " +
                                         std::to_string(r.layout.num_unresolved) + " triangles at up to " +
                                         fmt(r.layout.layout_radius) + " from the centre: " +
                                         laid.single_chart_failure + ")";
  r.edge_lengths = lengths;
  r.gluing_tolerance = gluing_tolerance(r.layout, r.max_curvature_error);
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
  r.time_s = seconds_since(t0);
  return r;
}

/// uniformize_one_metric with its failures as UniformizationError (the
/// message unchanged): every step of the chain (flow, loops, layout, checks)
/// throws SolveError, and all of them mean that no metric was delivered.
UniformizeResult uniformize_typed(const TriMesh& mesh, const UniformizeOptions& options) {
  try {
    return uniformize_one_metric(mesh, options);
  } catch (const UniformizationError&) {
    throw;
  } catch (const SolveError& e) {
    throw UniformizationError(e.what());
  }
}

}  // namespace

UniformizeResult uniformize(const TriMesh& mesh, const UniformizeOptions& options) {
  if (options.metric != UniformizationMetric::FixedFirst) return uniformize_typed(mesh, options);
  // Fixed connectivity first; the flip-based metric only when that one
  // throws (docs/uniformization.md "Which target metric runs").
  UniformizeOptions fixed = options;
  fixed.metric = UniformizationMetric::FixedConnectivity;
  std::string fixed_failure;
  try {
    return uniformize_typed(mesh, fixed);
  } catch (const UniformizationError& e) {
    fixed_failure = e.what();
  }
  UniformizeOptions flips = options;
  flips.metric = UniformizationMetric::IntrinsicDelaunay;
  UniformizeResult r = uniformize_typed(mesh, flips);
  r.metric += " (fixed connectivity failed: " + fixed_failure + ")";
  return r;
}

}  // namespace surfmap
