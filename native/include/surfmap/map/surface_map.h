#pragma once
// The globally optimal surface map (docs/method.md §2.3–2.11).
//
// Flat case (genus 1), implemented here: the target is uniformized to a flat
// torus C / (ω1 Z + ω2 Z); the map is given by one point z_i per source
// vertex and one lattice translation t_ij per source edge (the homotopy
// class, from both surfaces' canonical polygon schemata), and the harmonic
// energy E = Σ w_ij |z_i − z_j − t_ij|² with the cotangent weights of the
// source's intrinsic Delaunay triangulation is quadratic: one sparse solve
// gives the exact optimum (unique up to a translation of the torus). Each
// candidate homotopy class (handle correspondence) reuses the same
// factorisation; the one of lowest energy is the default.
//
// Hyperbolic case (genus >= 2): the energy Σ w_ij d(z_i, ρ_ij z_j)² in the
// Poincaré disk is geodesically convex; Riemannian Newton with line search
// (map/hyperbolic_harmonic.h) converges in a handful of iterations. The
// candidate classes (docs/method.md §2.10), in this order: (0) the class the two
// shapes induce when overlaid in normalised bounding boxes (the source's
// loops carried to the nearest target points, topology/projected_loops.h:
// the identity for a remeshed copy, handles to the handles they overlap for
// shapes posed alike; absent when the images jump); (1) a_i -> a'_i,
// b_i -> b'_i of the two canonical polygon schemata; (2...) the signed
// handle permutations between meridian/longitude bases found from linking
// numbers (topology/handle_basis.h), best-matching handle positions first,
// each lifted to an exact surface-group isomorphism and shortened over
// separating twists (with an overlay class: the overlay composed with a
// signed handle permutation of the source, the target's handles being the
// overlay's images of the source's); classes with the same action on homology as an
// earlier one are dropped. When the best coarse energy is more than 10% above
// the conformal bound 8 pi (g - 1), the class search adds lifted classes from
// more cuts and then descends over Dehn twists (topology/mapping_class_search.h,
// SurfaceMapOptions::homotopy.search). Ranking: every candidate is solved to convergence
// on a coarse copy of the source (map/coarse_source.h, 3000 vertices by
// default; the class energy is a property of the surfaces, so this estimates
// it, and is recorded as HomotopyCandidate::coarse_energy); the best by that
// estimate, and up to `homotopy.full_solves` in all of those within 10% of
// it, are solved at full resolution, starting from their coarse solutions
// (sources under 2000 vertices: every class at full resolution). The lowest
// full-resolution energy is the default (ties within 1e-4 relative, from
// symmetric shapes, go to the earlier candidate); its converged solve is the
// optimum (convex energy) and is kept, and that class then runs the rest of the
// pipeline (initial map for the "before" figures, landmarks, location; with
// another start_seed or the relaxation method it is solved again from that
// start). If that pipeline fails for the default class, the next class is
// used (solved ones by energy, then the coarse-ranked ones by estimate) and the failed
// one's description says "[not used: ...]". Classes whose solve fails
// numerically (deck elements too large) or does not converge are listed with infinite energy and
// "[solve failed: ...]".
//
// Genus 0 (map/spherical_map.h): both surfaces are uniformized onto the unit
// sphere and Möbius-centred; all harmonic maps are then conformal, and the
// remaining Möbius freedom is fixed by a rigid rotation aligning the shapes,
// or by the landmarks.
#include <complex>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap {

/// Optimiser of the harmonic energy (genus >= 2; the flat case is one exact
/// linear solve either way).
enum class MapMethod {
  Newton,      ///< Riemannian Newton with line search (docs/method.md §7), the default
  /// the paper's per-vertex relaxation in Möbius-centred charts (docs/method.md §2.8,
  /// map/harmonic_relaxation.h), for comparison; genus 1 keeps the exact solve
  Relaxation,
};

/// Initial ("before") map of genus >= 2 (map/initial_map.h).
enum class InitialMapMethod {
  /// The source cut along its cut graph and flattened onto the convex
  /// polygon of the cut graph's harmonic map into the target
  /// (map/cut_graph_initial_map.h; an embedding by construction); when that
  /// polygon is not strictly convex (or round-off degenerates a face), as
  /// Polygon (the default)
  CutGraph,
  /// The source's cut disk flattened onto the target's geodesic polygon of
  /// the source's loops when that polygon is convex (and the source's faces
  /// come out unflipped, or a few folds are repaired locally), else the
  /// uniform-weight harmonic map
  Polygon,
  /// Always the uniform-weight (Tutte-type) harmonic map in the class
  UniformHarmonic,
};

/// Weights of the harmonic energy on the source (genus >= 1).
enum class SourceWeights {
  /// Intrinsic Delaunay cotangent weights; if the straight images of the
  /// source's own faces then fold, genus >= 2 first repairs them locally
  /// (SolveOptions::local_fold_repair), and otherwise the chosen class is
  /// solved again with OwnEdges (the default).
  Automatic,
  /// Cotangent weights of the source's intrinsic Delaunay triangulation
  /// only (docs/method.md §2.8): reproduce affine maps, embed the intrinsic
  /// triangulation; folds of the user's faces are a SolveError.
  IntrinsicDelaunay,
  /// Positive weights on the source's own edges
  /// (geometry/positive_edge_weights.h): embed the user's faces.
  OwnEdges,
};

/// Genus >= 2 class search in the mapping class group
/// (SurfaceMapOptions::homotopy.search; topology/mapping_class_search.h).
struct HomotopySearchOptions {
  /// Default class only: a greedy search in the mapping class group from the
  /// best candidate on the coarse copy: neighbours are the class composed
  /// with Dehn twists along a_i, b_i, the chain curves and separating curves
  /// (on either surface), screened by the target lengths of the source
  /// loops' images and ranked by converged coarse solves; an improved class
  /// is added as a candidate ("[class search ...]"). Default true.
  bool enabled = true;
  /// At most this many coarse solves (default 24).
  int evaluations = 24;
  /// Not run when the best candidate's coarse energy is within this fraction
  /// (default 0.1) of the conformal lower bound 8 pi (g - 1) that every
  /// degree-1 map's energy exceeds (nothing to gain; it costs 0.3-0.5 s per
  /// coarse solve at genus 2-6).
  double gap = 0.1;
  /// Before the twists, under the same condition: lifted classes from this
  /// many more source cuts (default 12, spread over the vertex list; at most
  /// HomotopyOptions::extra_cut_classes of their new classes solved on the
  /// coarse copy, lowest screen first, and added; the rest are dropped once
  /// one comes within `gap` of the bound).
  /// (Tests can start the search elsewhere: testing/map_hooks.h.)
  int cuts = 12;
  /// Then, under the same condition (issue 14; docs/handle_classes.md
  /// "Geometric candidates"): at most this many classes from short markings
  /// of the two surfaces' hyperbolic metrics (map/geometric_classes.h),
  /// lowest curve lower bound first, solved on the coarse copy and added
  /// (default 4; 0: none), and as many again from short pants
  /// decompositions with Fenchel–Nielsen twists (map/pants_classes.h).
  /// Needs the source's own uniformization
  /// (SurfaceMapResult::class_bound_status).
  int geometric = 4;
  /// Issue 19: the geometric classes only when the best class so far has at
  /// least this many times the conformal bound 8 pi (g - 1) (default 2; they
  /// cost 1-6 s on genus-2 pairs and never won below that; 0: whenever the
  /// search runs).
  double geometric_ratio = 2.0;
  /// The geometric classes' solves accept start edges up to this size
  /// (HyperbolicHarmonicOptions::max_start_edge_size; default 1e60, about
  /// 276 units, where the other classes' solves refuse 1e15, about 70): the
  /// images of the source's loops under a geometric class can be 25-100
  /// units long in the target without any twist (every geometric class of
  /// the fertility -> genus-4 plate pair was refused before: issue 14).
  double geometric_start_edge_size = 1e60;
  /// The other candidates' solves refuse start edges beyond this size
  /// (default 1e15, about 70 units: HyperbolicHarmonicOptions'
  /// max_start_edge_size). Issue 13: when that refused every candidate
  /// (from the origin, an edge starts as long as its deck element: the
  /// genus-9 and 11 plate <-> wheel pairs' combinatorial classes, 85-300
  /// units), the refused ones are solved again accepting start edges up to
  /// geometric_start_edge_size, and so are the pipeline's later solves (the
  /// class search's, the fallbacks'): a refusal is no answer when nothing
  /// else is left. SurfaceMapResult::long_starts says when.
  double start_edge_size = 1e15;
  /// With the geometric classes: as many again (`geometric`) from the two
  /// surfaces' greedy short pants decompositions, pairing their curves by
  /// length with the twists matched (map/greedy_pants.h
  /// greedy_pants_classes; default true; CLI --no-greedy-pants).
  bool greedy_pants = true;
  /// Issue 13 (session 25; docs/robustness.md "Canonical generators"): the geometric
  /// classes read the target's lengths in the short canonical basis of its
  /// layout's own boundary word (CanonicalSchemaOptions::short_generators),
  /// whose generators are short elements (the raw genus-12 wheel: 1.6 ..
  /// 7.5 units), instead of the canonical basis of the target's own class
  /// loops, whose b_i can grow handle by handle (the same wheel: up to 36
  /// units, matrices beyond 1e12, no short marking found); each class is
  /// then written in the class loops' letters (the inverse of their
  /// canonical generators in the layout's letters, checked exactly). Off by
  /// default; CLI --geometric-layout-basis, Python geometric_layout_basis.
  bool geometric_layout_basis = false;
  /// Issue 13 (session 27; docs/history/robustness.md "Session 27 (branch edge27)"): the twist search
  /// also moves by Dehn twists along each surface's short simple closed
  /// curves, the 2g generators of its short marking and the 3g - 3 curves
  /// of its short pants decomposition (map/pants_classes.h
  /// short_curve_twists): the source's on the source side, the target's on
  /// the target side, each way round, screened and solved like the other
  /// moves (a plate's hole tunnels are not among the canonical bases'
  /// curves). Needs the source's own uniformization, as the geometric
  /// classes do (without it the search runs without them, said in
  /// HomotopySearchInfo::curve_twists). Off by default; CLI
  /// --short-curve-twists, Python short_curve_twists=True.
  bool curve_twists = false;
  /// Issue 13: sources without a coarse copy (under coarse_vertices) start
  /// each full-resolution solve of a class from the snapped overlay (every
  /// source vertex at the target vertex nearest to it in 3D, sheets along a
  /// tree of the shortest image edges) instead of the origin when that start
  /// has the lower energy and no longer edge; in the class of the overlay
  /// (a remeshed copy) it starts near the optimum (CAD plate genus 2, 64 ->
  /// 48 rim segments: E 32.7 against the optimum 28.8; 2199 from the
  /// origin). Same optimum either way (the energy is convex in a class).
  /// The candidate's description then ends "[started from the snapped
  /// overlay]". Default true.
  bool snapped_start = true;
  /// The twist search restarts from each geometric class and from the class
  /// carried from the other direction (two-way run) that is within this
  /// factor of the best coarse energy (default 1.5; 0: one start only), and
  /// tries pairs of twists when no single twist improves (default true).
  double restart_ratio = 1.5;
  bool pair_moves = true;
  /// Issue 14 (session 26; docs/handle_classes.md "The search, restarted"), C++ only,
  /// for measuring how wide a search the pipeline's class needs: the twist
  /// search's coarse solves per step (TwistSearchOptions::
  /// evaluations_per_step, default 8, the lowest screens first; raise it
  /// with `evaluations` to solve every neighbour), and its iterated local
  /// search (TwistSearchOptions::kicks: `kicks` random kicks of
  /// `kick_moves` moves from the best class, each move among the
  /// `kick_choices` neighbours of lowest screen, each kick followed by a
  /// descent of at most `kick_evaluations` solves; default 0, none). A
  /// count below its least (0 for kicks, 1 for the others) is an InputError.
  int evaluations_per_step = 8;
  int kicks = 0;
  int kick_moves = 3;
  int kick_evaluations = 24;
  int kick_choices = 16;
  unsigned kick_seed = 1;
  /// Issue 14 (session 28; docs/history/handle_classes.md "Session 28
  /// (prep, branch class28)"): when `kicks` is 0 and the twist search (its
  /// restarts included) ends at or above `high_kick_ratio` (default 2) x
  /// the conformal bound 8 pi (g - 1), `high_kicks` kicks (default 8; 0:
  /// none) are made from the best class it reached, as `kicks` are
  /// (kick_moves, kick_evaluations, kick_choices, kick_seed), with their
  /// own budget of high_kicks x (1 + kick_evaluations) solves (200 by
  /// default; the CAD block <-> polycube g3 pair's lower class, 2.03 -> 1.81
  /// x, came at the fifth kick, about 150 solves). HomotopySearchInfo::
  /// high_kicks_status, kicks and lower_kicks say what was done. A count
  /// below 0 or a ratio that is negative or NaN is an InputError.
  /// CLI --high-kicks N, Python high_kicks=N (0: none).
  int high_kicks = 8;
  double high_kick_ratio = 2.0;
};

