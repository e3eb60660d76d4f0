// Genus 1: the flat-torus case of the optimal map (docs/method.md §2.8).
#include <algorithm>
#include <utility>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>

#include "landmarks.h"
#include "map_support.h"
#include "stages/flat_landmarks.h"
#include "stages/flat_location.h"
#include "stages/flat_overlay.h"
#include "stages/landmark_ranking.h"
#include "stages/source_weights_fallback.h"
#include "surfmap/error.h"
#include "surfmap/work_counters.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/point_location.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/edge_homotopy.h"

namespace surfmap::detail {
namespace {

using ComplexL = std::complex<long double>;

std::vector<Complex> rounded(const std::vector<ComplexL>& zl) {
  std::vector<Complex> z(zl.size());
  for (size_t i = 0; i < zl.size(); ++i) z[i] = Complex(static_cast<double>(zl[i].real()), static_cast<double>(zl[i].imag()));
  return z;
}

const GroupOps<Complex> kTranslations{Complex(0.0), [](const Complex& a, const Complex& b) { return a + b; },
                                      [](const Complex& a) { return -a; }};

// Evaluates a word whose letters index `values` (1-based) in the translation group.
Complex evaluate(const Word& w, const std::vector<Complex>& values) {
  Complex s = 0;
  for (int x : w) s += (x > 0 ? 1.0 : -1.0) * values[std::abs(x) - 1];
  return s;
}

// Everything about the target that the solve needs: its flat uniformization
// (layout on the refined mesh of its system of loops, the metric's account)
// and the canonical lattice basis.
struct FlatTarget : UniformizedTarget {
  Complex A, B;  // translations of the canonical generators a', b'
};

FlatTarget flat_target(const TriMesh& target, const Connectivity& tc, const SurfaceMapOptions& options) {
  FlatTarget t;
  static_cast<UniformizedTarget&>(t) = uniformized_target(target, Background::Euclidean, options, &tc);
  const CanonicalSchema cs = canonical_schema(t.layout.word);
  t.A = evaluate(cs.generators[0], t.layout.generator_translations);
  t.B = evaluate(cs.generators[1], t.layout.generator_translations);
  return t;
}

// The source's Laplacian (cotangent weights of `idt`, or uniform ones for
// the Tutte-type initial map) with vertex 0 pinned, factorised once and
// solved for every class's translations.
class FlatSolver {
 public:
  FlatSolver(int n, const IntrinsicDelaunayResult& idt, bool uniform) : n_(n), idt_(idt), uniform_(uniform) {
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
    factorisation_ = std::make_unique<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>();
    factorisation_->compute(L);
    ++work::analyses, ++work::factorisations;
    if (factorisation_->info() != Eigen::Success)
      throw SolveError("the source Laplacian could not be factorised (weights disconnect the mesh?)");
  }
  // Solves L z = b with b_i += w t, b_j -= w t for each edge i->j (image of
  // the edge runs from z_i to z_j + t, energy w |z_j + t - z_i|^2, whose
  // gradient in z_i is 2w (z_i - z_j - t)); returns z and the cotangent
  // energy.
  std::pair<std::vector<Complex>, double> solve(const std::vector<Complex>& t) const {
    const std::vector<ComplexL> zl = solve_extended(t);
    return std::make_pair(rounded(zl), energy_of(zl, t));
  }
  // The same solution in long double (extended_solve below): where the
  // harmonic map crowds triangles to ~1e-14 of the torus, their shapes are
  // only known to long double's 64-bit mantissa (docs/robustness.md).
  std::vector<ComplexL> solve_extended(const std::vector<Complex>& t) const {
    const int n = n_;
    const IntrinsicDelaunayResult& idt = idt_;
    Eigen::VectorXd bx = Eigen::VectorXd::Zero(n), by = Eigen::VectorXd::Zero(n);
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      const auto& ie = idt.edges[e];
      const double w = uniform_ ? 1.0 : ie.cot_weight;
      bx[ie.i] += w * t[e].real(), by[ie.i] += w * t[e].imag();
      bx[ie.j] -= w * t[e].real(), by[ie.j] -= w * t[e].imag();
    }
    const Eigen::VectorXd x = factorisation_->solve(bx.tail(n - 1)), y = factorisation_->solve(by.tail(n - 1));
    std::vector<ComplexL> zl(n, 0.0L);
    for (int i = 1; i < n; ++i) zl[i] = {x[i - 1], y[i - 1]};
    refine(t, zl);
    return zl;
  }
  // The cotangent energy of points zl (#V) with translations t (#idt edges).
  double energy_of(const std::vector<ComplexL>& zl, const std::vector<Complex>& t) const {
    long double energy = 0;
    for (size_t e = 0; e < idt_.edges.size(); ++e) {
      const auto& ie = idt_.edges[e];
      energy += static_cast<long double>(ie.cot_weight) * std::norm(zl[ie.j] + ComplexL(t[e]) - zl[ie.i]);
    }
    return static_cast<double>(energy);
  }

