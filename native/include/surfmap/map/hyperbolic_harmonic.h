#pragma once
// Discrete harmonic map into a hyperbolic surface (docs/method.md
// §2.8 and §7): minimises E(z) = Σ_e w_e d(z_i, ρ_e z_j)² over one point z_i
// per vertex in the Poincaré disk, with a deck element ρ_e per edge i->j and
// weights w_e >= 0. E is geodesically convex (the disk is a Hadamard space),
// so the minimiser in the homotopy class fixed by ρ is unique.
//
// Method: Riemannian Newton with the Hessian of docs/method.md §7 (radial and
// normal blocks, frame rotations), a Levenberg shift when the model is
// indefinite, and a backtracking line search on E along the exponential map.
// The solve runs in charts: every vertex has an isometry C_i with C_i(0) = z_i
// and every edge its element in the charts of its two ends, so no distance is
// computed between points near |z| = 1 and no deck matrix is multiplied by a
// chart (see the .cpp). Vertices that wander far from the origin are moved to
// another sheet by deck elements (the algebraic form of the paper's dynamic
// charts, docs/method.md §2.6): z_i ← γ z_i and, implicitly, ρ_e ← γ_i ρ_e γ_j⁻¹.
#include <complex>
#include <functional>
#include <memory>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap {

/// Vertices that slide along geodesics (issue 16: the boundary of an open
/// surface's half mapped onto the target's geodesic boundary, docs/open_surfaces.md
/// "The half's solve"). Each sliding vertex has one real unknown, its arc length
/// along its geodesic: its Newton step is a translation along the geodesic
/// through its chart's origin, which maps that geodesic onto itself, so the
/// vertex stays on it to round-off (the start is projected onto it). The
/// energy restricted to such constraints is still geodesically convex.
struct BoundarySlideOptions {
  /// #V or empty (no sliding vertex): nonzero for a vertex that slides.
  std::vector<char> slides;
  /// #V (read where `slides` is set): G_i with vertex i's geodesic the image
  /// G_i(-1..1) of the real diameter, in the coordinates of the start points
  /// z0 (the deck moves of the solve are applied to it as to z_i).
  std::vector<hyperbolic::Mobius> geodesic;
  /// Indices of edges i -> j whose two ends slide on the same geodesic
  /// (consecutive vertices of a boundary loop): the order of their images
  /// along it is kept as at the start (a line-search trial that turns one
  /// over is shortened), so that consecutive boundary images cannot slide
  /// past each other. Edges starting with both images at one point are not
  /// checked.
  std::vector<int> ordered_edges;
  /// Terms w · δ(z_v, G(diameter))² added to the energy, δ the distance of
  /// vertex v from a geodesic (G in the start points' coordinates, like
  /// `geodesic`): the half's share of a double's edge from v to its own
  /// mirror image v' across the boundary (an intrinsic Delaunay edge
  /// crossing it), w_e d(z_v, σ z_v)² / 2 = 2 w_e δ², so w = 2 w_e. Their
  /// Hessian, 2 dδ ⊗ dδ + 2 δ tanh δ (t ⊗ t) with t along the geodesic, is
  /// positive semidefinite: the energy stays geodesically convex. Only on
  /// vertices that neither slide nor are held.
  struct Pull {
    int vertex = -1;
    double w = 0;
    hyperbolic::Mobius geodesic;
  };
  std::vector<Pull> pulls;
};

