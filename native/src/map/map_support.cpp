#include "map_support.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <memory>
#include <optional>

#include "surfmap/error.h"
#include "surfmap/map/initial_map.h"
#include "surfmap/mesh/exact_refinement.h"
#include "surfmap/uniformize/feasible_metric.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/uniformize/carried_loops.h"
#include "surfmap/uniformize/coarse_start.h"
#include "surfmap/uniformize/intrinsic_loops.h"
#include "surfmap/uniformize/simplicial_flips.h"
#include "concurrency.h"

namespace surfmap::detail {
namespace {

// The input face that contains refined face rf: among the faces around its
// vertices' origins, the one whose plane holds the centroid with all
// barycentrics >= -eps. Refined faces lie inside input faces.
int containing_input_face(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& s, int rf,
                          Eigen::Vector3d* bary_of_centroid) {
  const Eigen::Vector3d c =
      (s.mesh.V.row(s.mesh.F(rf, 0)) + s.mesh.V.row(s.mesh.F(rf, 1)) + s.mesh.V.row(s.mesh.F(rf, 2))) / 3.0;
  std::vector<int> candidates;
  for (int k = 0; k < 3; ++k) {
    const int v = s.mesh.F(rf, k);
    candidates.push_back(s.origin_face[v]);
    if (v < input.num_vertices())
      for (int h : ic.outgoing(v)) candidates.push_back(Connectivity::face(h));
    else
      for (int k2 = 0; k2 < 3; ++k2) {  // faces across the origin face's edges
        const int h = 3 * s.origin_face[v] + k2;
        candidates.push_back(Connectivity::face(ic.twin(h)));
      }
  }
  int best = -1;
  double best_score = -std::numeric_limits<double>::infinity();
  for (int f : candidates) {
    const Eigen::Vector3d p0 = input.V.row(input.F(f, 0)), p1 = input.V.row(input.F(f, 1)),
                          p2 = input.V.row(input.F(f, 2));
    const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
    const double n2 = n.squaredNorm();
    if (n2 <= 0) continue;
    const Eigen::Vector3d b((p1 - c).cross(p2 - c).dot(n) / n2, (p2 - c).cross(p0 - c).dot(n) / n2,
                            (p0 - c).cross(p1 - c).dot(n) / n2);
    const double off_plane = std::abs((c - p0).dot(n)) / std::sqrt(n2);
    const double score = b.minCoeff() - off_plane / std::sqrt(std::sqrt(n2));
    if (score > best_score) best_score = score, best = f, *bary_of_centroid = b;
  }
  return best;
}

}  // namespace

PointOnSurface point_in_face(const TriMesh& m, int f, Eigen::Vector3d b) {
  b = b.cwiseMax(0.0);
  b /= b.sum();
  PointOnSurface ps;
  ps.face = f;
  ps.barycentric = b;
  ps.position = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) ps.position += b[k] * m.V.row(m.F(f, k)).transpose();
  return ps;
}

TargetIntrinsic::TargetIntrinsic(const RicciFlowResult& flow, int nv)
    : faces(flow.faces), conn(flow.faces, nv), correspondence(flow), num_input_vertices(nv) {}

PointOnSurface point_on_input(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& s,
                              const TargetIntrinsic* intrinsic, std::vector<int>& cache, int rf,
                              const Eigen::Vector3d& b) {
  if (intrinsic) {
    Eigen::Vector3d w = b.cwiseMax(0.0);
    w /= w.sum();
    const FacePoint on_t = intrinsic_face_point(s, intrinsic->faces, intrinsic->conn,
                                                intrinsic->num_input_vertices, rf, w);
    const FacePoint on_input = intrinsic->correspondence.to_input(on_t.face, on_t.barycentric);
    return point_in_face(input, on_input.face, on_input.barycentric);
  }
  PointOnSurface ps = point_in_face(s.mesh, rf, b);
  if (cache[rf] < 0) {
    Eigen::Vector3d unused;
    cache[rf] = containing_input_face(input, ic, s, rf, &unused);
  }
  ps.face = cache[rf];
  ps.barycentric = barycentric_in_input_face(input, ps.face, ps.position);
  return ps;
}

CanonicalSchemaOptions schema_options(const SurfaceMapOptions& options) {
  CanonicalSchemaOptions o;
  o.short_generators = options.loops.short_canonical_generators;
  return o;
}

CanonicalSchemaOptions other_schema_options(const SurfaceMapOptions& options) {
  CanonicalSchemaOptions o = schema_options(options);
  o.short_generators = !o.short_generators;
  return o;
}