 private:
  // Mixed-precision iterative refinement (residual in long double, the
  // correction from the same factorisation): the solution to the rounding
  // of its own coordinates, not to cond(L) times it. Long protrusions
  // (g1_camel's legs) are crowded by the harmonic map into image triangles
  // of 1e-14 of the torus, whose orientation a plain solve gets wrong.
  // Rounds until the correction is below long double's rounding of the
  // largest coordinate (or 12 rounds; each gains ~-log10(cond(L) eps) digits).
  void refine(const std::vector<Complex>& t, std::vector<ComplexL>& zl) const {
    const int n = n_;
    for (int round = 0; round < 12; ++round) {
      std::vector<ComplexL> r(n, 0.0L);
      for (size_t e = 0; e < idt_.edges.size(); ++e) {
        const auto& ie = idt_.edges[e];
        const long double w = uniform_ ? 1.0L : static_cast<long double>(ie.cot_weight);
        const ComplexL d = zl[ie.j] + ComplexL(t[e]) - zl[ie.i];
        r[ie.i] += w * d, r[ie.j] -= w * d;
      }
      Eigen::VectorXd rx(n - 1), ry(n - 1);
      for (int i = 1; i < n; ++i) rx[i - 1] = static_cast<double>(r[i].real()), ry[i - 1] = static_cast<double>(r[i].imag());
      const Eigen::VectorXd dx = factorisation_->solve(rx), dy = factorisation_->solve(ry);
      long double largest = 0, step = 0;
      for (int i = 1; i < n; ++i) {
        zl[i] += ComplexL(dx[i - 1], dy[i - 1]);
        largest = std::max(largest, std::abs(zl[i]));
        step = std::max(step, std::abs(ComplexL(dx[i - 1], dy[i - 1])));
      }
      if (!(step > 4 * std::numeric_limits<long double>::epsilon() * largest)) break;
    }
  }

