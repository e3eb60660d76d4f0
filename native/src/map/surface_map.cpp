#include "surfmap/map/surface_map.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <functional>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <tuple>
#include <string>
#include <unordered_map>

#include <Eigen/CholmodSupport>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include "surfmap/error.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/edge_homotopy.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {
namespace {

using Complex = std::complex<double>;
using Clock = std::chrono::steady_clock;

const GroupOps<Complex> kTranslations{Complex(0.0), [](const Complex& a, const Complex& b) { return a + b; },
                                      [](const Complex& a) { return -a; }};

// Evaluates a word whose letters index `values` (1-based) in the translation group.
Complex evaluate(const Word& w, const std::vector<Complex>& values) {
  Complex s = 0;
  for (int x : w) s += (x > 0 ? 1.0 : -1.0) * values[std::abs(x) - 1];
  return s;
}

// Everything about the target that the solve needs: its flat layout (on the
// refined mesh of its system of loops) and the canonical lattice basis.
struct FlatTarget {
  SystemOfLoops loops;
  DiskLayout layout;
  Complex A, B;  // translations of the canonical generators a', b'
  std::vector<int> refined_to_input_face;
};

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

Eigen::Vector3d barycentric_in_face(const TriMesh& m, int f, const Eigen::Vector3d& p) {
  const Eigen::Vector3d p0 = m.V.row(m.F(f, 0)), p1 = m.V.row(m.F(f, 1)), p2 = m.V.row(m.F(f, 2));
  const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
  const double n2 = n.squaredNorm();
  Eigen::Vector3d b((p1 - p).cross(p2 - p).dot(n) / n2, (p2 - p).cross(p0 - p).dot(n) / n2,
                    (p0 - p).cross(p1 - p).dot(n) / n2);
  b = b.cwiseMax(0.0);
  return b / b.sum();
}

// The point with (clamped, renormalised) barycentrics b in face f of m.
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

// A point given in face rf of the refined mesh s.mesh, expressed on the input
// mesh (face + barycentrics). `cache` (#F refined, initially -1) remembers the
// input face of each refined face.
PointOnSurface point_on_input(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& s,
                              std::vector<int>& cache, int rf, const Eigen::Vector3d& b) {
  PointOnSurface ps = point_in_face(s.mesh, rf, b);
  if (cache[rf] < 0) {
    Eigen::Vector3d unused;
    cache[rf] = containing_input_face(input, ic, s, rf, &unused);
  }
  ps.face = cache[rf];
  ps.barycentric = barycentric_in_face(input, ps.face, ps.position);
  return ps;
}

// The target laid out in its uniformization metric: system of loops (refined,
// as the layout needs simple loops), Ricci flow, disk layout.
struct UniformizedTarget {
  SystemOfLoops loops;
  DiskLayout layout;
};

UniformizedTarget uniformized_target(const TriMesh& target, Background background, const SurfaceMapOptions& options) {
  UniformizedTarget t;
  SystemOfLoopsOptions lo;
  lo.base_vertex = options.target_base_vertex;
  t.loops = system_of_loops(target, lo);
  const Connectivity conn(t.loops.mesh.F, t.loops.mesh.num_vertices());
  RicciFlowOptions ro;
  ro.tolerance = options.uniformization_tolerance;
  const RicciFlowResult flow = ricci_flow(conn, edge_lengths(t.loops.mesh, conn), background, ro);
  if (!flow.converged) throw SolveError("target uniformization did not converge: " + flow.message);
  t.layout = layout_disk(conn, flow.edge_lengths, background, t.loops);
  if (t.layout.num_flipped > 0)
    throw SolveError("target layout has " + std::to_string(t.layout.num_flipped) + " flipped triangles");
  return t;
}

// The source's unrefined system of loops: it keeps the source's own
// connectivity, and contracting its tree gives a one-vertex schema.
SystemOfLoops source_loops(const TriMesh& source, const SurfaceMapOptions& options) {
  SystemOfLoopsOptions slo;
  slo.base_vertex = options.source_base_vertex;
  slo.refine = false;
  SystemOfLoops sl = system_of_loops(source, slo);
  if (sl.mesh.num_vertices() != source.num_vertices() || sl.mesh.F != source.F)
    throw SolveError("the unrefined system of loops changed the source mesh");
  return sl;
}

FlatTarget flat_target(const TriMesh& target, const SurfaceMapOptions& options) {
  FlatTarget t;
  UniformizedTarget u = uniformized_target(target, Background::Euclidean, options);
  t.loops = std::move(u.loops);
  t.layout = std::move(u.layout);
  const CanonicalSchema cs = canonical_schema(t.layout.word);
  t.A = evaluate(cs.generators[0], t.layout.generator_translations);
  t.B = evaluate(cs.generators[1], t.layout.generator_translations);
  return t;
}

// Uniform grid over triangles in the plane for point location.
class TriangleGrid {
 public:
  TriangleGrid(const std::vector<std::array<Complex, 3>>& tris) : tris_(tris) {
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300, perimeter = 0;
    for (const auto& t : tris_)
      for (int k = 0; k < 3; ++k) {
        xmin = std::min(xmin, t[k].real()), xmax = std::max(xmax, t[k].real());
        ymin = std::min(ymin, t[k].imag()), ymax = std::max(ymax, t[k].imag());
        perimeter += std::abs(t[(k + 1) % 3] - t[k]);
      }
    cell_ = std::max(perimeter / (3.0 * std::max<size_t>(tris_.size(), 1)), 1e-300) * 2.0;
    x0_ = xmin, y0_ = ymin;
    nx_ = std::max(1, static_cast<int>((xmax - xmin) / cell_) + 1);
    ny_ = std::max(1, static_cast<int>((ymax - ymin) / cell_) + 1);
    if (static_cast<double>(nx_) * ny_ > 8.0 * tris_.size() + 64) {  // keep memory bounded
      const double s = std::sqrt(static_cast<double>(nx_) * ny_ / (8.0 * tris_.size() + 64));
      cell_ *= s;
      nx_ = std::max(1, static_cast<int>((xmax - xmin) / cell_) + 1);
      ny_ = std::max(1, static_cast<int>((ymax - ymin) / cell_) + 1);
    }
    cells_.assign(static_cast<size_t>(nx_) * ny_, {});
    for (int i = 0; i < static_cast<int>(tris_.size()); ++i) {
      const auto& t = tris_[i];
      const int ix0 = cx(std::min({t[0].real(), t[1].real(), t[2].real()}));
      const int ix1 = cx(std::max({t[0].real(), t[1].real(), t[2].real()}));
      const int iy0 = cy(std::min({t[0].imag(), t[1].imag(), t[2].imag()}));
      const int iy1 = cy(std::max({t[0].imag(), t[1].imag(), t[2].imag()}));
      for (int x = ix0; x <= ix1; ++x)
        for (int y = iy0; y <= iy1; ++y) cells_[static_cast<size_t>(y) * nx_ + x].push_back(i);
    }
  }
  /// Triangle containing p (largest minimum barycentric >= -tol) or -1.
  int locate(Complex p, Eigen::Vector3d* bary, double tol = 1e-9) const {
    const double fx = (p.real() - x0_) / cell_, fy = (p.imag() - y0_) / cell_;
    if (fx < 0 || fy < 0 || fx >= nx_ || fy >= ny_) return -1;
    int best = -1;
    double best_min = -tol;
    for (int i : cells_[static_cast<size_t>(fy) * nx_ + static_cast<int>(fx)]) {
      const Eigen::Vector3d b = barycentric(tris_[i], p);
      if (b.minCoeff() >= best_min) best_min = b.minCoeff(), best = i, *bary = b;
    }
    return best;
  }
  static Eigen::Vector3d barycentric(const std::array<Complex, 3>& t, Complex p) {
    auto cross = [](Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); };
    const double area = cross(t[1] - t[0], t[2] - t[0]);
    return Eigen::Vector3d(cross(t[1] - p, t[2] - p), cross(t[2] - p, t[0] - p), cross(t[0] - p, t[1] - p)) / area;
  }