struct HyperbolicHarmonicOptions {
  /// Stop when the largest per-vertex gradient length is below this times
  /// the largest weight-scaled edge length (default 1e-10).
  double tolerance = 1e-10;
  int max_iterations = 300;
  /// A start whose edge element has |a| + |b| beyond this (default 1e15:
  /// about 70 hyperbolic units) is refused with a SolveError: from a start
  /// with every vertex at the origin such an edge is a class twisted by
  /// dozens of tiles, which costs hundreds of capped steps. The geometric
  /// classes raise it (HomotopySearchOptions::geometric_start_edge_size):
  /// their source loops' images are that long without any twist (the
  /// fertility -> genus-4 plate pair: 25-100 units). The elements are kept
  /// as words and multiplied out in long double, so the size is not a
  /// precision limit up to ~1e150.
  double max_start_edge_size = 1e15;
  /// Issue 13 (session 24): with words (`relator`), a start whose edge
  /// element, multiplied out letter by letter in long double, carries a
  /// round-off estimate beyond this fraction of its own size (default 1e-3:
  /// fewer than three digits left) is refused with a SolveError saying so:
  /// its word's partial products wander far beyond the element (a
  /// Dehn-reduced word of hundreds of letters through a long thin domain
  /// reaches tiles 10^100 away for an element of 10^10), so the element is
  /// not evaluable, whatever its apparent size. Such a class was refused as
  /// "beyond double range" when its garbage came out large, and solved into
  /// a map of no surface when it came out small. 0 or less: no check.
  double max_start_round_off = 1e-3;
  /// Called every iteration with (iteration, energy, gradient norm); return
  /// false to cancel (throws Cancelled).
  std::function<bool(int, double, double)> progress;
  /// #V or empty (default): vertices held at their start point (landmarks,
  /// docs/method.md §2.10). Their Newton step is zero; the chart moves may still
  /// re-express them by a deck element, which is the same point of the surface.
  std::vector<char> fixed;
  /// Optional: the group's relator in generator letters (e.g.
  /// DeckGroup::side_relator()). With it, and WeightedEdge::rho_word on the
  /// edges, every edge's effective element (after the chart moves) is kept
  /// as a Dehn-reduced word and multiplied out afresh when it changes, so an
  /// edge that was long at some point (a bad start: a canonical generator 20
  /// tiles away has entries 1e13) carries no round-off of its largest
  /// matrix into the result. Without it the effective elements are
  /// conjugated as matrices (fine while they stay small).
  Word relator;
  /// Optional: moves a point into the fundamental domain and returns the
  /// element applied (z_new = γ(z_old)) as a word in generator letters, e.g.
  /// by crossing the polygon's sides. Called on every vertex after every step
  /// so that no chart drifts far from the domain. Default: greedy moves by
  /// the generators while the distance from the origin decreases
  /// (geometry/dynamic_charts.h), which can stall outside the domain when
  /// the polygon is not a Dirichlet domain centred at the origin.
  std::function<Word(std::complex<double>&)> reduce_point;
  /// Optional: vertices constrained to geodesics (BoundarySlideOptions);
  /// not with per-face charts and not on a held (`fixed`) vertex.
  BoundarySlideOptions boundary_slide;
};

struct WeightedEdge {
  int i = -1, j = -1;
  double w = 0;
  hyperbolic::Mobius rho;  ///< image of the edge runs from z_i to rho(z_j)
  /// Optional: rho as a word in generator letters (+(k+1) = generators[k]),
  /// see HyperbolicHarmonicOptions::relator.
  Word rho_word;
};

struct HyperbolicHarmonicResult {
  bool converged = false;
  int iterations = 0;
  std::vector<double> energy_history, gradient_history;
  /// #V points in the Poincaré disk and the deck element applied to each
  /// vertex while solving: the effective element of edge i->j is
  /// vertex_deck[i] * rho * vertex_deck[j]^-1. The matrices of long decks
  /// can have huge entries, and that product then keeps no digits: use
  /// edge_effective for the solve's edges, and vertex_deck_word (the same
  /// elements as freely reduced words, letter +(k+1) = generators[k], -(k+1)
  /// its inverse, product order as written) to build others exactly.
  std::vector<std::complex<double>> z;
  /// Per-face charts only (hyperbolic_harmonic_map_in_face_charts): #V, the
  /// target face whose canonical chart z[i] is given in (empty otherwise).
  std::vector<int> face;
  std::vector<hyperbolic::Mobius> vertex_deck;
  std::vector<Word> vertex_deck_word;
  /// #edges: the effective element of each edge at the end, i.e.
  /// vertex_deck[i] * rho * vertex_deck[j]^-1 (multiplied out from small
  /// matrices only).
  std::vector<hyperbolic::Mobius> edge_effective;
  /// #edges: each edge in the charts of its ends, A_e = C_i^-1 ρ_e C_j with
  /// C_i the isometry taking 0 to z[i] (frames parallel-transported along the
  /// solve): the edge's image runs from 0 to A_e(0) in i's chart. Accurate to
  /// round-off whatever |z| is; use it for orientation and length tests.
  std::vector<hyperbolic::Mobius> edge_local;
  double energy = 0;
  /// Cost breakdown: numeric factorisations of the Newton system (each
  /// Levenberg retry counts), energy evaluations of the line searches, and
  /// seconds spent in the symbolic analysis (once per solve) and in the
  /// numeric factorisations.
  int factorizations = 0, energy_evaluations = 0;
  /// Newton steps solved by conjugate gradients preconditioned with an
  /// earlier iteration's factorisation (large sources, issue 19), and the CG
  /// iterations spent (one solve with the factor each, failed tries included).
  int preconditioned_steps = 0, cg_iterations = 0;
  double analysis_seconds = 0, factorization_seconds = 0;
  /// With options.boundary_slide: the largest hyperbolic distance of a
  /// sliding vertex from its geodesic at the end, and the line-search trials
  /// shortened because they turned an ordered edge over.
  double slide_off_geodesic = 0;
  int order_rejections = 0;
};

