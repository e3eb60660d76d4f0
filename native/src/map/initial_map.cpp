#include "surfmap/map/initial_map.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include <unordered_map>

#include <Eigen/Geometry>
#include <Eigen/Sparse>

#include "../seconds_since.h"
#include "disk_flattening.h"
#include "surfmap/error.h"
#include "surfmap/topology/cut_mesh.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

namespace {

using detail::seconds_since;

// Σ_s d(p, A_s p) and its Riemannian gradient at p (orthonormal coordinates
// of the chart centring p), everything evaluated in that chart.
double displacement_sum(const std::vector<Mobius>& A, Complex p, Complex* gradient) {
  const Mobius T = Mobius::centring(p), Ti = T.inverse();
  double sum = 0;
  Complex g(0.0);
  for (const Mobius& a : A) {
    const Mobius B = (T * a * Ti).normalized();
    sum += B.displacement_of_origin();
    for (const Complex q : {B.apply(Complex(0.0)), B.inverse().apply(Complex(0.0))})
      if (std::abs(q) > 0) g -= q / std::abs(q);
  }
  if (gradient) *gradient = g;
  return sum;
}

// The convex function Σ_s d(p, A_s p) (a sum of displacement functions) by
// gradient descent with backtracking; returns its minimiser from p0.
Complex minimise_displacement(const std::vector<Mobius>& A, Complex p0, int iterations) {
  Complex p = p0, g;
  double F = displacement_sum(A, p, &g), step = 0.5;
  for (int it = 0; it < iterations && std::abs(g) > 1e-9; ++it) {
    bool moved = false;
    for (int back = 0; back < 40; ++back, step *= 0.5) {
      const Complex xi = -step * g;
      const Complex q = Mobius::centring(p).inverse().apply(Mobius::translation(xi).apply(Complex(0.0)));
      Complex gq;
      const double Fq = displacement_sum(A, q, &gq);
      if (Fq <= F - 1e-4 * step * std::norm(g)) {
        p = q, F = Fq, g = gq, moved = true;
        step *= 2;
        break;
      }
    }
    if (!moved) break;
  }
  return p;
}

using detail::GiveUp;

// The class's flat connection carried to the refined mesh `rs`: every
// refined vertex u gets a home frame (an input vertex its own lift; a split
// or bend point the frame of its origin face, i.e. that face developed with
// corner 0 at its lift), and psi(f', k) is the element taking corner k of
// refined face f' from its home frame into the frame of the input face F
// holding f': the position of u in F's frame is psi * lift(u). 3 x #F'.
std::vector<Word> refined_corner_words(const TriMesh& source, const SystemOfLoops& rs,
                                       const std::vector<Word>& halfedge_word, const DeckGroup& group) {
  const TriMesh& rm = rs.mesh;
  const int n_in = source.num_vertices(), nrf = rm.num_faces();
  auto phi = [&](int F, int k) -> Word {
    return k == 0 ? Word{} : k == 1 ? halfedge_word[3 * F] : inverse(halfedge_word[3 * F + 2]);
  };
  auto corner_of = [&](int F, int v) {
    for (int k = 0; k < 3; ++k)
      if (source.F(F, k) == v) return k;
    return -1;
  };
  std::vector<Word> psi(3 * static_cast<size_t>(nrf));
  for (int f = 0; f < nrf; ++f) {
    const int F = rs.face_origin[f];
    for (int k = 0; k < 3; ++k) {
      const int u = rm.F(f, k);
      if (u < n_in) {
        const int ku = corner_of(F, u);
        if (ku < 0) throw GiveUp{"refined face " + std::to_string(f) + " has a corner outside its input face"};
        psi[3 * f + k] = phi(F, ku);
        continue;
      }
      const int H = rs.origin_face[u];
      if (H == F) continue;  // identity
      // u lies on an edge shared by F and its home face H: compare an
      // endpoint's position in both frames.
      int kh = -1, kf = -1;
      for (int j = 0; j < 3 && kf < 0; ++j)
        if (rs.origin_barycentric(u, j) > 0) kh = j, kf = corner_of(F, source.F(H, j));
      if (kf < 0 || rs.origin_barycentric.row(u).minCoeff() > 0)
        throw GiveUp{"refined vertex " + std::to_string(u) + " is not on its face's input face"};
      psi[3 * f + k] = group.reduce(concat(phi(F, kf), inverse(phi(H, kh))));
    }
  }
  return psi;
}

// The boundary of the refined cut disk: 4g sides between the copies of the
// base vertex x, counter-clockwise, `bl` rotated to start at a corner and
// closed, corner_pos[ns] = #boundary, side_of: the side of each non-corner
// boundary copy (-1 elsewhere). Fills out.corner_word, side_partner and
// side_pairing_word from the development's deck words `c`.
struct PolygonSides {
  std::vector<int> bl, corner_pos, side_of;
};

PolygonSides polygon_sides(const CutMesh& cm, const SystemOfLoops& rs, const std::vector<Word>& c,
                           const DeckGroup& group, PolygonInitialMapResult& out) {
  const int x = rs.base_vertex, nd = static_cast<int>(cm.original_vertex.size());
  PolygonSides ps;
  std::vector<int>& bl = ps.bl;
  std::vector<int>& corner_pos = ps.corner_pos;
  bl = cm.boundary_loops[0];
  for (int i = 0; i < static_cast<int>(bl.size()); ++i)
    if (cm.original_vertex[bl[i]] == x) corner_pos.push_back(i);
  const int ns = static_cast<int>(corner_pos.size());
  if (ns != 4 * rs.genus || ns < 8) throw GiveUp{"the refined cut has " + std::to_string(ns) + " corners, not 4g"};
  std::rotate(bl.begin(), bl.begin() + corner_pos[0], bl.end());
  for (int& i : corner_pos) i -= corner_pos[0];
  corner_pos.push_back(static_cast<int>(bl.size()));
  bl.push_back(bl[0]);
  ps.side_of.assign(nd, -1);  // non-corner boundary copies
  std::vector<std::vector<int>> sides_of_refined(rs.mesh.num_vertices());
  for (int s = 0; s < ns; ++s) {
    for (int i = corner_pos[s] + 1; i < corner_pos[s + 1]; ++i) {
      ps.side_of[bl[i]] = s;
      sides_of_refined[cm.original_vertex[bl[i]]].push_back(s);
    }
    if (corner_pos[s + 1] - corner_pos[s] < 2) throw GiveUp{"side " + std::to_string(s) + " has no inner vertex"};
  }
  out.corner_word.resize(ns);
  for (int s = 0; s < ns; ++s) out.corner_word[s] = c[bl[corner_pos[s]]];
  out.side_partner.assign(ns, -1);
  out.side_pairing_word.resize(ns);
  for (int s = 0; s < ns; ++s) {
    const int d = bl[corner_pos[s] + 1];
    const auto& ss = sides_of_refined[cm.original_vertex[d]];
    if (ss.size() != 2) throw GiveUp{"a loop vertex is not on two sides"};
    const int partner = ss[0] == s ? ss[1] : ss[0];
    out.side_partner[s] = partner;
    int d2 = -1;
    for (int i = corner_pos[partner] + 1; i < corner_pos[partner + 1] && d2 < 0; ++i)
      if (cm.original_vertex[bl[i]] == cm.original_vertex[d]) d2 = bl[i];
    out.side_pairing_word[s] = group.reduce(concat(c[d], inverse(c[d2])));
  }
  return ps;
}

// The polygon: base point p (the lift of x) minimising the perimeter
// Σ_s d(p, A_s p), A_s = C_s^-1 C_s+1 (the side elements), which makes the
// sides short and balanced (start: the target domain's centre); its
// corners in the chart centred at their Klein centroid (qc: Poincaré, kq:
// Klein); out.base_point, perimeter, corners, turns and convexity. GiveUp
// when the polygon has no digits left or is not strictly convex.
struct ChartedPolygon {
  Mobius chart;
  std::vector<Complex> qc, kq;
};

ChartedPolygon charted_polygon(const DeckGroup& group, const PolygonInitialMapOptions& options,
                               PolygonInitialMapResult& out) {
  const int ns = static_cast<int>(out.corner_word.size());
  std::vector<Mobius> A(ns);
  for (int s = 0; s < ns; ++s)
    A[s] = group.evaluate_side_word(group.reduce(concat(inverse(out.corner_word[s]), out.corner_word[(s + 1) % ns])));
  const Complex p = minimise_displacement(A, Complex(0.0), options.base_point_iterations);
  out.base_point = p;
  out.perimeter = displacement_sum(A, p, nullptr) / 2;  // each side counted from both ends
  std::vector<Mobius> C(ns);
  out.corners.resize(ns);
  for (int s = 0; s < ns; ++s) {
    C[s] = group.evaluate_side_word(out.corner_word[s]);
    out.corners[s] = C[s].apply(p);
  }
  // The chart: centred at the (Klein) centroid of the corners.
  ChartedPolygon poly;
  Mobius& chart = poly.chart;
  chart = Mobius::centring(p);
  for (int it = 0; it < 3; ++it) {
    Complex m(0.0);
    for (int s = 0; s < ns; ++s) m += hyperbolic::poincare_to_klein((chart * C[s]).normalized().apply(p));
    chart = (Mobius::centring(hyperbolic::klein_to_poincare(m / double(ns))) * chart).normalized();
  }
  poly.qc.resize(ns), poly.kq.resize(ns);
  for (int s = 0; s < ns; ++s) {
    poly.qc[s] = (chart * C[s]).normalized().apply(p);
    poly.kq[s] = hyperbolic::poincare_to_klein(poly.qc[s]);
  }
  const std::vector<Complex>& kq = poly.kq;
  // A polygon reaching |k| ~ 1 in its own centred chart (very twisted
  // classes: corners tens of units apart) has no digits left for positions.
  for (int s = 0; s < ns; ++s)
    if (!(std::isfinite(kq[s].real()) && std::isfinite(kq[s].imag()) && std::abs(kq[s]) < 1 - 1e-9))
      throw GiveUp{"the polygon is too large for double precision (corner " + std::to_string(s) + ")"};
  // Convexity in the Klein model: every exterior angle in (0, π), total 2π.
  const detail::KleinTurns turns = detail::klein_turns(kq);
  const double total_turn = turns.total;
  out.min_turn = turns.min, out.max_turn = turns.max;
  out.convex = out.min_turn > options.min_turn && std::abs(total_turn - 2 * M_PI) < 1e-6;
  if (!out.convex) {
    const bool clockwise = std::abs(total_turn + 2 * M_PI) < 1e-6;
    throw GiveUp{clockwise ? "the polygon is negatively oriented"
                 : std::abs(total_turn - 2 * M_PI) < 1e-6
                     ? "the polygon is simple but not convex (smallest turn " + std::to_string(out.min_turn) + ")"
                     : "the polygon is not simple (total turn " + std::to_string(total_turn / (2 * M_PI)) + " x 2pi)"};
  }
  return poly;
}

// Disk positions (Klein model of the polygon's chart), #disk vertices.
// Boundary: on side s at the fraction of the loop's 3D length, the same on
// both copies of a loop, so that the side pairing carries one copy onto the
// other. Interior: symmetrised mean-value weights (Floater) from the 3D
// geometry, positive on any triangle, so the flattening onto a convex
// polygon is an embedding; chords (interior edges joining two boundary
// copies of one side, whose faces would degenerate) are split at a free
// midpoint (counted in out.chords_split).
std::vector<Complex> flatten_refined_disk(const CutMesh& cm, const PolygonSides& ps, const ChartedPolygon& poly,
                                          int hyperboloid_rounds, PolygonInitialMapResult& out) {
  const std::vector<int>& bl = ps.bl;
  const std::vector<int>& corner_pos = ps.corner_pos;
  const std::vector<int>& side_of = ps.side_of;
  const int nd = static_cast<int>(cm.original_vertex.size()), ns = static_cast<int>(corner_pos.size()) - 1;
  std::vector<Complex> k(nd, Complex(0.0));
  std::vector<char> on_boundary(nd, 0);
  for (int s = 0; s < ns; ++s) {
    std::vector<double> cum{0.0};
    for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i)
      cum.push_back(cum.back() + (cm.mesh.V.row(bl[i + 1]) - cm.mesh.V.row(bl[i])).norm());
    for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i) {
      const double t = cum[i - corner_pos[s]] / cum.back();
      k[bl[i]] = hyperbolic::poincare_to_klein(hyperbolic::geodesic_point(poly.qc[s], poly.qc[(s + 1) % ns], t));
      on_boundary[bl[i]] = 1;
    }
    k[bl[corner_pos[s]]] = poly.kq[s];
  }
  const auto dedges = detail::mean_value_disk_edges(cm.mesh);
  auto shares_side = [&](int a, int bb) {
    auto sides = [&](int d, int* s2) {
      if (side_of[d] >= 0) return *s2 = side_of[d], side_of[d];
      for (int s = 0; s < ns; ++s)
        if (bl[corner_pos[s]] == d) return *s2 = s, (s + ns - 1) % ns;
      return *s2 = -1, -1;
    };
    int a2, b2;
    const int a1 = sides(a, &a2), b1 = sides(bb, &b2);
    return a1 >= 0 && b1 >= 0 && (a1 == b1 || a1 == b2 || a2 == b1 || a2 == b2);
  };
  std::vector<detail::FlatteningEdge> graph;
  for (const auto& [kk, de] : dedges) {
    const int i = static_cast<int>(kk / nd), j = static_cast<int>(kk % nd);
    if (de.faces != 2) {
      if (de.faces != 1 || !on_boundary[i] || !on_boundary[j]) throw GiveUp{"the refined cut disk is not a manifold disk"};
      continue;  // boundary edge: both ends fixed
    }
    if (on_boundary[i] && on_boundary[j] && shares_side(i, j)) {
      const int m = nd + out.chords_split++;
      graph.push_back({i, m, de.w});
      graph.push_back({j, m, de.w});
      graph.push_back({de.opposite[0], m, de.w});
      graph.push_back({de.opposite[1], m, de.w});
    } else {
      graph.push_back({i, j, de.w});
    }
  }
  // Klein positions of every node (chord midpoints after the disk copies).
  std::vector<Complex> kn(k);
  kn.resize(nd + out.chords_split, Complex(0.0));
  std::vector<char> fixed(on_boundary);
  fixed.resize(nd + out.chords_split, 0);
  std::string why;
  if (!detail::flatten_in_klein(graph, fixed, hyperboloid_rounds, kn, &why)) throw GiveUp{why};
  for (int d = 0; d < nd; ++d) k[d] = kn[d];
  return k;
}