 private:
  int cx(double x) const { return std::clamp(static_cast<int>((x - x0_) / cell_), 0, nx_ - 1); }
  int cy(double y) const { return std::clamp(static_cast<int>((y - y0_) / cell_), 0, ny_ - 1); }
  const std::vector<std::array<Complex, 3>>& tris_;
  double cell_ = 1, x0_ = 0, y0_ = 0;
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> cells_;
};

// Locates p modulo the lattice (w1, w2) in the grid: reduce p to the
// parallelogram around `centre`, then try nearby translates.
int locate_periodic(const TriangleGrid& grid, Complex p, Complex centre, Complex w1, Complex w2,
                    Eigen::Vector3d* bary) {
  const double det = w1.real() * w2.imag() - w1.imag() * w2.real();
  const Complex d = p - centre;
  const double alpha = (d.real() * w2.imag() - d.imag() * w2.real()) / det;
  const double beta = (w1.real() * d.imag() - w1.imag() * d.real()) / det;
  const Complex q = p - std::round(alpha) * w1 - std::round(beta) * w2;
  for (int ring = 0; ring <= 3; ++ring)
    for (int m = -ring; m <= ring; ++m)
      for (int n = -ring; n <= ring; ++n) {
        if (std::max(std::abs(m), std::abs(n)) != ring) continue;
        const int f = grid.locate(q + double(m) * w1 + double(n) * w2, bary);
        if (f >= 0) return f;
      }
  return -1;
}