/// Which homotopy classes are listed, ranked and searched
/// (SurfaceMapOptions::homotopy; the ranking: the header comment above).
struct HomotopyOptions {
  /// Homotopy class to use: index into SurfaceMapResult::candidates, or -1
  /// (default) for the one of lowest energy. An index names a class within
  /// one run's list only: another run (other options, landmarks, or a class
  /// given) lists other candidates in another order, so to ask a later run
  /// for a class of an earlier one give its class_words instead (issue 14,
  /// docs/handle_classes.md "Classes named by words").
  int class_index = -1;
  /// Genus >= 2: the class to use, named by its words (2g words: source
  /// canonical generator j+1 -> word in the target's canonical letters, as
  /// SurfaceMapResult::chosen_class_words or HomotopyCandidate::words of an
  /// earlier run of the same two meshes with the same LoopOptions, whose
  /// cuts write them; empty, the default: none). A name that does not depend
  /// on the run's list: it is the only candidate, solved like a class_index
  /// (no ranking, class search, geometric classes, two-way run or
  /// through-shape step; with landmarks they are held in it). An InputError
  /// with class_index, on genus 0 or 1, or with malformed words; a
  /// SolveError when the words are no isomorphism of the surface groups.
  /// CLI --class-words, Python class_words=.
  std::vector<std::vector<int>> class_words;
  /// Genus 1 with landmarks: list each class M of the flat torus with both
  /// signs, M and -M (default true; false: up to the sign, the canonical
  /// sign only, as before issue 16). Without landmarks the list is always up
  /// to the sign: the half turn z -> -z gives the same energy. With two or
  /// more landmarks the two signs hold them with different energies, and the
  /// canonical sign alone can force a twisted class (docs/handle_classes.md,
  /// "Genus 1: the two signs"); with one landmark they tie exactly (the half
  /// turn about it; round-off picks the sign). The candidates' indices
  /// (class_index) then count both signs.
  bool flat_both_signs = true;
  /// Genus 1 without landmarks: choose the flat map's translation, and among
  /// classes of tied energy the class and its sign, by the 3D overlay of the
  /// shapes (default true; stages/flat_overlay.h, docs/handle_classes.md
  /// "Genus 1: placement by the overlay"), so that a copy maps onto itself.
  /// false: the source's base vertex onto the target's, the lowest energy's
  /// class and the canonical sign, as before; a placement that does not
  /// depend on how the shapes are posed (surfmap.compare maps every shape
  /// onto one domain so).
  bool flat_overlay = true;
  /// Genus >= 2: how many handle correspondences (signed handle
  /// permutations, topology/handle_basis.h, ranked by how well the handle
  /// positions match) are considered (default 8: all of them for genus 2).
  int candidates = 8;
  /// Genus >= 2: at most how many of the candidates, ranked by their energy
  /// on the coarse copy of the source, are solved at full resolution
  /// (default 2: the best and the runner-up when within 10% of it; <= 0:
  /// all of them).
  int full_solves = 2;
  /// Genus >= 2, default class, coarse copy (issue 19): the first candidate
  /// (the overlay class when the shapes overlap) is solved alone first; when
  /// its coarse energy is within this fraction (default 0.02) of the
  /// conformal bound 8 pi (g - 1), below which no class's energy lies, the
  /// other classes are not solved ("[not ranked: ...]"); otherwise those
  /// whose curve lower bound (map/class_lower_bound.h) is above that energy
  /// are not solved, nor those with an earlier candidate's fingerprint (the
  /// same class up to an isometry of the target, so the same energy; ties go
  /// to the earlier candidate). < 0: every class is solved (also when
  /// full_solves <= 0). SurfaceMapResult::ranking_coarse_solves counts the
  /// solves.
  double ranking_gap = 0.02;
  /// Genus >= 2: vertices of the coarse copy of the source on which every
  /// candidate class is solved to rank them (map/coarse_source.h; default
  /// 3000, at most a quarter of the source's vertices; 0, or a source under
  /// 2000 vertices: every class is solved at full resolution instead).
  int coarse_vertices = 3000;
  /// Genus >= 2: lifted handle classes are also built from this many other
  /// systems of source loops (base vertices spread evenly over the vertex
  /// list), which give other Torelli representatives of the same signed
  /// handle permutations; only classes new by their fingerprint (target
  /// lengths of the generators' images) are added (default 3; 0: none).
  int extra_cuts = 3;
  /// Of the new lifted classes from the extra cuts, at most this many (the
  /// lowest by a screening score from the target lengths of the source
  /// loops' images, no solve) are kept and ranked (default 6).
  int extra_cut_classes = 6;
  /// Genus >= 2, default class only: the search in the mapping class group.
  HomotopySearchOptions search;
  /// Genus >= 2, default class only (issue 14; docs/handle_classes.md): when
  /// the chosen class's energy is at least `two_way_ratio` (default 2) x the
  /// conformal bound 8 pi (g - 1), the pair is also mapped the other way
  /// (target -> source, same options, no landmarks); when that direction's
  /// energy ratio is lower, the source's loops carried by its inverse give
  /// one more candidate, the map is computed again, and the lower-energy
  /// result is returned (SurfaceMapResult::two_way_status says what was
  /// done). About 3x the time for such pairs; nothing for pairs below the
  /// ratio. Default true.
  bool two_way = true;
  double two_way_ratio = 2.0;
  /// With two_way, below two_way_ratio (issue 14; docs/handle_classes.md
  /// "The two directions today"): when the chosen class's energy is at least
  /// `agreement_ratio` (default 1.1) x 8 pi (g - 1), the other direction is
  /// mapped too (one way), and unless its class ψ is this class θ inverted
  /// (or, genus 2, inverted up to the hyperelliptic involution), θ^-1 is
  /// solved there alone and ψ^-1 here alone; the pair of inverse classes of
  /// lower total energy, E(θ) + E'(θ^-1) against E(ψ^-1) + E'(ψ), is kept
  /// (this map becomes the ψ^-1 map when that pair is lower; a tie goes to
  /// the class chosen from the mesh that comes first in a fixed order of
  /// the two meshes, whichever is the source), so that separate runs of the
  /// two directions end on inverse classes. SurfaceMapResult::directions
  /// `agreement` says what was done. About 3x the time for such pairs;
  /// nothing below the ratio. agreement_ratio >= two_way_ratio turns it off.
  double agreement_ratio = 1.1;
  /// With two_way, when the other direction's ratio is not lower (issue 14;
  /// docs/handle_classes.md "The two directions today"): its class inverted
  /// is solved here alone and adopted when lower; else this class inverted
  /// is solved alone the other way, and the pair of inverse classes of
  /// lower total energy is kept, so the two directions' classes are
  /// inverse or SurfaceMapResult::directions says why not. Two single-class
  /// runs; default true (false: the class is kept unchecked, as before).
  bool cheap_direction_check = true;
  /// Genus >= 2, default class, with two_way: map the other way for every
  /// pair, whatever the energy ratio, and carry that direction's class here
  /// as a candidate even when its ratio is not lower, so that
  /// SurfaceMapResult::reverse_inverse always compares the two directions
  /// (a diagnostic: about 3x the time; default false; CLI
  /// --compare-directions).
  bool compare_directions = false;
  /// Genus >= 2, default class, no landmarks (issue 14; docs/handle_classes.md
  /// "Through generated shapes" and the sections after it): when the chosen
  /// class's energy (after the two-way run) is at least `through_shape_ratio`
  /// (default 3, where the quality warning starts) x 8 pi (g - 1), the source
  /// is mapped onto each generated shape M of its genus (the CAD plate
  /// samples::cad_plate, then the n-hole torus samples::n_hole_torus up to
  /// genus 8 with at least `through_shape_resolution` grid cells: 16 per
  /// handle up to genus 4, 64 for the wheels beyond; not M that is the source
  /// or the target itself) and M onto the target (the two-way run as given).
  /// A leg whose ratio is not below the first run's cannot help and ends
  /// that shape's attempt, unless the same leg in this run's class composed
  /// with the other end's own leg (target -> M, or M -> source) and searched
  /// on from there is below it (session 20: fertility -> n-hole torus g4
  /// through the plate). The composed classes (the two legs' classes
  /// composed) are ranked here together (given_class), the twist search
  /// runs on from the best (session 18), and each is listed as one more
  /// candidate ("[through a generated genus-g n-hole torus]"); the
  /// lower-energy result is returned. With the two-way run on, the composed
  /// classes are then inverted and searched on in the other direction too,
  /// and the pair of inverse classes of lower total energy is kept, so that
  /// both directions end on inverse classes (session 19).
  /// SurfaceMapResult::through_shape_status says what was done. Why: a
  /// shape far from both has its classes searched from handle permutations
  /// and twists of its own cut, which can stop in a twisted class, while the
  /// maps onto and from an evenly sized shape of the same genus are found
  /// more reliably. Several one-way runs and a few given-class runs, only
  /// for pairs at or above the ratio. Default true.
  bool through_shape = true;
  double through_shape_ratio = 3.0;
  int through_shape_resolution = 32;
  /// Genus >= 2: classes given as words (2g each: source generator j+1 ->
  /// word in the target's canonical letters, as chosen_class_words, in these
  /// options' cuts; k classes as k 2g words in a row, repeats dropped), ranked
  /// like candidates with no other candidate, geometric classes, two-way run
  /// or through-shape step; the twist search alone runs on from the best (a
  /// SolveError when one is no isomorphism). The through-shape step uses it.
  std::vector<std::vector<int>> given_class;
  /// With given_class: each class's name in its candidate's description, one
  /// per class (the through-shape step: "through a generated <shape>");
  /// empty, the default: "the given class", or "the given class k" for k
  /// classes. Like given_class, no CLI flag or Python keyword.
  std::vector<std::string> given_class_names;
  /// Genus >= 2, set by the two-way run: per source vertex a point on the
  /// target (#V_source x 3; empty, the default: none), where the inverse of
  /// a target -> source map puts it. The source's loops carried to those
  /// points give one more candidate ("[the source's loops carried by the
  /// target -> source map]"), listed after the one-way candidates.
  Eigen::MatrixXd source_images;
  /// Genus >= 2, set by the two-way run (issue 14; docs/handle_classes.md
  /// "Both directions"): the class chosen for target -> source, written in
  /// this run's letters (2g words: target canonical generator j+1 -> word in
  /// the source's canonical letters; empty, the default: none). Its inverse
  /// (topology/outer_automorphisms.h invert_automorphism) is listed as a
  /// candidate ("[the other direction's class, inverted algebraically]") and
  /// SurfaceMapResult::directions compares the chosen class with it.
  std::vector<std::vector<int>> reverse_class;
  /// With source_images: the class of the source's loops carried to them is
  /// the only candidate (no overlays, schemata, handle permutations, extra
  /// cuts, class search, geometric classes or two-way run; a SolveError
  /// when the loops do not carry). For callers that know the class, e.g.
  /// the doubles of open surfaces, whose class must commute with the
  /// reflections (docs/open_surfaces.md "Doubling"). Default false.
  bool images_only = false;
  /// With reverse_class: its inverse (inverted algebraically) is the only
  /// candidate, solved at full resolution, no class search, no geometric
  /// classes, no two-way run (a SolveError when it cannot be inverted). The
  /// two-way run's cheap check uses it (docs/handle_classes.md "The two directions today"): one
  /// solve of the other direction's class in this
  /// direction instead of a whole run. Default false.
  bool reverse_class_only = false;
};