  int n_;
  const IntrinsicDelaunayResult& idt_;
  bool uniform_;
  std::unique_ptr<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>> factorisation_;
};

// The image triangles of the source's own faces for a class's edge
// translations `te` (#E) and points `zz` (#V): corner 0 at z_{F0}; corner 1
// = z_{F1} + t(F0->F1); corner 2 = z_{F2} - t(F2->F0).
Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> flat_image_corners(const TriMesh& source, const Connectivity& sc,
                                                                             const std::vector<Complex>& te,
                                                                             const std::vector<Complex>& zz) {
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(source.num_faces(), 3);
  auto of = [&](int h) { return sc.edge_halfedge(sc.edge(h)) == h ? te[sc.edge(h)] : -te[sc.edge(h)]; };
  for (int f = 0; f < source.num_faces(); ++f) {
    img(f, 0) = zz[source.F(f, 0)];
    img(f, 1) = zz[source.F(f, 1)] + of(3 * f);
    img(f, 2) = zz[source.F(f, 2)] - of(3 * f + 2);
  }
  return img;
}

// The image triangles as in flat_image_corners, from points `zl` (#V) in
// long double, each translated so that its corner 0 is at the origin:
// the shapes of triangles crowded to ~1e-14 of the torus keep long
// double's relative precision (in absolute coordinates of size 1 they
// would have a few ulps per side), for orientation counts and D'.
Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> flat_image_shapes(const TriMesh& source, const Connectivity& sc,
                                                                            const std::vector<Complex>& te,
                                                                            const std::vector<ComplexL>& zl) {
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(source.num_faces(), 3);
  auto of = [&](int h) { return sc.edge_halfedge(sc.edge(h)) == h ? te[sc.edge(h)] : -te[sc.edge(h)]; };
  auto to_double = [](const ComplexL& c) { return Complex(static_cast<double>(c.real()), static_cast<double>(c.imag())); };
  for (int f = 0; f < source.num_faces(); ++f) {
    const ComplexL c0 = zl[source.F(f, 0)];
    img(f, 0) = 0;
    img(f, 1) = to_double(zl[source.F(f, 1)] + ComplexL(of(3 * f)) - c0);
    img(f, 2) = to_double(zl[source.F(f, 2)] - ComplexL(of(3 * f + 2)) - c0);
  }
  return img;
}

// Classes whose free energies agree to this relative tolerance are the same
// optimum up to a symmetry of the shapes (M and -M exactly; a square or
// hexagonal lattice's rotations up to discretisation): the 3D overlay
// chooses among them (stages/flat_overlay.h).
constexpr double kFlatEnergyTie = 1e-4;

// Candidate classes: a -> p A + q B, b -> r A + s B for small SL(2,Z)
// matrices (the handle correspondences of a torus), simplest first. Without
// landmarks up to the sign ±I, which gives the same energy (the hyperelliptic
// involution). With landmarks (HomotopyOptions::flat_both_signs, default
// on) both signs: M and -M hold the landmarks with different energies (with
// two or more landmarks the half turn z -> -z moves them apart), so the
// ranking needs both (docs/handle_classes.md, "Genus 1: the two signs").
std::vector<std::array<int, 4>> candidate_matrices(bool both_signs) {
  std::vector<std::array<int, 4>> mats;
  for (int p = -1; p <= 1; ++p)
    for (int q = -1; q <= 1; ++q)
      for (int r = -1; r <= 1; ++r)
        for (int s2 = -1; s2 <= 1; ++s2) {
          if (p * s2 - q * r != 1) continue;
          const bool canonical_sign = p > 0 || (p == 0 && q > 0);
          if (canonical_sign || both_signs) mats.push_back({p, q, r, s2});
        }
  // Simplest first; of M and -M the canonical sign first (the order without
  // landmarks unchanged).
  std::stable_sort(mats.begin(), mats.end(), [](const auto& m1, const auto& m2) {
    auto cost = [](const auto& m) { return std::abs(m[0]) + std::abs(m[1]) + std::abs(m[2]) + std::abs(m[3]); };
    auto negative = [](const auto& m) { return m[0] < 0 || (m[0] == 0 && m[1] < 0); };
    return std::make_pair(cost(m1), negative(m1)) < std::make_pair(cost(m2), negative(m2));
  });
  return mats;
}

// Flipped images among the triangles of the intrinsic triangulation (the
// energy lives there, where positive weights guarantee an embedding), for
// points z and translations t (#idt edges).
template <class Scalar>
int flat_intrinsic_flipped(const IntrinsicDelaunayResult& idt, const std::vector<std::complex<Scalar>>& z,
                           const std::vector<Complex>& t_intrinsic) {
  using C = std::complex<Scalar>;
  int intrinsic_flipped = 0;
  for (int f = 0; f < idt.F.rows(); ++f) {
    C c[3];
    c[0] = 0;  // relative to corner 0 (only the shape counts)
    for (int k = 1; k < 3; ++k) {
      const int e = idt.face_edges(f, k - 1);  // side from corner k-1 to corner k
      const auto& ie = idt.edges[e];
      const bool along = idt.face_edge_forward(f, k - 1) != 0;
      const C side = z[ie.j] + C(t_intrinsic[e]) - z[ie.i];
      c[k] = c[k - 1] + (along ? side : -side);
    }
    const C e1 = c[1] - c[0], e2 = c[2] - c[0];
    if (e1.real() * e2.imag() - e1.imag() * e2.real() <= 0) ++intrinsic_flipped;
  }
  return intrinsic_flipped;
}

// How well the intrinsic triangles close (LayoutClosure): the lattice
// translations of each triangle's edges, oriented along it, sum to 0 for
// the true problem; the gap is |that sum| / `period` (the shorter period).
LayoutClosure flat_layout_closure(const IntrinsicDelaunayResult& idt, const std::vector<Complex>& t_intrinsic,
                                  double period) {
  return layout_closure(static_cast<int>(idt.F.rows()), [&](int f) {
    Complex sum = 0;
    for (int k = 0; k < 3; ++k) {
      const int e = idt.face_edges(f, k);
      sum += idt.face_edge_forward(f, k) ? t_intrinsic[e] : -t_intrinsic[e];
    }
    return std::abs(sum) / period;
  });
}

// The flat harmonic-map problem as solved (testing/map_hooks.h).
HarmonicProblem flat_problem(const IntrinsicDelaunayResult& idt, const std::vector<Complex>& t_intrinsic,
                             const std::vector<Complex>& z_init) {
  HarmonicProblem p;
  p.flat = true;
  p.num_vertices = static_cast<int>(z_init.size());
  for (size_t e = 0; e < idt.edges.size(); ++e) {
    p.flat_i.push_back(idt.edges[e].i), p.flat_j.push_back(idt.edges[e].j);
    p.flat_weight.push_back(idt.edges[e].cot_weight), p.flat_translation.push_back(t_intrinsic[e]);
  }
  p.start = z_init;
  return p;
}


// The homotopy data of the class a -> a_img, b -> b_img (docs/method.md §2.10, flat
// case: translations): the translation of every intrinsic edge (#idt edges)
// and of every source edge (#E, along its edge_halfedge); the translations
// around every source face (the root of T* included) must cancel, the
// abelianised surface relation (a SolveError names the face otherwise).
std::pair<std::vector<Complex>, std::vector<Complex>> class_translations(
    const TriMesh& source, const Connectivity& sc, const SystemOfLoops& sl, const CanonicalSchema& scs,
    const std::vector<int>& first, const IntrinsicDelaunayResult& idt, const Complex a_img, const Complex b_img) {
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
}


// The default genus-1 class: the requested one, else the lowest free
// energy, else with landmarks the lowest held energy (docs/method.md §2.10,
// stages/landmark_ranking.h: branch and bound on the plain pins' lower
// bounds, every class has one here; +inf where the landmarks cannot be held
// bijectively, a SolveError when that is every class). `hold(k)` holds the
// landmarks in class k; the chosen class's held map goes to `chosen_hold`.
int choose_flat_class(const SurfaceMapOptions& options, std::vector<HomotopyCandidate>& candidates,
                      const std::function<FlatHold(int k)>& hold, std::unique_ptr<FlatHold>* chosen_hold) {
  int chosen = options.homotopy.class_index;
  if (chosen < 0 && options.landmarks.empty()) {
    chosen = 0;
    for (size_t i = 1; i < candidates.size(); ++i)
      if (candidates[i].energy < candidates[chosen].energy) chosen = static_cast<int>(i);
  } else if (chosen < 0) {
    std::vector<int> order(candidates.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::vector<std::unique_ptr<FlatHold>> holds(candidates.size());
    const int best = landmark_branch_and_bound(order, candidates, [&](int k) -> std::optional<double> {
      holds[k] = std::make_unique<FlatHold>(hold(k));
      return holds[k]->energy;
    });
    if (best < 0)
      throw SolveError("the landmarks cannot be held bijectively in any of the " + std::to_string(candidates.size()) +
                       " homotopy classes tried");
    *chosen_hold = std::move(holds[best]);
    chosen = best;
  } else {
    check_candidate_index(chosen, static_cast<int>(candidates.size()), "homotopy class");
  }
  return chosen;
}

// What every pass of map_flat (one per choice of source weights) shares:
// the inputs, the target's flat uniformization and the source's homotopy data.
struct FlatInputs {
  const TriMesh& source;
  const TriMesh& target;
  const Connectivity& sc;
  const Connectivity& tc;
  const SurfaceMapOptions& options;
  const testing::MapHooks& hooks;
  const StageDone& stage_done;
  FlatTarget tgt;
  SystemOfLoops sl;
  CanonicalSchema scs;
  std::vector<int> first;
  Eigen::VectorXd lengths;  ///< #E source edge lengths
};

// The chosen class's optimum `z` (#V), its initial map `z_init` (#V),
// recorded in `out` with their energies, D' and the located
// correspondences; the translations of the intrinsic edges `t_intrinsic`
// and of the source's edges `t_edges`. False when its source faces fold and
// the automatic fallback switches the weights (source_weights_fallback.h).
bool record_flat_map(const FlatInputs& in, const IntrinsicDelaunayResult& idt, const std::vector<Complex>& t_intrinsic,
                     const std::vector<Complex>& t_edges, const std::vector<Complex>& z,
                     const std::vector<Complex>& z_init, const std::vector<ComplexL>* z_extended, double energy,
                     bool own_weights, SurfaceMapResult& out) {
  if (in.hooks.inspect_problem) in.hooks.inspect_problem(flat_problem(idt, t_intrinsic, z_init));
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
  out.target_omega1 = in.tgt.A;
  out.target_omega2 = in.tgt.B;
  in.stage_done("harmonic solve", 0.7);

  // Quality on the source's own triangles.
  auto image_corners = [&](const std::vector<Complex>& zz) { return flat_image_corners(in.source, in.sc, t_edges, zz); };
  const auto img = image_corners(z);
  store_distortion(planar_distortion(in.source.V, in.source.F, z_extended ? flat_image_shapes(in.source, in.sc, t_edges, *z_extended) : img), out);
  store_initial_distortion(planar_distortion(in.source.V, in.source.F, image_corners(z_init)), out);
  // The energy lives on the intrinsic triangulation, where positive weights
  // guarantee an embedding; count its image triangles too.
  out.intrinsic_flipped_triangles =
      z_extended ? flat_intrinsic_flipped(idt, *z_extended, t_intrinsic) : flat_intrinsic_flipped(idt, z, t_intrinsic);
  out.layout_closure = flat_layout_closure(idt, t_intrinsic, std::min(std::abs(in.tgt.A), std::abs(in.tgt.B)));
  // (landmarks_may_fold: the held map's folds are the caller's to keep.)
  if (!(in.options.landmarks_may_fold && !in.options.landmarks.empty()) && retry_with_own_weights(in.options, own_weights, out))
    return false;
  in.stage_done("quality", 0.75);

  // Location (stages/flat_location.h); the initial map is the uniform Tutte one.
  out.initial_map.construction = "uniform Tutte";
  out.initial_map.location_requested = in.options.initial.locate;
  FlatLocationResult located = locate_flat_map(in.source, in.target, in.tc, in.tgt.loops, in.tgt.intrinsic.get(), in.tgt.layout, in.tgt.A,
                                               in.tgt.B, z, z_extended, z_init, img, image_corners(z_init),
                                               in.options.initial.locate, in.stage_done);
  out.forward = std::move(located.forward);
  out.inverse = std::move(located.inverse);
  out.initial_forward = std::move(located.initial_forward);
  out.initial_inverse = std::move(located.initial_inverse);
  in.stage_done("inverse location", 1.0);
  return true;
}

// One pass of map_flat with the source weights `own_weights`: weights,
// solvers, (first pass) every candidate class's energy and the choice of
// class, the chosen class's optimum (with the landmarks held), then
// record_flat_map. False when the weights must switch.
bool flat_pass(const FlatInputs& in, bool own_weights, bool first_pass, SurfaceMapResult& out) {
  const SurfaceMapOptions& options = in.options;
  const FlatTarget& tgt = in.tgt;
  const IntrinsicDelaunayResult idt =
      own_weights ? positive_edge_weights(in.sc, in.lengths, {options.solve.own_weights_floor}) : delaunay_energy_weights(in.sc, in.lengths);
  if (!idt.delaunay) throw SolveError("the source's intrinsic Delaunay flips did not finish");
  out.source_weights = source_weights_name(own_weights, idt.raised_weights);
  in.stage_done("source homotopy data and weights", 0.4);

  // Laplacian with vertex 0 pinned (the optimum is unique up to
  // translation), cotangent and uniform (FlatSolver above).
  const int n = in.source.num_vertices();
  const FlatSolver solver(n, idt, false), tutte(n, idt, true);

  // Landmarks (landmarks.h): each source vertex held at the lift of its
  // target vertex nearest to where the unconstrained optimum puts it; the
  // classes are then ranked by their energy with the landmarks held.
  const bool landmarks = !options.landmarks.empty();
  std::vector<int> lm_source;
  std::vector<Complex> lm_target;
  for (const auto& [s, t] : options.landmarks)
    lm_source.push_back(s), lm_target.push_back(tgt.layout.vertex_positions[t]);
  std::unique_ptr<PinnedFlatHarmonic> pinned_cot;
  if (landmarks) {
    pinned_cot = std::make_unique<PinnedFlatHarmonic>(n, idt.edges, lm_source, false);
  }
  // (optimum, lifts) with the landmarks held.
  auto pinned_solve = [&](const std::vector<Complex>& t) {
    const std::vector<Complex> free = solver.solve(t).first;
    const std::vector<Complex> lifts = flat_landmark_lifts(free, lm_source, lm_target, tgt.A, tgt.B);
    return std::make_pair(pinned_cot->solve(t, lifts), lifts);
  };
  // The landmarks held in one class (stages/flat_landmarks.h).
  FlatLandmarkProblem lm_problem;
  lm_problem.source = &in.source, lm_problem.idt = &idt, lm_problem.landmarks = &options.landmarks;
  lm_problem.lm_source = lm_source, lm_problem.lm_target = lm_target, lm_problem.w1 = tgt.A, lm_problem.w2 = tgt.B;
  lm_problem.free_optimum = [&](const std::vector<Complex>& t) { return solver.solve(t).first; };
  lm_problem.pinned = pinned_cot.get();
  lm_problem.folds_allowed = options.landmarks_may_fold;
  lm_problem.image_corners = [&](const std::vector<Complex>& te, const std::vector<Complex>& zz) {
    return flat_image_corners(in.source, in.sc, te, zz);
  };
  auto hold_landmarks = [&](const std::vector<Complex>& t, const std::vector<Complex>& te) {
    return hold_flat_landmarks(lm_problem, t, te);
  };

  // Classes whose free energies agree to this relative tolerance are the same
// optimum up to a symmetry of the shapes (M and -M exactly; a square or
// hexagonal lattice's rotations up to discretisation): the 3D overlay
// chooses among them (stages/flat_overlay.h).
constexpr double kFlatEnergyTie = 1e-4;

// Candidate classes: a -> p A + q B, b -> r A + s B for small SL(2,Z)
  // matrices (the handle correspondences of a torus), up to the sign ±I,
  // which gives the same energy (the hyperelliptic involution); both signs
  // with landmarks (unless HomotopyOptions::flat_both_signs is off).
  const std::vector<std::array<int, 4>> mats =
      candidate_matrices(landmarks && in.options.homotopy.flat_both_signs);
  auto translations_of = [&](const int* m) {
    return class_translations(in.source, in.sc, in.sl, in.scs, in.first, idt,
                              double(m[0]) * tgt.A + double(m[1]) * tgt.B, double(m[2]) * tgt.A + double(m[3]) * tgt.B);
  };
  // (Ranked once: on the pass with own-edge weights the class chosen with
  // the intrinsic weights stays, and so do the candidates' energies.)
  // Each class's free optimum energy; with landmarks also its plain pins'
  // energy, the infimum over held maps (folded ones included) and so a
  // lower bound of the bijective held energy.
  for (const auto& m : first_pass ? mats : std::vector<std::array<int, 4>>{}) {
    HomotopyCandidate c;
    std::copy(m.begin(), m.end(), c.matrix);
    c.description = "a -> " + std::to_string(m[0]) + " a' + " + std::to_string(m[1]) + " b',  b -> " +
                    std::to_string(m[2]) + " a' + " + std::to_string(m[3]) + " b'";
    const auto tr = translations_of(c.matrix);
    c.energy = solver.solve(tr.first).second;
    if (landmarks) c.landmark_lower_bound = pinned_solve(tr.first).first.second;
    out.candidates.push_back(c);
  }
  // The default class (choose_flat_class), and with landmarks the chosen
  // class's held map from the ranking; the class chosen on the first pass stays.
  std::unique_ptr<FlatHold> chosen_hold;
  if (first_pass)
    out.chosen_candidate = choose_flat_class(options, out.candidates, [&](int k) {
      const auto tr = translations_of(out.candidates[k].matrix);
      return hold_landmarks(tr.first, tr.second);
    }, &chosen_hold);
  // Without landmarks nothing in the energy fixes the translation, nor the
  // choice between M and -M (the half turn z -> -z) or between classes
  // whose energies tie (a symmetric lattice): the 3D overlay decides
  // (stages/flat_overlay.h), so that a remeshed or posed copy maps to itself.
  const bool place_by_overlay = !landmarks && options.homotopy.flat_overlay;
  std::unique_ptr<FlatOverlay> overlay;
  if (place_by_overlay)
    overlay = std::make_unique<FlatOverlay>(in.source, in.target, tgt.layout.vertex_positions, tgt.A, tgt.B);
  std::string placement_class_note;
  if (place_by_overlay && first_pass && options.homotopy.class_index < 0) {
    const int by_energy = out.chosen_candidate;
    const double lowest = out.candidates[by_energy].energy;
    int best_k = by_energy;
    double best_sign = 1;
    FlatOverlayFit best_fit;
    best_fit.residual = std::numeric_limits<double>::infinity();
    for (int k = 0; k < static_cast<int>(out.candidates.size()); ++k) {
      if (!(out.candidates[k].energy <= lowest * (1 + kFlatEnergyTie))) continue;
      const std::vector<Complex> zk = solver.solve(translations_of(out.candidates[k].matrix).first).first;
      for (const double sign : {1.0, -1.0}) {
        std::vector<Complex> zs = zk;
        for (Complex& zi : zs) zi *= sign;  // the class -M: translations and optimum negated
        const FlatOverlayFit f = overlay->fit(zs);
        // The energy's choice stays unless another tied class overlaps
        // better; an overlay as posed beats one after a rotation.
        auto rank = [](const FlatOverlayFit& g) { return std::make_pair(g.as_posed ? 0 : g.overlaps ? 1 : 2, g.residual); };
        const bool better = k == by_energy && sign > 0 ? rank(f) < rank(best_fit) : f.overlaps && rank(f) < rank(best_fit);
        if (better) best_k = k, best_sign = sign, best_fit = f;
      }
    }
    // The list keeps one sign per class: the class listed becomes -M, the
    // sign the overlay picks (the same energy; a requested class index then
    // gives this map again).
    out.chosen_candidate = best_k;
    if (best_sign < 0) {
      HomotopyCandidate& c = out.candidates[best_k];
      for (int& x : c.matrix) x = -x;
      const int* m = c.matrix;
      c.description = "a -> " + std::to_string(m[0]) + " a' + " + std::to_string(m[1]) + " b',  b -> " +
                      std::to_string(m[2]) + " a' + " + std::to_string(m[3]) + " b'  [the sign -M: the same energy, the 3D overlay's]";
    }
    if (out.chosen_candidate != by_energy)
      placement_class_note = "; class " + std::to_string(out.chosen_candidate) + " instead of " +
                             std::to_string(by_energy) + " (their energies tie to 1e-4)";
    if (best_sign < 0) placement_class_note += "; the class's sign -M";
  }
  in.stage_done("homotopy candidates", 0.6);

  const int* M = out.candidates[out.chosen_candidate].matrix;
  const auto [t_intrinsic, t_edges] = translations_of(M);
  std::vector<Complex> z, z_init;
  std::vector<ComplexL> zl;  // without landmarks: the optimum in long double
  double energy = 0;
  if (landmarks) {
    // The ranking's held map of this class when it has one (first pass).
    const FlatHold h = chosen_hold ? std::move(*chosen_hold) : hold_landmarks(t_intrinsic, t_edges);
    if (options.homotopy.class_index >= 0 && first_pass) out.candidates[out.chosen_candidate].landmark_energy = h.energy;
    z = h.z, energy = h.energy;
    out.landmark_method = h.method;
    out.landmark_rings = h.rings;
    out.landmark_solves = h.solves;
    out.landmark_steps = h.steps;
    out.landmark_held_vertices = h.held_count;
    // The initial (Tutte-type) map holds the same vertices at the same points.
    z_init = PinnedFlatHarmonic(n, idt.edges, h.held, true).solve(t_intrinsic, h.values).first;
  } else {
    z_init = tutte.solve(t_intrinsic).first;
    zl = solver.solve_extended(t_intrinsic);
    energy = solver.energy_of(zl, t_intrinsic);
    // The optimum is unique up to a translation of the torus: the one that
    // carries it onto the 3D overlay of the shapes (a copy onto itself),
    // else, when the shapes do not overlap, the source's base vertex onto
    // the target's base vertex (both are central vertices of their shapes),
    // a reproducible choice.
    FlatOverlayFit fit;  // (overlaps false: the base vertex rule)
    if (overlay) fit = overlay->fit(rounded(zl));
    const Complex shift = fit.overlaps ? fit.shift : tgt.layout.vertex_positions[tgt.loops.base_vertex] - rounded(zl)[in.sl.base_vertex];
    for (ComplexL& zi : zl) zi += ComplexL(shift);
    z = rounded(zl);
    char residual[32];
    std::snprintf(residual, sizeof residual, "%.3g", fit.residual);
    out.flat_placement = !overlay      ? "base vertex onto the target's base vertex (homotopy.flat_overlay off)"
                         : fit.overlaps ? "3D overlay (" + fit.pose + "): mean residual " + residual + " of the torus's scale" + placement_class_note
                                        : "base vertex onto the target's base vertex (the shapes do not overlap: best overlay residual " +
                                              std::string(residual) + ")" + placement_class_note;
    // The initial map likewise (it is located below for the "before" morph).
    FlatOverlayFit fit0;
    if (overlay) fit0 = overlay->fit(z_init);
    const Complex shift0 = fit0.overlaps ? fit0.shift : tgt.layout.vertex_positions[tgt.loops.base_vertex] - z_init[in.sl.base_vertex];
    for (Complex& zi : z_init) zi += shift0;
  }
  return record_flat_map(in, idt, t_intrinsic, t_edges, z, z_init, landmarks ? nullptr : &zl, energy, own_weights,
                         out);
}

}  // namespace

// Genus 1 (docs/method.md §2.8, flat case): one exact sparse solve per class, in
// passes (flat_pass), one per choice of source weights: the automatic
// fallback (stages/source_weights_fallback.h) maps the chosen class again
// with positive weights on the source's own edges when the straight images
// of the user's faces fold with the intrinsic Delaunay cotangents (caps: a
// vertex just off the opposite edge; with positive weights on the mesh's own
// edges the harmonic map into the flat torus embeds the mesh itself, the
// Tutte-type theorem on the torus). The
// class chosen with the intrinsic weights stays.
void map_flat(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
              const SurfaceMapOptions& options, const testing::MapHooks& hooks, SurfaceMapResult& out,
              const StageDone& stage_done) {
  // Target: flat uniformization and canonical lattice basis.
  FlatInputs in{source, target, sc, tc, options, hooks, stage_done, flat_target(target, tc, options), {}, {}, {}, {}};
  record_target_metric(in.tgt, out);
  stage_done("target uniformization", 0.3);

  // Source: homotopy data and edge lengths.
  in.sl = source_loops(source, sc, options);
  in.scs = canonical_schema(in.sl.word);
  in.first = loop_first_vertices(in.sl, sc);
  in.lengths = edge_lengths(source, sc);
  bool own_weights = options.solve.source_weights == SourceWeights::OwnEdges;
  for (bool first_pass = true; !flat_pass(in, own_weights, first_pass, out); first_pass = false) own_weights = true;
}

}  // namespace surfmap::detail