// Genus >= 2: hyperbolic target, harmonic map by preconditioned Riemannian
// descent (map/hyperbolic_harmonic.h), only the canonical class a_i -> a'_i,
// b_i -> b'_i for now.
void map_hyperbolic(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                    const SurfaceMapOptions& options, SurfaceMapResult& out,
                    const std::function<void(const std::string&, double)>& stage_done) {
  using hyperbolic::Mobius;
  auto evaluate_mobius = [](const Word& w, const std::vector<Mobius>& values) {
    Mobius m;
    for (int x : w) m = (m * (x > 0 ? values[std::abs(x) - 1] : values[std::abs(x) - 1].inverse())).normalized();
    return m;
  };

  // Target: hyperbolic metric, layout, canonical generators.
  const UniformizedTarget ut = uniformized_target(target, Background::Hyperbolic, options);
  const SystemOfLoops& tl = ut.loops;
  const DiskLayout& layout = ut.layout;
  const CanonicalSchema tcs = canonical_schema(layout.word);
  stage_done("target uniformization", 0.3);

  // Source homotopy data in the target's deck group.
  const SystemOfLoops sl = source_loops(source, options);
  const CanonicalSchema scs = canonical_schema(sl.word);
  // Deck elements are computed as words first and multiplied out only when
  // reduced: products like g g^-1 of large SU(1,1) matrices lose digits, and
  // the words of single edges are short (their crossings with the cut).
  // Source letter k as a word in the target's loop letters:
  std::vector<Word> letter_image;
  for (const Word& w : scs.letters) {
    Word img;
    for (int x : w) img = concat(img, x > 0 ? tcs.generators[x - 1] : inverse(tcs.generators[-x - 1]));
    letter_image.push_back(dehn_reduce(img, layout.word));
  }
  std::vector<Word> src_letters;
  for (size_t k = 0; k < scs.letters.size(); ++k) src_letters.push_back({static_cast<int>(k) + 1});
  const GroupOps<Word> free_group{Word{}, [](const Word& u, const Word& v) { return concat(u, v); },
                                  [](const Word& u) { return inverse(u); }};
  const std::vector<Word> edge_word =
      edge_group_elements(sc, sl.tree_parent_halfedge, sl.dual_tree_parent_halfedge, sl.generator_edges,
                          loop_first_vertices(sl, sc), src_letters, free_group);
  std::vector<Word> target_word(edge_word.size());
  for (size_t e = 0; e < edge_word.size(); ++e)
    for (int x : edge_word[e])
      target_word[e] = concat(target_word[e], x > 0 ? letter_image[x - 1] : inverse(letter_image[-x - 1]));
  // Shortest-form words keep the products of SU(1,1) matrices small.
  for (Word& w : target_word) w = dehn_reduce(w, layout.word);
  auto word_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? target_word[e] : inverse(target_word[e]);
  };
  std::vector<Mobius> rho_edge(edge_word.size());
  for (size_t e = 0; e < edge_word.size(); ++e) rho_edge[e] = evaluate_mobius(target_word[e], layout.generators);
  auto rho_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? rho_edge[e] : rho_edge[e].inverse();
  };
  // Exact check (Dehn's algorithm solves the word problem of the surface
  // group): the product around every source face is the identity.
  for (int f = 0; f < source.num_faces(); ++f) {
    const Word around = concat({word_of(3 * f), word_of(3 * f + 1), word_of(3 * f + 2)});
    const bool ok = dehn_reduce(around, layout.word).empty();
    if (!ok) throw SolveError("homotopy data inconsistent around source face " + std::to_string(f));
  }
  const IntrinsicDelaunayResult idt = intrinsic_delaunay(sc, edge_lengths(source, sc));
  if (!idt.delaunay) throw SolveError("the source's intrinsic Delaunay flips did not finish");
  std::vector<WeightedEdge> edges(idt.edges.size());
  for (size_t e = 0; e < idt.edges.size(); ++e) {
    const auto& ie = idt.edges[e];
    edges[e].i = ie.i;
    edges[e].j = ie.j;
    edges[e].w = ie.cot_weight;
    Word w;
    for (int h : ie.path) w = concat(w, word_of(h));
    edges[e].rho = evaluate_mobius(dehn_reduce(w, layout.word), layout.generators);
  }
  HomotopyCandidate c;
  c.description = "a_i -> a'_i, b_i -> b'_i (canonical systems of both surfaces)";
  out.candidates = {c};
  if (options.homotopy > 0)
    throw InputError("homotopy class " + std::to_string(options.homotopy) +
                     " does not exist; for genus >= 2 only class 0 (canonical handle order) is available so far");
  out.chosen_candidate = 0;
  stage_done("source homotopy data and weights", 0.4);

  HyperbolicHarmonicOptions ho;
  if (options.progress)
    ho.progress = [&](int it, double E, double g) { return options.progress("harmonic solve", 0.4 + 0.3 * std::min(1.0, it / 50.0)); };
  std::vector<Complex> start(source.num_vertices(), Complex(0.0));
  if (options.start_seed != 0) {
    std::mt19937 rng(options.start_seed);
    std::uniform_real_distribution<double> U(-0.35, 0.35);
    for (Complex& z : start) z = Complex(U(rng), U(rng));
  }
  const HyperbolicHarmonicResult hr = hyperbolic_harmonic_map(source.num_vertices(), edges, layout.generators, start, ho);
  if (!hr.converged)
    throw SolveError("the harmonic map solve did not converge in " + std::to_string(hr.iterations) +
                     " iterations (gradient " + std::to_string(hr.gradient_history.back()) + ")");
  out.converged = true;
  out.iterations = hr.iterations;
  out.energy_history = hr.energy_history;
  out.initial_energy = hr.energy_history.front();
  out.final_energy = hr.energy;
  out.candidates[0].energy = hr.energy;
  stage_done("harmonic solve", 0.7);

  // The geodesic 4g-gon P on the layout's corners is a convex fundamental
  // domain (in the Klein model) with side maps built from its corners:
  // side i (c_i -> c_i+1, letter x) is glued to the side j of letter x^-1,
  // traversed backwards, so M_i takes (c_i, c_i+1) to (c_j+1, c_j) and the
  // outside of side i to the inside of P along side j.
  const int nsides = static_cast<int>(layout.side_start.size());
  std::vector<Complex> corner(nsides), kcorner(nsides);
  for (int i = 0; i < nsides; ++i) {
    const int h = layout.boundary_halfedges[layout.side_start[i]];
    corner[i] = layout.corners(h / 3, h % 3);
    kcorner[i] = hyperbolic::poincare_to_klein(corner[i]);
  }
  std::vector<Mobius> side_map(nsides);
  for (int i = 0; i < nsides; ++i) {
    int j = -1;
    for (int q = 0; q < nsides; ++q)
      if (layout.word[q] == -layout.word[i]) j = q;
    if (j < 0) throw SolveError("the target's boundary word has no partner for side " + std::to_string(i));
    side_map[i] = hyperbolic::isometry_from_pairs(corner[i], corner[(i + 1) % nsides], corner[(j + 1) % nsides], corner[j]);
  }
  // Moves z into P; returns the element applied.
  auto reduce_into_polygon = [&](Complex& z) {
    Mobius acc;
    for (int guard = 0; guard < 200; ++guard) {
      const Complex k = hyperbolic::poincare_to_klein(z);
      int worst = -1;
      double worst_value = -1e-13;
      for (int i = 0; i < nsides; ++i) {
        const Complex e = kcorner[(i + 1) % nsides] - kcorner[i], d = k - kcorner[i];
        const double side = (e.real() * d.imag() - e.imag() * d.real()) / std::abs(e);
        if (side < worst_value) worst_value = side, worst = i;
      }
      if (worst < 0) break;
      z = side_map[worst].apply(z);
      acc = (side_map[worst] * acc).normalized();
    }
    return acc;
  };
  std::vector<Complex> zp = hr.z;
  std::vector<Mobius> deck = hr.vertex_deck;
  for (int i = 0; i < source.num_vertices(); ++i) deck[i] = (reduce_into_polygon(zp[i]) * deck[i]).normalized();

  // Effective element of source halfedge h after the solve's chart moves.
  auto eff = [&](int h) { return (deck[sc.tail(h)] * rho_of(h) * deck[sc.head(h)].inverse()).normalized(); };
  // Image triangles: corners in the Poincaré disk, anchored at corner 0.
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(source.num_faces(), 3);
  for (int f = 0; f < source.num_faces(); ++f) {
    img(f, 0) = zp[source.F(f, 0)];
    img(f, 1) = eff(3 * f).apply(zp[source.F(f, 1)]);
    img(f, 2) = eff(3 * f + 2).inverse().apply(zp[source.F(f, 2)]);
  }
  // Dilatation from hyperbolic side lengths; orientation in the chart
  // centring corner 0 (Möbius maps preserve orientation).
  out.dilatation.assign(source.num_faces(), std::numeric_limits<double>::infinity());
  double weighted = 0, total_area = 0;
  for (int f = 0; f < source.num_faces(); ++f) {
    const Mobius T = Mobius::centring(img(f, 0));
    const Complex b = T.apply(img(f, 1)), cc = T.apply(img(f, 2));
    const double cross = b.real() * cc.imag() - b.imag() * cc.real();
    if (std::abs(cross) <= 1e-14 * std::max(std::norm(b), std::norm(cc))) {
      ++out.degenerate_triangles;
      continue;
    }
    if (cross < 0) {
      ++out.flipped_triangles;
      continue;
    }
    const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                          p2 = source.V.row(source.F(f, 2));
    const Eigen::Vector3d ss((p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm());
    const Eigen::Vector3d is(hyperbolic::distance(img(f, 0), img(f, 1)), hyperbolic::distance(img(f, 1), img(f, 2)),
                             hyperbolic::distance(img(f, 2), img(f, 0)));
    const double d = triangle_dilatation(ss, is);
    out.dilatation[f] = d;
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    weighted += area * d;
    total_area += area;
    out.max_dilatation = std::max(out.max_dilatation, d);
  }
  out.mean_dilatation = weighted / std::max(total_area, 1e-300);
  out.initial_mean_dilatation = std::numeric_limits<double>::quiet_NaN();
  out.initial_max_dilatation = std::numeric_limits<double>::quiet_NaN();
  if (out.flipped_triangles || out.degenerate_triangles)
    throw SolveError("the optimised map has " + std::to_string(out.flipped_triangles) + " flipped and " +
                     std::to_string(out.degenerate_triangles) + " degenerate image triangles; it is not returned");
  out.source_image = zp;
  stage_done("quality", 0.75);

  // Location, with geodesic triangles as straight ones in the Klein model.
  // How far (in Klein units) a point lies outside P; 0 inside.
  auto outside_P = [&](Complex z) {
    const Complex k = hyperbolic::poincare_to_klein(z);
    double out_by = 0;
    for (int i = 0; i < nsides; ++i) {
      const Complex e = kcorner[(i + 1) % nsides] - kcorner[i], d = k - kcorner[i];
      out_by = std::max(out_by, -(e.real() * d.imag() - e.imag() * d.real()) / std::abs(e));
    }
    return out_by;
  };
  // Points are first reduced into P. The mesh regions differ from P only
  // near its sides and corners, so the containing triangle is in an image
  // of the point under side maps that keep it near P (around a corner up to
  // 4g of them): breadth first over those, pruning images far from P.
  auto locate = [&](const TriangleGrid& grid, Complex z, Eigen::Vector3d* bary) {
    reduce_into_polygon(z);
    // Exhaustively up to two side maps (the usual case: the mesh's cut
    // sides bulge away from P's geodesic sides) ...
    int f = grid.locate(hyperbolic::poincare_to_klein(z), bary);
    for (int a1 = 0; f < 0 && a1 < nsides; ++a1) {
      const Complex w = side_map[a1].apply(z);
      f = grid.locate(hyperbolic::poincare_to_klein(w), bary);
      for (int a2 = 0; f < 0 && a2 < nsides; ++a2)
        f = grid.locate(hyperbolic::poincare_to_klein(side_map[a2].apply(w)), bary);
    }
    if (f >= 0) return f;
    // ... then breadth first over longer words (around corners up to 4g),
    // pruning images that are far from P.
    std::vector<Complex> frontier{z};
    std::set<std::pair<long long, long long>> seen;
    auto key = [](Complex w) { return std::make_pair(std::llround(w.real() * 1e9), std::llround(w.imag() * 1e9)); };
    seen.insert(key(z));
    for (int depth = 1; depth <= nsides && !frontier.empty() && seen.size() < 20000; ++depth) {
      std::vector<Complex> next;
      for (Complex w : frontier)
        for (const auto& m : side_map) {
          const Complex q = m.apply(w);
          if (outside_P(q) > 0.5 || !seen.insert(key(q)).second) continue;
          if ((f = grid.locate(hyperbolic::poincare_to_klein(q), bary)) >= 0) return f;
          next.push_back(q);
        }
      frontier.swap(next);
    }
    return -1;
  };
  const int ntf = tl.mesh.num_faces();
  std::vector<std::array<Complex, 3>> ttris(ntf);
  for (int f = 0; f < ntf; ++f)
    for (int k = 0; k < 3; ++k) ttris[f][k] = hyperbolic::poincare_to_klein(layout.corners(f, k));
  const TriangleGrid tgrid(ttris);
  std::vector<int> refined_face_origin(ntf, -1);
  out.forward.resize(source.num_vertices());
  for (int i = 0; i < source.num_vertices(); ++i) {
    Eigen::Vector3d b;
    const int rf = locate(tgrid, zp[i], &b);
    if (rf < 0) throw SolveError("source vertex " + std::to_string(i) + " could not be located on the target");
    out.forward[i] = point_on_input(target, tc, tl, refined_face_origin, rf, b);
  }
  stage_done("forward location", 0.85);
  std::vector<std::array<Complex, 3>> stris(source.num_faces());
  for (int f = 0; f < source.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) stris[f][k] = hyperbolic::poincare_to_klein(img(f, k));
  const TriangleGrid sgrid(stris);
  out.inverse.resize(target.num_vertices());
  for (int v = 0; v < target.num_vertices(); ++v) {
    Eigen::Vector3d b;
    const int f = locate(sgrid, layout.vertex_positions[v], &b);
    if (f < 0) throw SolveError("target vertex " + std::to_string(v) + " could not be located in the source image");
    out.inverse[v] = point_in_face(source, f, b);
  }
  stage_done("inverse location", 1.0);
}

}  // namespace

