// Genus >= 2: the hyperbolic case of the optimal map (paper §VI; DESIGN.md §2.8, §7).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <future>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "concurrency.h"
#include "landmarks.h"
#include "map_support.h"
#include "surfmap/error.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/map/coarse_source.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/initial_map.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/edge_homotopy.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/mapping_class_search.h"
#include "surfmap/topology/projected_loops.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {
namespace {

// Point location by a straight walk in the universal cover: from a point
// inside face f along the geodesic towards q, face by face. corners(f) gives
// face f's three corners in its own frame (counter-clockwise); cross(f, s,
// c, q) returns the face across side s (corner s -> s+1) and moves the two
// points into that face's frame. The geodesic is straight in the Klein
// model, and every test runs in the chart centring q, so tiny triangles near
// |z| = 1 keep their digits; following the segment (rather than the most
// violated side) cannot cycle on a triangulation with long thin triangles.
// Returns the face with q's hyperboloid barycentrics, or -1.
template <class Corners, class Cross>
int straight_walk(int f, Complex q, const Corners& corners, const Cross& cross, int max_steps, double tol,
                  Eigen::Vector3d* bary) {
  auto orient = [](Complex a, Complex b, Complex c) {
    return (b.real() - a.real()) * (c.imag() - a.imag()) - (b.imag() - a.imag()) * (c.real() - a.real());
  };
  std::array<Complex, 3> t = corners(f);
  Complex c = hyperbolic::geodesic_point(t[0], hyperbolic::midpoint(t[1], t[2]), 2.0 / 3.0);
  int entry = -1;
  for (int step = 0; step < max_steps; ++step) {
    double l[3];
    hyperbolic::triangle_barycentric(q, t[0], t[1], t[2], l);
    if (std::min({l[0], l[1], l[2]}) >= -tol) {
      *bary = Eigen::Vector3d(l[0], l[1], l[2]);
      return f;
    }
    Complex k[3];
    for (int i = 0; i < 3; ++i) k[i] = hyperbolic::poincare_to_klein(hyperbolic::centred(q, t[i]));
    const Complex kc = hyperbolic::poincare_to_klein(hyperbolic::centred(q, c));
    // Exit side: crossed by the segment c -> q (q is the origin here), with q
    // beyond it; else the side opposite the most negative barycentric.
    int exit = -1;
    double best = 0;
    for (int s = 0; s < 3; ++s) {
      if (s == entry) continue;
      const Complex p0 = k[s], p1 = k[(s + 1) % 3];
      const double o0 = orient(kc, Complex(0.0), p0), o1 = orient(kc, Complex(0.0), p1);
      const double beyond = orient(p0, p1, Complex(0.0));
      if (o0 * o1 <= 0 && beyond < 0 && beyond < best) best = beyond, exit = s;
    }
    if (exit < 0) {
      int worst = 0;
      for (int i = 1; i < 3; ++i)
        if (l[i] < l[worst]) worst = i;
      exit = (worst + 1) % 3;  // the side opposite corner `worst`
    }
    int g_entry = -1;
    const int g = cross(f, exit, c, q, &g_entry);
    if (g < 0 || !(std::abs(q) < 1) || !(std::abs(c) < 1)) return -1;
    f = g;
    entry = g_entry;
    t = corners(f);
  }
  return -1;
}

// The effective element of halfedge h (tail's chart to head's) for a
// solution with per-vertex charts (HyperbolicHarmonicResult or
// HyperbolicInitialMapResult): from reduced side words when the solver kept
// them (no round-off of long deck matrices), else from the matrices.
template <class Charts>
hyperbolic::Mobius effective_element(const Charts& r, int h, const Connectivity& sc, const DeckGroup& group,
                                       const std::vector<Word>& halfedge_word, const std::vector<hyperbolic::Mobius>& halfedge_rho) {
  const int i = sc.tail(h), j = sc.head(h);
  if (r.vertex_deck_word.size() == r.z.size())
    return group.evaluate_side_word(group.reduce(concat({r.vertex_deck_word[i], halfedge_word[h], inverse(r.vertex_deck_word[j])})));
  return (r.vertex_deck[i] * halfedge_rho[h] * r.vertex_deck[j].inverse()).normalized();
}

}  // namespace

