#include "face_chart_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <queue>
#include <sstream>
#include <utility>

#include "../seconds_since.h"
#include "face_chart_elements.h"
#include "stages/hyperbolic_quality.h"
#include "stages/source_weights_fallback.h"
#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/geometry/nearest_point.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/point_location.h"
#include "surfmap/uniformize/simplicial_flips.h"

namespace surfmap::detail {

namespace {

using hyperbolic::Mobius;
using Clock = std::chrono::steady_clock;

// Faces of the target's universal cover one source face's image may meet
// before the inverse search gives up (a bound on the work, far above what
// any image of a map with 0 flipped meets).
constexpr size_t kMaxLiftsPerImage = 200000;

// The target side: T' (the flip-based metric's triangulation of the user's
// target), its atlas and each vertex's home halfedge (the vertex sits at the
// tail corner of it, in its face's chart).
struct TargetCharts {
  std::unique_ptr<TargetIntrinsic> intrinsic;
  FaceAtlas atlas;
  Eigen::VectorXd lengths;  ///< #E of T', hyperbolic
  std::vector<int> home;    ///< #V: an outgoing halfedge of T'
  /// #E of the user's target (tc's edges, along edge_halfedge): each edge's
  /// element, its head's home coordinates -> its tail's. An edge T' kept
  /// (never flipped away) reads it off T' (`kept`); the others close a
  /// target face whose other two edges are known (`by_faces`), else run
  /// along the shortest edge path of T' in the metric (`by_paths`). (The
  /// flips may join two vertices again by another curve, e.g. around a hole
  /// of a plate, whose class is not the straight edge's: a T' edge counts as
  /// the user's edge only when its points carried back lie on it.)
  std::vector<Mobius> input_rho;
  Eigen::VectorXd input_length;  ///< #E of tc, 3D
  int kept = 0, by_faces = 0, by_paths = 0;
  int flips = 0;