ClassLoops own_class_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoopsOptions& lo,
                           const SystemOfLoops* own_loops, const CanonicalSchemaOptions& schema) {
  ClassLoops cl;
  // The greedy basis once per mesh and base vertex (issue 19): the caller's
  // unrefined loops of this mesh, refined, are these loops.
  const bool reuse = own_loops && (lo.base_vertex < 0 || lo.base_vertex == own_loops->base_vertex);
  cl.loops = reuse ? refine_system_of_loops(mesh, conn, *own_loops, lo) : system_of_loops(mesh, conn, lo);
  cl.word = cl.loops.word;
  const auto first = std::find(cl.word.begin(), cl.word.end(), 1);
  if (first == cl.word.end()) throw SolveError("the target's loops have no letter 1 in their word");
  std::rotate(cl.word.begin(), first, cl.word.end());
  cl.schema = canonical_schema(cl.word, schema);
  return cl;
}

namespace {

/// The location and the harmonic map read the target's layout in its one
/// Poincaré chart (corners, deck elements as matrices); a domain reaching
/// farther than double coordinates resolve (issue 13: CAD plates of genus
/// 13 .. 24, 37 .. 73 from the centre) would be read as garbage, so it is
/// refused here (uniformize itself checks such layouts in per-face charts:
/// UniformizeResult::single_chart). When the per-face checks hold (no face
/// flipped in its neighbours' charts, none taller than its corners' round-off
/// flipped in the chart) the layout is valid and its reach is the surface's
/// metric, not this path's: SingleChartError, which no metric fallback
/// catches (the fixed-connectivity path, exactly refined, would lay out the
/// same surface as far out, after minutes of refinement: genus-13 plate,
/// more than 300 s). Otherwise the layout is broken, a SolveError like any
/// other, so the other metric path is tried. `mesh`: "source" or "target".
void require_single_chart(const DiskLayout& layout, Background background, const std::string& mesh) {
  if (background != Background::Hyperbolic || layout.num_unresolved == 0) return;
  const std::string where = "the " + mesh + " mesh's hyperbolic layout reaches " + std::to_string(layout.layout_radius) +
                            " from the centre of the Poincare disk (layout radius), where " +
                            std::to_string(layout.num_unresolved) +
                            " of its triangles are below the round-off of double coordinates";
  if (layout.num_flipped_local == 0 && layout.num_flipped_above_roundoff == 0)
    throw SingleChartError(where + ": maps of surfaces this long in their metric need per-face charts (the layout "
                                   "itself is valid in per-face charts; face_charts 'auto' maps the snapped class "
                                   "there)",
                           mesh, layout.layout_radius);
  throw SolveError(where + ", and " + std::to_string(layout.num_flipped_local) + " flipped in per-face charts, " +
                   std::to_string(layout.num_flipped_above_roundoff) + " taller than their round-off flipped");
}

/// The target's own loops (own_class_loops) and their words on T'
/// (carry_loops_through_flips): combinatorial, they need neither the metric
/// nor the layout, so the pipeline builds them next to the flow and the
/// layout (intrinsic_target).
struct OwnLoopsOnTPrime {
  ClassLoops cl;
  CarriedLoops carried;
};

/// The target's loops on its own connectivity, carried onto T' (ClassLoops),
/// from their words on T' and the layout's word. Throws SolveError when the
/// carried generators do not present the group of T' (the canonical
/// relation, unimodular homology): that would be a bug.
std::shared_ptr<const ClassLoops> class_loops_on_input(OwnLoopsOnTPrime own, const DiskLayout& layout) {
  auto cl = std::make_shared<ClassLoops>(std::move(own.cl));
  const CarriedLoops& carried = own.carried;
  cl->flips_on_loops = carried.flips_on_loops;
  cl->longest_edge_path = carried.longest_edge_path;
  const DehnReducer reduce(layout.word);
  const int n = static_cast<int>(carried.words.size());
  for (const Word& g : cl->schema.generators) cl->generators_in_layout_letters.push_back(reduce(substitute(g, carried.words)));
  if (!reduce(commutator_product(cl->generators_in_layout_letters)).empty())
    throw SolveError("the carried loops break the canonical relation on T'");
  const double det = homology_matrix(cl->generators_in_layout_letters, n).cast<double>().determinant();
  if (std::abs(std::abs(det) - 1.0) > 1e-9)
    throw SolveError("the carried loops' homology has determinant " + std::to_string(det) + ", not +-1");
  return cl;
}

/// The flow's per-Newton-step hook of intrinsic_target: false once `stop` is
/// set; for the target (`mesh` "target") also the map's progress callback,
/// as stage "target uniformization". Session 26 (ui26): the target's flow is
/// the first long stage of a map (7 of 14 s on a 123k -> 174k vertex genus-2
/// pair) and reported nothing, so a progress bar sat at 0% and a cancel
/// waited for the stage's end. The fraction runs from 0 to
/// kTargetFlowFraction as the residual falls from its first value to the
/// tolerance on a log scale (Newton's steps), never backwards (the coarse
/// start's flow and the flow from u = 0 share it). The source's flow (the
/// class bounds, on the second thread) reports nothing: its stage is not
/// the one the caller shows.
constexpr double kTargetFlowFraction = 0.25;  // (the stage ends at 0.3 in every pipeline)
std::function<bool(int, double)> flow_progress(const SurfaceMapOptions& options, const std::atomic<bool>* stop,
                                               const std::string& mesh) {
  const auto report = mesh == "target" ? options.progress : nullptr;
  if (!stop && !report) return nullptr;
  struct Shown {
    double first = 0, fraction = 0;
  };
  auto shown = std::make_shared<Shown>();
  const double tolerance = options.uniformization.tolerance;
  return [stop, report, shown, tolerance](int, double residual) {
    if (stop && stop->load()) return false;
    if (!report) return true;
    if (shown->first <= 0) shown->first = residual;
    const double first = shown->first, floor = std::max(tolerance, 1e-300);
    if (first > floor && residual > 0) {
      const double f = std::log(first / std::max(residual, floor)) / std::log(first / floor);
      shown->fraction = std::max(shown->fraction, std::clamp(f, 0.0, 1.0));
    }
    return report("target uniformization", kTargetFlowFraction * shown->fraction);
  };
}

/// The flip-based path of uniformized_target: Newton with intrinsic Delaunay
/// flips on the user's target, loops on T' (uniformize/intrinsic_loops.h),
/// disk layout. Throws SolveError when any step fails (typed_target makes it
/// a UniformizationError).
UniformizedTarget intrinsic_target(const TriMesh& target, const Connectivity& tc, Background background,
                                   const SurfaceMapOptions& options, const SystemOfLoopsOptions& lo,
                                   const std::atomic<bool>* stop, const std::string& mesh,
                                   const SystemOfLoops* own_loops, bool class_loops) {
  UniformizedTarget t;
  const bool hyperbolic = background == Background::Hyperbolic;
  const bool with_class_loops = hyperbolic && class_loops;
  const int threads = pipeline_threads(options.threads);
  // Issue 19: the handle classes' loops (the target's own, carried onto T')
  // are combinatorial: with two threads the own loops are built next to the
  // flow and carried through its flips next to the layout, off the stage's
  // critical path (~0.2 s of CPU on a 56k target). Errors surface at get(),
  // where the sequential path's would. Each future is declared after
  // everything its task reads, so that an exception waits for the task
  // before those go.
  std::future<ClassLoops> own_future;
  if (with_class_loops && threads > 1)
    own_future = std::async(std::launch::async, [&] { return own_class_loops(target, tc, lo, own_loops, schema_options(options)); });
  RicciFlowOptions fo;
  fo.tolerance = options.uniformization.tolerance;
  fo.intrinsic_delaunay = true;
  // The evaluations' per-face loop in two halves (the same bits as one).
  fo.threads = threads;
  fo.progress = flow_progress(options, stop, mesh);
  const Eigen::VectorXd lengths = edge_lengths(target, tc);
  // Issue 19: Newton from a coarse copy's solution, prolonged (the same
  // metric within the tolerance, fewer Newton steps and CG iterations on
  // large targets). Session 18: the flow first reads the energy's slopes
  // along the segment from u = 0 to the start and starts from u = 0 when
  // the start overshoots that segment's minimum (irregular meshes, whose
  // copy's u is a poor guess: the vhacd teapot took 13 Newton steps from it,
  // 7 from u = 0), then the run from u = 0 bit for bit
  // (ricci_flow_from_checked). Should a run from the start not converge,
  // the flow from u = 0 decides.
  CoarseStartOptions co;
  co.threads = threads;  // (its flow's evaluations in two halves: the same bits)
  const CoarseStart start = coarse_conformal_start(target, tc, background, co);
  RicciFlowResult flow;
  bool done = false;
  if (start.ok) {
    try {
      CheckedFlow checked = ricci_flow_from_checked(tc, lengths, background, fo, start.u);
      flow = std::move(checked.flow);
      done = flow.converged || !checked.start.start_used;
    } catch (const SolveError&) {
      // (the flow from u = 0 below reports its own failure, if any)
    }
  }
  if (!done) flow = ricci_flow(tc, lengths, background, fo);
  if (!flow.converged) throw SolveError("the flow did not converge: " + flow.message);
  // A Δ-complex T' (loop or double edges) made simplicial by exact flips of
  // the final metric, as in uniformize (uniformize/simplicial_flips.h).
  if (!is_simplicial(flow)) make_simplicial(flow);
  // The loops and layout chosen as uniformize chooses them (lay_out_loops:
  // checked like uniformize's; for genus >= 2 by default again on loops
  // shortest in the metric when the 3D loops' layout fails or crowds
  // |z| = 1, where the forward location misplaced whole regions).
  const LoopMetric which = options.uniformization.loops;
  const bool in_metric = hyperbolic && which == LoopMetric::Metric;
  IntrinsicLoops il = intrinsic_loops(target, flow, background, lo, in_metric);
  const std::string loop_metric = in_metric ? "metric" : "embedding";
  // The own loops' words on T' read T''s loops and faces only.
  auto carry = [&](ClassLoops cl, const SystemOfLoops& tprime_loops) {
    OwnLoopsOnTPrime r{std::move(cl), CarriedLoops{}};
    r.carried = carry_loops_through_flips(target, r.cl.loops, flow, tprime_loops);
    return r;
  };
  std::future<OwnLoopsOnTPrime> carried_future;
  if (own_future.valid())
    carried_future = std::async(std::launch::async, [&, tprime = il.loops]() mutable {
      return carry(own_future.get(), tprime);
    });
  LayoutOptions layout_options;
  layout_options.threads = threads;
  LoopsLayout laid = lay_out_loops(target, flow, background, lo, std::move(il.loops), std::move(il.lengths),
                                   loop_metric, hyperbolic && which == LoopMetric::Automatic, layout_options,
                                   UniformizeOptions{}.crowded_roundoff);
  // (lay_out_loops keeps T''s loops unless their layout failed or crowded
  // |z| = 1: then they are the loops shortest in the metric.)
  const bool same_tprime_loops = laid.loop_metric == loop_metric;
  t.loops = std::move(laid.loops);
  t.layout = std::move(laid.layout);
  t.loop_metric = std::move(laid.loop_metric);
  require_single_chart(t.layout, background, mesh);
  t.intrinsic = std::make_shared<const TargetIntrinsic>(flow, target.num_vertices());
  // The refined vertices at their points of the user's target (intrinsic_loops
  // interpolates them on T' chords, off the surface): the handle-class
  // machinery reads the loops' mesh in 3D (nearest vertices, handle positions).
  SystemOfLoops& s = t.loops;
  for (int v = target.num_vertices(); v < s.mesh.num_vertices(); ++v) {
    const FacePoint p = t.intrinsic->correspondence.to_input(s.origin_face[v], s.origin_barycentric.row(v).transpose());
    s.mesh.V.row(v) = point_in_face(target, p.face, p.barycentric).position.transpose();
  }
  // The handle classes read the loops of the user's own connectivity, as on
  // the fixed path (docs/uniformization.md "Handle classes on the flip
  // path"); when carrying them fails the classes read the loops of T'.
  if (with_class_loops) {
    try {
      OwnLoopsOnTPrime own;
      if (carried_future.valid() && same_tprime_loops) {
        own = carried_future.get();
      } else {
        // No task, or it carried the loops on T''s loops the layout did not
        // keep: carried here on the kept ones.
        std::optional<ClassLoops> cl;
        if (carried_future.valid()) {
          try {
            cl = std::move(carried_future.get().cl);
          } catch (const Error&) {
            // (built and carried again below, which reports the error)
          }
        }
        if (!cl) cl = own_class_loops(target, tc, lo, own_loops, schema_options(options));
        own = carry(std::move(*cl), t.loops);
      }
      t.class_loops = class_loops_on_input(std::move(own), t.layout);
      t.class_loops_status = "the target's own loops, carried through " + std::to_string(t.class_loops->flips_on_loops) +
                             " of the flips";
    } catch (const Error& e) {
      t.class_loops_status = std::string("the loops of T' (carrying the target's own loops failed: ") + e.what() + ")";
    }
  }
  t.flips = flow.flips;
  t.metric = "intrinsic Delaunay";
  return t;
}

/// The fixed-connectivity path of uniformized_target: the metric on the
/// target's own (loops-refined) edges, refined exactly when it does not exist
/// and `refine` is set (uniformize/feasible_metric.h); the layout and location
/// only see a refined system of loops with origins on the user's target.
/// Throws SolveError when the flow does not converge or the layout flips
/// (typed_target makes it a UniformizationError); `flip_failure` (non-empty:
/// the flip path failed first) goes in both.
UniformizedTarget fixed_target(const TriMesh& target, Background background, const SurfaceMapOptions& options,
                               const SystemOfLoopsOptions& lo, bool refine, const std::string& flip_failure,
                               const std::string& mesh) {
  UniformizedTarget t;
  t.metric = flip_failure.empty() ? "fixed connectivity"
                                  : "fixed connectivity (intrinsic Delaunay failed: " + flip_failure + ")";
  t.loops = system_of_loops(target, lo);
  FeasibleMetricOptions fo;
  fo.flow.tolerance = options.uniformization.tolerance;
  if (!refine) fo.refine_max_angles.clear();
  FeasibleMetricResult fm = feasible_metric(target, t.loops, background, fo);
  const RicciFlowResult& flow = fm.flow;
  if (!flow.converged)
    throw SolveError("target uniformization did not converge: " + flow.message +
                     (fm.refinement_splits > 0 ? " (after refining the target exactly: " +
                                                     std::to_string(fm.refinement_splits) + " splits; unrefined: " +
                                                     fm.unrefined_failure + ")"
                                               : std::string()) +
                     (flip_failure.empty() ? std::string() : "; intrinsic Delaunay path: " + flip_failure));
  t.loops = std::move(fm.loops);
  t.refinement_splits = fm.refinement_splits;
  t.refinement_max_angle = fm.refinement_max_angle;
  const Connectivity conn(t.loops.mesh.F, t.loops.mesh.num_vertices());
  t.layout = layout_disk(conn, flow.edge_lengths, background, t.loops);
  require_single_chart(t.layout, background, mesh);
  if (t.layout.num_flipped > 0)
    throw SolveError("target layout has " + std::to_string(t.layout.num_flipped) + " flipped triangles");
  return t;
}

/// One path of uniformized_target with its failures typed: every step of
/// either chain (flow, loops, layout) throws SolveError, and any of them
/// means this metric was not delivered: UniformizationError, message kept.
template <class Path>
UniformizedTarget typed_target(const Path& path) {
  try {
    return path();
  } catch (const UniformizationError&) {
    throw;
  } catch (const SingleChartError&) {
    throw;  // a valid layout out of the chart's reach: no other metric helps
  } catch (const SolveError& e) {
    throw UniformizationError(e.what());
  }
}

}  // namespace