SurfaceMapResult surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options) {
  SurfaceMapResult out;
  const auto t_start = Clock::now();
  auto t_stage = t_start;
  auto stage_done = [&](const std::string& name, double fraction) {
    const auto now = Clock::now();
    out.stage_times.emplace_back(name, std::chrono::duration<double>(now - t_stage).count());
    t_stage = now;
    if (options.progress && !options.progress(name, fraction)) throw Cancelled("cancelled after stage " + name);
  };

  const Connectivity sc(source.F, source.num_vertices());
  const Connectivity tc(target.F, target.num_vertices());
  if (sc.genus() != tc.genus())
    throw InputError("the source has genus " + std::to_string(sc.genus()) + " but the target has genus " +
                     std::to_string(tc.genus()) + "; both surfaces must have the same genus");
  out.genus = sc.genus();
  if (out.genus == 0)
    throw InputError("surface maps of genus 0 are not implemented yet; genus >= 1 is");
  if (out.genus >= 2) {
    map_hyperbolic(source, target, sc, tc, options, out, stage_done);
    out.total_time = std::chrono::duration<double>(Clock::now() - t_start).count();
    return out;
  }

  // Target: flat uniformization and canonical lattice basis.
  const FlatTarget tgt = flat_target(target, options);
  stage_done("target uniformization", 0.3);

  // Source: homotopy data.
  const SystemOfLoops sl = source_loops(source, options);
  const CanonicalSchema scs = canonical_schema(sl.word);
  const std::vector<int> first = loop_first_vertices(sl, sc);

  // Source weights: intrinsic Delaunay cotangents of its 3D metric.
  Eigen::VectorXd lengths = edge_lengths(source, sc);
  const IntrinsicDelaunayResult idt = intrinsic_delaunay(sc, lengths);
  if (!idt.delaunay) throw SolveError("the source's intrinsic Delaunay flips did not finish");
  stage_done("source homotopy data and weights", 0.4);

  // Laplacian with vertex 0 pinned (the optimum is unique up to translation).
  const int n = source.num_vertices();
  auto factor = [&](bool uniform) {
    std::vector<Eigen::Triplet<double>> trip;
    for (const auto& e : idt.edges) {
      const double w = uniform ? 1.0 : e.cot_weight;
      if (w == 0) continue;
      for (auto [a, b, s] : {std::tuple{e.i, e.i, w}, std::tuple{e.j, e.j, w}, std::tuple{e.i, e.j, -w},
                             std::tuple{e.j, e.i, -w}})
        if (a > 0 && b > 0) trip.emplace_back(a - 1, b - 1, s);
    }
    Eigen::SparseMatrix<double> L(n - 1, n - 1);
    L.setFromTriplets(trip.begin(), trip.end());
    auto solver = std::make_unique<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>();
    solver->compute(L);
    if (solver->info() != Eigen::Success)
      throw SolveError("the source Laplacian could not be factorised (weights disconnect the mesh?)");
    return solver;
  };
  const auto solver = factor(false);
  const auto tutte = factor(true);

  // Translation of each intrinsic edge for a given homotopy class.
  auto intrinsic_translations = [&](const Complex a_img, const Complex b_img) {
    std::vector<Complex> letter_values;
    for (const Word& w : scs.letters) letter_values.push_back(evaluate(w, {a_img, b_img}));
    const std::vector<Complex> edge_t = edge_group_elements(sc, sl.tree_parent_halfedge, sl.dual_tree_parent_halfedge,
                                                            sl.generator_edges, first, letter_values, kTranslations);
    auto of = [&](int h) { return sc.edge_halfedge(sc.edge(h)) == h ? edge_t[sc.edge(h)] : -edge_t[sc.edge(h)]; };
    // Around every face (the root of T* included) the translations must
    // cancel: the abelianised surface relation.
    const double scale = std::abs(a_img) + std::abs(b_img);
    for (int f = 0; f < source.num_faces(); ++f)
      if (std::abs(of(3 * f) + of(3 * f + 1) + of(3 * f + 2)) > 1e-9 * scale)
        throw SolveError("homotopy data inconsistent around source face " + std::to_string(f));
    std::vector<Complex> t(idt.edges.size());
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      Complex s = 0;
      for (int h : idt.edges[e].path) s += of(h);
      t[e] = s;
    }
    return std::make_pair(t, std::vector<Complex>(edge_t));
  };
  // Solve L z = b with b_i += w t, b_j -= w t for each edge i->j (image of the
  // edge runs from z_i to z_j + t, energy w |z_j + t - z_i|^2, whose
  // gradient in z_i is 2w (z_i - z_j - t)).
  auto solve = [&](const auto& factorisation, const std::vector<Complex>& t, bool uniform) {
    Eigen::VectorXd bx = Eigen::VectorXd::Zero(n), by = Eigen::VectorXd::Zero(n);
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      const auto& ie = idt.edges[e];
      const double w = uniform ? 1.0 : ie.cot_weight;
      bx[ie.i] += w * t[e].real(), by[ie.i] += w * t[e].imag();
      bx[ie.j] -= w * t[e].real(), by[ie.j] -= w * t[e].imag();
    }
    const Eigen::VectorXd x = factorisation->solve(bx.tail(n - 1)), y = factorisation->solve(by.tail(n - 1));
    std::vector<Complex> z(n, 0.0);
    for (int i = 1; i < n; ++i) z[i] = Complex(x[i - 1], y[i - 1]);
    double energy = 0;
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      const auto& ie = idt.edges[e];
      energy += ie.cot_weight * std::norm(z[ie.j] + t[e] - z[ie.i]);
    }
    return std::make_pair(z, energy);
  };

  // Candidate classes: a -> p A + q B, b -> r A + s B for small SL(2,Z)
  // matrices (the handle correspondences of a torus), up to the sign ±I,
  // which gives the same energy (the hyperelliptic involution).
  std::vector<std::array<int, 4>> mats;
  for (int p = -1; p <= 1; ++p)
    for (int q = -1; q <= 1; ++q)
      for (int r = -1; r <= 1; ++r)
        for (int s2 = -1; s2 <= 1; ++s2) {
          if (p * s2 - q * r != 1) continue;
          const bool canonical_sign = p > 0 || (p == 0 && q > 0);
          if (canonical_sign) mats.push_back({p, q, r, s2});
        }
  std::sort(mats.begin(), mats.end(), [](const auto& m1, const auto& m2) {
    auto cost = [](const auto& m) { return std::abs(m[0]) + std::abs(m[1]) + std::abs(m[2]) + std::abs(m[3]); };
    return cost(m1) < cost(m2);
  });
  for (const auto& m : mats) {
    HomotopyCandidate c;
    std::copy(m.begin(), m.end(), c.matrix);
    c.description = "a -> " + std::to_string(m[0]) + " a' + " + std::to_string(m[1]) + " b',  b -> " +
                    std::to_string(m[2]) + " a' + " + std::to_string(m[3]) + " b'";
    const auto tr = intrinsic_translations(double(m[0]) * tgt.A + double(m[1]) * tgt.B,
                                           double(m[2]) * tgt.A + double(m[3]) * tgt.B);
    c.energy = solve(solver, tr.first, false).second;
    out.candidates.push_back(c);
  }
  out.chosen_candidate = options.homotopy;
  if (out.chosen_candidate < 0) {
    out.chosen_candidate = 0;
    for (size_t i = 1; i < out.candidates.size(); ++i)
      if (out.candidates[i].energy < out.candidates[out.chosen_candidate].energy) out.chosen_candidate = static_cast<int>(i);
  } else if (out.chosen_candidate >= static_cast<int>(out.candidates.size())) {
    throw InputError("homotopy class " + std::to_string(options.homotopy) + " does not exist; there are " +
                     std::to_string(out.candidates.size()) + " candidates (0.." +
                     std::to_string(out.candidates.size() - 1) + ")");
  }
  stage_done("homotopy candidates", 0.6);

  const int* M = out.candidates[out.chosen_candidate].matrix;
  const auto [t_intrinsic, t_edges] = intrinsic_translations(double(M[0]) * tgt.A + double(M[1]) * tgt.B,
                                                             double(M[2]) * tgt.A + double(M[3]) * tgt.B);
  const auto [z_init, e_init_unused] = solve(tutte, t_intrinsic, true);
  (void)e_init_unused;
  auto [z, energy] = solve(solver, t_intrinsic, false);
  // The optimum is unique up to a translation of the torus; put the source's
  // base vertex where the target's base vertex lies (both are central
  // vertices of their shapes), a reproducible and usually natural choice.
  const Complex shift = tgt.layout.vertex_positions[tgt.loops.base_vertex] - z[sl.base_vertex];
  for (Complex& zi : z) zi += shift;
  double e_init = 0;
  for (size_t e = 0; e < idt.edges.size(); ++e) {
    const auto& ie = idt.edges[e];
    e_init += ie.cot_weight * std::norm(z_init[ie.j] + t_intrinsic[e] - z_init[ie.i]);
  }
  out.initial_energy = e_init;
  out.final_energy = energy;
  out.energy_history.assign({e_init, static_cast<double>(energy)});
  out.iterations = 1;
  out.converged = true;
  out.source_image = z;
  out.target_omega1 = tgt.A;
  out.target_omega2 = tgt.B;
  stage_done("harmonic solve", 0.7);

  // Quality on the source's own triangles.
  auto image_corners = [&](const std::vector<Complex>& zz) {
    Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(source.num_faces(), 3);
    auto of = [&](int h) { return sc.edge_halfedge(sc.edge(h)) == h ? t_edges[sc.edge(h)] : -t_edges[sc.edge(h)]; };
    for (int f = 0; f < source.num_faces(); ++f) {
      // corner 0 at z_{F0}; corner 1 = z_{F1} + t(F0->F1); corner 2 = z_{F2} - t(F2->F0).
      img(f, 0) = zz[source.F(f, 0)];
      img(f, 1) = zz[source.F(f, 1)] + of(3 * f);
      img(f, 2) = zz[source.F(f, 2)] - of(3 * f + 2);
    }
    return img;
  };
  const auto img = image_corners(z);
  const DistortionStats q = planar_distortion(source.V, source.F, img);
  const DistortionStats q0 = planar_distortion(source.V, source.F, image_corners(z_init));
  out.dilatation = q.per_face;
  out.mean_dilatation = q.mean;
  out.max_dilatation = q.max;
  out.flipped_triangles = q.flipped;
  out.degenerate_triangles = q.degenerate;
  out.initial_mean_dilatation = q0.mean;
  out.initial_max_dilatation = q0.max;
  out.initial_flipped_triangles = q0.flipped;
  // The energy lives on the intrinsic triangulation, where positive weights
  // guarantee an embedding; count its image triangles too.
  int intrinsic_flipped = 0;
  for (int f = 0; f < idt.F.rows(); ++f) {
    Complex c[3];
    c[0] = z[idt.F(f, 0)];
    for (int k = 1; k < 3; ++k) {
      const int e = idt.face_edges(f, k - 1);  // side from corner k-1 to corner k
      const auto& ie = idt.edges[e];
      const bool along = ie.i == idt.F(f, k - 1) && ie.j == idt.F(f, k);
      c[k] = c[k - 1] + (along ? (z[ie.j] + t_intrinsic[e] - z[ie.i]) : -(z[ie.j] + t_intrinsic[e] - z[ie.i]));
    }
    const Complex e1 = c[1] - c[0], e2 = c[2] - c[0];
    if (e1.real() * e2.imag() - e1.imag() * e2.real() <= 0) ++intrinsic_flipped;
  }
  if (q.flipped || q.degenerate)
    throw SolveError("the optimised map has " + std::to_string(q.flipped) + " flipped and " +
                     std::to_string(q.degenerate) + " degenerate image triangles (" +
                     std::to_string(intrinsic_flipped) + " in the intrinsic triangulation); it is not returned");
  stage_done("quality", 0.75);

  // Forward map: locate every z_i in the target's disk (modulo the lattice).
  const int ntf = tgt.loops.mesh.num_faces();
  std::vector<std::array<Complex, 3>> ttris(ntf);
  Complex centre = 0;
  for (int f = 0; f < ntf; ++f) {
    for (int k = 0; k < 3; ++k) ttris[f][k] = tgt.layout.corners(f, k);
    centre += (ttris[f][0] + ttris[f][1] + ttris[f][2]) / 3.0;
  }
  centre /= double(ntf);
  const TriangleGrid tgrid(ttris);
  std::vector<int> refined_face_origin(ntf, -1);
  out.forward.resize(n);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d b;
    const int rf = locate_periodic(tgrid, z[i], centre, tgt.A, tgt.B, &b);
    if (rf < 0) throw SolveError("source vertex " + std::to_string(i) + " could not be located on the target");
    out.forward[i] = point_on_input(target, tc, tgt.loops, refined_face_origin, rf, b);
  }
  stage_done("forward location", 0.85);

  // Inverse map: locate every target vertex in the image of the source triangles.
  std::vector<std::array<Complex, 3>> stris(source.num_faces());
  Complex scentre = 0;
  for (int f = 0; f < source.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) stris[f][k] = img(f, k);
    scentre += (stris[f][0] + stris[f][1] + stris[f][2]) / 3.0;
  }
  scentre /= double(source.num_faces());
  const TriangleGrid sgrid(stris);
  out.inverse.resize(target.num_vertices());
  for (int v = 0; v < target.num_vertices(); ++v) {
    Eigen::Vector3d b;
    const int f = locate_periodic(sgrid, tgt.layout.vertex_positions[v], scentre, tgt.A, tgt.B, &b);
    if (f < 0) throw SolveError("target vertex " + std::to_string(v) + " could not be located in the source image");
    out.inverse[v] = point_in_face(source, f, b);
  }
  stage_done("inverse location", 1.0);
  out.total_time = std::chrono::duration<double>(Clock::now() - t_start).count();
  return out;
}

}  // namespace surfmap