// The steps of the header's comment in order: refined loops and their cut,
// the class's connection on the refined mesh, the development, the sides,
// the polygon, the flattening and the input vertices read off it.
void build_polygon_map(const TriMesh& source, const std::vector<Word>& halfedge_word, const DeckGroup& group,
                       const PolygonInitialMapOptions& options, PolygonInitialMapResult& out) {
  const int n_in = source.num_vertices();
  // Refined loops: simple, meeting only at x, so the cut is a 4g-gon. The
  // refined mesh keeps the input vertices first (system_of_loops.h).
  SystemOfLoopsOptions lo;
  lo.base_vertex = options.base_vertex;
  lo.refine = true;
  SystemOfLoops rs;
  try {
    rs = system_of_loops(source, lo);
  } catch (const SolveError& e) {
    throw GiveUp{std::string("refined loops: ") + e.what()};
  }
  const TriMesh& rm = rs.mesh;
  const int nrv = rm.num_vertices(), nrf = rm.num_faces();
  out.refined_vertices = nrv;
  if (static_cast<int>(rs.face_origin.size()) != nrf) throw GiveUp{"refined mesh without face origins"};
  const Connectivity rc(rm.F, nrv);
  std::vector<char> cut(rc.num_edges(), 0);
  for (const auto& loop : rs.loops)
    for (size_t q = 0; q + 1 < loop.size(); ++q) {
      const int h = rc.find_halfedge(loop[q], loop[q + 1]);
      if (h < 0) throw GiveUp{"refined loop is not an edge path"};
      cut[rc.edge(h)] = 1;
    }
  const CutMesh cm = cut_mesh_along_edges(rm, rc, cut);
  if (cm.euler_characteristic != 1 || cm.boundary_loops.size() != 1) throw GiveUp{"the refined cut is not a disk"};
  out.disk_vertices = static_cast<int>(cm.original_vertex.size());

  const std::vector<Word> psi = refined_corner_words(source, rs, halfedge_word, group);
  // Develop the disk: per face the frame element b_f of its input face,
  // per disk vertex c_d = b_f psi (the deck element of that copy: its point
  // in the development is c_d(lift)). Neighbours across uncut edges share
  // the copy of their common vertex.
  const detail::DiskDevelopment dev =
      detail::develop_disk(cm.mesh, rc, cut, group, [&](int f, int k) { return psi[3 * f + k]; });
  const std::vector<Word>& c = dev.c;
  if (dev.faces_reached != nrf) throw GiveUp{"the refined cut disk is not connected"};
  if (dev.mismatch > 1e-6)
    throw GiveUp{"the class's deck elements are not flat on the refined mesh (" + std::to_string(dev.mismatch) + ")"};

  const PolygonSides ps = polygon_sides(cm, rs, c, group, out);
  const ChartedPolygon poly = charted_polygon(group, options, out);
  const std::vector<Complex> k = flatten_refined_disk(cm, ps, poly, options.hyperboloid_rounds, out);

  // The input vertices: one copy's point (global frame) and its deck word,
  // then moved into the target's domain.
  const std::string unread = detail::read_disk_vertices(cm.original_vertex, n_in, k, c, poly.chart,
                                                        options.reduce_point, group, "input vertex", "the refined mesh",
                                                        out.z, out.vertex_deck, out.vertex_deck_word);
  if (!unread.empty()) throw GiveUp{unread};
}

}  // namespace