UniformizedTarget uniformized_target(const TriMesh& target, Background background, const SurfaceMapOptions& options,
                                     const Connectivity* conn, const std::atomic<bool>* stop,
                                     const std::string& mesh, const SystemOfLoops* own_loops, bool class_loops) {
  SystemOfLoopsOptions lo;
  lo.base_vertex = options.loops.target_base_vertex;
  const UniformizationMetric policy = options.uniformization.target_metric;
  auto flips = [&] {
    return typed_target([&] {
      if (conn) return intrinsic_target(target, *conn, background, options, lo, stop, mesh, own_loops, class_loops);
      return intrinsic_target(target, Connectivity(target.F, target.num_vertices()), background, options, lo, stop,
                              mesh, own_loops, class_loops);
    });
  };
  auto fixed = [&](const std::string& flip_failure) {
    return typed_target([&] { return fixed_target(target, background, options, lo, true, flip_failure, mesh); });
  };
  if (policy == UniformizationMetric::FixedConnectivity) {
    UniformizedTarget t = fixed("");
    t.metric_choice = "requested";
    return t;
  }
  if (policy == UniformizationMetric::FixedFirst) {
    // The fixed-connectivity metric (exactly refined when needed) when it
    // can be delivered, the flip path only when it throws.
    std::string fixed_failure;
    try {
      UniformizedTarget t = fixed("");
      t.metric_choice = "fixed first: the fixed-connectivity metric";
      return t;
    } catch (const UniformizationError& e) {
      fixed_failure = e.what();
    }
    UniformizedTarget t = flips();
    t.metric = "intrinsic Delaunay (fixed connectivity failed: " + fixed_failure + ")";
    t.metric_choice = "fixed first: the fixed connectivity failed, flips";
    return t;
  }
  // Flips (requested) or automatic: the flip path, whose metric exists on
  // every closed mesh (docs/uniformization.md "Which
  // target metric runs"); the handle classes read the target's own loops on
  // both paths (carried onto T'; when carrying fails, the loops of T', as
  // `target_class_loops` says), so they are the same objects. The
  // fixed-connectivity metric (exactly refined when needed) only when the
  // flip path throws. The two differ only in how the choice is reported.
  const bool requested = policy == UniformizationMetric::IntrinsicDelaunay;
  std::string flip_failure;
  try {
    UniformizedTarget t = flips();
    t.metric_choice = requested ? "requested" : "automatic: the flip-based metric";
    return t;
  } catch (const UniformizationError& e) {
    flip_failure = e.what();
  }
  UniformizedTarget t = fixed(flip_failure);
  t.metric_choice = requested ? "fallback: the flip path failed" : "automatic: the flip path failed, fixed connectivity";
  return t;
}