/// The harmonic solve (SurfaceMapOptions::solve).
struct SolveOptions {
  /// Optimiser of the harmonic energy (default Newton).
  MapMethod method = MapMethod::Newton;
  /// Relative gradient tolerance of the harmonic solve (default 1e-10) and
  /// its iteration cap (default 300). For the relaxation an iteration is one
  /// sweep over all vertices, and it needs of the order of #V sweeps per
  /// decade of gradient: raise the cap (e.g. 1e6) or the tolerance. Either
  /// method not reaching the tolerance within the cap is a SolveError.
  double tolerance = 1e-10;
  int max_iterations = 300;
  /// Start of the hyperbolic solve: 0 (default) starts from the initial map
  /// (map/initial_map.h, the uniform-weight Tutte-type map in the class);
  /// another value draws random start points (seeded) in the disk of radius
  /// 0.5. The energy is convex, so the result must not depend on it.
  unsigned start_seed = 0;
  /// Genus >= 1: weights of the energy on the source (default Automatic).
  SourceWeights source_weights = SourceWeights::Automatic;
  /// Genus >= 1, own-edge weights (OwnEdges, or the Automatic fallback):
  /// every weight is at least this times the mean positive cotangent weight
  /// (PositiveEdgeWeightsOptions::floor; default 0.1, must be > 0). Any
  /// positive floor embeds the user's faces; a lower one stays closer to the
  /// cotangents (lower D' where they were negative), see
  /// docs/handle_classes.md "Flat images, folds and the own-edge retry".
  double own_weights_floor = 0.1;
  /// Genus >= 2, SourceWeights::Automatic: when straight images of some of
  /// the source's faces fold under the intrinsic map, first re-solve only
  /// the vertices within a few rings of them with positive own-edge
  /// weights, every other vertex held (SurfaceMapResult::fold_repair;
  /// docs/handle_classes.md "Flat images, folds and the own-edge retry"); the whole map is solved
  /// again with own-edge weights only when that does not unfold them.
  /// Default true; false is the global fallback alone.
  bool local_fold_repair = true;
  /// Within the local repair, the distortion-aware untangling of the folds
  /// the projection leaves (clusters of slivers folded together): the
  /// vertices around them move jointly to minimise a barrier on their
  /// faces' dilatation, the rest held (docs/handle_classes.md "Flat images, folds and the own-edge
  /// retry"). Default true; false: the projection, then the held
  /// re-solves, as before.
  bool fold_untangle = true;
};

/// The initial ("before") map (SurfaceMapOptions::initial).
struct InitialMapOptions {
  /// Genus >= 2: how it is built (default CutGraph, with the polygon and
  /// the uniform-weight map as fallbacks).
  InitialMapMethod method = InitialMapMethod::CutGraph;
  /// Genus >= 1: locate the initial map on the target (initial_forward) and
  /// the target's vertices on the source through it (initial_inverse), for
  /// the "before" morph and UV transfer: only on request (default false;
  /// Python's locate_initial_map=True, the CLI's --locate-initial-map, also
  /// set by --initial-out; the add-on asks for it). Not requested, both stay
  /// empty, the report's initial_map.located is false and
  /// initial_map.location_requested says why; the initial map itself, its
  /// energy, distortion and flipped faces are computed either way, and the
  /// optimum does not depend on it. Issue 19: on the 50k pair this location
  /// is 1.32 G instructions, the longer of the location stage's two threads.
  bool locate = false;
};