PolygonInitialMapResult polygon_initial_map(const TriMesh& source, const Connectivity& sc,
                                            const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                            const PolygonInitialMapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  PolygonInitialMapResult out;
  const int n_in = source.num_vertices();
  if (static_cast<int>(halfedge_word.size()) != 3 * sc.num_faces() || sc.num_vertices() != n_in)
    throw InputError("polygon_initial_map: one side word per source halfedge (3 x #F) needed");
  detail::build_or_give_up(out, [&](auto& o) { build_polygon_map(source, halfedge_word, group, options, o); });
  out.time_s = seconds_since(t0);
  return out;
}

namespace {

// A flattening with a few bad faces (the 50k genus-2 bench source: 2 of 1e5,
// where the loops cross) is kept and repaired where it is bad: the
// uniform-weight harmonic map of the rings around those faces, the rest of
// the flattening held (hyperbolic_harmonic.h `fixed`). That costs a solve of
// a few hundred vertices instead of the whole uniform-weight map, whose full
// solve is the fallback when the repair does not clear every fold.
// Source edge e with weight 1, its element in the charts of `vertex_word`
// (the effective element as a reduced side word).
WeightedEdge uniform_edge_in_charts(const Connectivity& sc, int e, const std::vector<Word>& halfedge_word,
                                    const DeckGroup& group, const std::vector<Word>& vertex_word) {
  const int h = sc.edge_halfedge(e);
  WeightedEdge out;
  out.i = sc.tail(h);
  out.j = sc.head(h);
  out.w = 1.0;
  out.rho_word = group.reduce(concat({vertex_word[out.i], halfedge_word[h], inverse(vertex_word[out.j])}));
  out.rho = group.evaluate_side_word(out.rho_word);
  return out;
}

bool repair_flattening(const TriMesh& source, const Connectivity& sc, const std::vector<Word>& halfedge_word,
                       const DeckGroup& group, const HyperbolicInitialMapOptions& options,
                       const std::vector<double>& per_face, PolygonInitialMapResult& poly) {
  const int nv = source.num_vertices(), nf = source.num_faces();
  if (static_cast<int>(poly.z.size()) != nv ||
      !std::all_of(poly.z.begin(), poly.z.end(), [](Complex z) { return std::abs(z) < 1; }))
    return false;
  for (int rings : {3, 6, 12}) {
    std::vector<int> ring(nv, -1), frontier;
    for (int f = 0; f < nf; ++f)
      if (!std::isfinite(per_face[f]))
        for (int k = 0; k < 3; ++k)
          if (ring[source.F(f, k)] < 0) ring[source.F(f, k)] = 0, frontier.push_back(source.F(f, k));
    for (size_t q = 0; q < frontier.size(); ++q) {
      const int v = frontier[q];
      if (ring[v] == rings) continue;
      for (int h : sc.outgoing(v))
        if (const int u = sc.head(h); ring[u] < 0) ring[u] = ring[v] + 1, frontier.push_back(u);
    }
    if (static_cast<int>(frontier.size()) > nv / 4) return false;  // not local: the full fallback
    std::vector<char> fixed(nv, 1);
    for (int v : frontier) fixed[v] = 0;
    // Edges touching a free vertex (the others' energy is constant), in the
    // flattening's charts.
    std::vector<WeightedEdge> edges;
    for (int e = 0; e < sc.num_edges(); ++e)
      if (!fixed[sc.edge_vertex(e, 0)] || !fixed[sc.edge_vertex(e, 1)])
        edges.push_back(uniform_edge_in_charts(sc, e, halfedge_word, group, poly.vertex_deck_word));
    HyperbolicHarmonicOptions ho;
    ho.tolerance = options.tolerance;
    ho.max_iterations = options.max_iterations;
    ho.relator = group.side_relator();
    ho.reduce_point = options.reduce_point;
    ho.fixed = fixed;
    if (options.keep_going) ho.progress = [&](int, double, double) { return options.keep_going(); };
    HyperbolicHarmonicResult hr;
    try {
      hr = hyperbolic_harmonic_map(nv, edges, group.side_pairings(), poly.z, ho);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error&) {
      return false;
    }
    std::vector<Word> words(nv);
    const bool have_words = hr.vertex_deck_word.size() == static_cast<size_t>(nv);
    for (int v = 0; v < nv && have_words; ++v)
      words[v] = group.reduce(concat(hr.vertex_deck_word[v], poly.vertex_deck_word[v]));
    if (!have_words) return false;  // chart moves without words cannot be composed exactly
    const DistortionStats q = hyperbolic_distortion(source, group, halfedge_word, hr.z, words);
    if (q.flipped || q.degenerate > q.flat) continue;  // flat but positive faces are embedded
    poly.z = std::move(hr.z);
    poly.vertex_deck_word = std::move(words);
    poly.vertex_deck.resize(nv);
    for (int v = 0; v < nv; ++v) poly.vertex_deck[v] = group.evaluate_side_word(poly.vertex_deck_word[v]);
    poly.repaired_vertices = static_cast<int>(frontier.size());
    poly.reason.clear();
    return true;
  }
  return false;
}

/// Why the source's faces, straight between their vertices' images, do not
/// embed (`q`: their distortion): "N flipped and M degenerate source faces";
/// empty when none is flipped or degenerate within round-off (flat but
/// positive faces, DistortionStats::flat, are embedded).
std::string folded_source_faces(const DistortionStats& q) {
  if (!q.flipped && q.degenerate <= q.flat) return {};
  return std::to_string(q.flipped) + " flipped and " + std::to_string(q.degenerate - q.flat) +
         " degenerate source faces";
}

}  // namespace