// Genus >= 2: hyperbolic target, harmonic map by preconditioned Riemannian
// Newton (map/hyperbolic_harmonic.h) or the paper's relaxation, in the handle
// correspondence of lowest energy among the candidates of
// topology/handle_basis.h and topology/projected_loops.h.
void map_hyperbolic(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                    const SurfaceMapOptions& options, SurfaceMapResult& out,
                    const StageDone& stage_done) {
  using hyperbolic::Mobius;
  const SingleThreadedBlas single_threaded_blas;  // concurrency.h: our own threads instead

  // The source's side of the homotopy data (loops, edge words, weights,
  // handle basis, coarse copy) needs no target: built on the second thread
  // while the target is uniformized (concurrency.h; its errors are rethrown
  // below, after the target's). With one thread it is built there, in order.
  const int threads = pipeline_threads(options.threads);
  struct SourceSide {
    SystemOfLoops sl;
    CanonicalSchema scs;
    std::vector<Word> edge_word;
    IntrinsicDelaunayResult idt;
    HandleBasis shb;
    CoarseSource cs;
  };
  bool own_weights = options.source_weights == SourceWeights::OwnEdges;
  const int nv = source.num_vertices();
  CoarseSourceOptions cso;
  cso.target_vertices = std::min(options.homotopy_coarse_vertices, nv / 4);
  auto build_source_side = [&] {
    SourceSide ss;
    ss.sl = source_loops(source, options);
    ss.scs = canonical_schema(ss.sl.word);
    // Deck elements are computed as words first and multiplied out only when
    // reduced: products like g g^-1 of large SU(1,1) matrices lose digits, and
    // the words of single edges are short (their crossings with the cut).
    std::vector<Word> src_letters;
    for (size_t k = 0; k < ss.scs.letters.size(); ++k) src_letters.push_back({static_cast<int>(k) + 1});
    const GroupOps<Word> free_group{Word{}, [](const Word& u, const Word& v) { return concat(u, v); },
                                    [](const Word& u) { return inverse(u); }};
    ss.edge_word = edge_group_elements(sc, ss.sl.tree_parent_halfedge, ss.sl.dual_tree_parent_halfedge,
                                       ss.sl.generator_edges, loop_first_vertices(ss.sl, sc), src_letters, free_group);
    // The energy's triangulation and weights: intrinsic Delaunay, or positive
    // weights on the source's own edges (options.source_weights; the automatic
    // fallback below switches when the user's faces fold).
    ss.idt = own_weights ? positive_edge_weights(sc, edge_lengths(source, sc))
                         : intrinsic_delaunay(sc, edge_lengths(source, sc));
    if (!ss.idt.delaunay) throw SolveError("the source's intrinsic Delaunay flips did not finish");
    ss.shb = handle_basis(source, ss.sl.loops, ss.scs);
    // The ranking level (below): a coarse copy of the source.
    if (options.homotopy_coarse_vertices > 0 && cso.target_vertices >= 500) ss.cs = coarse_source(source, sc, cso);
    return ss;
  };

  // The source-only part of lifting classes from other source cuts (below:
  // the loops at another base vertex, the default cut's generators as words
  // in that cut's, and its handle basis; ~0.2 s per cut at 50k vertices)
  // for every cut the class search may ask for, in the order it asks: the
  // homotopy_extra_cuts first, then stage 1's homotopy_search_cuts. The
  // second thread prepares the first ones after the source side, while the
  // target is still being uniformized; stage 1's are prepared on both
  // threads when it runs. Whichever thread prepares a cut, the result is
  // the same.
  struct CutPrep {
    bool ok = false;
    GroupMap psi;  ///< default canonical generator -> word in this cut's canonical generators
    HandleBasis shb;
    std::vector<std::vector<int>> loops;  ///< this cut's loops and canonical generators (for its overlay)
    std::vector<Word> generators;
  };
  struct CutSlot {
    int base = -1;
    std::once_flag once;
    CutPrep prep;
  };
  std::vector<int> prep_bases;
  if (options.homotopy_extra_cuts > 0) {
    for (int c = 1; c <= options.homotopy_extra_cuts; ++c)
      prep_bases.push_back(static_cast<int>((static_cast<long long>(nv) * c) / (options.homotopy_extra_cuts + 1)));
    if (options.homotopy_search && options.homotopy < 0)
      for (int c = 1; c <= options.homotopy_search_cuts; ++c)
        prep_bases.push_back(static_cast<int>((static_cast<long long>(nv) * c) / (options.homotopy_search_cuts + 1)));
  }
  std::vector<CutSlot> cut_slots(prep_bases.size());
  for (size_t k = 0; k < prep_bases.size(); ++k) cut_slots[k].base = prep_bases[k];
  // What preparing a cut needs of the default one (set before the source
  // side is handed over, read-only after).
  std::vector<std::vector<int>> default_loops;
  std::vector<Word> default_generators;
  auto prepare_cut = [&](CutSlot& slot) -> const CutPrep& {
    std::call_once(slot.once, [&] {
      CutPrep cp;
      const int n2 = 2 * out.genus;
      SurfaceMapOptions o2 = options;
      o2.source_base_vertex = slot.base;
      SystemOfLoops sl2;
      try {
        sl2 = source_loops(source, o2);
      } catch (const Error&) {
        slot.prep = std::move(cp);  // no system of loops at that vertex: the default one is enough
        return;
      }
      const CanonicalSchema scs2 = canonical_schema(sl2.word);
      const ProjectedLoopsResult self = project_loops(source, default_loops, sl2, sl2.word);
      if (self.ok) {
        const Word R2 = canonical_relator(out.genus);
        const IntMatrix J2 = symplectic_form(out.genus);
        cp.psi.assign(n2, Word{});
        for (int j = 0; j < n2; ++j)
          cp.psi[j] = dehn_reduce(substitute(substitute(default_generators[j], self.loop_images), scs2.letters), R2);
        const IntMatrix Mpsi = homology_matrix(cp.psi, n2);
        if (Mpsi.transpose() * J2 * Mpsi == J2 && dehn_reduce(substitute(R2, cp.psi), R2).empty()) {
          cp.shb = handle_basis(source, sl2.loops, scs2);
          cp.loops = sl2.loops;
          cp.generators = scs2.generators;
          cp.ok = true;
        }
      }
      slot.prep = std::move(cp);
    });
    return slot.prep;
  };
  std::atomic<bool> cut_prep_stop{false};
  std::promise<SourceSide> source_promise;
  std::future<SourceSide> source_side = source_promise.get_future();
  std::future<void> side_thread;
  if (threads > 1)
    side_thread = std::async(std::launch::async, [&] {
      try {
        SourceSide ss = build_source_side();
        default_loops = ss.sl.loops;
        default_generators = ss.scs.generators;
        source_promise.set_value(std::move(ss));
      } catch (...) {
        source_promise.set_exception(std::current_exception());
        return;
      }
      try {
        // Only the homotopy_extra_cuts, which are always lifted: the
        // machine's scheduler shares CPU between sessions, not threads
        // (autogroups), so under load speculative work on this thread slows
        // the other one down (10k genus 6, load 8, where stage 1 does not
        // run: 13-15 s with all 15 cuts prepared here against 9-10 s).
        for (int k = 0; k < static_cast<int>(cut_slots.size()) && k < options.homotopy_extra_cuts; ++k) {
          if (cut_prep_stop) break;
          prepare_cut(cut_slots[k]);
        }
      } catch (...) {
        // (prepared again where needed, which reports the error)
      }
    });
  // Raised before anything that needs the second thread, and on the way out
  // (the thread is joined by side_thread's destructor, after this).
  struct RaiseOnExit {
    std::atomic<bool>& flag;
    ~RaiseOnExit() { flag = true; }
  } raise_cut_prep_stop{cut_prep_stop};

  // Target: hyperbolic metric, layout, canonical generators.
  const UniformizedTarget ut = uniformized_target(target, Background::Hyperbolic, options);
  out.target_refinement_splits = ut.refinement_splits;
  const SystemOfLoops& tl = ut.loops;
  const DiskLayout& layout = ut.layout;
  const CanonicalSchema tcs = canonical_schema(layout.word);
  // Words are multiplied out through the polygon's side pairings, never
  // through the loop generators' (possibly huge) matrices: deck_group.h.
  const DeckGroup deck_group(layout);
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
  // Side i carries letter w_i; its side map is D_k for w_i = +(k+1) and
  // D_k^-1 for -(k+1), i.e. side letter w_i (DiskLayout::side_relator).
  std::vector<Mobius> side_map(nsides);
  for (int i = 0; i < nsides; ++i) side_map[i] = deck_group.evaluate_side_word(Word{layout.word[i]});
  // Moves z into P; returns the side word of the element applied.
  auto reduce_into_polygon = [&](Complex& z) {
    Word acc;
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
      acc.insert(acc.begin(), layout.word[worst]);
    }
    return acc;
  };
  stage_done("target uniformization", 0.3);

  // Source homotopy data in the target's deck group.
  SourceSide ss;
  if (threads > 1) {
    ss = source_side.get();
  } else {
    ss = build_source_side();
    default_loops = ss.sl.loops;
    default_generators = ss.scs.generators;
  }
  const SystemOfLoops& sl = ss.sl;
  const CanonicalSchema& scs = ss.scs;
  const std::vector<Word>& edge_word = ss.edge_word;
  IntrinsicDelaunayResult& idt = ss.idt;

  // Handle correspondences (topology/handle_basis.h): meridian/longitude
  // bases of both surfaces from linking numbers, signed handle permutations
  // between them, each an exact isomorphism of the canonical surface groups.
  const int n = 2 * out.genus;
  const Word R = canonical_relator(out.genus);
  const IntMatrix J = symplectic_form(out.genus);
  const HandleBasis& shb = ss.shb;
  HandleBasis thb = handle_basis(tl.mesh, tl.loops, tcs);
  // The classes induced by overlaying the two shapes
  // (topology/projected_loops.h): as posed, then after the rigid alignments
  // of rotation_overlay_poses for shapes not posed alike. For a remeshed
  // copy, as posed or turned, one of them is the identity; for shapes posed
  // alike up to a rotation they send handles to the handles they overlap.
  // Each must be an isomorphism (relator image trivial, symplectic
  // homology); poses whose images jump are refused by project_loops (but
  // see the fallback below).
  constexpr double kOverlayJump = 0.25;  // (see the fallback below)
  std::vector<OverlayPose> poses{{Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity(), "as posed"}};
  for (OverlayPose& p : rotation_overlay_poses(source, tl.mesh)) poses.push_back(std::move(p));
  // (Jumps are joined in the same pass, for the fallback below.)
  ProjectedLoopsOptions plo;
  plo.max_jump_box = kOverlayJump;
  const LoopProjector projector(tl, layout.word);
  const std::vector<ProjectedLoopsResult> projections = projector.project(source, sl.loops, poses, plo);
  auto overlay_class = [&](const ProjectedLoopsResult& proj, bool joined, GroupMap* theta) {
    if (!(joined ? proj.ok_with_joins && !proj.ok : proj.ok)) return false;
    theta->assign(n, Word{});
    for (int j = 0; j < n; ++j)
      (*theta)[j] = dehn_reduce(substitute(substitute(scs.generators[j], proj.loop_images), tcs.letters), R);
    const IntMatrix M = homology_matrix(*theta, n);
    return M.transpose() * J * M == J && dehn_reduce(substitute(R, *theta), R).empty();
  };
  // A class's fingerprint: the hyperbolic lengths in the target of the
  // images of the source's generators x_j and of x_i x_j^±1 (conjugation
  // invariant, so the same for every representative of an outer class;
  // classes differing by a Torelli element, same homology, differ here).
  // Equal fingerprints: the same class, or classes differing by an isometry
  // of the target, which have the same energy too.
  const DehnReducer fp_canonical(R), fp_target_loops(layout.word);
  auto fingerprint = [&](const GroupMap& theta) {
    std::vector<Word> probes;
    for (int i = 0; i < n; ++i) {
      probes.push_back({i + 1});
      for (int j = i + 1; j < n; ++j) probes.push_back({i + 1, j + 1}), probes.push_back({i + 1, -(j + 1)});
    }
    std::vector<double> lengths;
    for (const Word& w : probes) {
      const Word image = fp_target_loops(substitute(fp_canonical(substitute(w, theta)), tcs.generators));
      const Mobius m = deck_group.evaluate(image);
      lengths.push_back(2 * std::acosh(std::max(1.0, std::abs(m.a.real()) / std::sqrt(std::max(m.determinant(), 1e-300)))));
    }
    return lengths;
  };
  auto same_fingerprint = [](const std::vector<double>& x, const std::vector<double>& y) {
    if (x.empty() || x.size() != y.size()) return false;
    for (size_t k = 0; k < x.size(); ++k)
      if (!std::isfinite(x[k]) || !(std::abs(x[k] - y[k]) <= 1e-6 * std::max({1.0, x[k], y[k]}))) return false;
    return true;
  };
  struct NamedClass {
    GroupMap theta;
    std::string tag;
    std::vector<double> fingerprint;
  };
  std::vector<NamedClass> overlays;
  GroupMap overlay(n);
  bool have_overlay = false;  // candidate 0 is the overlay class as posed
  auto collect_overlays = [&](bool joined) {
    for (size_t p = 0; p < projections.size(); ++p) {
      GroupMap theta;
      if (!overlay_class(projections[p], joined, &theta)) continue;
      if (p == 0) have_overlay = true, overlay = theta;
      NamedClass c{theta,
                   (p == 0 ? "as the shapes overlap: loops carried to the nearest points"
                           : "as the shapes overlap after a rotation (" + poses[p].description + ")") +
                       (joined ? ", jumps joined" : ""),
                   fingerprint(theta)};
      bool seen = false;
      for (const NamedClass& o : overlays) seen = seen || same_fingerprint(o.fingerprint, c.fingerprint);
      if (!seen) overlays.push_back(std::move(c));
    }
  };
  collect_overlays(false);
  // No pose overlaps within the strict gap test: shapes alike in layout but
  // not in cross-section (a round tube over a square one) send a loop to the
  // nearest points of a wall on one side, then of a wall on the other
  // (n_hole_torus(3) -> polycube(3): jumps of 0.14-0.3 of the unit box on
  // every pose, so no overlay, and the lifted classes reached 4e4-1e5
  // letters, unsolvable: mean D' 123 from a twist search stuck at E 229
  // against the bound 50.3; with 0.15 resolution 32 of that pair still had
  // no joined overlay from any cut). Jumps up to kOverlayJump of the box are then
  // joined by the target's shortest path between the two images; a wrong
  // join gives a non-isomorphism (refused by overlay_class) or one more
  // candidate, ranked by its energy like the others.
  const bool strict_overlay = !overlays.empty();
  if (!strict_overlay) collect_overlays(true);
  if (have_overlay) {
    // The target's handles are then the overlay's images of the source's:
    // the other candidates are the overlay composed with a signed handle
    // permutation of the source (no lift on the target side, so no Torelli
    // ambiguity there), and descriptions are consistent with it.
    HandleBasis moved = shb;
    moved.P = homology_matrix(overlay, n) * shb.P;
    moved.to_canonical.map = compose(overlay, shb.to_canonical.map);
    for (Word& w : moved.to_canonical.map) w = dehn_reduce(w, R);
    moved.to_canonical.inverse.clear();  // not needed for a target basis
    thb = std::move(moved);
  }
  std::vector<HandleCandidate> handle_classes = handle_candidates(shb, thb, options.homotopy_candidates);
  // Source loop letter k as a word in the target's loop letters under theta.
  // Reduced after each substitution: the unreduced product of the three
  // substitutions grows like the product of their lengths (over 5e5 letters
  // for a twisted genus-3 class: minutes of Dehn reduction per candidate).
  const DehnReducer reduce_canonical(R), reduce_target_loops(layout.word);
  auto loop_letter_images = [&](const GroupMap& theta) {
    std::vector<Word> images;
    for (const Word& w : scs.letters)
      images.push_back(reduce_target_loops(substitute(reduce_canonical(substitute(w, theta)), tcs.generators)));
    return images;
  };
  auto loop_image_length = [&](const GroupMap& theta) {
    double total = 0;
    for (const Word& w : loop_letter_images(theta)) total += static_cast<double>(w.size());
    return total;
  };
  // A class whose loops' images are this long (in letters, summed over the
  // 2g loops) is not evaluated: its deck elements would be products of
  // hundreds of side pairings per edge, far beyond double precision (the
  // solve refuses points beyond ~70 hyperbolic units), and building its
  // homotopy data alone took minutes (lifted classes of some cuts reach 1e6
  // letters; the classes that solve have a few hundred at most).
  const double max_image_letters = 500.0 * n;
  // Screening score of a class: sum over the source's loops of (target
  // length of its image / its source length)^2, a rough stand-in for the
  // energy (a map's energy is at least the squared length of any curve's
  // image over the curve's extremal length), conjugation invariant, with no
  // solve (+inf when the images are too long to evaluate). Used to choose
  // which lifted classes of the extra cuts are solved and by the class
  // search (measured: the order agrees with the coarse energies' among the
  // twist neighbours of a class, 2.29 -> 26.7, 3.71 -> 46.8, 4.33 -> 63.9).
  std::vector<double> loop_length(sl.loops.size(), 0.0);
  for (size_t k = 0; k < sl.loops.size(); ++k)
    for (size_t q = 0; q + 1 < sl.loops[k].size(); ++q)
      loop_length[k] += (sl.mesh.V.row(sl.loops[k][q + 1]) - sl.mesh.V.row(sl.loops[k][q])).norm();
  auto class_screen = [&](const GroupMap& theta) {
    const std::vector<Word> images = loop_letter_images(theta);
    double letters = 0, score = 0;
    for (const Word& w : images) letters += static_cast<double>(w.size());
    if (letters > max_image_letters) return std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < images.size(); ++k) {
      const Mobius m = deck_group.evaluate(images[k]);
      const double t = std::abs(m.a.real()) / std::sqrt(std::max(m.determinant(), 1e-300));
      if (!std::isfinite(t)) return std::numeric_limits<double>::infinity();  // beyond double range
      const double l = 2 * std::acosh(std::max(1.0, t));
      score += l * l / std::max(loop_length[k] * loop_length[k], 1e-300);
    }
    return std::isfinite(score) ? score : std::numeric_limits<double>::infinity();
  };
  // Of the Torelli-equivalent versions of each lifted class, the one whose
  // source loops have the shortest images in the target (least twisted).
  for (HandleCandidate& hc : handle_classes)
    if (loop_image_length(hc.map) <= max_image_letters)
      hc.map = reduce_separating_twists(hc.map, out.genus, loop_image_length);
  // Named classes go in front, in order: the overlay classes, then the
  // canonical one. A named class drops the lifted ones with its homology
  // (it is the more geometric or the shorter version of that Torelli
  // coset), and is itself dropped when an earlier named class has its
  // fingerprint (the same class).
  std::vector<std::vector<double>> named_fingerprints;
  int num_named = 0;
  auto add_named = [&](const GroupMap& theta, const std::string& tag, const std::vector<double>& fp) {
    for (const auto& other : named_fingerprints)
      if (same_fingerprint(other, fp)) return false;
    HandleCandidate hc;
    hc.map = theta;
    hc.homology = homology_matrix(theta, n);
    std::string handles;
    handle_correspondence_of(shb, thb, hc.homology, &hc.permutation, &hc.sign, &handles);
    hc.description = handles + "  [" + tag + "]";
    handle_classes.erase(std::remove_if(handle_classes.begin() + num_named, handle_classes.end(),
                                        [&](const HandleCandidate& c) { return c.homology == hc.homology; }),
                         handle_classes.end());
    handle_classes.insert(handle_classes.begin() + num_named, hc);
    named_fingerprints.push_back(fp);
    ++num_named;
    return true;
  };
  for (const NamedClass& c : overlays) add_named(c.theta, c.tag, c.fingerprint);
  // The class of the two canonical polygon schemata, a_i -> a'_i, b_i -> b'_i:
  // short words whatever the loops look like.
  GroupMap canonical(n);
  for (int j = 0; j < n; ++j) canonical[j] = {j + 1};
  add_named(canonical, "a_i -> a'_i, b_i -> b'_i of the canonical polygon schemata", fingerprint(canonical));

  // Lifted classes are fixed only up to Torelli elements (same homology),
  // and which representative the lift picks depends on the loops: lifts
  // from the systems of loops at other source base vertices give other
  // representatives, and sometimes the geometric one where the default cut
  // does not (double_torus_g2 -> vase_g2: energy 66.9, mean D' 5.4 from the
  // default cut; 26.0, D' 1.36 from the cut at vertex 2000). Those classes
  // are carried to the default cut's generators by the identity overlay of
  // the source onto itself (each loop of the default system as a word in
  // the other system's letters), kept when their fingerprint is new.
  std::vector<std::vector<double>> known;  // fingerprints of the classes listed so far
  size_t word_cap = 0;
  std::vector<int> cut_bases_used{sl.base_vertex};
  // Lifted classes from the systems of loops at `cut_bases`: the new ones
  // (by fingerprint), at most homotopy_extra_cut_classes, lowest screen first.
  std::function<std::vector<HandleCandidate>(const std::vector<int>&)> lift_from_cuts;
  if (options.homotopy_extra_cuts > 0) {
    size_t longest = 0;  // total word length of the longest lifted class from the default cut
    for (const HandleCandidate& hc : handle_classes) {
      // (Classes too twisted to be evaluated get no fingerprint.)
      known.push_back(loop_image_length(hc.map) <= max_image_letters ? fingerprint(hc.map) : std::vector<double>{});
      size_t total = 0;
      for (const Word& w : hc.map) total += w.size();
      longest = std::max(longest, total);
    }
    // Classes from another cut whose words come out much longer than any
    // from the default cut are very twisted (their energies are orders of
    // magnitude above the others'): skipped, which also keeps the twist
    // reduction below (Dehn's algorithm on every try) cheap.
    // (Lengths seen: 14..144 letters in genus 2 where the default cut's
    // longest is 86.)
    word_cap = std::min(4 * longest + 16 * static_cast<size_t>(n), 48 * static_cast<size_t>(n));
    // Base vertices spread over the vertex list (deterministic). Not the
    // farthest points: those are the shape's extremities, where the loops
    // come out long and skewed (the demo pair: no geometric class from the
    // two farthest; from 3 of 7 spread ones).
    lift_from_cuts = [&](const std::vector<int>& cut_bases) {
    std::vector<std::pair<double, HandleCandidate>> extra;  // new lifted classes and their screening scores
    std::vector<HandleCandidate> overlaid;                   // new overlay classes from the other cuts
    std::vector<int> bases{sl.base_vertex};
    for (int b : cut_bases)
      if (std::find(cut_bases_used.begin(), cut_bases_used.end(), b) == cut_bases_used.end())
        bases.push_back(b), cut_bases_used.push_back(b);
    for (size_t c = 1; c < bases.size(); ++c) {
      auto slot = std::find_if(cut_slots.begin(), cut_slots.end(), [&](const CutSlot& x) { return x.base == bases[c]; });
      CutSlot unplanned;  // (every cut asked for is planned above; this keeps a mismatch harmless)
      unplanned.base = bases[c];
      const CutPrep& cp = prepare_cut(slot != cut_slots.end() ? *slot : unplanned);
      if (!cp.ok) continue;
      const GroupMap& psi = cp.psi;
      const HandleBasis& shb2 = cp.shb;
      // Without a strict overlay from the default cut, the other cuts' loops
      // are overlaid too (as posed, jumps joined): which loops jump depends
      // on the cut (n_hole_torus(3, 36) -> polycube(3, 36): the geometric
      // class from 5 of 12 cuts' loops, from neither the default cut nor
      // the lifts).
      if (!strict_overlay) {
        ProjectedLoopsOptions po;
        po.max_jump_box = kOverlayJump;
        const ProjectedLoopsResult proj = projector.project(source, cp.loops, po);
        if (proj.ok_with_joins) {
          GroupMap theta2(n);
          for (int j = 0; j < n; ++j)
            theta2[j] = dehn_reduce(substitute(substitute(cp.generators[j], proj.loop_images), tcs.letters), R);
          GroupMap theta = compose(theta2, psi);
          for (Word& w : theta) w = dehn_reduce(w, R);
          const IntMatrix M = homology_matrix(theta, n);
          if (M.transpose() * J * M == J && dehn_reduce(substitute(R, theta), R).empty() &&
              loop_image_length(theta) <= max_image_letters) {
            const std::vector<double> fp = fingerprint(theta);
            bool seen = false;
            for (const auto& k : known) seen = seen || same_fingerprint(k, fp);
            if (!seen) {
              known.push_back(fp);
              HandleCandidate hc;
              hc.map = theta;
              hc.homology = M;
              std::string handles;
              handle_correspondence_of(shb, thb, hc.homology, &hc.permutation, &hc.sign, &handles);
              hc.description = handles + "  [as the shapes overlap: the loops at source vertex " + std::to_string(bases[c]) +
                               " carried to the nearest points" + (proj.ok ? "" : ", jumps joined") + "]";
              overlaid.push_back(std::move(hc));
            }
          }
        }
      }
      for (HandleCandidate hc : handle_candidates(shb2, thb, options.homotopy_candidates)) {
        size_t lifted = 0;
        for (const Word& w : hc.map) lifted += w.size();
        if (lifted > 4 * word_cap) continue;  // composing would only make it longer
        GroupMap theta = compose(hc.map, psi);
        for (Word& w : theta) w = dehn_reduce(w, R);
        size_t total = 0;
        for (const Word& w : theta) total += w.size();
        if (total > word_cap || !dehn_reduce(substitute(R, theta), R).empty()) continue;
        theta = reduce_separating_twists(theta, out.genus, loop_image_length, 10);
        const std::vector<double> fp = fingerprint(theta);
        bool seen = false;
        for (const auto& k : known) seen = seen || same_fingerprint(k, fp);
        if (seen) continue;
        known.push_back(fp);
        hc.map = theta;
        hc.homology = homology_matrix(theta, n);
        std::string handles;
        handle_correspondence_of(shb, thb, hc.homology, &hc.permutation, &hc.sign, &handles);
        hc.description = handles + "  [lifted from the loops at source vertex " + std::to_string(bases[c]) + "]";
        extra.push_back({class_screen(theta), std::move(hc)});
      }
    }
    // Only the most promising new classes get homotopy data and a coarse
    // solve (each costs about as much as the cut itself).
    std::stable_sort(extra.begin(), extra.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    // The overlay classes go first (few: most cuts' overlays coincide).
    std::vector<HandleCandidate> kept = std::move(overlaid);
    for (size_t k = 0; k < extra.size() && static_cast<int>(k) < options.homotopy_extra_cut_classes; ++k)
      kept.push_back(std::move(extra[k].second));
    return kept;
    };
    std::vector<int> first_bases;
    for (int c = 1; c <= options.homotopy_extra_cuts; ++c)
      first_bases.push_back(static_cast<int>((static_cast<long long>(source.num_vertices()) * c) / (options.homotopy_extra_cuts + 1)));
    for (HandleCandidate& hc : lift_from_cuts(first_bases)) handle_classes.push_back(std::move(hc));
    if (!ss.cs.ok) cut_prep_stop = true;  // no coarse copy: no class search, no more cuts needed
  }

  // The homotopy data of one class theta (source canonical generator ->
  // word in the target's canonical generators): a deck element per source
  // edge (checked exactly around every face) and per intrinsic edge.
  struct ClassData {
    std::vector<Mobius> rho_edge;
    std::vector<Word> side_word_edge;  ///< rho_edge as reduced side words
    std::vector<WeightedEdge> edges;
  };
  // Every original source edge is a solver edge too (weight 0 when the
  // intrinsic triangulation flipped it away), so that the image triangles of
  // the source's own faces come out of the solve in local charts
  // (HyperbolicHarmonicResult::edge_local), to round-off.
  std::vector<int> orig_solver_edge(sc.num_edges());
  std::vector<char> orig_forward(sc.num_edges(), 1);
  auto index_solver_edges = [&] {
    int next = static_cast<int>(idt.edges.size());
    for (int e = 0; e < sc.num_edges(); ++e) {
      const int h = sc.edge_halfedge(e);
      if (idt.edges[e].path.size() == 1 && sc.edge(idt.edges[e].path[0]) == e) {
        orig_solver_edge[e] = e;
        orig_forward[e] = idt.edges[e].path[0] == h;
      } else {
        orig_solver_edge[e] = next++;
      }
    }
  };
  index_solver_edges();
  auto class_data = [&](const GroupMap& theta) {
    const std::vector<Word> letter_image = loop_letter_images(theta);
    std::vector<Word> target_word(edge_word.size());
    // Shortest-form words keep the products of SU(1,1) matrices small. Few
    // distinct words occur (edges crossing the same loops share one), so
    // each is reduced once.
    std::map<Word, Word> memo;
    auto reduced = [&](const Word& w) -> const Word& {
      auto it = memo.find(w);
      if (it == memo.end()) it = memo.emplace(w, dehn_reduce(w, layout.word)).first;
      return it->second;
    };
    for (size_t e = 0; e < edge_word.size(); ++e) target_word[e] = reduced(substitute(edge_word[e], letter_image));
    auto word_of = [&](int h) {
      const int e = sc.edge(h);
      return sc.edge_halfedge(e) == h ? target_word[e] : inverse(target_word[e]);
    };
    // Exact check (Dehn's algorithm solves the word problem of the surface
    // group): the product around every source face is the identity.
    for (int f = 0; f < source.num_faces(); ++f) {
      const Word around = concat({word_of(3 * f), word_of(3 * f + 1), word_of(3 * f + 2)});
      if (!reduced(around).empty())
        throw SolveError("homotopy data inconsistent around source face " + std::to_string(f));
    }
    ClassData cd;
    cd.rho_edge.resize(edge_word.size());
    cd.side_word_edge.resize(edge_word.size());
    std::map<Word, Word> side_memo;
    auto side_word = [&](const Word& w) -> const Word& {
      auto it = side_memo.find(w);
      if (it == side_memo.end()) it = side_memo.emplace(w, deck_group.side_word(w)).first;
      return it->second;
    };
    for (size_t e = 0; e < edge_word.size(); ++e) {
      cd.side_word_edge[e] = side_word(target_word[e]);
      cd.rho_edge[e] = deck_group.evaluate_side_word(cd.side_word_edge[e]);
    }
    cd.edges.resize(idt.edges.size());
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      const auto& ie = idt.edges[e];
      cd.edges[e].i = ie.i;
      cd.edges[e].j = ie.j;
      cd.edges[e].w = ie.cot_weight;
      Word w;
      for (int h : ie.path) w = concat(w, word_of(h));
      cd.edges[e].rho_word = side_word(reduced(w));
      cd.edges[e].rho = deck_group.evaluate_side_word(cd.edges[e].rho_word);
    }
    for (int e = 0; e < sc.num_edges(); ++e) {
      if (orig_solver_edge[e] < static_cast<int>(idt.edges.size())) continue;
      const int h = sc.edge_halfedge(e);
      WeightedEdge we;
      we.i = sc.tail(h);
      we.j = sc.head(h);
      we.w = 0;
      we.rho_word = cd.side_word_edge[e];
      we.rho = cd.rho_edge[e];
      cd.edges.push_back(we);
    }
    return cd;
  };
  int ncand = static_cast<int>(handle_classes.size());
  if (options.homotopy >= ncand)
    throw InputError("homotopy class " + std::to_string(options.homotopy) + " does not exist; there are " +
                     std::to_string(ncand) + " candidates (0.." + std::to_string(ncand - 1) + ")");
  std::vector<ClassData> data;
  std::vector<char> usable(handle_classes.size(), 1);
  for (size_t k = 0; k < handle_classes.size(); ++k) {
    const HandleCandidate& hc = handle_classes[k];
    const double letters = loop_image_length(hc.map);
    HomotopyCandidate c;
    c.description = hc.description;
    if (letters <= max_image_letters) {
      data.push_back(class_data(hc.map));
    } else {
      data.emplace_back();
      usable[k] = 0;
      c.energy = std::numeric_limits<double>::infinity();
      c.solved = false;
      c.description += "  [not solved: the images of the source's loops have " + std::to_string(static_cast<long>(letters)) +
                       " letters, too twisted for double-precision deck elements]";
      if (options.homotopy == static_cast<int>(k))
        throw SolveError("homotopy class " + std::to_string(k) + " cannot be solved: the images of the source's loops have " +
                         std::to_string(static_cast<long>(letters)) + " letters in the target's group (at most " +
                         std::to_string(static_cast<long>(max_image_letters)) + " can be evaluated in double precision)");
    }
    for (int r = 0; r < hc.homology.rows(); ++r)
      for (int q = 0; q < hc.homology.cols(); ++q) c.homology.push_back(static_cast<int>(hc.homology(r, q)));
    out.candidates.push_back(c);
  }
  stage_done("source homotopy data and weights", 0.4);

  // Ranking (DESIGN §2.10). The energy of a class is a property of the two
  // continuous surfaces, so every candidate is solved to convergence on a
  // coarse copy of the source (map/coarse_source.h; its vertices are fine
  // vertices, its deck elements products of the fine ones along paths, so a
  // coarse solution is also a start for the fine solve), and only the best by
  // that estimate (and whichever are within kCoarseMargin of it, up to
  // `homotopy_full_solves`) are solved at full resolution, from their coarse
  // solutions prolonged to the fine vertices. The energy is geodesically
  // convex, so that converged solve is the class's optimum: the chosen class
  // is not solved again. Small sources (fewer than 4 coarse copies' worth of
  // vertices) are ranked by full-resolution solves of every class instead.
  constexpr double kCoarseMargin = 0.1;
  HyperbolicHarmonicOptions ho;
  ho.tolerance = options.tolerance;
  ho.max_iterations = options.max_iterations;
  ho.relator = deck_group.side_relator();
  ho.reduce_point = [&](Complex& z) { return reduce_into_polygon(z); };
  if (options.progress)
    ho.progress = [&](int, double, double) { return options.progress("homotopy candidates", 0.4); };
  // Side word of source halfedge h in class data cd.
  auto side_of = [&](const ClassData& cd, int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? cd.side_word_edge[e] : inverse(cd.side_word_edge[e]);
  };
  // A solve of `edges` (n vertices) from points `start` with vertex decks
  // `deck_word` (side words): the edges are conjugated by the decks (as
  // words, never as matrix products), and the decks are composed back, so
  // the result is relative to `edges` as given.
  auto solve_from = [&](int n, const std::vector<WeightedEdge>& edges, const std::vector<Complex>& start,
                        const std::vector<Word>& deck_word, const HyperbolicHarmonicOptions& o) {
    std::vector<WeightedEdge> e = edges;
    std::vector<Mobius> deck(n);
    bool any = false;
    for (int i = 0; i < n; ++i)
      if (!deck_word[i].empty()) any = true, deck[i] = deck_group.evaluate_side_word(deck_word[i]);
    if (any)
      for (auto& ed : e) {
        if (deck_word[ed.i].empty() && deck_word[ed.j].empty()) continue;
        ed.rho_word = deck_group.reduce(concat({deck_word[ed.i], ed.rho_word, inverse(deck_word[ed.j])}));
        ed.rho = deck_group.evaluate_side_word(ed.rho_word);
      }
    HyperbolicHarmonicResult r = hyperbolic_harmonic_map(n, e, deck_group.side_pairings(), start, o);
    if (any)
      for (int i = 0; i < n; ++i) {
        r.vertex_deck[i] = (r.vertex_deck[i] * deck[i]).normalized();
        r.vertex_deck_word[i] = deck_group.reduce(concat(r.vertex_deck_word[i], deck_word[i]));
      }
    return r;
  };
  // The initial map of class k (map/initial_map.h): the source's cut disk
  // flattened onto the target's geodesic polygon of the source's loops when
  // that polygon is convex, else the uniform-weight (Tutte-type) map in this
  // class; the "before" figures, and the start unless start_seed asks for a
  // random one. `stop` (another thread's task, concurrency.h): gives up
  // (Cancelled) when raised.
  struct InitialOf {
    std::vector<Mobius> halfedge_rho;
    std::vector<Word> halfedge_word;
    HyperbolicInitialMapResult init;
  };
  auto initial_of = [&](int k, const std::atomic<bool>* stop, std::vector<Complex> start_z = {},
                        std::vector<Word> start_word = {}) {
    InitialOf r;
    const ClassData& cd = data[k];
    r.halfedge_rho.resize(3 * source.num_faces());
    r.halfedge_word.resize(3 * source.num_faces());
    for (int h = 0; h < 3 * source.num_faces(); ++h) {
      const int e = sc.edge(h);
      const bool fwd = sc.edge_halfedge(e) == h;
      r.halfedge_rho[h] = fwd ? cd.rho_edge[e] : cd.rho_edge[e].inverse();
      r.halfedge_word[h] = fwd ? cd.side_word_edge[e] : inverse(cd.side_word_edge[e]);
    }
    try {
      HyperbolicInitialMapOptions io;
      io.cut_graph = options.initial_map == InitialMapMethod::CutGraph;
      io.polygon = options.initial_map != InitialMapMethod::UniformHarmonic;
      io.base_vertex = sl.base_vertex;
      io.source_loops = &sl.loops;
      io.reduce_point = [&](Complex& z) { return reduce_into_polygon(z); };
      if (stop) io.keep_going = [stop] { return !*stop; };
      io.start_z = std::move(start_z), io.start_word = std::move(start_word);
      r.init = hyperbolic_initial_map(source, sc, r.halfedge_rho, r.halfedge_word, deck_group, io);
    } catch (const SolveError&) {
      // The start then is every vertex at the origin (as before the initial
      // map existed); the "before" figures report its degenerate triangles.
      r.init = HyperbolicInitialMapResult();
      r.init.z.assign(source.num_vertices(), Complex(0.0));
      r.init.vertex_deck.assign(source.num_vertices(), Mobius());
      r.init.vertex_deck_word.assign(source.num_vertices(), Word{});
      r.init.construction = "none (the uniform-weight solve failed; origin)";
    }
    return r;
  };
  // The class most likely chosen (the requested one, or the ranking's
  // leader) and its initial map when it was computed next to the
  // full-resolution solves.
  int likely_class = -1;
  std::unique_ptr<InitialOf> likely_init;
  // Runs a solve of class k; a class whose solve fails numerically (deck
  // elements too large for double precision: very twisted classes) or does
  // not converge is reported with infinite energy instead of failing the
  // whole map, unless it was asked for.
  // A failed coarse solve (`coarse`) of a class that must be solved anyway
  // (requested, or the only one) only loses its estimate: it is then solved
  // at full resolution from the origin.
  std::vector<char> coarse_failed(ncand, 0);
  auto try_solve = [&](int k, const std::function<HyperbolicHarmonicResult()>& solve, HyperbolicHarmonicResult& r,
                       bool coarse = false) {
    std::string why;
    try {
      r = solve();
      bool finite = std::isfinite(r.energy);
      for (size_t i = 0; i < r.z.size() && finite; ++i) finite = std::isfinite(r.z[i].real()) && std::isfinite(r.z[i].imag());
      if (!finite) why = "non-finite energy or positions";
      else if (!r.converged)
        why = "did not converge in " + std::to_string(r.iterations) + " iterations (gradient " +
              std::to_string(r.gradient_history.empty() ? 0.0 : r.gradient_history.back()) + ")";
      else return true;
    } catch (const SolveError& e) {
      why = e.what();
    }
    const bool needed = options.homotopy == k || (options.homotopy < 0 && ncand == 1);
    if (needed && coarse) {
      coarse_failed[k] = 1;
      return false;
    }
    if (needed) throw SolveError("the harmonic map solve of homotopy class " + std::to_string(k) + " failed: " + why);
    usable[k] = 0;
    out.candidates[k].energy = std::numeric_limits<double>::infinity();
    out.candidates[k].solved = false;
    out.candidates[k].description += "  [solve failed: " + why + "]";
    return false;
  };

  // The ranking level: the coarse copy, its class data, and its solves.
  CoarseSource& cs = ss.cs;
  std::vector<std::vector<WeightedEdge>> coarse_data;
  // For the class search: every coarse solver edge's element as a reduced
  // word in the source's loop letters (class independent), so a new class's
  // coarse data is one substitution per edge, without fine data.
  std::vector<WeightedEdge> coarse_template;
  std::vector<Word> coarse_source_word;
  if (cs.ok) {
    const Connectivity cc(cs.mesh.F, cs.mesh.num_vertices());
    const IntrinsicDelaunayResult cidt = intrinsic_delaunay(cc, edge_lengths(cs.mesh, cc));
    if (options.homotopy_search && options.homotopy < 0 && cidt.delaunay) {
      const DehnReducer reduce_source_loops(sl.word);
      std::vector<Word> csw(cc.num_halfedges());
      for (int e = 0; e < cc.num_edges(); ++e) {
        Word w;
        for (int h : cs.edge_path[e]) {
          const int fe = sc.edge(h);
          w = concat(w, sc.edge_halfedge(fe) == h ? edge_word[fe] : inverse(edge_word[fe]));
        }
        const int h = cc.edge_halfedge(e);
        csw[h] = reduce_source_loops(w);
        csw[cc.twin(h)] = inverse(csw[h]);
      }
      for (const auto& ie : cidt.edges) {
        WeightedEdge we;
        we.i = ie.i, we.j = ie.j, we.w = ie.cot_weight;
        Word w;
        for (int h : ie.path) w = concat(w, csw[h]);
        coarse_template.push_back(we);
        coarse_source_word.push_back(reduce_source_loops(w));
      }
    }
    for (int k = 0; k < ncand && cs.ok; ++k) {
      if (!usable[k]) {  // no homotopy data (a class refused before its data was built)
        coarse_data.emplace_back();
        continue;
      }
      std::vector<Word> ch(cc.num_halfedges());
      for (int e = 0; e < cc.num_edges(); ++e) {
        Word w;
        for (int h : cs.edge_path[e]) w = concat(w, side_of(data[k], h));
        const int h = cc.edge_halfedge(e);
        ch[h] = deck_group.reduce(w);
        ch[cc.twin(h)] = inverse(ch[h]);
      }
      // The fine paths around every coarse face must bound a disk: exactly
      // when the product of their deck elements is the identity.
      for (int f = 0; f < cc.num_faces() && cs.ok; ++f)
        if (!deck_group.reduce(concat({ch[3 * f], ch[3 * f + 1], ch[3 * f + 2]})).empty())
          cs.ok = false, cs.why = "the fine paths around coarse face " + std::to_string(f) + " are not contractible";
      std::vector<WeightedEdge> edges(cidt.edges.size());
      for (size_t e = 0; e < cidt.edges.size() && cs.ok; ++e) {
        const auto& ie = cidt.edges[e];
        edges[e].i = ie.i, edges[e].j = ie.j, edges[e].w = ie.cot_weight;
        Word w;
        for (int h : ie.path) w = concat(w, ch[h]);
        edges[e].rho_word = deck_group.reduce(w);
        edges[e].rho = deck_group.evaluate_side_word(edges[e].rho_word);
      }
      coarse_data.push_back(std::move(edges));
    }
    if (!cs.ok || !cidt.delaunay) cs.ok = false, coarse_data.clear();
  }
  // The requested class's full-resolution solve reports to solve_progress live.
  auto fine_options = [&](int k) {
    HyperbolicHarmonicOptions o = ho;
    if (options.homotopy == k && options.solve_progress)
      o.progress = [&](int it, double E, double g) {
        return options.solve_progress(it, E, g) && (!options.progress || options.progress("harmonic solve", 0.43));
      };
    return o;
  };
  // Full-resolution solves kept for the pipeline below (by class).
  std::vector<std::unique_ptr<HyperbolicHarmonicResult>> fine_result(ncand);
  std::vector<char> full(ncand, 0);
  std::vector<int> order(ncand);
  for (int k = 0; k < ncand; ++k) order[k] = k;
  const int full_solves = options.homotopy_full_solves <= 0 ? ncand : std::min(options.homotopy_full_solves, ncand);
  if (cs.ok) {
    const int ncv = cs.mesh.num_vertices();
    const std::vector<Complex> corigin(ncv, Complex(0.0));
    const std::vector<Word> no_decks(ncv);
    std::vector<HyperbolicHarmonicResult> coarse_result(ncand);
    cut_prep_stop = true;  // the second thread is needed here
    // Independent solves, on two threads (concurrency.h: only this thread
    // calls the progress callback, the other one sees a stop flag).
    parallel_for(threads, ncand, [&](int k, const std::atomic<bool>* stop) {
      if (!usable[k]) return;
      HyperbolicHarmonicOptions o = ho;
      if (stop) o.progress = [stop](int, double, double) { return !*stop; };
      if (!try_solve(k, [&] { return solve_from(ncv, coarse_data[k], corigin, no_decks, o); }, coarse_result[k], true))
        return;
      out.candidates[k].coarse_energy = coarse_result[k].energy;
      out.candidates[k].energy = coarse_result[k].energy;
      out.candidates[k].solved = false;
    });
    std::stable_sort(order.begin(), order.end(),
                     [&](int x, int y) { return out.candidates[x].energy < out.candidates[y].energy; });
    // Class search (topology/mapping_class_search.h): from the best class on
    // the coarse copy, a greedy descent over Dehn twists screened by
    // class_screen, each neighbour evaluated by a solve on the coarse copy.
    auto coarse_edges_of = [&](const GroupMap& theta) {
      const std::vector<Word> image = loop_letter_images(theta);
      std::vector<WeightedEdge> e = coarse_template;
      std::map<Word, Word> memo;
      for (size_t k = 0; k < e.size(); ++k) {
        auto it = memo.find(coarse_source_word[k]);
        if (it == memo.end())
          it = memo.emplace(coarse_source_word[k],
                            deck_group.side_word(dehn_reduce(substitute(coarse_source_word[k], image), layout.word))).first;
        e[k].rho_word = it->second;
        e[k].rho = deck_group.evaluate_side_word(e[k].rho_word);
      }
      return e;
    };
    struct Evaluated {
      GroupMap theta;
      std::vector<WeightedEdge> edges;
      HyperbolicHarmonicResult result;
    };
    // A converged coarse solve of class theta from the origin (false when
    // it fails or does not converge).
    auto solve_coarse = [&](const GroupMap& theta, Evaluated* ev) {
      try {
        *ev = Evaluated{theta, coarse_edges_of(theta), {}};
        ev->result = solve_from(ncv, ev->edges, corigin, no_decks, ho);
        bool finite = std::isfinite(ev->result.energy) && ev->result.converged;
        for (size_t i = 0; i < ev->result.z.size() && finite; ++i) finite = std::isfinite(std::abs(ev->result.z[i]));
        return finite;
      } catch (const SolveError&) {
        return false;
      }
    };
    // Appends a class found after the ranking, with its coarse solve.
    auto append_class = [&](HandleCandidate hc, ClassData cd, const Evaluated& ev) {
      hc.map = ev.theta;
      hc.homology = homology_matrix(hc.map, n);
      HomotopyCandidate c;
      c.description = hc.description;
      c.coarse_energy = c.energy = ev.result.energy;
      c.solved = false;
      for (int r = 0; r < hc.homology.rows(); ++r)
        for (int q = 0; q < hc.homology.cols(); ++q) c.homology.push_back(static_cast<int>(hc.homology(r, q)));
      data.push_back(std::move(cd));
      handle_classes.push_back(std::move(hc));
      out.candidates.push_back(c);
      usable.push_back(1);
      coarse_failed.push_back(0);
      coarse_data.push_back(ev.edges);
      coarse_result.push_back(ev.result);
      fine_result.emplace_back();
      full.push_back(0);
      order.push_back(ncand);
      ++ncand;
      std::stable_sort(order.begin(), order.end(),
                       [&](int x, int y) { return out.candidates[x].energy < out.candidates[y].energy; });
      return ncand - 1;
    };
    const double conformal_bound = 8 * M_PI * (out.genus - 1);
    // The class search, stage 1: when the best class is far from the
    // conformal bound (see below), lifts from homotopy_search_cuts more
    // source cuts (other Torelli representatives; cheap next to their
    // solves, and of their new classes only the lowest-screen ones are
    // solved, in that order, until one is within the gap: what the twist
    // search would not run for either). The bench pair n_hole_torus(2) ->
    // vase at 50k vertices gets its geometric class (E 25.96, mean D' 1.36)
    // only this way: the 3 default cuts give 66.8 (D' 5.41), and no twist
    // neighbour of that class is lower.
    if (!coarse_source_word.empty() && lift_from_cuts && options.homotopy_search_cuts > 0 &&
        options.homotopy_search_start < 0 && usable[order[0]] &&
        out.candidates[order[0]].energy > (1 + options.homotopy_search_gap) * conformal_bound) {
      const auto t_cuts = std::chrono::steady_clock::now();
      std::vector<int> late;
      for (int c = 1; c <= options.homotopy_search_cuts; ++c)
        late.push_back(static_cast<int>((static_cast<long long>(nv) * c) / (options.homotopy_search_cuts + 1)));
      // The late cuts' source-only parts, on both threads.
      parallel_for(threads, static_cast<int>(late.size()), [&](int k, const std::atomic<bool>*) {
        auto slot = std::find_if(cut_slots.begin(), cut_slots.end(), [&](const CutSlot& x) { return x.base == late[k]; });
        if (slot != cut_slots.end()) prepare_cut(*slot);
      });
      auto lifted_late = lift_from_cuts(late);
      for (HandleCandidate& hc : lifted_late) {
        if (loop_image_length(hc.map) > max_image_letters) continue;
        ClassData cd;
        Evaluated ev;
        try {
          cd = class_data(hc.map);
        } catch (const SolveError&) {
          continue;
        }
        ++out.homotopy_search.cut_classes;
        if (!solve_coarse(hc.map, &ev)) continue;
        append_class(std::move(hc), std::move(cd), ev);
        // Within the gap of the bound: what the search below would not run
        // for, so the rest (lowest screen first) are not solved either.
        if (ev.result.energy <= (1 + options.homotopy_search_gap) * conformal_bound) break;
      }
      out.homotopy_search.cuts_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_cuts).count();
    }
    if (options.homotopy_search_start >= ncand)
      throw InputError("homotopy_search_start " + std::to_string(options.homotopy_search_start) + " does not exist; there are " +
                       std::to_string(ncand) + " candidates");
    const int search_start = options.homotopy_search_start >= 0 ? options.homotopy_search_start : order[0];
    // Every map of degree 1 onto the hyperbolic target has E >= 2 x its
    // area = 8 pi (g - 1) (|df|^2 >= 2 J_f, equality for conformal maps), so
    // a start within homotopy_search_gap of that bound leaves nothing worth
    // a search (the coarse energies of good classes sit 0.3-4% above it:
    // 75.8 vs 75.4 at genus 4, 26.0 vs 25.1 for the genus-2 demo pair).
    const bool near_bound = options.homotopy_search_start_twists.empty() &&
                            out.candidates[search_start].energy <= (1 + options.homotopy_search_gap) * conformal_bound;
    if (!coarse_source_word.empty() && near_bound)
      out.homotopy_search.stop_reason = "not run: the best class is within " +
                                        std::to_string(static_cast<int>(std::lround(100 * options.homotopy_search_gap))) +
                                        "% of the conformal bound 8 pi (g - 1)";
    if (!coarse_source_word.empty() && usable[search_start] && !near_bound &&
        (std::isfinite(out.candidates[search_start].energy) || !options.homotopy_search_start_twists.empty())) {
      const auto t_search = std::chrono::steady_clock::now();
      HomotopySearchInfo& info = out.homotopy_search;
      info.run = true;
      info.start_candidate = search_start;
      GroupMap search_from = handle_classes[search_start].map;
      if (!options.homotopy_search_start_twists.empty()) {
        const std::vector<MappingClassMove> moves = twist_moves(out.genus);
        for (const std::string& name : options.homotopy_search_start_twists) {
          auto it = std::find_if(moves.begin(), moves.end(), [&](const MappingClassMove& m) { return m.name == name; });
          if (it == moves.end()) throw InputError("homotopy_search_start_twists: no move named '" + name + "'");
          search_from = compose(search_from, it->automorphism.map);
          for (Word& w : search_from) w = reduce_canonical(w);
        }
      }
      std::vector<Evaluated> evaluated;
      auto coarse_energy = [&](const GroupMap& theta) {
        Evaluated ev;
        if (!solve_coarse(theta, &ev)) return std::numeric_limits<double>::infinity();
        evaluated.push_back(std::move(ev));
        return evaluated.back().result.energy;
      };
      info.start_energy = options.homotopy_search_start_twists.empty() ? out.candidates[search_start].energy
                                                                        : coarse_energy(search_from);
      TwistSearchOptions tso;
      tso.max_evaluations = options.homotopy_search_evaluations;
      const TwistSearchResult ts =
          twist_search(search_from, info.start_energy, out.genus, class_screen, coarse_energy, tso);
      info.moves = ts.moves;
      info.energies = ts.energies;
      info.energy = ts.energy;
      info.evaluations = static_cast<int>(ts.evaluations.size());
      for (const TwistSearchEvaluation& ev : ts.evaluations) {
        info.evaluated_moves.push_back(ev.move);
        info.evaluated_step.push_back(ev.step);
        info.evaluated_screen.push_back(ev.screen);
        info.evaluated_energy.push_back(ev.energy);
      }
      info.screened = ts.screened;
      info.stop_reason = ts.stop_reason;
      const Evaluated* found = nullptr;
      if (!ts.moves.empty())
        for (const Evaluated& ev : evaluated)
          if (ev.theta == ts.best) found = &ev;
      ClassData found_data;
      if (found && loop_image_length(found->theta) > max_image_letters) found = nullptr;
      if (found) try {
          found_data = class_data(found->theta);
        } catch (const SolveError&) {
          found = nullptr;  // (cannot happen for an exact automorphism; then the search found nothing usable)
        }
      if (found) {
        HandleCandidate hc;
        hc.homology = homology_matrix(found->theta, n);
        std::string handles;
        handle_correspondence_of(shb, thb, hc.homology, &hc.permutation, &hc.sign, &handles);
        std::string path;
        for (const std::string& m : ts.moves) path += (path.empty() ? "" : ", ") + m;
        std::string from = std::to_string(search_start);
        for (const std::string& m : options.homotopy_search_start_twists) from += " " + m;
        hc.description = handles + "  [class search from candidate " + from + ": " + path + "]";
        info.found_candidate = append_class(std::move(hc), std::move(found_data), *found);
      }
      info.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_search).count();
    }
    // Which classes get the full-resolution solve: the requested one, or the
    // best by coarse energy and those within the margin of it. The margin is
    // a few times the coarse-versus-fine energy differences measured between
    // classes (the discretisation error is mostly common to all classes of
    // one source, so the ranking is more accurate than the energies are).
    if (options.homotopy >= 0) {
      full[options.homotopy] = usable[options.homotopy];
      likely_class = options.homotopy;
    } else {
      const double best = out.candidates[order[0]].energy;
      // Ties (symmetric shapes: equal energies to ~1e-7 on the coarse copy
      // too) are decided at full resolution by the earliest candidate, the
      // overlay class first, so the earliest of the tied goes first here.
      std::vector<int> pick;
      for (int q = 0; q < ncand; ++q)
        if (usable[order[q]] && (q == 0 || options.homotopy_full_solves <= 0 ||
                                 out.candidates[order[q]].energy <= best * (1 + kCoarseMargin)))
          pick.push_back(order[q]);
      int leader = -1;
      for (int k : pick)
        if (out.candidates[k].energy <= best * (1 + 1e-4) && (leader < 0 || k < leader)) leader = k;
      if (leader >= 0) pick.erase(std::find(pick.begin(), pick.end(), leader)), pick.insert(pick.begin(), leader);
      // A runner-up tied with the leader to 1e-6 on the coarse copy is the
      // same optimum up to a symmetry of the shapes (its full solve gave the
      // leader's energy to 1e-10 on the 50k bench pair): solving it again at
      // full resolution cannot change the choice, so it is not (unless every
      // class is asked for: homotopy_full_solves <= 0).
      if (!pick.empty() && options.homotopy_full_solves > 0) {
        const double lead = out.candidates[pick[0]].energy;
        pick.erase(std::remove_if(pick.begin() + 1, pick.end(),
                                  [&](int k) { return std::abs(out.candidates[k].energy - lead) <= 1e-6 * lead; }),
                   pick.end());
      }
      for (int q = 0; q < static_cast<int>(pick.size()) && q < full_solves; ++q) full[pick[q]] = 1;
      if (!pick.empty()) likely_class = pick[0];
    }
    stage_done("homotopy candidates", 0.42);
    // Prolongation: a coarse vertex is its fine vertex (same point, same
    // deck); every other fine vertex starts at the image of its region's
    // coarse vertex, with that deck times the element of the tree path to it
    // (the collapsed start has the right global layout; Newton spreads the
    // clusters in a few steps).
    std::vector<int> settle;  // fine vertices, parents first
    {
      std::vector<char> seen(nv, 0);
      for (int v = 0; v < nv; ++v) {
        std::vector<int> chain;
        for (int u = v; u >= 0 && !seen[u]; u = cs.parent_halfedge[u] >= 0 ? sc.tail(cs.parent_halfedge[u]) : -1)
          chain.push_back(u), seen[u] = 1;
        settle.insert(settle.end(), chain.rbegin(), chain.rend());
      }
    }
    // The full-resolution solves (the first on this thread: it may report
    // live progress) and, on the second thread, the likely class's initial
    // map (-1 in the task list; with one thread it is built when needed).
    std::vector<int> tasks;
    for (int k = 0; k < ncand; ++k)
      if (full[k] && usable[k]) tasks.push_back(k);
    const bool init_ahead = threads > 1 && likely_class >= 0 && usable[likely_class];
    if (init_ahead) tasks.insert(tasks.begin() + std::min<size_t>(1, tasks.size()), -1);
    std::exception_ptr init_error;
    // Class k's coarse solution prolonged to the fine vertices (all at the
    // origin when its coarse solve failed).
    auto prolonged = [&](int k, std::vector<Complex>& z, std::vector<Word>& deck) {
      const HyperbolicHarmonicResult& rc = coarse_result[k];
      z.assign(nv, Complex(0.0));
      deck.assign(nv, Word{});
      for (int v : settle) {
        if (coarse_failed[k]) break;  // from the origin
        const int c = cs.region[v], ph = cs.parent_halfedge[v];
        z[v] = rc.z[c];
        deck[v] = ph < 0 ? rc.vertex_deck_word[c] : deck_group.reduce(concat(deck[sc.tail(ph)], side_of(data[k], ph)));
      }
    };
    parallel_for(threads, static_cast<int>(tasks.size()), [&](int t, const std::atomic<bool>* stop) {
      const int k = tasks[t];
      if (k < 0) {
        try {
          // The uniform-weight fallback (polygon not usable) starts from the
          // class's prolonged coarse solution: the same map, in fewer steps.
          std::vector<Complex> z;
          std::vector<Word> deck;
          if (!coarse_failed[likely_class]) prolonged(likely_class, z, deck);
          likely_init = std::make_unique<InitialOf>(initial_of(likely_class, stop, std::move(z), std::move(deck)));
        } catch (...) {
          init_error = std::current_exception();  // rethrown only if the class is chosen: built again then
        }
        return;
      }
      std::vector<Complex> z;
      std::vector<Word> deck;
      prolonged(k, z, deck);
      HyperbolicHarmonicOptions o = fine_options(k);
      if (stop) o.progress = [stop](int, double, double) { return !*stop; };
      auto r = std::make_unique<HyperbolicHarmonicResult>();
      if (!try_solve(k, [&] { return solve_from(nv, data[k].edges, z, deck, o); }, *r)) return;
      out.candidates[k].energy = r->energy;
      out.candidates[k].solved = true;
      fine_result[k] = std::move(r);
    });
    if (init_error) likely_init.reset();
  } else {
    const std::vector<Complex> origin(nv, Complex(0.0));
    const std::vector<Word> no_decks(nv);
    for (int k = 0; k < ncand; ++k) {
      if (!usable[k]) continue;
      auto r = std::make_unique<HyperbolicHarmonicResult>();
      if (!try_solve(k, [&] { return solve_from(nv, data[k].edges, origin, no_decks, fine_options(k)); }, *r)) continue;
      out.candidates[k].energy = r->energy;
      out.candidates[k].solved = true;
      full[k] = 1;
      fine_result[k] = std::move(r);
    }
    stage_done("homotopy candidates", 0.42);
  }
  out.chosen_candidate = -1;
  for (int k = 0; k < ncand; ++k)
    if (out.candidates[k].solved && (out.chosen_candidate < 0 || out.candidates[k].energy < out.candidates[out.chosen_candidate].energy))
      out.chosen_candidate = k;
  if (options.homotopy >= 0) out.chosen_candidate = options.homotopy;
  if (out.chosen_candidate < 0) throw SolveError("the harmonic map solve failed in every candidate homotopy class");
  // Ties (symmetric shapes: a symmetry composed with the best class has the
  // same energy up to discretisation, ~1e-8..1e-5 relative) go to the
  // earliest candidate, the overlay class first.
  if (options.homotopy < 0)
    for (int k = 0; k < out.chosen_candidate; ++k)
      if (out.candidates[k].solved && out.candidates[k].energy <= out.candidates[out.chosen_candidate].energy * (1 + 1e-4)) {
        out.chosen_candidate = k;
        break;
      }
  // Landmarks in class k from its free optimum `free_k` (landmarks.h):
  // plain pins, else the barrier continuation, else carried
  // neighbourhoods; the returned map is bijective or this throws. Folds are
  // the source faces hyperbolic_distortion leaves without a dilatation
  // (flipped or degenerate; chart elements from reduced side words when the
  // solver kept them); the continuation's face elements are the free
  // optimum's.
  auto hold_in_class = [&](int k, const HyperbolicHarmonicResult& free_k, const HyperbolicHarmonicOptions& ho,
                           bool relax, const HarmonicRelaxationOptions& ro, LandmarkHold& hold) {
    std::vector<int> lm_source, lm_target_vertex;
    std::vector<Complex> lm_target;
    for (const auto& [s, t] : options.landmarks)
      lm_source.push_back(s), lm_target_vertex.push_back(t), lm_target.push_back(layout.vertex_positions[t]);
    std::vector<Mobius> halfedge_rho(3 * source.num_faces());
    std::vector<Word> halfedge_word(3 * source.num_faces());
    for (int h = 0; h < 3 * source.num_faces(); ++h) {
      const int e = sc.edge(h);
      const bool fwd = sc.edge_halfedge(e) == h;
      halfedge_rho[h] = fwd ? data[k].rho_edge[e] : data[k].rho_edge[e].inverse();
      halfedge_word[h] = fwd ? data[k].side_word_edge[e] : inverse(data[k].side_word_edge[e]);
    }
    auto bad_faces = [&](const HyperbolicHarmonicResult& held) {
      const DistortionStats q = held.vertex_deck_word.size() == held.z.size()
                                    ? hyperbolic_distortion(source, deck_group, halfedge_word, held.z, held.vertex_deck_word)
                                    : hyperbolic_distortion(source, halfedge_rho, held.z, held.vertex_deck);
      std::vector<int> bad;
      for (int f = 0; f < source.num_faces(); ++f)
        if (!std::isfinite(q.per_face[f])) bad.push_back(f);
      return bad;
    };
    std::vector<Mobius> face_elements(3 * source.num_faces());
    for (int h = 0; h < 3 * source.num_faces(); ++h)
      face_elements[h] = effective_element(free_k, h, sc, deck_group, halfedge_word, halfedge_rho);
    return hold_hyperbolic_landmarks(source.num_vertices(), data[k].edges, deck_group.side_pairings(),
                                     deck_group.side_pairings(), free_k, lm_source, lm_target, lm_target_vertex, ho, relax,
                                     ro, &source.F, bad_faces, &hold, &face_elements);
  };
  // Landmarks change which class is best: the classes solved at full
  // resolution are ranked by their energy with the landmarks held the way
  // the returned map holds them (hold_in_class: the bijective held map),
  // and the chosen class's held map is kept. That can take a continuation
  // per class, so it is a branch and bound: the plain pins' energy (one
  // Newton solve from the class's optimum) is the infimum over all held
  // maps, folded ones included, so a lower bound; classes are held in the
  // order of their bounds, and one whose bound is not below the best held
  // energy so far cannot win and is not held (landmark_energy NaN,
  // landmark_lower_bound set). A class whose landmarks cannot be held
  // bijectively has +inf. Classes only estimated on the coarse copy are
  // not ranked (their free estimate is not comparable).
  std::vector<std::unique_ptr<HyperbolicHarmonicResult>> held_result(ncand);
  std::vector<LandmarkHold> held_record(ncand);
  if (!options.landmarks.empty() && options.homotopy < 0) {
    HyperbolicHarmonicOptions lo;
    lo.tolerance = options.tolerance;
    lo.max_iterations = options.max_iterations;
    lo.progress = [&](int, double, double) { return !options.progress || options.progress("landmarks", 0.44); };
    std::vector<int> lm_s, lm_t;
    std::vector<Complex> lm_p;
    for (const auto& [s, t] : options.landmarks) lm_s.push_back(s), lm_t.push_back(t), lm_p.push_back(layout.vertex_positions[t]);
    std::vector<int> order;
    for (int k = 0; k < ncand; ++k) {
      if (!out.candidates[k].solved || !fine_result[k]) continue;
      try {
        const HyperbolicHarmonicResult pins = hold_hyperbolic_landmarks(
            nv, data[k].edges, deck_group.side_pairings(), deck_group.side_pairings(), *fine_result[k], lm_s, lm_p, lm_t, lo);
        if (!pins.converged) continue;
        out.candidates[k].landmark_lower_bound = pins.energy;
        order.push_back(k);
      } catch (const SolveError&) {
      }
    }
    std::stable_sort(order.begin(), order.end(), [&](int x, int y) {
      return out.candidates[x].landmark_lower_bound < out.candidates[y].landmark_lower_bound;
    });
    int best = -1;
    for (int k : order) {
      if (best >= 0 && out.candidates[k].landmark_lower_bound >= out.candidates[best].landmark_energy) break;
      try {
        auto held = std::make_unique<HyperbolicHarmonicResult>(hold_in_class(k, *fine_result[k], lo, false, {}, held_record[k]));
        if (!held->converged) continue;
        out.candidates[k].landmark_energy = held->energy;
        if (best < 0 || held->energy < out.candidates[best].landmark_energy) best = k;
        held_result[k] = std::move(held);
      } catch (const SolveError&) {
        out.candidates[k].landmark_energy = std::numeric_limits<double>::infinity();
      }
    }
    if (best >= 0) out.chosen_candidate = best;
  }
  stage_done("full-resolution solve", 0.44);
  // The chosen class, then (when it was the default and fails below: flips,
  // location) the next ones: solved classes by energy, then the coarse-ranked
  // ones by their estimate (solved below from their initial maps).
  // The body of this loop is the single-class pipeline, left unindented.
  std::vector<int> fallback;
  for (int k = 0; k < ncand; ++k)
    if (k != out.chosen_candidate && usable[k] && std::isfinite(out.candidates[k].energy)) fallback.push_back(k);
  std::stable_sort(fallback.begin(), fallback.end(), [&](int x, int y) {
    const bool sx = out.candidates[x].solved, sy = out.candidates[y].solved;
    return sx != sy ? sx : out.candidates[x].energy < out.candidates[y].energy;
  });
  if (options.homotopy >= 0) fallback.clear();
  fallback.insert(fallback.begin(), out.chosen_candidate);
  const SurfaceMapResult before_attempts = out;
  for (size_t attempt = 0;; ++attempt) try {
  if (attempt > 0) {
    const std::vector<HomotopyCandidate> cands = out.candidates;
    out = before_attempts;
    out.candidates = cands;
  }
  out.chosen_candidate = fallback[attempt];
  out.source_weights = own_weights ? "positive on the source's own edges" : "intrinsic Delaunay cotangent";
  const std::vector<Mobius>& rho_edge = data[out.chosen_candidate].rho_edge;
  const std::vector<WeightedEdge>& edges = data[out.chosen_candidate].edges;
  const std::vector<Word>& side_word_edge = data[out.chosen_candidate].side_word_edge;

  // Initial map (initial_of above), computed next to the full-resolution
  // solves when this class was the likely choice.
  InitialOf initial;
  if (likely_init && likely_class == out.chosen_candidate) {
    initial = std::move(*likely_init);
    likely_init.reset();
  } else {
    initial = initial_of(out.chosen_candidate, nullptr);
  }
  const std::vector<Mobius>& halfedge_rho = initial.halfedge_rho;
  const std::vector<Word>& halfedge_word = initial.halfedge_word;
  HyperbolicInitialMapResult& init = initial.init;
  set_initial_map_info(init, out.initial_map);
  if (options.inspect_initial_map) options.inspect_initial_map({&halfedge_rho, &halfedge_word, &deck_group, &init});
  // From reduced words when the map has them (initial_map.h: the matrix
  // products lose digits for large decks).
  const DistortionStats q0 = init.vertex_deck_word.size() == init.z.size()
                                 ? hyperbolic_distortion(source, deck_group, halfedge_word, init.z, init.vertex_deck_word)
                                 : hyperbolic_distortion(source, halfedge_rho, init.z, init.vertex_deck);
  out.initial_dilatation = q0.per_face;
  out.initial_mean_dilatation = q0.mean;
  out.initial_max_dilatation = q0.max;
  out.initial_flipped_triangles = q0.flipped;
  stage_done("initial map", 0.45);

  // The solve runs on the edges expressed in the initial map's charts
  // (effective elements), its vertex decks are composed back afterwards.
  // Conjugated as reduced side words (the initial map's decks are side
  // words too), never as products of the deck matrices.
  std::vector<WeightedEdge> start_edges = edges;
  for (auto& e : start_edges) {
    e.rho_word = deck_group.reduce(
        concat({init.vertex_deck_word[e.i], e.rho_word, inverse(init.vertex_deck_word[e.j])}));
    e.rho = deck_group.evaluate_side_word(e.rho_word);
  }
  std::vector<Complex> start = init.z;
  std::vector<Mobius> start_deck = init.vertex_deck;
  std::vector<Word> start_deck_word = init.vertex_deck_word;
  out.initial_energy = hyperbolic_energy(start_edges, start, std::vector<Mobius>(start.size()));
  if (options.start_seed != 0) {
    std::mt19937 rng(options.start_seed);
    std::uniform_real_distribution<double> U(-0.35, 0.35);
    for (Complex& z : start) z = Complex(U(rng), U(rng));
    start_edges = edges;
    start_deck.assign(start.size(), Mobius());
    start_deck_word.assign(start.size(), Word{});
  }
  // Progress fraction: Newton by iterations; the relaxation (thousands of
  // sweeps) by how many of the decades from its first gradient down to the
  // tolerance are done.
  double first_gradient = -1;
  auto solve_progress = [&](int it, double E, double g) {
    if (options.solve_progress && !options.solve_progress(it, E, g)) return false;
    if (first_gradient < 0) first_gradient = g;
    double done = std::min(1.0, it / 50.0);
    if (options.method == MapMethod::Relaxation && first_gradient > 0 && g > 0) {
      const double decades = std::log(first_gradient / std::max(options.tolerance, 1e-300));
      done = decades > 0 ? std::clamp(std::log(first_gradient / g) / decades, 0.0, 1.0) : 1.0;
    }
    return !options.progress || options.progress("harmonic solve", 0.45 + 0.25 * done);
  };
  if (options.inspect_problem) {
    HarmonicProblem p;
    p.num_vertices = source.num_vertices();
    p.edges = start_edges;
    p.generators = deck_group.side_pairings();
    p.start = start;
    p.relator = deck_group.side_relator();
    p.reduce_point = [&](Complex& z) { return reduce_into_polygon(z); };
    options.inspect_problem(p);
  }
  HyperbolicHarmonicResult hr;
  // The class's full-resolution Newton solve from the ranking is its
  // optimum (convex energy): kept, unless another start or method is asked
  // for (uniqueness checks, the relaxation for comparison).
  const bool reuse = fine_result[out.chosen_candidate] && options.method == MapMethod::Newton && options.start_seed == 0;
  if (reuse) {
    hr = std::move(*fine_result[out.chosen_candidate]);
    fine_result[out.chosen_candidate].reset();
    // solve_progress saw the requested class's solve live; otherwise (the
    // default class is known only after the ranking) its iterations are
    // reported now.
    if (options.homotopy < 0 && options.solve_progress)
      for (size_t it = 0; it < hr.gradient_history.size(); ++it)
        if (!options.solve_progress(static_cast<int>(it), hr.energy_history[std::min(it, hr.energy_history.size() - 1)],
                                    hr.gradient_history[it]))
          throw Cancelled("harmonic map solve cancelled");
  } else if (options.method == MapMethod::Relaxation) {
    HarmonicRelaxationOptions ro;
    ro.tolerance = options.tolerance;
    ro.max_iterations = options.max_iterations;
    ro.check_every = 10;  // the evaluation pass costs about a sweep
    ro.progress = solve_progress;
    hr = as_harmonic_result(harmonic_relaxation(source.num_vertices(), start_edges, deck_group.side_pairings(), start, ro));
  } else {
    HyperbolicHarmonicOptions ho;
    ho.tolerance = options.tolerance;
    ho.max_iterations = options.max_iterations;
    ho.progress = solve_progress;
    ho.relator = deck_group.side_relator();
    ho.reduce_point = [&](Complex& z) { return reduce_into_polygon(z); };
    hr = hyperbolic_harmonic_map(source.num_vertices(), start_edges, deck_group.side_pairings(), start, ho);
  }
  if (!reuse) {
  for (size_t i = 0; i < hr.vertex_deck.size(); ++i) hr.vertex_deck[i] = (hr.vertex_deck[i] * start_deck[i]).normalized();
  if (hr.vertex_deck_word.size() == hr.vertex_deck.size())
    for (size_t i = 0; i < hr.vertex_deck_word.size(); ++i)
      hr.vertex_deck_word[i] = deck_group.reduce(concat(hr.vertex_deck_word[i], start_deck_word[i]));
  }
  if (!hr.converged)
    throw SolveError(std::string("the harmonic map solve (") +
                     (options.method == MapMethod::Relaxation ? "relaxation" : "Newton") + ") did not converge in " +
                     std::to_string(hr.iterations) + " iterations (gradient " +
                     std::to_string(hr.gradient_history.back()) + "); raise max_iterations or the tolerance");
  if (!options.landmarks.empty()) {
    // Landmarks (hold_in_class above): held at the lifts nearest to the free
    // optimum; the ranking's held map when it was this class's.
    HyperbolicHarmonicOptions ho;
    ho.tolerance = options.tolerance;
    ho.max_iterations = options.max_iterations;
    ho.progress = solve_progress;
    // The relaxation holds them too (its sweeps skip the held vertices).
    const bool relax = options.method == MapMethod::Relaxation;
    HarmonicRelaxationOptions ro;
    ro.tolerance = options.tolerance;
    ro.max_iterations = options.max_iterations;
    ro.check_every = 10;
    ro.progress = solve_progress;
    LandmarkHold hold;
    HyperbolicHarmonicResult held;
    if (reuse && held_result[out.chosen_candidate]) {
      held = std::move(*held_result[out.chosen_candidate]);
      held_result[out.chosen_candidate].reset();
      hold = held_record[out.chosen_candidate];
    } else {
      held = hold_in_class(out.chosen_candidate, hr, ho, relax, ro, hold);
    }
    out.candidates[out.chosen_candidate].landmark_energy = held.energy;
    out.landmark_rings = hold.rings;
    out.landmark_method = hold.method;
    out.landmark_solves = hold.solves;
    out.landmark_steps = hold.barrier_steps;
    out.landmark_held_vertices = hold.held_vertices;
    if (!held.converged)
      throw SolveError(std::string("the harmonic map with the landmarks held (") + (relax ? "relaxation" : "Newton") +
                       ") did not converge in " + std::to_string(held.iterations) + " iterations");
    held.energy_history.insert(held.energy_history.begin(), hr.energy_history.begin(), hr.energy_history.end());
    held.iterations += hr.iterations;
    hr = std::move(held);
  }
  out.converged = true;
  out.iterations = hr.iterations;
  out.energy_history = hr.energy_history;
  out.final_energy = hr.energy;
  out.candidates[out.chosen_candidate].energy = hr.energy;
  out.candidates[out.chosen_candidate].solved = true;
  stage_done("harmonic solve", 0.7);

  // Every vertex in P, with its chart change as a side word (the solve's
  // moves were side pairings too).
  // (A solver that keeps no deck words, the relaxation, falls back to the
  // products of its deck matrices, and to local charts built from points.)
  const int nv = source.num_vertices();
  const bool have_words = static_cast<int>(hr.vertex_deck_word.size()) == nv;
  std::vector<Complex> zp = hr.z;
  std::vector<Word> deck(nv);
  std::vector<Mobius> deck_matrix(nv);
  for (int i = 0; i < nv; ++i) {
    const Word into_P = reduce_into_polygon(zp[i]);
    if (have_words)
      deck[i] = deck_group.reduce(concat(into_P, hr.vertex_deck_word[i]));
    else
      deck_matrix[i] = (deck_group.evaluate_side_word(into_P) * hr.vertex_deck[i]).normalized();
  }

  // Effective element of every source edge after the chart moves, as a
  // reduced side word (short: the tile next to P holding the edge's far end).
  std::vector<Mobius> eff_edge(edge_word.size());
  for (size_t e = 0; e < edge_word.size(); ++e) {
    const int h = sc.edge_halfedge(static_cast<int>(e));
    eff_edge[e] = have_words ? deck_group.evaluate_side_word(deck_group.reduce(
                                   concat({deck[sc.tail(h)], side_word_edge[e], inverse(deck[sc.head(h)])})))
                             : (deck_matrix[sc.tail(h)] * rho_edge[e] * deck_matrix[sc.head(h)].inverse()).normalized();
  }
  if (hr.edge_local.size() != edges.size()) {
    hr.edge_local.resize(edges.size());
    for (int e = 0; e < sc.num_edges(); ++e) {
      const int h = sc.edge_halfedge(e);
      const Mobius A = (Mobius::centring(zp[sc.tail(h)]) * eff_edge[e] * Mobius::translation_to(zp[sc.head(h)])).normalized();
      hr.edge_local[orig_solver_edge[e]] = orig_forward[e] ? A : A.inverse();
    }
  }
  auto eff = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? eff_edge[e] : eff_edge[e].inverse();
  };
  // Image triangles: corners in the Poincaré disk, anchored at corner 0.
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(source.num_faces(), 3);
  for (int f = 0; f < source.num_faces(); ++f) {
    img(f, 0) = zp[source.F(f, 0)];
    img(f, 1) = eff(3 * f).apply(zp[source.F(f, 1)]);
    img(f, 2) = eff(3 * f + 2).inverse().apply(zp[source.F(f, 2)]);
  }
  // Halfedge h's element in the solve's charts of its ends (edge_local).
  auto local = [&](int h) {
    const int e = sc.edge(h);
    const Mobius& A = hr.edge_local[orig_solver_edge[e]];
    return (sc.edge_halfedge(e) == h) == static_cast<bool>(orig_forward[e]) ? A : A.inverse();
  };
  // Dilatation from hyperbolic side lengths and orientation, both in the
  // chart of corner 0 where the corners are 0, A_01(0) and A_20^-1(0):
  // exact to round-off however close to |z| = 1 the triangle lies in P.
  out.dilatation.assign(source.num_faces(), std::numeric_limits<double>::infinity());
  double weighted = 0, total_area = 0;
  for (int f = 0; f < source.num_faces(); ++f) {
    const Mobius A01 = local(3 * f), A12 = local(3 * f + 1), A20 = local(3 * f + 2);
    const Complex b = A01.apply(Complex(0.0)), cc = A20.inverse().apply(Complex(0.0));
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
    const Eigen::Vector3d is(A01.displacement_of_origin(), A12.displacement_of_origin(), A20.displacement_of_origin());
    // From the side lengths (paper §VII-A) unless the image is needle-thin:
    // then a + b − c is below the lengths' round-off (~1e-9 relative after a
    // long solve) and the Euclidean frame built from them is meaningless,
    // although the orientation test above resolved the area. Then take the
    // affine map to the image seen from the chart centring its centroid (D'
    // is scale-free, so the conformal factor there does not matter), with
    // the source frame built from the 3D corners: D' + 1/D' = |A|_F²/|det A|.
    const double defect = std::min({is[0] + is[1] - is[2], is[1] + is[2] - is[0], is[2] + is[0] - is[1]});
    double d = defect > 1e-4 * is.sum() ? triangle_dilatation(ss, is) : std::numeric_limits<double>::infinity();
    if (!std::isfinite(d)) {
      const Complex m = hyperbolic::klein_to_poincare(
          (hyperbolic::poincare_to_klein(b) + hyperbolic::poincare_to_klein(cc)) / 3.0);
      const Complex w0 = hyperbolic::centred(m, Complex(0.0)), w1 = hyperbolic::centred(m, b) - w0,
                    w2 = hyperbolic::centred(m, cc) - w0;
      const Eigen::Vector3d e1 = p1 - p0, e2 = p2 - p0;
      const double l1 = e1.norm();
      Eigen::Matrix2d S, I;
      S << l1, e2.dot(e1) / l1, 0, e1.cross(e2).norm() / l1;
      I << w1.real(), w2.real(), w1.imag(), w2.imag();
      const Eigen::Matrix2d A = I * S.inverse();
      const double q = A.squaredNorm() / std::abs(A.determinant());
      d = 0.5 * (q + std::sqrt(std::max(q * q - 4.0, 0.0)));
    }
    out.dilatation[f] = d;
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    weighted += area * d;
    total_area += area;
    out.max_dilatation = std::max(out.max_dilatation, d);
  }
  out.mean_dilatation = weighted / std::max(total_area, 1e-300);
  // The intrinsic Delaunay triangles (the energy's own triangulation): their
  // images from the solver's local charts, oriented by the face's corners.
  out.intrinsic_flipped_triangles = 0;
  if (hr.edge_local.size() >= idt.edges.size()) {
    for (int f = 0; f < static_cast<int>(idt.F.rows()); ++f) {
      Mobius side[3];
      bool known = true;
      for (int k = 0; k < 3; ++k) {
        const int e = idt.face_edges(f, k);
        const auto& ie = idt.edges[e];
        const int a = idt.F(f, k), b = idt.F(f, (k + 1) % 3);
        if (ie.i == a && ie.j == b && a != b) side[k] = hr.edge_local[e];
        else if (ie.i == b && ie.j == a && a != b) side[k] = hr.edge_local[e].inverse();
        else known = false;  // a loop edge: orientation not recorded
      }
      if (!known) continue;
      const Complex p1 = side[0].apply(Complex(0.0)), p2 = side[2].inverse().apply(Complex(0.0));
      if (p1.real() * p2.imag() - p1.imag() * p2.real() <= 0) ++out.intrinsic_flipped_triangles;
    }
  }
  if ((out.flipped_triangles || out.degenerate_triangles) && !own_weights &&
      options.source_weights == SourceWeights::Automatic) {
    // The intrinsic triangulation is embedded but straight images of the
    // user's own faces fold (slivers): positive weights on the own edges
    // embed those faces (Tutte-type theorem); the class stays, the energy
    // and so the map change. Every class's data follows the new weights.
    own_weights = true;
    idt = positive_edge_weights(sc, edge_lengths(source, sc));
    index_solver_edges();
    for (int k = 0; k < ncand; ++k)
      if (!data[k].edges.empty()) data[k] = class_data(handle_classes[k].map);  // empty: never evaluable
    const std::vector<HomotopyCandidate> cands = out.candidates;
    out = before_attempts;
    out.candidates = cands;
    --attempt;  // the same class again
    continue;
  }
  if (out.flipped_triangles || out.degenerate_triangles)
    throw SolveError("the optimised map has " + std::to_string(out.flipped_triangles) + " flipped and " +
                     std::to_string(out.degenerate_triangles) + " degenerate image triangles of the source's faces (" +
                     std::to_string(out.intrinsic_flipped_triangles) +
                     " flipped on its intrinsic Delaunay triangulation, where the energy lives); it is not returned");
  out.source_image = zp;
  stage_done("quality", 0.75);

  // Location. Barycentrics are those of the hyperboloid model, computed in
  // the chart centring the query point (geometry/hyperbolic.h): exact to
  // round-off for tiny triangles near |z| = 1, where Klein coordinates of
  // the whole layout (1 − |k| ~ 1e-9 at 10 units from the centre) would
  // leave a handful of digits. The Klein grid only proposes candidates.
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
  constexpr double kInsideTol = 1e-9;
  using Tris = std::vector<std::array<Complex, 3>>;
  // Best candidate triangle for z (largest smallest barycentric), or -1.
  auto exact_locate = [&](const TriangleGrid& grid, const Tris& tris, Complex z, Eigen::Vector3d* bary) {
    int best = -1;
    double best_min = -kInsideTol;
    for (int t : grid.candidates(hyperbolic::poincare_to_klein(z))) {
      double l[3];
      hyperbolic::triangle_barycentric(z, tris[t][0], tris[t][1], tris[t][2], l);
      const double m = std::min({l[0], l[1], l[2]});
      if (m >= best_min) best_min = m, best = t, *bary = Eigen::Vector3d(l[0], l[1], l[2]);
    }
    return best;
  };
  // Points are first reduced into P. The mesh regions differ from P only
  // near its sides and corners, so the containing triangle is in an image
  // of the point under side maps that keep it near P (around a corner up to
  // 4g of them): breadth first over those, pruning images far from P.
  auto locate = [&](const TriangleGrid& grid, const Tris& tris, Complex z, Eigen::Vector3d* bary) {
    reduce_into_polygon(z);
    // Exhaustively up to two side maps (the usual case: the mesh's cut
    // sides bulge away from P's geodesic sides) ...
    int f = exact_locate(grid, tris, z, bary);
    for (int a1 = 0; f < 0 && a1 < nsides; ++a1) {
      const Complex w = side_map[a1].apply(z);
      f = exact_locate(grid, tris, w, bary);
      for (int a2 = 0; f < 0 && a2 < nsides; ++a2) f = exact_locate(grid, tris, side_map[a2].apply(w), bary);
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
          if ((f = exact_locate(grid, tris, q, bary)) >= 0) return f;
          next.push_back(q);
        }
      frontier.swap(next);
    }
    return -1;
  };
  const int ntf = tl.mesh.num_faces();
  Tris tpoints(ntf), ttris(ntf);
  for (int f = 0; f < ntf; ++f)
    for (int k = 0; k < 3; ++k) {
      tpoints[f][k] = layout.corners(f, k);
      ttris[f][k] = hyperbolic::poincare_to_klein(layout.corners(f, k));
    }
  const TriangleGrid tgrid(ttris, 1e-12);
  // Forward map: a straight walk over the target's faces in the universal
  // cover, from the face found for the previous vertex. Crossing a cut edge
  // applies its deck map, so the walk never leaves the layout and does not
  // depend on how the cut disk differs from P.
  const Connectivity tconn(tl.mesh.F, tl.mesh.num_vertices());
  auto target_corners = [&](int f) {
    return std::array<Complex, 3>{layout.corners(f, 0), layout.corners(f, 1), layout.corners(f, 2)};
  };
  auto target_cross = [&](int f, int s, Complex& c, Complex& q, int* entry) {
    const int h = 3 * f + s, e = tconn.edge(h), t = tconn.twin(h);
    if (layout.cut_edge[e]) {
      const Mobius D = tconn.edge_halfedge(e) == h ? layout.edge_deck_mobius[e] : layout.edge_deck_mobius[e].inverse();
      c = D.apply(c), q = D.apply(q);
    }
    *entry = t % 3;
    return Connectivity::face(t);
  };
  auto walk = [&](int f, Complex q, Eigen::Vector3d* bary) {
    return straight_walk(f, q, target_corners, target_cross, 4 * ntf + 100, kInsideTol, bary);
  };
  // The initial map's location (below, its "before" morph and UVs) runs
  // next to the optimum's (concurrency.h), which reports the stages.
  auto locate_initial = [&](const std::atomic<bool>* stop) {
    // The initial map, located the same way (the "before" morph and UVs); a
    // vertex that cannot be located leaves it unlocated (empty), not an error.
    std::vector<int> initial_face_origin(ntf, -1);
    out.initial_forward.resize(source.num_vertices());
    int last_face = layout.root_face >= 0 ? layout.root_face : 0;
    for (int i = 0; i < source.num_vertices(); ++i) {
      if (*stop) return;
      Eigen::Vector3d b;
      Complex q = init.z[i];
      reduce_into_polygon(q);
      int rf = walk(last_face, q, &b);
      if (rf < 0) rf = locate(tgrid, tpoints, q, &b);
      if (rf < 0) {
        out.initial_forward.clear();
        break;
      }
      last_face = rf;
      out.initial_forward[i] = point_on_input(target, tc, tl, initial_face_origin, rf, b);
    }
    // The initial map's inverse (the "before" UV transfer): its image
    // triangles from its own chart elements, each moved into P by the
    // reduction of its corner 0, located by the grid; left empty (not an
    // error) when a target vertex is not covered.
    {
      auto init_eff = [&](int h) { return effective_element(init, h, sc, deck_group, halfedge_word, halfedge_rho); };
      // Corner k of face f is init_corner[3f+k] applied to its vertex's point
      // (corner 0 reduced into P); the walk crosses into the neighbour g
      // through the shared vertex u by init_corner(g, u) init_corner(f, u)^-1.
      std::vector<Mobius> init_corner(3 * source.num_faces());
      Tris ipoints(source.num_faces()), itris(source.num_faces());
      for (int f = 0; f < source.num_faces(); ++f) {
        Complex c0 = init.z[source.F(f, 0)];
        const Mobius R = deck_group.evaluate_side_word(reduce_into_polygon(c0));
        init_corner[3 * f] = R;
        init_corner[3 * f + 1] = (R * init_eff(3 * f)).normalized();
        init_corner[3 * f + 2] = (R * init_eff(3 * f + 2).inverse()).normalized();
        ipoints[f] = {c0, init_corner[3 * f + 1].apply(init.z[source.F(f, 1)]),
                      init_corner[3 * f + 2].apply(init.z[source.F(f, 2)])};
        for (int k = 0; k < 3; ++k) itris[f][k] = hyperbolic::poincare_to_klein(ipoints[f][k]);
      }
      auto init_corners = [&](int f) { return ipoints[f]; };
      auto init_cross = [&](int f, int s, Complex& c, Complex& q, int* entry) {
        const int h = 3 * f + s, t = sc.twin(h), g = Connectivity::face(t);
        const int cg = (t % 3 + 1) % 3;
        const Mobius M = (init_corner[3 * g + cg] * init_corner[3 * f + s].inverse()).normalized();
        c = M.apply(c), q = M.apply(q);
        *entry = t % 3;
        return g;
      };
      const TriangleGrid igrid(itris, 1e-12);
      out.initial_inverse.resize(target.num_vertices());
      int last_face0 = 0;
      for (int v = 0; v < target.num_vertices(); ++v) {
        if (*stop) return;
        Eigen::Vector3d b;
        Complex q = layout.vertex_positions[v];
        reduce_into_polygon(q);
        int f = straight_walk(last_face0, q, init_corners, init_cross, 4 * source.num_faces() + 100, kInsideTol, &b);
        if (f < 0) f = locate(igrid, ipoints, layout.vertex_positions[v], &b);
        if (f < 0) {
          out.initial_inverse.clear();
          break;
        }
        last_face0 = f;
        out.initial_inverse[v] = point_in_face(source, f, b);
      }
    }
  };
  const std::atomic<bool> never{false};
  parallel_for(threads, 2, [&](int task, const std::atomic<bool>* stop) {
    if (task == 1) return locate_initial(stop ? stop : &never);
    std::vector<int> refined_face_origin(ntf, -1);
    out.forward.resize(source.num_vertices());
    int last_face = layout.root_face >= 0 ? layout.root_face : 0;
    for (int i = 0; i < source.num_vertices(); ++i) {
      Eigen::Vector3d b;
      int rf = walk(last_face, zp[i], &b);
      if (rf < 0) rf = locate(tgrid, tpoints, zp[i], &b);
      if (rf < 0) throw SolveError("source vertex " + std::to_string(i) + " could not be located on the target");
      last_face = rf;
      out.forward[i] = point_on_input(target, tc, tl, refined_face_origin, rf, b);
    }
    stage_done("forward location", 0.85);
    Tris spoints(source.num_faces()), stris(source.num_faces());
    for (int f = 0; f < source.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        spoints[f][k] = img(f, k);
        stris[f][k] = hyperbolic::poincare_to_klein(img(f, k));
      }
    const TriangleGrid sgrid(stris, 1e-12);
    // Inverse map: the same walk over the source's image triangles. Face f's
    // image is stored with corner k at γ_{f,k}(zp[F(f,k)]) (γ_{f,0} = id,
    // γ_{f,1} = eff(h0), γ_{f,2} = eff(h2)^-1); crossing into face g through
    // the vertex u they share maps the query by γ_{g,u} γ_{f,u}^-1 (identity
    // unless the edge straddles a side of P).
    auto corner_element = [&](int f, int k) {
      return k == 0 ? Mobius() : k == 1 ? eff(3 * f) : eff(3 * f + 2).inverse();
    };
    auto source_corners = [&](int f) { return std::array<Complex, 3>{img(f, 0), img(f, 1), img(f, 2)}; };
    auto source_cross = [&](int f, int s, Complex& c, Complex& q, int* entry) {
      const int h = 3 * f + s, t = sc.twin(h), g = Connectivity::face(t);
      // Shared vertex u = tail(h) = corner s of f = corner (t+1)%3 of g.
      const int cg = (t % 3 + 1) % 3;
      const Mobius M = (corner_element(g, cg) * corner_element(f, s).inverse()).normalized();
      c = M.apply(c), q = M.apply(q);
      *entry = t % 3;
      return g;
    };
    auto walk_source = [&](int f, Complex q, Eigen::Vector3d* bary) {
      return straight_walk(f, q, source_corners, source_cross, 4 * source.num_faces() + 100, kInsideTol, bary);
    };
    out.inverse.resize(target.num_vertices());
    int last_source_face = 0;
    for (int v = 0; v < target.num_vertices(); ++v) {
      Eigen::Vector3d b;
      Complex q = layout.vertex_positions[v];
      reduce_into_polygon(q);
      int f = walk_source(last_source_face, q, &b);
      if (f < 0) f = locate(sgrid, spoints, layout.vertex_positions[v], &b);
      if (f < 0) throw SolveError("target vertex " + std::to_string(v) + " could not be located in the source image");
      last_source_face = f;
      out.inverse[v] = point_in_face(source, f, b);
    }
  });
  stage_done("inverse location", 1.0);
  return;
  } catch (const SolveError& e) {
    if (attempt + 1 >= fallback.size()) throw;
    out.candidates[fallback[attempt]].description += std::string("  [not used: ") + e.what() + "]";
  }
}

}  // namespace surfmap::detail