/// The systems of loops (topology/system_of_loops.h) on both surfaces
/// (SurfaceMapOptions::loops).
struct LoopOptions {
  /// Base vertices of the systems of loops (default -1: automatic). Genus
  /// >= 2 with the default class (no class_index, no source_images or
  /// reverse_class): the class is chosen with the automatic base vertices
  /// and then solved alone in the cuts at the given ones (the source's loops
  /// at the given base vertex carried by the chosen map, the class's words
  /// in those cuts' letters), so a given base vertex changes how the class
  /// is written, not which class is chosen (unless search_in_given_cuts;
  /// issue 14; docs/
  /// handle_classes.md "The class does not depend on the base vertex";
  /// SurfaceMapResult::class_cuts_status says what was done).
  int source_base_vertex = -1, target_base_vertex = -1;
  /// With a base vertex given: search the class in the cuts at the given
  /// base vertices themselves, not in the automatic ones first (default
  /// false: chosen in the automatic cuts, as above). For a caller that has
  /// already run the automatic cuts and wants another cut's search, e.g. the
  /// last resort of the two-way run after every class folded (docs/
  /// handle_classes.md "Every class folded"): the automatic cuts would only
  /// fail again, one full one-way run for nothing.
  bool search_in_given_cuts = false;
  /// Genus >= 2: both surfaces' canonical generators from the cut-and-paste
  /// moves that conjugate only each new pair (CanonicalSchemaOptions::
  /// short_generators), not the classical ones whose conjugators pile up
  /// handle by handle (default false: on fertility -> CAD plate g4 the
  /// short basis ends at 2.964 x, just under the 3 x of the through-shape
  /// step, where the classical one goes on to 2.129 x; docs/robustness.md
  /// "Canonical generators"; true: CLI --short-canonical-generators; report
  /// `canonical_generators`).
  /// Issue 13: on the raw genus-12 wheel the classical generators are up to
  /// 253 loop letters with matrices of |a| = 4e100 and their canonical
  /// relator multiplies out to 1e1805; the short ones are up to 60 letters
  /// (|a| 8e11), translation lengths near the systole's (docs/robustness.md
  /// "Canonical generators"). With both_canonical_bases the candidate classes are
  /// listed in both bases (src/map/stages/other_basis.h; docs/robustness.md
  /// "Canonical generators"), so the candidate list does not depend on this choice
  /// (the geometric classes still do).
  bool short_canonical_generators = false;
  /// Issue 13 (session 27; docs/history/robustness.md "Session 27 (branch edge27)"): when a genus >= 2
  /// run with the classical generators fails at its start edges (a
  /// SolveError of reason SolveFailure::start_edges: deck elements that the
  /// classical generators' long words put beyond what the solve accepts), it
  /// is run again with the short ones, and the result says so
  /// (SurfaceMapResult::canonical_generators_fallback; the error, when that
  /// fails too, gives both). Its progress is reported as stages "retry with
  /// the short generators (<stage>)". Default true; false: CLI
  /// --no-short-generators-fallback (or --classical-canonical-generators,
  /// which asks for the classical basis), Python
  /// short_generators_fallback=False.
  bool short_generators_fallback = true;
  /// Issue 13 (session 28; docs/robustness.md "Canonical generators"): when a
  /// genus >= 2 run of the default class with the classical generators fails
  /// because every class it mapped folds (a SolveError of reason
  /// SolveFailure::folds or no_bijective_class, after the two-way run's
  /// rescue), it is run once more
  /// with the short canonical generators and one way (HomotopyOptions::
  /// two_way off), the settings that map the CAD block g12 -> raw wheel g12
  /// one-to-one; the result says so (SurfaceMapResult::fold_fallback), and
  /// when the retry fails too the error gives both reasons. Its progress is
  /// reported as stages "retry after folds (<stage>)" and the callback can
  /// cancel it. Default true; false: CLI --no-fold-fallback (or
  /// --classical-canonical-generators), Python fold_fallback=False.
  bool fold_fallback = true;
  /// Genus >= 2: list the candidate classes (overlays, the canonical
  /// schemata's class, signed handle permutations, other cuts' lifts) in
  /// both canonical bases, the classical and the short, each written in the
  /// run's, and twist-search a class listed in the short basis by the short
  /// basis's twists (src/map/stages/other_basis.h; docs/robustness.md
  /// "Canonical generators"). Default true (session 25): fertility -> CAD plate g4
  /// goes from 2.803 x to 2.13 x the bound and polycube g3 -> plate g3 from
  /// 73.19 to 64.86. (Off until session 25: two genus-2 landmark tests
  /// failed with it, from faults of the landmark code that the short
  /// basis's long class words exposed, fixed there: docs/history/handle_classes.md
  /// "Session 24" and "Session 25".) False: CLI --one-canonical-basis.
  bool both_canonical_bases = true;
};

/// When the genus >= 2 map runs in per-face charts of the target
/// (UniformizationOptions::face_charts).
enum class FaceCharts { Automatic, Always, Never };

/// The uniformization of the target (and, for genus 0, of both surfaces)
/// (SurfaceMapOptions::uniformization).
struct UniformizationOptions {
  /// Curvature tolerance of the Ricci flow (default 1e-10).
  double tolerance = 1e-10;
  /// Genus >= 1: which metric the target is uniformized with, and in which
  /// order (docs/uniformization.md "Which target metric runs"; spelled
  /// "auto", "flips", "fixed", "fixed-first" in the CLI's --target-metric,
  /// Python's target_metric= and the report's target_metric_requested):
  ///  * Automatic (default): the flip-based metric (Newton with Ptolemy
  ///    flips on the user's target; it exists on every closed mesh), results
  ///    carried back through the flips (uniformize/intrinsic_correspondence.h);
  ///    the fixed-connectivity one (exactly refined) only when the flip path
  ///    throws UniformizationError.
  ///  * IntrinsicDelaunay: the same order, reported as requested / fallback.
  ///  * FixedConnectivity: the metric on the target's own edges alone,
  ///    refined exactly (altitude-foot splits) when it does not exist.
  ///  * FixedFirst: FixedConnectivity when it can be delivered, the flip path
  ///    only when that throws UniformizationError.
  /// SurfaceMapResult::target_metric / target_metric_choice say which ran
  /// and why; when every allowed metric fails, UniformizationError.
  UniformizationMetric target_metric = UniformizationMetric::Automatic;
  /// Flip path: the lengths the target's loops are shortest in, as for
  /// uniformize (LoopMetric; default Automatic: 3D, and for genus >= 2 the
  /// metric's own when the 3D loops' layout fails its checks or crowds
  /// |z| = 1). Why: a crowded layout misplaces the forward location (issue
  /// 13: the raw genus-11 wheel r32 onto itself put 178 source vertices
  /// up to 34% of the diagonal away, with "1 intrinsic flipped triangle").
  /// SurfaceMapResult::target_loop_metric says which ran.
  LoopMetric loops = LoopMetric::Automatic;
  /// Genus >= 2: whether the map may run in per-face charts of the target
  /// (issue 13; spelled "auto", "always", "never" in the CLI's
  /// --face-charts, Python's face_charts= and the report's
  /// face_charts_requested; docs/robustness.md "High genus"):
  ///  * Automatic (default): only when the target's layout is valid but one
  ///    Poincaré chart in double cannot hold it (CAD plates of genus >= 13),
  ///    where SingleChartError used to end the map. Every other map is
  ///    unchanged.
  ///  * Always: the per-face path on every genus >= 2 pair (a test and
  ///    comparison switch: it is the restricted path described below).
  ///  * Never: SingleChartError as before.
  /// The per-face path is restricted: one class only, the snapped class of
  /// near-identical shapes (each source vertex at its nearest target vertex,
  /// each source edge along the target's edges between them), no class
  /// search, no landmarks, positive weights on the source's own edges.
  /// SurfaceMapResult::face_charts says whether it ran and why.
  FaceCharts face_charts = FaceCharts::Automatic;
};