void record_target_metric(const UniformizedTarget& target, SurfaceMapResult& out) {
  out.target_refinement_splits = target.refinement_splits;
  out.target_metric = target.metric;
  out.target_flips = target.flips;
  out.target_metric_choice = target.metric_choice;
  out.target_loop_metric = target.loop_metric;
  out.target_class_loops = target.class_loops_status;
}

void set_initial_map_info(const HyperbolicInitialMapResult& init, InitialMapInfo& info) {
  info.construction = init.construction;
  const PolygonInitialMapResult& p = init.polygon;
  info.polygon_status = init.construction == "polygon" ? "used" : p.reason.empty() ? "not tried" : p.reason;
  info.polygon_convex = p.convex;
  info.polygon_min_turn = p.min_turn;
  info.polygon_perimeter = p.perimeter;
  info.polygon_chords_split = p.chords_split;
  info.polygon_flipped = p.source_flipped;
  info.polygon_repaired_vertices = p.repaired_vertices;
  const CutGraphInitialMapResult& c = init.cut_graph;
  info.cut_graph_status = init.construction == "cut-graph polygon" ? "used" : c.reason.empty() ? "not tried" : c.reason;
  info.cut_graph_branch_vertices = c.branch_vertices;
  info.cut_graph_sides = 2 * c.chains;
  info.cut_graph_chords_rerouted = c.chords_rerouted;
  info.cut_graph_min_turn = c.min_turn;
  info.cut_graph_flipped = init.cut_graph_flipped;
  info.cut_graph_degenerate = init.cut_graph_degenerate;
  info.cut_graph_time_s = c.time_s;
  info.iterations = init.construction.rfind("uniform harmonic", 0) == 0 ? init.iterations : 0;
  info.time_s = init.time_s;
  info.polygon_time_s = p.time_s;
}