  const Connectivity& conn() const { return intrinsic->conn; }
  int home_face(int v) const { return Connectivity::face(home[v]); }
  Complex home_point(int v) const { return atlas.corners[home_face(v)][home[v] % 3]; }
  // Target halfedge g (a -> b): b's home coordinates -> a's.
  Mobius along(int g) const {
    const int a = conn().tail(g), b = conn().head(g);
    return (around_vertex(conn(), atlas, home[a], g) *
            around_vertex(conn(), atlas, home[b], Connectivity::next(g)).inverse())
        .normalized();
  }
};

// The element b's home coordinates -> a's along the shortest edge path of
// T' from a to b in the metric.
Mobius along_metric_path(const TargetCharts& t, int a, int b) {
  Mobius m;
  for (int h : shortest_edge_path_back(t.conn(), t.lengths, a, b, "T'")) m = (t.along(h) * m).normalized();
  return m;
}

// The element b's home coordinates -> a's along the shortest edge path of
// the user's target from a to b in 3D, composed of its edges' elements
// (TargetCharts::input_rho).
Mobius along_target_path(const Connectivity& tc, const TargetCharts& t, int a, int b) {
  Mobius m;
  for (int h : shortest_edge_path_back(tc, t.input_length, a, b, "the target")) {
    const int e = tc.edge(h);
    m = ((tc.edge_halfedge(e) == h ? t.input_rho[e] : t.input_rho[e].inverse()) * m).normalized();
  }
  return m;
}

TargetCharts target_charts(const TriMesh& target, const Connectivity& tc, const SurfaceMapOptions& options) {
  RicciFlowOptions fo;
  fo.tolerance = options.uniformization.tolerance;
  fo.intrinsic_delaunay = true;
  RicciFlowResult flow = ricci_flow(tc, edge_lengths(target, tc), Background::Hyperbolic, fo);
  if (!flow.converged) throw UniformizationError("per-face charts: the target's flow did not converge: " + flow.message);
  if (!is_simplicial(flow)) make_simplicial(flow);
  TargetCharts t;
  t.intrinsic = std::make_unique<TargetIntrinsic>(flow, target.num_vertices());
  // (flow.face_edges(f, k) is the side opposite corner k; T''s halfedge
  // 3f + k runs from corner k to k + 1.)
  t.lengths.resize(t.conn().num_edges());
  for (int f = 0; f < t.conn().num_faces(); ++f)
    for (int k = 0; k < 3; ++k) t.lengths[t.conn().edge(3 * f + k)] = flow.edge_lengths[flow.face_edges(f, (k + 2) % 3)];
  t.flips = flow.flips;
  t.atlas = hyperbolic_face_atlas(t.conn(), t.lengths);
  t.home.resize(target.num_vertices());
  for (int v = 0; v < target.num_vertices(); ++v) t.home[v] = t.conn().vertex_halfedge(v);
  // A T' edge is the user's edge between its ends when two of its points,
  // carried back through the flips, lie on that edge (a geodesic meeting
  // the straight edge at two interior points is the edge).
  const Connectivity& conn = t.conn();
  const int ne = tc.num_edges();
  t.input_rho.resize(ne);
  t.input_length.resize(ne);
  std::vector<char> known(ne, 0);
  for (int e = 0; e < ne; ++e) {
    const int h = tc.edge_halfedge(e), a = tc.tail(h), b = tc.head(h);
    t.input_length[e] = (target.V.row(a) - target.V.row(b)).norm();
    const int g = conn.find_halfedge(a, b);
    if (g < 0) continue;
    const int f = Connectivity::face(g), k = g % 3;
    bool on_edge = true;
    for (double x : {0.3, 0.7}) {
      Eigen::Vector3d w = Eigen::Vector3d::Zero();
      w[k] = x, w[(k + 1) % 3] = 1 - x;
      const FacePoint p = t.intrinsic->correspondence.to_input(f, w);
      double off = 1;
      for (int c = 0; c < 3; ++c) {
        const int v = target.F(p.face, c);
        if (v != a && v != b) off = p.barycentric[c];
      }
      on_edge = on_edge && off < 1e-6;
    }
    if (on_edge) t.input_rho[e] = t.along(g), known[e] = 1, ++t.kept;
  }
  t.by_faces = close_faces(tc, known, [&](int e) -> Mobius& { return t.input_rho[e]; });
  for (int e = 0; e < ne; ++e)
    if (!known[e]) {
      const int h = tc.edge_halfedge(e);
      t.input_rho[e] = along_metric_path(t, tc.tail(h), tc.head(h));
      ++t.by_paths;
    }
  return t;
}

// The snapped start (step 2 of face_chart_map.h).
struct SnappedStart {
  std::vector<int> face0;
  std::vector<Complex> w0;
  std::vector<WeightedEdge> edges;  ///< #E source, edge_halfedge's direction
  int own_edges = 0, by_faces = 0, along_paths = 0, repaired = 0, open_before = 0, open_after = 0;
};

SnappedStart snapped_start(const TriMesh& source, const Connectivity& sc, const TriMesh& target, const Connectivity& tc,
                           const TargetCharts& t,
                           const IntrinsicDelaunayResult& weights) {
  SnappedStart s;
  const int nv = source.num_vertices();
  std::vector<Eigen::Vector3d> points(target.num_vertices());
  for (int v = 0; v < target.num_vertices(); ++v) points[v] = target.V.row(v).transpose();
  const NearestPointIndex index(std::move(points));
  std::vector<int> snap(nv);
  s.face0.resize(nv), s.w0.resize(nv);
  for (int v = 0; v < nv; ++v) {
    snap[v] = index.nearest(source.V.row(v).transpose());
    s.face0[v] = t.home_face(snap[v]);
    s.w0[v] = t.home_point(snap[v]);
  }
  const int ne = sc.num_edges();
  s.edges.resize(ne);
  std::vector<char> known(ne, 0), exact(ne, 0);
  for (int e = 0; e < ne; ++e) {
    const int h = sc.edge_halfedge(e);
    WeightedEdge& ed = s.edges[e];
    ed.i = sc.tail(h), ed.j = sc.head(h), ed.w = weights.edges[e].cot_weight;
    const int a = snap[ed.i], b = snap[ed.j];
    if (a == b) {
      known[e] = exact[e] = 1;  // both ends at one point: the identity
      ++s.own_edges;
    } else if (const int g = tc.find_halfedge(a, b); g >= 0) {
      const int te = tc.edge(g);
      ed.rho = tc.edge_halfedge(te) == g ? t.input_rho[te] : t.input_rho[te].inverse();
      known[e] = exact[e] = 1;
      ++s.own_edges;
    }
  }
  s.by_faces = close_faces(sc, known, [&](int e) -> Mobius& { return s.edges[e].rho; });
  for (int e = 0; e < ne; ++e)
    if (!known[e]) {
      s.edges[e].rho = along_target_path(tc, t, snap[s.edges[e].i], snap[s.edges[e].j]);
      ++s.along_paths;
    }
  const OpenFaceRepair repair = rederive_open_faces(sc, exact, s.edges);
  s.open_before = repair.open_before, s.repaired = repair.repaired, s.open_after = repair.open_after;
  return s;
}

// Euclidean distance from 0 to the segment pq.
double distance_to_segment(Complex p, Complex q) {
  const Complex d = q - p;
  const double n = std::norm(d);
  const double s = n > 0 ? std::clamp(-std::real(std::conj(p) * d) / n, 0.0, 1.0) : 0.0;
  return std::abs(p + s * d);
}

// The inverse map: every target vertex in the image of a source face
// (largest smallest barycentric over the faces whose image holds it).
// Each source face's image is laid out in the chart of its first corner's
// face; the target faces that may meet it are those reached from there
// across sides that meet the ball around that corner holding the image
// (a Euclidean disk of radius tanh(R) in the Klein chart centring it).
std::vector<PointOnSurface> inverse_points(const TriMesh& source, const Connectivity& sc, const TargetCharts& t,
                                           const HyperbolicHarmonicResult& hr, const std::vector<int>& located,
                                           const std::vector<Mobius>& moved, int* unlocated, double* worst,
                                           int* worst_vertex) {
  const Connectivity& conn = t.conn();
  const int nt = conn.num_vertices();
  std::vector<double> best(nt, -std::numeric_limits<double>::infinity());
  std::vector<PointOnSurface> inverse(nt);
  std::vector<int> stamp(conn.num_faces(), -1);
  std::vector<std::vector<Complex>> lifts(conn.num_faces());
  auto effective = [&](int h) {  // head's face chart -> tail's face chart
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? hr.edge_effective[e] : hr.edge_effective[e].inverse();
  };
  for (int s = 0; s < sc.num_faces(); ++s) {
    const int h0 = 3 * s, i = sc.tail(h0), j = sc.head(h0), k = sc.tail(3 * s + 2);
    // (in the chart of the face containing corner i's image)
    const Complex p0 = moved[i].apply(hr.z[i]);
    const Complex p1 = (moved[i] * effective(h0)).apply(hr.z[j]);
    const Complex p2 = (moved[i] * effective(sc.twin(3 * s + 2))).apply(hr.z[k]);
    const Mobius centre = Mobius::centring(p0);
    const double reach = std::max(hyperbolic::distance(p0, p1), hyperbolic::distance(p0, p2));
    const double klein_reach = std::tanh(reach) + 1e-12;
    // Faces of the universal cover: one face of T' may meet the ball in
    // several lifts where a loop of the surface is shorter than the image
    // (a plate's thin necks: two lifts of one vertex 0.08 apart), so a
    // face is skipped only when this lift of it was seen already.
    std::vector<std::pair<int, Mobius>> queue{{located[i], Mobius()}};
    auto seen = [&](int g, const Mobius& m) {
      if (stamp[g] != s) {
        stamp[g] = s, lifts[g].clear();
      } else {
        const Complex c0 = m.apply(t.atlas.corners[g][0]);
        for (const Complex& c : lifts[g])
          if (hyperbolic::distance(c, c0) < 1e-6) return true;
      }
      lifts[g].push_back(m.apply(t.atlas.corners[g][0]));
      return false;
    };
    seen(located[i], Mobius());
    for (size_t q = 0; q < queue.size(); ++q) {
      if (q > kMaxLiftsPerImage) throw SolveError("per-face charts: the image of source face " + std::to_string(s) + " meets more than " + std::to_string(kMaxLiftsPerImage) + " faces of the target");
      const int g = queue[q].first;
      const Mobius to_chart_g = queue[q].second;
      Complex c[3], kc[3];
      for (int m = 0; m < 3; ++m) {
        c[m] = to_chart_g.apply(t.atlas.corners[g][m]);
        kc[m] = hyperbolic::poincare_to_klein(centre.apply(c[m]));
      }
      for (int m = 0; m < 3; ++m) {
        const int v = conn.tail(3 * g + m);
        double lambda[3];
        hyperbolic::triangle_barycentric(c[m], p0, p1, p2, lambda);
        const double worst = std::min({lambda[0], lambda[1], lambda[2]});
        if (worst > best[v] && std::isfinite(worst)) {
          best[v] = worst;
          Eigen::Vector3d b(lambda[0], lambda[1], lambda[2]);
          inverse[v] = point_in_face(source, s, b);
        }
        if (distance_to_segment(kc[m], kc[(m + 1) % 3]) > klein_reach) continue;
        const int across = Connectivity::face(conn.twin(3 * g + m));
        const Mobius to_chart_across = (to_chart_g * t.atlas.transition[3 * g + m]).normalized();
        if (!seen(across, to_chart_across)) queue.push_back({across, to_chart_across});
      }
    }
  }
  *unlocated = 0;
  *worst = std::numeric_limits<double>::infinity();
  for (int v = 0; v < nt; ++v) {
    *unlocated += !(best[v] >= -kInsideTolerance);
    if (best[v] < *worst) *worst = best[v], *worst_vertex = v;
  }
  return inverse;
}

}  // namespace

bool face_chart_map_applies(const SurfaceMapOptions& options, std::string* why) {
  const HomotopyOptions& h = options.homotopy;
  std::string what;
  if (!options.landmarks.empty()) what = "landmarks";
  else if (h.class_index >= 0) what = "a class index";
  else if (!h.given_class.empty()) what = "a given class";
  else if (h.source_images.size() > 0) what = "source images";
  else if (!h.reverse_class.empty()) what = "a reverse class";
  if (what.empty()) return true;
  if (why) *why = "the per-face path maps the snapped class alone and takes no " + what;
  return false;
}

void map_in_face_charts(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                        const SurfaceMapOptions& options, const std::string& reason, SurfaceMapResult& out,
                        const StageDone& stage_done) {
  const TargetCharts t = target_charts(target, tc, options);
  out.target_metric = "intrinsic Delaunay";
  out.target_flips = t.flips;
  out.target_metric_choice = "per-face charts: the flip-based metric";
  stage_done("target uniformization", 0.25);

  const auto t_initial = Clock::now();
  int raised = 0;
  const IntrinsicDelaunayResult weights =
      positive_edge_weights(sc, edge_lengths(source, sc), {options.solve.own_weights_floor}, &raised);
  out.source_weights = "positive on the source's own edges";
  out.source_weights_reason = "per-face charts: the own edges' harmonic map embeds the source (" +
                              std::to_string(raised) + " weights raised to the floor)";
  const SnappedStart start = snapped_start(source, sc, target, tc, t, weights);
  std::ostringstream cls;
  cls << "the snapped class: each source vertex at its nearest target vertex; target edges: " << t.kept
      << " kept by T', " << t.by_faces << " closing a face, " << t.by_paths << " along paths of T'; source edges: "
      << start.own_edges << " on one target edge or vertex, " << start.by_faces << " closed by a face, " << start.along_paths
      << " along target edge paths, " << start.repaired << " re-derived from a face; faces not closing "
      << start.open_before << " -> " << start.open_after;
  out.snapped_class_status = cls.str();
  out.snapped_inconsistent_faces = start.open_after;
  if (start.open_after > 0)
    throw SolveError("per-face charts: " + out.snapped_class_status +
                     " (the snapped class is not a map of the surfaces; the shapes are too far apart for the "
                     "per-face path, which has no class search)");
  out.snapped_class = 0;
  out.initial_flipped_triangles = count_flipped(sc, [&](int h) {
    const int e = sc.edge(h);
    const WeightedEdge& ed = start.edges[e];
    const Mobius A =
        (Mobius::translation_to(start.w0[ed.i]).inverse() * ed.rho * Mobius::translation_to(start.w0[ed.j])).normalized();
    return (sc.edge_halfedge(e) == h ? A : A.inverse()).apply(Complex(0.0));
  });
  out.initial_map.construction = "snapped to the nearest target vertices (per-face charts)";
  out.initial_map.time_s = seconds_since(t_initial);
  stage_done("initial map", 0.35);

  HyperbolicHarmonicOptions ho;
  ho.tolerance = options.solve.tolerance;
  ho.max_iterations = options.solve.max_iterations;
  if (options.solve_progress) ho.progress = options.solve_progress;
  HyperbolicHarmonicResult hr =
      hyperbolic_harmonic_map_in_face_charts(source.num_vertices(), start.edges, t.atlas, start.face0, start.w0, ho);
  out.converged = hr.converged;
  out.iterations = hr.iterations;
  out.energy_history = hr.energy_history;
  out.initial_energy = hr.energy_history.empty() ? hr.energy : hr.energy_history.front();
  out.final_energy = hr.energy;
  HomotopyCandidate candidate;
  candidate.description = "the snapped class (per-face charts; no other class listed)";
  candidate.energy = hr.energy;
  out.candidates = {candidate};
  out.chosen_candidate = 0;
  stage_done("solve", 0.7);

  SolverEdgeIndex index;
  index.solver_edge.resize(sc.num_edges());
  index.forward.assign(sc.num_edges(), 1);
  for (int e = 0; e < sc.num_edges(); ++e) index.solver_edge[e] = e;
  store_distortion(chart_distortion(source, sc, hr.edge_local, index), out);
  out.layout_closure = source_layout_closure(sc, hr.edge_local, index);
  if (out.flipped_triangles > 0 || out.degenerate_triangles > 0)
    throw SolveError("per-face charts: the optimised map has " + std::to_string(out.flipped_triangles) +
                     " flipped and " + std::to_string(out.degenerate_triangles) +
                     " degenerate image triangles of the source's faces; it is not returned");
  stage_done("quality", 0.8);

  // Forward: each vertex in the face of T' containing it, carried back
  // through the flips onto the user's target.
  out.forward.resize(source.num_vertices());
  std::vector<int> located(source.num_vertices());
  std::vector<Mobius> moved(source.num_vertices());
  for (int i = 0; i < source.num_vertices(); ++i) {
    Eigen::Vector3d bary;
    const int f = locate_in_face_charts(t.atlas, hr.face[i], hr.z[i], 4 * tc.num_faces(), &moved[i], &bary);
    if (f < 0) throw SolveError("per-face charts: source vertex " + std::to_string(i) + "'s image was not located");
    located[i] = f;
    Eigen::Vector3d w = bary.cwiseMax(0.0);
    w /= w.sum();
    const FacePoint p = t.intrinsic->correspondence.to_input(f, w);
    out.forward[i] = point_in_face(target, p.face, p.barycentric);
  }
  int unlocated = 0, worst_vertex = -1;
  double worst = 0;
  out.inverse = inverse_points(source, sc, t, hr, located, moved, &unlocated, &worst, &worst_vertex);
  if (unlocated > 0) {
    std::ostringstream m;
    m << "per-face charts: " << unlocated << " target vertices lie in no source face's image (the inverse map; "
      << "target vertex " << worst_vertex << " is " << worst << " in barycentrics outside the nearest)";
    throw SolveError(m.str());
  }
  stage_done("location", 0.95);

  out.face_charts = "per-face charts (" + reason +
                    "); restricted path: the snapped class only (no class search), positive weights on the "
                    "source's own edges, no energy ratio";
  out.class_bound_status = "not computed: per-face charts";
  out.ranking_status = "not run: per-face charts map the snapped class alone";
}

}  // namespace surfmap::detail