/// Options of surface_map, nested by concern: `homotopy` (classes listed,
/// ranked, searched), `solve` (the harmonic solve and the source's weights),
/// `loops` (their base vertices), `initial` (the initial map),
/// `uniformization` (its tolerance and the target's metric), then threads,
/// the landmarks and callbacks.
struct SurfaceMapOptions {
  HomotopyOptions homotopy;
  SolveOptions solve;
  LoopOptions loops;
  InitialMapOptions initial;
  UniformizationOptions uniformization;
  /// Threads the pipeline runs at once (genus >= 2: the coarse class solves
  /// of the ranking, and the initial map next to the full-resolution solves;
  /// src/map/concurrency.h). 0 (default): SURFMAP_THREADS when set, else 2
  /// on hardware with two or more cores; 1: every stage in order. Results do
  /// not depend on it, and the callbacks are only called on the calling thread.
  int threads = 0;
  /// Landmark pairs (source vertex, target vertex) whose images are held
  /// fixed: the source vertex maps exactly onto the target vertex (paper
  /// docs/method.md §2.10). Indices must be valid and each vertex used at most once.
  /// Genus >= 1: each source vertex is held at the lift of its target vertex
  /// (in the universal cover) nearest to where the map without landmarks
  /// puts it, so landmarks add no winding (src/map/landmarks.h). When the
  /// plain pins fold the map, the landmarks are moved there by an
  /// interior-point continuation (bijective at every step; the held map of
  /// least energy among bijective ones, up to the barrier; genus >= 2 along
  /// hyperbolic geodesics), and if that stalls each landmark carries rings
  /// of its free neighbourhood rigidly along (see landmark_method,
  /// landmark_steps, landmark_rings);
  /// landmarks that cannot be held so are a SolveError naming them. Both methods hold
  /// landmarks (the relaxation skips the held vertices). Genus 0:
  /// the Möbius map fixed by the landmarks (map/spherical_map.h), exact for
  /// up to 3, least squares beyond (see max_landmark_error).
  std::vector<std::pair<int, int>> landmarks;
  /// With landmarks, genus >= 1: hold them by the plain pins alone (each at
  /// its nearest lift: the exact held optimum of the class, which is the
  /// infimum over all held maps) and return that map even where it folds,
  /// instead of the barrier continuation and carried neighbourhoods and a
  /// SolveError when they cannot keep it bijective. The classes are ranked
  /// by that held energy; the folds are counted (flipped_triangles) and not
  /// repaired (no local fold repair, no own-edge weights fallback);
  /// landmark_method is "pinned (folds allowed)". Default false. For a
  /// caller that wants the homotopy class with the landmarks held, not the
  /// map: the class is defined whether or not its held map folds (the open
  /// surfaces' capped maps, docs/history/open_surfaces.md "Capped maps that fold").
  bool landmarks_may_fold = false;
  /// Called between stages with the stage name and a fraction in [0, 1];
  /// return false to cancel (throws Cancelled). The fractions never
  /// decrease and stay below 1 (at most 0.98) until the map is made: the
  /// last call is ("done", 1). Runs made after the main one (the other
  /// direction, the through-shape step's legs, the rescue's runs) report
  /// ("other runs (starting)", f) as each starts, then their stages as
  /// "other runs (<stage>)": when such runs may follow (genus >= 2, the
  /// default class, two_way or through_shape on), the main run's stages
  /// take the first half of the fractions and each further run half of what
  /// is left below 0.98, so the fraction moves during every run (when none
  /// follows, the main run's last stage reports 0.5 and ("done", 1) comes
  /// next); the automatic retries report theirs as "retry
  /// after folds (<stage>)" and "retry with the short generators (<stage>)"
  /// (LoopOptions::fold_fallback, short_generators_fallback).
  std::function<bool(const std::string& stage, double fraction)> progress;
  /// Called during the harmonic solve (genus >= 2) at every Newton
  /// iteration / relaxation check with (iteration, energy, gradient norm);
  /// return false to cancel (throws Cancelled).
  std::function<bool(int iteration, double energy, double gradient)> solve_progress;
};

/// One candidate homotopy class: for genus 1 an SL(2,Z) matrix taking the
/// source's reduced lattice basis to integer combinations of the target's;
/// for genus >= 2 a handle correspondence (description: "handle 1 -> handle
/// 2, handle 2 -> handle 1 (half turn)", handles numbered along each shape's
/// longest axis; `matrix` unused).
struct HomotopyCandidate {
  std::string description;
  int matrix[4] = {1, 0, 0, 1};
  /// Harmonic energy of the class's optimum at full resolution (`solved`),
  /// or, when `solved` is false (genus >= 2, ranked out on the coarse copy
  /// of the source), the coarse estimate `coarse_energy`; infinite when the
  /// class's solve failed.
  double energy = 0;
  bool solved = true;
  /// Genus >= 2: the class's converged energy on the coarse copy of the
  /// source used for ranking (NaN when the ranking ran at full resolution).
  /// When `solved` is false and this is finite, `energy` is this estimate.
  double coarse_energy = std::numeric_limits<double>::quiet_NaN();
  /// With landmarks: the class's energy with the landmarks held at their
  /// nearest lifts the way the pipeline would return its map (plain pins,
  /// else the barrier continuation, else carried rings), by which the
  /// classes are then ranked (branch and bound on landmark_lower_bound);
  /// +inf when the landmarks cannot be held bijectively in it; NaN when not
  /// computed: no landmarks, genus >= 2 classes not solved at full
  /// resolution, classes whose lower bound was not below the best held
  /// energy (they cannot win), or, with `homotopy` given, the other classes.
  /// `energy` stays the class's free optimum.
  double landmark_energy = std::numeric_limits<double>::quiet_NaN();
  /// With landmarks (genus 1: every class; genus >= 2: those solved at full
  /// resolution): the plain pins' energy, the infimum over held maps (folded
  /// ones included), so a lower bound of landmark_energy; NaN otherwise.
  double landmark_lower_bound = std::numeric_limits<double>::quiet_NaN();
  /// Genus >= 2: the class's action on H_1, 2g x 2g row-major, in the
  /// canonical coordinates (a_1, b_1, ...) of both surfaces; empty for genus 1.
  std::vector<int> homology;
  /// Genus >= 2 (issue 14; docs/handle_classes.md): lower bound of the
  /// class's energy without a solve (map/class_lower_bound.h): max(8 pi
  /// (g - 1), the collar bound over disjoint simple curves of the source);
  /// `class_curve_bound` the latter alone and `class_bound_curves` its
  /// family. NaN / empty when the source's own uniformization was not
  /// available or not needed (SurfaceMapResult::class_bound_status says why).
  double class_lower_bound = std::numeric_limits<double>::quiet_NaN();
  double class_curve_bound = std::numeric_limits<double>::quiet_NaN();
  std::string class_bound_curves;
  /// Genus >= 2: which class of HomotopyOptions::given_class this candidate
  /// is (0-based, in the order given); -1 for the classes the pipeline
  /// found. Read by the through-shape step; not in the report (the
  /// description names the class).
  int given_class = -1;
  /// Genus >= 2: the class as words (2g: source canonical generator j+1 ->
  /// word in the target's canonical letters, as chosen_class_words), the
  /// name by which a later run of the same pair and LoopOptions is asked for
  /// it (HomotopyOptions::class_words); empty for genus 0 and 1.
  std::vector<std::vector<int>> words;
};

/// Genus >= 2: the class search of SurfaceMapOptions::homotopy.search.
struct HomotopySearchInfo {
  bool run = false;
  /// Candidate it started from, its coarse energy and the energy reached.
  int start_candidate = -1;
  double start_energy = std::numeric_limits<double>::quiet_NaN();
  double energy = std::numeric_limits<double>::quiet_NaN();
  /// Moves taken ("source T(a1)^-1", "target [T(c1)] T(s1)", ...) and the
  /// coarse energy after each.
  std::vector<std::string> moves;
  std::vector<double> energies;
  /// Every neighbour solved on the coarse copy: its move (from the class
  /// current at that step, `evaluated_step`), screening score and coarse
  /// energy (infinite when its solve failed).
  std::vector<std::string> evaluated_moves;
  std::vector<int> evaluated_step;
  std::vector<double> evaluated_screen, evaluated_energy;
  /// Coarse solves run, classes screened (TwistSearchResult::screened), why
  /// it stopped, seconds.
  int evaluations = 0, screened = 0;
  std::string stop_reason;
  double time_s = 0;
  /// Stage 1 (HomotopySearchOptions::cuts): lifted classes from the late cuts that
  /// were new and tried on the coarse copy, and its seconds.
  int cut_classes = 0;
  double cuts_time_s = 0;
  /// Of the classes counted in cut_classes and `evaluations`, those not
  /// solved because their curve lower bound (HomotopyCandidate::
  /// class_curve_bound) was above the lowest coarse energy held: they cannot
  /// win (issue 14; docs/handle_classes.md).
  int pruned = 0;
  /// Geometric classes (HomotopySearchOptions::geometric) tried on the
  /// coarse copy, their seconds (markings included), and the lengths of the
  /// two short markings' generators a1 b1 a2 b2 ... ("" when not run).
  int geometric_classes = 0;
  double geometric_time_s = 0;
  /// One line per geometric class tried whose solve failed: its list
  /// (markings / caterpillar pants / greedy pants), curve bound and the
  /// solve's reason (the SolveError's text, "not converged", "pruned").
  std::vector<std::string> geometric_failures;
  std::string source_marking, target_marking;
  /// The 8 shortest closed geodesics' lengths of each surface, ascending
  /// (map/geometric_classes.h short_geodesics).
  std::string source_geodesics, target_geodesics;
  /// The greedy short pants decompositions' curve lengths of each surface
  /// (map/greedy_pants.h; "" when not run), and their seconds with the
  /// greedy pants classes'.
  std::string source_greedy_pants, target_greedy_pants;
  double greedy_pants_time_s = 0;
  /// HomotopySearchOptions::curve_twists: the short curves whose twists the
  /// search moved by, "<n> source curves <lengths>; <m> target curves
  /// <lengths>" (ascending), or why none ("" when the option is off).
  std::string curve_twists;
  /// Every coarse solve of the search (stage 1, geometric classes, every
  /// twist search start), and the starts of the twist search.
  int coarse_solves = 0;
  std::vector<int> starts;
  /// Candidate index of the class found (-1: no improvement, nothing added).
  int found_candidate = -1;
  /// Kicks made by every twist search of this run (HomotopySearchOptions::
  /// kicks and high_kicks; restarts included) and how many of them ended
  /// below the best class held before them.
  int kicks = 0, lower_kicks = 0;
  /// HomotopySearchOptions::high_kicks: "off", "not run: ..." (kicks
  /// given, or the search ended below high_kick_ratio x 8 pi (g - 1)), or
  /// "<n> kicks from candidate <k> at <ratio> x: <m> lower[, reached <E>]"
  /// ("" when the search did not run).
  std::string high_kicks_status;
};