HyperbolicInitialMapResult hyperbolic_initial_map(const TriMesh& source, const Connectivity& sc,
                                                  const std::vector<Mobius>& halfedge_rho,
                                                  const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                                  const HyperbolicInitialMapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  HyperbolicInitialMapResult r;
  std::vector<Complex> start_z;
  std::vector<Word> start_word;
  if (options.cut_graph) {
    CutGraphInitialMapOptions co;
    co.base_vertex = options.base_vertex;
    co.loops = options.source_loops;
    co.reduce_point = options.reduce_point;
    CutGraphInitialMapResult cg;
    try {
      cg = cut_graph_initial_map(source, sc, halfedge_word, group, co);
    } catch (const Error& e) {
      cg = CutGraphInitialMapResult();
      cg.reason = e.what();
    }
    if (cg.applied) {
      // An embedding by construction; checked all the same (round-off on
      // sliver faces), from reduced words.
      const DistortionStats q = hyperbolic_distortion(source, group, halfedge_word, cg.z, cg.vertex_deck_word);
      r.cut_graph_flipped = q.flipped;
      // Flat but positive faces (DistortionStats::flat) are embedded too.
      r.cut_graph_degenerate = q.degenerate - q.flat;
      const std::string folded = folded_source_faces(q);
      if (!folded.empty()) {
        cg.applied = false;
        cg.reason = folded;
      }
    }
    if (cg.applied) {
      r.converged = true;
      r.construction = "cut-graph polygon";
      r.z = std::move(cg.z);
      r.vertex_deck = std::move(cg.vertex_deck);
      r.vertex_deck_word = std::move(cg.vertex_deck_word);
    }
    cg.z.clear(), cg.vertex_deck.clear(), cg.vertex_deck_word.clear();
    r.cut_graph = std::move(cg);
  }
  if (options.polygon && r.construction.empty()) {
    PolygonInitialMapOptions po;
    po.base_vertex = options.base_vertex;
    po.reduce_point = options.reduce_point;
    PolygonInitialMapResult poly;
    try {
      poly = polygon_initial_map(source, sc, halfedge_word, group, po);
    } catch (const Error& e) {
      poly = PolygonInitialMapResult();
      poly.reason = e.what();
    }
    if (poly.applied) {
      // The flattening is an embedding of the refined disk; the source's own
      // faces, straight between its vertices' images, are checked too.
      const DistortionStats q = hyperbolic_distortion(source, group, halfedge_word, poly.z, poly.vertex_deck_word);
      poly.source_flipped = q.flipped;
      poly.source_degenerate = q.degenerate - q.flat;
      const std::string folded = folded_source_faces(q);
      if (!folded.empty()) {
        poly.applied = false;
        poly.reason = folded;
        if (q.flipped + q.degenerate <= std::max(8, source.num_faces() / 2000))
          poly.applied = repair_flattening(source, sc, halfedge_word, group, options, q.per_face, poly);
      }
    }
    if (poly.applied) {
      r.converged = true;
      r.construction = "polygon";
      r.z = std::move(poly.z);
      r.vertex_deck = std::move(poly.vertex_deck);
      r.vertex_deck_word = std::move(poly.vertex_deck_word);
    } else if (!poly.z.empty() && std::all_of(poly.z.begin(), poly.z.end(), [](Complex z) { return std::abs(z) < 1; })) {
      // Flipped faces: the uniform-weight map, started from the flattening
      // (the same unique map, in fewer Newton steps than from the origin).
      // A flattening with points on or beyond |z| = 1 (or NaN: very twisted
      // deck words) is no start at all (genus-6 sliver source from base
      // vertex 1000); the origin is used then.
      start_z = std::move(poly.z);
      start_word = std::move(poly.vertex_deck_word);
    }
    poly.z.clear(), poly.vertex_deck.clear(), poly.vertex_deck_word.clear();
    r.polygon = std::move(poly);
  }
  if (r.construction.empty()) {
    const int nv = sc.num_vertices();
    const bool from_polygon = !start_z.empty();
    const bool from_given = !from_polygon && static_cast<int>(options.start_z.size()) == nv &&
                            static_cast<int>(options.start_word.size()) == nv;
    if (from_given) start_z = options.start_z, start_word = options.start_word;
    else if (!from_polygon) start_z.assign(nv, Complex(0.0)), start_word.assign(nv, Word{});
    // Edges in the start's charts (effective elements, as reduced side words).
    std::vector<WeightedEdge> edges(sc.num_edges());
    for (int e = 0; e < sc.num_edges(); ++e) edges[e] = uniform_edge_in_charts(sc, e, halfedge_word, group, start_word);
    HyperbolicHarmonicOptions ho;
    ho.tolerance = options.tolerance;
    ho.max_iterations = options.max_iterations;
    ho.relator = group.side_relator();
    ho.reduce_point = options.reduce_point;
    if (options.keep_going) ho.progress = [&](int, double, double) { return options.keep_going(); };
    HyperbolicHarmonicResult hr;
    try {
      hr = hyperbolic_harmonic_map(nv, edges, group.side_pairings(), start_z, ho);
    } catch (const Error&) {
      if (!from_polygon && !from_given) throw;
      // The flattening (or the given start) was no usable start after all:
      // from the origin.
      HyperbolicInitialMapOptions o = options;
      o.polygon = o.cut_graph = false;
      o.start_z.clear(), o.start_word.clear();
      HyperbolicInitialMapResult u = hyperbolic_initial_map(source, sc, halfedge_rho, halfedge_word, group, o);
      u.polygon = std::move(r.polygon);
      u.cut_graph = std::move(r.cut_graph);
      u.cut_graph_flipped = r.cut_graph_flipped, u.cut_graph_degenerate = r.cut_graph_degenerate;
      u.time_s = seconds_since(t0);
      return u;
    }
    r.polygon.z.clear();
    r.converged = hr.converged;
    r.iterations = hr.iterations;
    r.z = std::move(hr.z);
    r.vertex_deck_word.resize(nv);
    r.vertex_deck.resize(nv);
    const bool words = hr.vertex_deck_word.size() == static_cast<size_t>(nv);
    for (int i = 0; i < nv; ++i) {
      r.vertex_deck_word[i] = words ? group.reduce(concat(hr.vertex_deck_word[i], start_word[i])) : start_word[i];
      r.vertex_deck[i] = words ? group.evaluate_side_word(r.vertex_deck_word[i])
                               : (hr.vertex_deck[i] * group.evaluate_side_word(start_word[i])).normalized();
    }
    r.construction = from_polygon ? "uniform harmonic (from the polygon)" : "uniform harmonic";
  }
  r.time_s = seconds_since(t0);
  return r;
}