/// `generators`: the deck group's generators (their inverses are used too)
/// for moving vertices back towards the origin; pass the side pairings of
/// the fundamental polygon (DeckGroup::side_pairings), whose matrices are
/// small, rather than loop generators based at a far corner. `z0`: #V start points.
HyperbolicHarmonicResult hyperbolic_harmonic_map(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                 const std::vector<hyperbolic::Mobius>& generators,
                                                 std::vector<std::complex<double>> z0,
                                                 const HyperbolicHarmonicOptions& options = {});

/// The same solve with the target in per-face charts (issue 13: targets
/// whose fundamental domain reaches past what one Poincaré chart holds in
/// double precision, CAD plates of genus 13 .. 24). Vertex i starts in
/// target face face0[i] at the point w0[i] of that face's canonical chart
/// (FaceAtlas); each edge's `rho` is its start element in those charts: it
/// takes face0[j]'s canonical coordinates to face0[i]'s, composed of the
/// transitions along the faces between them (so its homotopy class is the
/// class of the faces crossed), and the image of edge i->j runs from w0[i]
/// to rho(w0[j]). Nothing is computed in a global chart: after every step a
/// vertex is walked to the face containing it (locate_in_face_charts) and
/// its edges' elements are conjugated by the transitions crossed, which have
/// entries of size ~1, as does every edge element of a map with short edges.
/// The Newton iteration, its line search and its stopping rules are those of
/// hyperbolic_harmonic_map (the same energy, gradient and Hessian read off
/// the same edge elements), so on a target that one chart does hold both
/// give the same map. Words are not used: options.relator and
/// options.reduce_point must be empty (InputError). The result's z[i] is a
/// point in the canonical chart of face[i]; vertex_deck / vertex_deck_word
/// are left as identities; edge_effective holds the final elements in the
/// face charts (face[j]'s coordinates -> face[i]'s).
HyperbolicHarmonicResult hyperbolic_harmonic_map_in_face_charts(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                                const FaceAtlas& atlas, std::vector<int> face0,
                                                                std::vector<std::complex<double>> w0,
                                                                const HyperbolicHarmonicOptions& options = {});

struct HessianAnalysis;  // (hyperbolic_harmonic.cpp)

/// The same solve for many problems on one sparsity pattern: the edges'
/// endpoints and which weights are positive (every homotopy class of one
/// source shares it, as do the class search's solves on the coarse copy;
/// only the deck elements and the weights' values differ). The fill-reducing
/// ordering and symbolic factorisation of the Newton Hessian are computed
/// once, here, and every solve (every Newton iteration of it) factorises
/// numerically on that analysis. Results are those of hyperbolic_harmonic_map
/// bit for bit. solve() is const and may run on several threads at once.
class HyperbolicHarmonicSolver {
 public:
  /// `edges` (#E): the pattern (endpoints, w > 0) on `num_vertices`
  /// vertices; deck elements are not read. Throws SolveError when the
  /// ordering or the symbolic factorisation fails, InputError on bad endpoints.
  HyperbolicHarmonicSolver(int num_vertices, const std::vector<WeightedEdge>& edges);
  ~HyperbolicHarmonicSolver();
  /// Whether `edges` on `num_vertices` vertices have the solver's pattern
  /// (solve accepts them).
  bool fits(int num_vertices, const std::vector<WeightedEdge>& edges) const;
  /// hyperbolic_harmonic_map(#z0, edges, generators, z0, options) for edges
  /// of the solver's pattern (InputError otherwise).
  HyperbolicHarmonicResult solve(const std::vector<WeightedEdge>& edges,
                                 const std::vector<hyperbolic::Mobius>& generators, std::vector<std::complex<double>> z0,
                                 const HyperbolicHarmonicOptions& options = {}) const;

 private:
  std::shared_ptr<const HessianAnalysis> analysis_;
};

/// E(z) for the given effective deck elements (for independent checks).
double hyperbolic_energy(const std::vector<WeightedEdge>& edges, const std::vector<std::complex<double>>& z,
                         const std::vector<hyperbolic::Mobius>& vertex_deck);

}  // namespace surfmap