struct PointOnSurface {
  int face = -1;                 ///< face of the other surface's input mesh
  Eigen::Vector3d barycentric;   ///< weights of that face's corners
  Eigen::Vector3d position;      ///< 3D point
};

/// How the initial map was built, and the polygon attempt's figures.
struct InitialMapInfo {
  /// "cut-graph polygon" (genus >= 2, the source cut along its own cut
  /// graph onto the convex polygon of that graph's harmonic map into the
  /// target, map/cut_graph_initial_map.h), "polygon" (genus >= 2, source
  /// disk onto the target's geodesic polygon of the source's loops), "uniform harmonic" (genus >= 2, Tutte-type map
  /// in the class, from the origin; "uniform harmonic (from the polygon)"
  /// when started from a flattening that had flipped faces: the same map),
  /// "uniform Tutte" (genus 1, flat), "" (genus 0: none).
  std::string construction;
  /// Genus >= 2: "used", "not tried", or why the polygon was not used
  /// ("the polygon is not simple ...", "... flipped source faces").
  std::string polygon_status;
  /// Genus >= 2: "used", "not tried", or why the cut-graph polygon was not
  /// used; its branch vertices, sides, chords rerouted, smallest Klein
  /// exterior angle, flipped / degenerate source faces (round-off; 0 when
  /// used) and seconds.
  std::string cut_graph_status;
  int cut_graph_branch_vertices = 0, cut_graph_sides = 0, cut_graph_chords_rerouted = 0;
  double cut_graph_min_turn = 0;
  int cut_graph_flipped = 0, cut_graph_degenerate = 0;
  double cut_graph_time_s = 0;
  /// The polygon's smallest exterior angle in the Klein model (radians;
  /// convex when > 0 with total 2π), its perimeter Σ d(Q_s, Q_s+1), chords
  /// split before the flattening; 0 when not computed.
  bool polygon_convex = false;
  double polygon_min_turn = 0, polygon_perimeter = 0;
  int polygon_chords_split = 0;
  /// Source faces (crossed by the loops) whose images the flattening
  /// flipped; 0 when not computed. A few (at most max(8, #F/2000)) are
  /// repaired by re-solving `polygon_repaired_vertices` vertices around them
  /// with uniform weights (the rest of the flattening held); when that does
  /// not clear them, or there are more, the fallback is used.
  int polygon_flipped = 0, polygon_repaired_vertices = 0;
  /// Newton iterations of the uniform-weight solve (0 for the polygon).
  int iterations = 0;
  /// Seconds: the whole initial map, and of it the polygon attempt.
  double time_s = 0, polygon_time_s = 0;
  /// Whether the initial map was to be located on the target
  /// (InitialMapOptions::locate; the report's initial_map.location_requested).
  /// The report's initial_map.located is whether initial_forward was
  /// delivered: false when not requested, or when a vertex could not be
  /// located. False for genus 0 and the per-face-chart map (no location of
  /// their initial map).
  bool location_requested = false;
};

/// One row of the stage table (issue 19; docs/cli.md, `surfmap map
/// --timings`): what one stage of the pipeline cost. The counts are those of
/// the process-wide counters (surfmap/work_counters.h) over the stage's wall
/// time, so work of the pipeline's second thread counts towards the stage
/// during which it ran.
struct StageRecord {
  std::string name;
  double seconds = 0;
  /// Sparse Cholesky symbolic analyses and numeric factorisations (CHOLMOD).
  long long analyses = 0, factorisations = 0;
  /// Newton iterations (the harmonic solve's and the uniformization's).
  long long newton_iterations = 0;
  /// Peak resident memory of the process during the stage, in bytes (Linux
  /// VmHWM; when its high-water mark cannot be reset, the peak so far:
  /// SurfaceMapResult::peak_memory_per_stage is then false); 0 where unknown.
  long long peak_memory_bytes = 0;
};

/// How well the map's layout closes around its triangles (issue 13). Around
/// every triangle the elements of its three edges compose to the identity
/// for the true problem (the target's deck elements form a cocycle on the
/// faces); what is left is the round-off of the target's side pairings and
/// of the solve's charts, or an element in a wrong class. Measured on the
/// triangles the energy lives on: the source's intrinsic Delaunay triangles
/// (genus 1 and >= 2 in one chart), the source's own faces (per-face
/// charts). The gap of a triangle: genus >= 2 the distance of the product of
/// its edges' elements in the solve's charts (edge_local, oriented along the
/// triangle) from ±identity as a matrix of determinant 1
/// (hyperbolic::distance_from_identity, ~ the distance a point near the
/// vertex moves); genus 1 |Σ ±t_e| of its edges' lattice translations over
/// the shorter period |ω|.
struct LayoutClosure {
  double tolerance = 1e-8;  ///< a triangle is open when its gap exceeds this
  int triangles = 0;        ///< triangles measured; 0 = not computed (genus 0, disks, annuli)
  int open_triangles = 0;   ///< gap > tolerance
  double worst_gap = 0;     ///< the largest gap
  int worst_triangle = -1;  ///< the triangle with it (-1 when none was measured)
};

/// Genus >= 2: how the returned map's image triangles cover the target, in
/// its hyperbolic metric, from the solver's local charts (issue 13, session
/// 26). Each image triangle's angles are read at its corners (signed, in
/// the chart centring each corner), its signed area pi minus their sum
/// (minus pi minus their sum for a flipped one, whose angles are negative); a map
/// whose every vertex star turns once (angle sum 2 pi) and whose triangles
/// are all positive covers the target once, with area 4 pi (g - 1). Exact
/// where the 3D check (`surfmap verify`) cannot resolve the images: a
/// twisted class can map an ordinary source face to a triangle tens of units
/// long, whose straight chord triangle in 3D says nothing.
struct ImageCover {
  int triangles = 0;              ///< source faces measured; 0 = not computed
  double area_ratio = 0;          ///< sum of the signed image areas / 4 pi (g - 1) (1: degree one)
  int vertices_off = 0;           ///< source vertices whose angle sum is off 2 pi by more than 1e-6
  double worst_angle_gap = 0;     ///< the largest |angle sum - 2 pi| (radians)
};