namespace {

// The figures of a map given by `z` and the effective element eff(h) of
// every halfedge h (hyperbolic_distortion below).
template <class Eff>
DistortionStats distortion_of(const TriMesh& source, const std::vector<Complex>& z, const Eff& eff,
                              Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>* image) {
  const int nf = source.num_faces();
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(nf, 3);
  for (int f = 0; f < nf; ++f) {
    img(f, 0) = z[source.F(f, 0)];
    img(f, 1) = eff(3 * f).apply(z[source.F(f, 1)]);
    img(f, 2) = eff(3 * f + 2).inverse().apply(z[source.F(f, 2)]);
  }
  // Möbius maps preserve orientation: tested in the chart centring corner 0.
  DistortionStats out = hyperbolic_image_distortion(
      source,
      [&](int f) {
        const Mobius T = Mobius::centring(img(f, 0));
        return std::make_pair(T.apply(img(f, 1)), T.apply(img(f, 2)));
      },
      [&](int f) {
        return Eigen::Vector3d(hyperbolic::distance(img(f, 0), img(f, 1)), hyperbolic::distance(img(f, 1), img(f, 2)),
                               hyperbolic::distance(img(f, 2), img(f, 0)));
      },
      false);
  if (image) *image = std::move(img);
  return out;
}

}  // namespace