SystemOfLoops source_loops(const TriMesh& source, const SurfaceMapOptions& options) {
  return source_loops(source, Connectivity(source.F, source.num_vertices()), options);
}

SystemOfLoops source_loops(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options,
                           const GreedyGraph* graph) {
  SystemOfLoopsOptions slo;
  slo.base_vertex = options.loops.source_base_vertex;
  slo.refine = false;
  SystemOfLoops sl = system_of_loops(source, sc, slo, graph);
  if (sl.mesh.num_vertices() != source.num_vertices() || sl.mesh.F != source.F)
    throw SolveError("the unrefined system of loops changed the source mesh");
  return sl;
}

void check_candidate_index(int index, int count, const std::string& what) {
  if (index >= count)
    throw InputError(what + " " + std::to_string(index) + " does not exist; there are " + std::to_string(count) +
                     " candidates (0.." + std::to_string(count - 1) + ")");
}

LayoutClosure layout_closure(int num_triangles, const std::function<double(int)>& gap) {
  LayoutClosure c;
  c.triangles = num_triangles;
  for (int t = 0; t < num_triangles; ++t) {
    // (A NaN gap, a product that is no longer a number, counts as infinite.)
    const double raw = gap(t), g = std::isnan(raw) ? std::numeric_limits<double>::infinity() : raw;
    if (g > c.tolerance) ++c.open_triangles;
    if (c.worst_triangle < 0 || g > c.worst_gap) c.worst_gap = g, c.worst_triangle = t;
  }
  return c;
}

}  // namespace surfmap::detail