struct SurfaceMapResult {
  int genus = 0;
  bool converged = false;
  /// Harmonic energy (cotangent weights) of the initial map and of the
  /// optimum. The initial map (`initial_map` says which): genus 1 the
  /// uniform Tutte embedding of the flat torus; genus >= 2 the source cut
  /// along its cut graph onto the convex polygon of that graph's harmonic
  /// map into the target (map/cut_graph_initial_map.h), else the source's
  /// cut disk flattened onto the target's geodesic polygon of the source's
  /// loops when it is convex, else the uniform-weight Tutte-type map in the class
  /// (map/initial_map.h: how both differ from docs/method.md §2.7
  /// composition); it is also the default start.
  double initial_energy = 0, final_energy = 0;
  std::vector<double> energy_history;
  int iterations = 0;
  /// Per source vertex: its image on the target; per target vertex: its
  /// preimage on the source (the inverse map).
  std::vector<PointOnSurface> forward, inverse;
  /// Dilatation D' of the optimised map (per source face, mean, max) and of
  /// the initial map; flipped / degenerate image triangles of each.
  std::vector<double> dilatation;
  double mean_dilatation = 0, max_dilatation = 0;
  double initial_mean_dilatation = 0, initial_max_dilatation = 0;
  std::vector<double> initial_dilatation;  ///< #F_source D' of the initial map (empty when not computed)
  /// Source faces left out of mean_dilatation / max_dilatation (and of the
  /// report's unweighted mean): thinner than the solvers resolve
  /// (map/distortion.h thin_source_faces: the faces intrinsic mollification
  /// reshapes, zero-area ones included). Their D' stays in `dilatation`; the
  /// largest finite one is thin_source_max_dilatation.
  std::vector<int> thin_source_faces;
  double thin_source_max_dilatation = 0;
  int flipped_triangles = 0, degenerate_triangles = 0;
  /// Genus >= 1 (closed): image triangles flat but positively oriented
  /// beyond round-off (map/distortion.h DistortionStats::flat): one-to-one,
  /// only extremely stretched (D' ~1e9 or more, +inf in `dilatation`, out of
  /// mean and max), so not among degenerate_triangles, which counts only the
  /// images degenerate within round-off. 0 for genus 0, disks and annuli
  /// (other open surfaces: their doubles' count, like degenerate_triangles).
  int flat_triangles = 0;
  /// Genus >= 1: flipped images among the triangles of the source's
  /// intrinsic Delaunay triangulation, on which the energy (and so the
  /// discrete harmonic map, an embedding for positive weights) is defined;
  /// -1 when not computed. flipped_triangles counts the source's own faces
  /// with straight (geodesic) images between the mapped vertices: on
  /// meshes with slivers that can be non-zero while this is 0, and the map
  /// then still fails (MORPH.obj uses the source's faces).
  int intrinsic_flipped_triangles = -1;
  /// How well the triangles of the layout close (genus >= 1 closed; see
  /// LayoutClosure): the gap of every triangle against a tolerance of 1e-8.
  LayoutClosure layout_closure;
  ImageCover image_cover;  ///< genus >= 2, the returned map (ImageCover)
  /// Largest distance between a landmark's located forward image and its
  /// target vertex: the least-squares residual for genus 0 with more than 3
  /// landmarks, otherwise the round-off of locating a held landmark (those
  /// are then set exactly onto their vertex in `forward` and `inverse`).
  double max_landmark_error = 0;
  /// Genus >= 1 with landmarks: per landmark, the rings of source
  /// neighbours carried rigidly with it so the held map stays bijective (0:
  /// the plain pin, the exact held optimum; src/map/landmarks.h), the held
  /// solves that took, and the source vertices held in the accepted one.
  std::vector<int> landmark_rings;
  /// How the landmarks were held: "pinned" (the exact held optimum),
  /// "barrier continuation" (genus >= 1, when the pins fold: the bijective
  /// held map of least energy up to the barrier, src/map/landmarks.h) or
  /// "carried neighbourhoods"; empty without landmarks.
  std::string landmark_method;
  int landmark_solves = 0;
  /// Steps the barrier continuation took (0 when it was not needed; also
  /// counted in landmark_solves, and kept when it stalled and the
  /// neighbourhoods were carried instead).
  int landmark_steps = 0;
  int landmark_held_vertices = 0;
  /// Genus 0: vertices whose sphere image was re-placed to untangle input
  /// faces flipped by the uniformization (map/spherical_map.h); 0 otherwise.
  /// On the source side only when its common subdivision could not be built
  /// (source_subdivision.status).
  int repaired_vertices = 0;
  /// Genus 0: the source faces whose chord triangle is inverted on the
  /// sphere, delivered piecewise (docs/uniformization.md "Genus 0", "The
  /// map on the common subdivision"). The conformal map sends such a face
  /// to a curved union of pieces of intrinsic triangles, which no triangle
  /// between its vertices' images can be; those faces, grown to a region
  /// whose boundary edges are intrinsic edges too, are replaced by their
  /// pieces of the common subdivision, fanned into triangles. Every source
  /// vertex keeps its harmonic image (forward); the new vertices are the
  /// crossings of the region's input edges with intrinsic edges.
  struct SourceSubdivision {
    /// "" (nothing inverted: the map is linear over the source's faces),
    /// "common subdivision", or "not built: <why>" (then the old local
    /// untangling moved vertices: repaired_vertices).
    std::string status;
    /// The map's triangles over the source: vertex ids < #V_source are the
    /// source's vertices, #V_source + k is source_points[k]. Empty unless
    /// status is "common subdivision".
    RowMatrixX3i faces;
    std::vector<int> face_origin;               ///< per row of faces: its source face
    std::vector<PointOnSurface> source_points;  ///< the new vertices on the source (on its edges)
    std::vector<PointOnSurface> forward;        ///< their images on the target
    int subdivided_faces = 0;                   ///< source faces replaced by pieces
    int inverted_faces = 0;                     ///< of them, faces whose chord triangle was inverted
    /// Of source_points, bends of a source edge inside an intrinsic face (the
    /// rest cross an intrinsic edge; uniformize/spherical_subdivision.h).
    int bends = 0;
    /// Σ of the spherical areas of the map's triangles on the sphere / 4π:
    /// 1 (with every triangle positive) certifies that they tile the sphere
    /// once, i.e. the map is bijective.
    double sphere_cover = 0;
  } source_subdivision;
  int initial_flipped_triangles = 0;
  InitialMapInfo initial_map;
  /// Per source vertex: the initial map's image on the target (face,
  /// barycentrics, 3D point), located like `forward`; empty for genus 0.
  std::vector<PointOnSurface> initial_forward;
  /// Per target vertex: its preimage on the source under the initial map
  /// (located in the initial map's image triangles like `inverse`; where
  /// the initial map folds, one of the covering triangles), for the "before"
  /// UV transfer; empty for genus 0 or when it could not be located.
  std::vector<PointOnSurface> initial_inverse;
  /// Genus >= 1: vertices added to the target by the exact refinement that
  /// made its uniformization metric exist (uniformize/feasible_metric.h; 0
  /// when the fixed-connectivity metric existed). Outputs stay on the
  /// user's target either way.
  int target_refinement_splits = 0;
  /// Genus >= 1: the target's metric ("intrinsic Delaunay", "fixed
  /// connectivity", or "fixed connectivity (intrinsic Delaunay failed: ...)"
  /// after the automatic fallback, "intrinsic Delaunay (fixed connectivity
  /// failed: ...)" after FixedFirst's) and its flow's edge flips (0 when fixed).
  std::string target_metric;
  int target_flips = 0;
  /// Genus >= 1: why that metric ran: "requested", "automatic: ..." (with
  /// the fixed-connectivity flow's failure when flips ran), "fallback: the
  /// flip path failed" (flips requested) or "fixed first: ..." (FixedFirst).
  /// The report also has the option itself as target_metric_requested.
  std::string target_metric_choice;
  /// Genus >= 1 on the flip path: the target's loops laid out
  /// (UniformizeResult::loop_metric: "embedding", "metric", or "metric
  /// (embedding loops: <why not>)"); empty on the fixed path.
  std::string target_loop_metric;
  /// Genus >= 2 on the flip path: which loops the handle classes read ("the
  /// target's own loops, carried through N of the flips", or the loops of T'
  /// and why; docs/uniformization.md). Empty otherwise.
  std::string target_class_loops;
  /// Genus >= 2: "classical" or "short" (LoopOptions::
  /// short_canonical_generators), with the target's canonical generators'
  /// lengths as the classes read them: "short: target generators 1 .. 60
  /// layout letters". Empty otherwise.
  std::string canonical_generators;
  /// LoopOptions::short_generators_fallback: empty, or why this map was made
  /// with the short canonical generators though the classical ones were
  /// asked for (the classical run's error, shortened).
  std::string canonical_generators_fallback;
  /// LoopOptions::fold_fallback: empty, or why this map was made by the
  /// retry after folds (the short canonical generators, one way): the first
  /// run's error, shortened.
  std::string fold_fallback;
  /// Genus >= 2: empty when the map ran in the target layout's one
  /// Poincaré chart; otherwise "per-face charts (...)" with why (the single
  /// chart's limit, or requested) and the path's restrictions
  /// (UniformizationOptions::face_charts).
  std::string face_charts;
  /// Genus >= 1: the weights the returned map was solved with:
  /// "intrinsic Delaunay cotangent" (after a local fold repair followed by
  /// "; N vertices around the folds moved (method)") or "positive on the
  /// source's own edges" (SourceWeights; after the automatic fallback the candidates' energies
  /// and the ranking are those of the intrinsic weights). Empty for genus 0.
  std::string source_weights;
  /// Genus >= 2, after the automatic fallback to own-edge weights or a local
  /// fold repair: why (the intrinsic map's counts of folded and flattened
  /// source faces, and what repaired them). Empty otherwise.
  std::string source_weights_reason;
  /// Genus >= 2, the local fold repair (SolveOptions::local_fold_repair):
  /// `status` "" (not run: nothing folded, or not asked), "repaired", or
  /// "not repaired: ..." (then the global own-edge fallback ran); `method`
  /// "projection" (folded faces' corners moved into their neighbours'
  /// kernel), "untangling of R rings" (the vertices within `rings` rings of
  /// the folds left moved jointly by the distortion barrier,
  /// SolveOptions::fold_untangle) or "held re-solve" (the vertices within
  /// `rings` rings solved again with own-edge weights). The intrinsic map's
  /// folded and flat source faces, the region sizes tried (untangling and
  /// held re-solves), and for a repair the vertices
  /// moved or re-solved and the faces with such a corner (the only faces
  /// whose image changed); the energy with the intrinsic weights before
  /// (the class's optimum) and after the repair.
  struct FoldRepair {
    std::string status, method;
    int folded_faces = 0, tries = 0, rings = 0, free_vertices = 0, changed_faces = 0;
    double energy_before = std::numeric_limits<double>::quiet_NaN();
    double energy_after = std::numeric_limits<double>::quiet_NaN();
  } fold_repair;
  /// Genus >= 2, issue 13 (session 25): fallback classes (tried after the
  /// chosen one failed) refused on their kept full-resolution solve's
  /// folded or flattened faces once no repair was left to try (the own-edge
  /// weights in use, or other weights than Automatic requested), without
  /// building their initial map: the refusal mapping them would give, read
  /// the same way; each such class's description ends "[not used: the
  /// optimised map has ... (read on its full-resolution solve before its
  /// initial map: not mapped again)]". Report
  /// `homotopy.fallbacks.refused_unmapped`.
  int fallbacks_refused_unmapped = 0;
  std::vector<HomotopyCandidate> candidates;
  int chosen_candidate = -1;
  /// Genus >= 2 (issue 19; HomotopyOptions::ranking_gap): coarse solves the
  /// ranking ran (the class search's are in homotopy_search.coarse_solves),
  /// the classes it did not solve, and why ("" when the ranking solved every
  /// class by rule; else "stopped: ...", "pruned by the curve lower bounds:
  /// ...", or why nothing was pruned; then how many were not solved as an
  /// earlier candidate's class up to an isometry of the target).
  int ranking_coarse_solves = 0;
  int ranking_skipped = 0;
  std::string ranking_status;
  /// Issue 13, sources without a coarse copy (HomotopySearchOptions::
  /// snapped_start): the candidate that is the snapped overlay's own class
  /// (each source vertex at its nearest target vertex, the source's loops
  /// followed through it in the target's deck group; -1: none), and what
  /// became of it ("listed as class k", "the same as class k", "not listed:
  /// why"), with the source faces around which the snapped edges' elements
  /// do not close up and the longest image path of a source edge (target
  /// edges). `snapped_inconsistent_faces`: that count (-1: not read). Each
  /// edge's element is exact (the target's cut edges crossed by its image
  /// path), so a face that does not close is one whose three image paths
  /// bound no disk of the target.
  int snapped_class = -1;
  std::string snapped_class_status;
  int snapped_inconsistent_faces = -1;
  /// Issue 13 (HomotopySearchOptions::start_edge_size): "" unless every
  /// candidate's solve was refused at the start-edge limit; then how many
  /// were solved again accepting long start edges, and the longest.
  std::string long_starts;
  HomotopySearchInfo homotopy_search;
  /// Target lattice (flat case) and the source's image in the plane.
  std::complex<double> target_omega1, target_omega2;
  /// Genus 1 without landmarks: how the flat map's translation (unique only
  /// up to the torus's translations) and, among classes of equal energy
  /// (M and -M, symmetric lattices), the class were chosen: by the 3D
  /// overlay of the shapes (stages/flat_overlay.h: its pose and mean
  /// residual) or, when the shapes do not overlap, the source's base vertex
  /// onto the target's (docs/handle_classes.md "Genus 1: placement by the
  /// overlay"). Empty otherwise.
  std::string flat_placement;
  std::vector<std::complex<double>> source_image;  ///< #V_source z_i
  // --- quality signal and two-way run (issue 14; docs/handle_classes.md) ---
  /// Genus >= 2: the chosen class's free energy over the conformal bound
  /// 8 pi (g - 1) (1 for a conformal map; NaN for genus < 2), and, when it
  /// is 3 or more, a plain warning that the handle class may be twisted.
  double energy_ratio = std::numeric_limits<double>::quiet_NaN();
  std::string quality_warning;
  /// Genus >= 2, when the source weights fell back to positive weights on
  /// the source's own edges (SourceWeights::Automatic): the chosen class's
  /// free energy with the intrinsic Delaunay cotangent weights (the energy
  /// the classes were ranked by; NaN when the class was not solved with
  /// them), and the ratio of its energy with the own-edge weights. The
  /// own-edge weights are a fallback for embedding the user's faces, not a
  /// discretisation of the Dirichlet energy the bound 8 pi (g - 1) refers
  /// to (on slivers they are far above the cotangent weights), so
  /// energy_ratio uses the intrinsic energy when there is one
  /// (docs/handle_classes.md "Quality signal").
  double intrinsic_class_energy = std::numeric_limits<double>::quiet_NaN();
  double energy_ratio_own_edges = std::numeric_limits<double>::quiet_NaN();
  /// Genus >= 2: candidate indices of the classes from the other direction
  /// (the source's loops carried by a target -> source map), why such a
  /// class is missing (empty when none was asked for), and the symmetry
  /// check: whether the chosen class is one of them.
  std::vector<int> reverse_candidates;
  std::string reverse_status, reverse_check;
  /// Genus >= 2, after a two-way run: whether the chosen class S -> T is
  /// the inverse of the class chosen for T -> S (1), is not (0), or was not
  /// compared (-1), and why (same homology action and same lengths of the
  /// probe curves' images, or which of them differs; or why no comparison).
  int reverse_inverse = -1;
  std::string reverse_inverse_reason;
  /// Genus >= 2: the chosen class as words (2g: source canonical generator
  /// j+1 -> word in the target's canonical letters), and the source's
  /// canonical generators as words in the canonical letters a map with the
  /// source as its target reads (the same surface's other system of loops:
  /// HomotopyOptions::loops swapped; identity overlay), with that map's
  /// inverse (up to inner automorphisms); empty when not available
  /// (source_as_target_status says why). The two-way run composes them
  /// (docs/handle_classes.md "Both directions").
  std::vector<std::vector<int>> chosen_class_words, source_as_target, source_as_target_inverse;
  std::string source_as_target_status;
  /// Genus >= 2, when the two directions were compared algebraically (issue
  /// 14; HomotopyOptions::reverse_class): `outcome` "inverse" (the composite
  /// of the two classes is inner: exact, Dehn's algorithm), "symmetric: both
  /// optimal" (they differ by a mapping class that preserves the lengths of
  /// every probe curve within `length_tolerance`: an isometry of one
  /// surface), "different" (the lower-energy class is kept), or "" when not
  /// compared (`reason` says why). Energies: the chosen class's and the other
  /// direction's class inverted (HomotopyCandidate::energy of
  /// `inverted_candidate`; NaN when not solved). Largest relative change of
  /// a probe curve's length under the difference, measured on the source and
  /// on the target (NaN when not evaluable).
  struct DirectionCheck {
    std::string outcome, reason;
    int inverted_candidate = -1;
    double energy = std::numeric_limits<double>::quiet_NaN();
    double inverted_energy = std::numeric_limits<double>::quiet_NaN();
    double source_length_change = std::numeric_limits<double>::quiet_NaN();
    double target_length_change = std::numeric_limits<double>::quiet_NaN();
    double length_tolerance = 0.02;
    /// The difference mapping class (source canonical letter -> word) as text.
    std::string difference;
    /// Below HomotopyOptions::two_way_ratio, at agreement_ratio or more: what
    /// the agreement of the two directions did ("" when it did not run):
    /// which pair of inverse classes was kept, by which rule (lower total,
    /// a tie broken by the meshes' order, the other direction's class kept
    /// by its own run), or why it could not decide. `own_pair_ratio` and
    /// `other_pair_ratio`: the two pairs' totals, E(θ) + E'(θ^-1) and
    /// E(ψ^-1) + E'(ψ), over 8 pi (g - 1) (θ this run's first class, ψ the
    /// other direction's; NaN when the step solved nothing, infinite when a
    /// class of that pair could not be solved).
    std::string agreement;
    double own_pair_ratio = std::numeric_limits<double>::quiet_NaN();
    double other_pair_ratio = std::numeric_limits<double>::quiet_NaN();
    /// The other direction's energy ratio mapped one way in this run (the
    /// two-way run, the agreement below it, the rescue when every class
    /// folded; NaN when it was not mapped), and, when the two directions
    /// agree ("inverse", "symmetric: both optimal"), the ratio of this
    /// class's inverse in the other direction as this run solved or read it
    /// (NaN when unknown). The through-shape step reads both, so that the
    /// direction below through_shape_ratio runs it when the other direction
    /// does (docs/handle_classes.md "Through generated shapes").
    double other_one_way_ratio = std::numeric_limits<double>::quiet_NaN();
    double inverse_there_ratio = std::numeric_limits<double>::quiet_NaN();
  } directions;
  /// Genus >= 2 (HomotopyOptions::two_way): what the two-way run did ("not
  /// run: ..."; the other direction's energy ratio; whether the carried
  /// class was used) and its seconds.
  std::string two_way_status;
  double two_way_time_s = 0;
  /// Genus >= 2 (HomotopyOptions::through_shape): what the through-shape
  /// step did ("not run: ..."; the two runs' ratios through the generated
  /// shape; the composed class's ratio here and whether it was used) and
  /// its seconds.
  std::string through_shape_status;
  double through_shape_time_s = 0;
  /// Genus >= 2 with a given base vertex (LoopOptions): how the class was
  /// chosen in the automatic cuts and carried to the given ones ("" when no
  /// base vertex was given or LoopOptions::search_in_given_cuts), and the seconds of the run in the automatic
  /// cuts (included in total_time).
  std::string class_cuts_status;
  double class_cuts_time_s = 0;
  /// Genus >= 2: why the class lower bounds are missing (empty when computed;
  /// "not computed: ..." when no decision needed them) and the seconds the source's uniformization took.
  std::string class_bound_status;
  double class_bound_time_s = 0;
  /// Genus >= 2 (issue 19): vertices of the surface the reported bounds were
  /// computed on: the source's own count, or that of its coarse copy (the
  /// ranking's, map/coarse_source.h) when no decision needed the source's
  /// own uniformization (docs/history/handle_classes.md "Bounds on the coarse copy"); 0 when not computed.
  int class_bound_vertices = 0;
  /// Seconds per stage, in order, and in total.
  std::vector<std::pair<std::string, double>> stage_times;
  double total_time = 0;
  /// The stage table (the stages of stage_times, in order, with their
  /// factorisations, Newton iterations and peak memory) and its total row
  /// (the whole map: total_time, every count, the peak over the run).
  std::vector<StageRecord> stages;
  StageRecord stage_total;
  /// Whether each stage's peak memory is its own (the kernel's high-water
  /// mark was reset at every stage boundary) rather than the peak so far.
  bool peak_memory_per_stage = false;
};

/// Maps `source` onto `target` (both closed, manifold, outward oriented, of
/// the same genus: run intake first). Throws InputError (unequal genus,
/// unsupported genus), SolveError (uniformization failed, flipped triangles
/// in the optimum: never returned as a success), Cancelled.
SurfaceMapResult surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options = {});

}  // namespace surfmap