DistortionStats hyperbolic_distortion(const TriMesh& source, const std::vector<Mobius>& halfedge_rho,
                                      const std::vector<Complex>& z, const std::vector<Mobius>& deck,
                                      Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>* image) {
  const int nf = source.num_faces();
  if (static_cast<int>(halfedge_rho.size()) != 3 * nf || static_cast<int>(z.size()) != source.num_vertices() ||
      deck.size() != z.size())
    throw InputError("hyperbolic_distortion: sizes of halfedge_rho (3 x #F), z and vertex_deck (#V) do not match the mesh");
  auto eff = [&](int h) {
    const int f = h / 3, k = h % 3;
    return (deck[source.F(f, k)] * halfedge_rho[h] * deck[source.F(f, (k + 1) % 3)].inverse()).normalized();
  };
  return distortion_of(source, z, eff, image);
}

DistortionStats hyperbolic_distortion(const TriMesh& source, const DeckGroup& group,
                                      const std::vector<Word>& halfedge_word, const std::vector<Complex>& z,
                                      const std::vector<Word>& vertex_deck_word,
                                      Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>* image) {
  const int nf = source.num_faces();
  if (static_cast<int>(halfedge_word.size()) != 3 * nf || static_cast<int>(z.size()) != source.num_vertices() ||
      vertex_deck_word.size() != z.size())
    throw InputError("hyperbolic_distortion: sizes of halfedge_word (3 x #F), z and vertex_deck_word (#V) do not match the mesh");
  // Few distinct effective words occur (the tiles next to P): each is
  // reduced and multiplied out once.
  std::map<Word, Mobius> memo;
  auto eff = [&](int h) {
    const int f = h / 3, k = h % 3;
    const Word w = concat({vertex_deck_word[source.F(f, k)], halfedge_word[h],
                           inverse(vertex_deck_word[source.F(f, (k + 1) % 3)])});
    auto it = memo.find(w);
    if (it == memo.end()) it = memo.emplace(w, group.evaluate_side_word(group.reduce(w))).first;
    return it->second;
  };
  return distortion_of(source, z, eff, image);
}

}  // namespace surfmap
