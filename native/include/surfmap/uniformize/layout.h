#pragma once
// Isometric layout of the disk obtained by cutting a closed surface along its
// system of loops, and the deck transformations that glue it back
// (docs/method.md §2.5).
//
// Input: a flat (genus 1) or hyperbolic (genus >= 2) metric given by edge
// lengths (the output of ricci_flow) and the system of loops of the same mesh.
// Faces are laid out one by one in breadth-first order along the cut tree T*
// (SystemOfLoops::dual_tree_parent_halfedge) starting from the face at the
// centre of that tree (fewest steps to every face, so round-off accumulates
// least). Every face has a chart: an isometry M_f taking its canonical
// triangle (vertex F(f,0) at 0, F(f,1) on the positive real axis) to its place
// in the plane / Poincaré disk; a child's chart is its parent's chart composed
// with a well-conditioned transition between the two canonical triangles, so
// hyperbolic positions are never computed from points near |z| = 1.
//
// Conventions (orientation matters for the group relations):
//  * Deck map of a cut edge e, with h = conn.edge_halfedge(e): the isometry
//    taking the copy of e bordering face(h) onto the copy bordering
//    face(twin(h)); it maps the copy of face(twin(h)) that would sit next to
//    face(h) onto the laid-out copy of face(twin(h)).
//  * Side pairing D_k of loop k: the deck map of the loop's edges oriented
//    along the loop: takes the copy of loop k with the disk on its LEFT (the
//    boundary side read as letter +k when the boundary is read
//    counter-clockwise) onto the copy with the disk on its right (letter −k).
//  * Boundary word: the disk boundary read counter-clockwise from the base
//    corner c_0; side i runs from corner c_i to c_{i+1}; letter +(k+1) when
//    it is loop k in its own direction, −(k+1) reversed.
//  * Loop generators g_k (the deck group element of loop k seen from the base
//    corner c_0): lifting loop k from c_0 ends at g_k(c_0); they satisfy the
//    word relation g_{w_0} g_{w_1} ... g_{w_{4g−1}} = id (inverse for negative
//    letters; canonical word a1 b1 a1⁻¹ b1⁻¹ ... gives Π [a_i, b_i] = id).
//    Corner c_i = G_i(c_0) with G_i = g_{w_0}...g_{w_{i−1}}.
#include <array>
#include <complex>
#include <vector>

#include <Eigen/Core>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

using Complex = std::complex<double>;
using RowMatrixX3c = Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct LayoutOptions {
  /// Face to lay out first; -1 (default): the centre of the cut tree.
  int root_face = -1;
  /// Move the result so that its centre sits at 0 (default true): hyperbolic,
  /// the Karcher mean (point minimising the sum of squared distances) of the
  /// corner positions is moved to 0 by a Möbius map, so that points do not
  /// crowd |z| = 1; flat, the area centroid is translated to 0.
  bool recentre = true;
  /// Hyperbolic, with `recentre`: then move the domain's 1-centre (the point
  /// nearest to its farthest corner, approximately) to 0 instead (default
  /// false). A long domain's Karcher mean sits towards where its faces
  /// crowd, not in its middle: the genus-13 CAD plate's reaches 36.8 from
  /// it and 28 from the 1-centre, which double coordinates still resolve.
  /// lay_out_loops asks for it when the Karcher-centred layout is held by
  /// per-face charts only.
  bool minimax_centre = false;
  /// Threads the layout may run on (default 1). With 2 or more, the checks
  /// in per-face charts (DiskLayout::max_vertex_holonomy, num_flipped_local),
  /// which read no chart, run on a second thread next to the charts and their
  /// re-centring; the layout is the same with any number.
  int threads = 1;
};

struct DiskLayout {
  Background background = Background::Euclidean;
  int genus = 0;
  int root_face = -1;
  /// #F x 3 positions of the face corners (corner k of face f is vertex
  /// F(f,k)); plane or Poincaré disk coordinates.
  RowMatrixX3c corners;
  /// The cut disk as its own mesh: #F x 3 indices into disk_positions, and
  /// per disk vertex the mesh vertex it is a copy of. Vertices off the loops
  /// have one copy, loop vertices two, the base vertex 4g.
  RowMatrixX3i disk_faces;
  std::vector<Complex> disk_positions;
  std::vector<int> disk_vertex_origin;
  /// #V: a position per mesh vertex (its first copy in breadth-first order)
  /// and its number of copies in the disk.
  std::vector<Complex> vertex_positions;
  std::vector<int> vertex_copies;
  /// Per-face charts (hyperbolic: SU(1,1) maps; flat: stored as rotation
  /// r = a/ā and translation b/ā of z ↦ r z + t, i.e. Mobius{a,b} is not used;
  /// see face_rotation / face_translation).
  std::vector<hyperbolic::Mobius> face_charts;     ///< hyperbolic only (#F)
  std::vector<Complex> face_rotation, face_translation;  ///< flat only (#F)
  /// Per edge: true when cut (on a loop). Deck maps of cut edges (identity
  /// for the others), convention in the file comment.
  std::vector<bool> cut_edge;
  std::vector<hyperbolic::Mobius> edge_deck_mobius;  ///< hyperbolic, #E
  std::vector<Complex> edge_deck_translation;        ///< flat, #E
  /// Boundary of the disk counter-clockwise from the base corner: halfedges
  /// with the disk on their left, the corner indices where sides start, and
  /// the word (letters ±(k+1)).
  std::vector<int> boundary_halfedges;
  std::vector<int> side_start;  ///< 4g indices into boundary_halfedges
  std::vector<int> word;
  /// 2g side pairings D_k and 2g loop generators g_k (file comment).
  std::vector<hyperbolic::Mobius> side_pairings, generators;  ///< hyperbolic
  std::vector<Complex> side_translations, generator_translations;  ///< flat
  /// The same group presented by the side pairings (Poincaré's polygon
  /// theorem), in "side letters": +(k+1) is D_k, −(k+1) its inverse, and a
  /// word x_1 x_2 ... stands for the product D_{x_1} ∘ D_{x_2} ∘ ... .
  /// `side_relator`: the vertex-cycle relation (cyclic, length 4g, every
  /// letter once with each sign, so Dehn's algorithm applies to it as to
  /// `word`). `generator_side_words[k]`: g_k as a reduced side word.
  /// Why: g_k is a loop seen from the base corner c_0, which can sit far from
  /// the centre, so its matrix can have entries of 1e5 and products of such
  /// matrices lose every digit; D_k moves the tile across one side of the
  /// polygon onto the polygon, and the elements that matter (the tiles around
  /// the polygon) are short side words whose partial products stay small.
  /// See uniformize/deck_group.h.
  Word side_relator;
  std::vector<Word> generator_side_words;
  /// The word relation g_{w_0} ... g_{w_{4g−1}} = ±id: distance of the
  /// product from ±identity (max |entry difference| of the SU(1,1) matrices),
  /// multiplied out in the chart centring the base corner c_0 (where the
  /// generators have entries ~ cosh(loop length/2); in the layout frame they
  /// can reach 1e5 and the product is meaningless in floating point).
  /// Flat: |Σ ± g_k| / max |g_k|.
  double product_relation_error = 0;
  /// Hyperbolic: (|a| + |b|)² of the largest partial product of that word
  /// (1 for flat). Entry errors of the product are this times the relative
  /// accuracy of the layout: a domain of hyperbolic diameter d gives about
  /// e^d, so a long, thin fundamental domain (long loops) makes the matrix
  /// relation lose digits although every point glues to 1e-7 (see
  /// max_deck_inconsistency for the well-conditioned, point-wise check).
  double relation_condition = 1;
  /// Diagnostics: max over interior edges of the distance between the two
  /// copies of each endpoint (should be round-off); max over cut edges of
  /// the distance between the side pairing's image of an endpoint copy and
  /// the other copy (the corners are max_corner_inconsistency); flat only:
  /// max |rotation part − 1| of the deck maps (holonomy; 0 for a flat torus).
  double max_interior_mismatch = 0;
  double max_deck_inconsistency = 0;
  /// The largest round-off bound of the two copies in the interior check:
  /// each copy's chart evaluation (apply_roundoff) times the number of
  /// rounded chart products behind that chart (its breadth-first depth + 1);
  /// and the largest interior gap beyond 10 times its own bound: the part
  /// that is not rounding (uniformize checks this one against its
  /// tolerance; genus 11 and up lay points out 1e-11 from |z| = 1, where
  /// the rounding alone is 1e-2, issue 13).
  double interior_roundoff = 0;
  double max_interior_excess = 0;
  /// The largest round-off bound of the side pairing's evaluations in that
  /// check (hyperbolic: ε |a| / ((1 − |z|²)(1 − |w|²))^½ roughly, 1e-4 for
  /// a pairing with |a| ~ 1e5 between points 1e-7 from |z| = 1 on the
  /// long fundamental domains of genus 11 and up), and the largest gap
  /// beyond 10 times its own evaluation's bound: the gluing error that is
  /// not rounding (uniformize checks this one against its tolerance).
  double deck_roundoff = 0;
  double max_deck_excess = 0;
  /// The corners of the 4g-gon against their images c_m = Ψ_m(c_0) under
  /// the products Ψ_m of side pairings (distance in the metric), and that
  /// check's condition: 4g × max (|a| + |b|)² of the Ψ_m (1 for flat), the
  /// factor by which the products multiply the round-off of the pairings.
  double max_corner_inconsistency = 0;
  double corner_condition = 1;
  /// Round-off of the corner coordinates expressed in the metric: machine ε
  /// times the largest scale factor of the model at a corner (hyperbolic
  /// 2/(1−|z|²) = 1 + cosh d at distance d from 0, with d read off the
  /// chart; flat max(|z|, 1)). Mismatches of a few hundred times this are
  /// rounding, not a gluing error (long hyperbolic domains: 1e-4).
  double coordinate_roundoff = 0;
  double max_holonomy_rotation = 0;
  /// Hyperbolic re-centring: the passes over the corners that found their
  /// Karcher mean (each one every corner's logarithm; 0 without re-centring
  /// or for flat layouts). A diagnostic of the Newton iteration's cost.
  int centre_evaluations = 0;
  /// Number of corner triangles with non-positive orientation (hyperbolic:
  /// tested in the Klein model, where the triangle sides are straight),
  /// among the resolvable ones.
  int num_flipped = 0;
  /// Of those, the ones whose height (2 area / longest side) is at least 100
  /// times the coordinate round-off at their corners: flipped for real, not
  /// slivers turned over by rounding (the per-face layout accepts the
  /// latter, uniformize.cpp check_layout).
  int num_flipped_above_roundoff = 0;
  /// Triangles whose sides are all shorter than 100 times the coordinate
  /// round-off at their corners (flat metrics of long thin parts: sides of
  /// 1e-13 at |z| ~ 5000): double precision cannot place them, so their
  /// orientation is not tested. Reported, not hidden.
  int num_unresolved = 0;
  /// Largest distance of a corner from 0 in the metric (hyperbolic), read off
  /// the face charts (exact where the coordinates round to |z| = 1); flat:
  /// the largest |z|. The coordinate round-off and num_unresolved use each
  /// corner's distance read the same way.
  double layout_radius = 0;
  /// The checks in per-face charts, which need no position in the layout's
  /// frame (issue 13: CAD plates of genus 13 .. 24 reach 37 .. 73 from the
  /// centre, where double coordinates have no digits left): the largest
  /// distance from the identity of the product of the transitions between
  /// neighbouring canonical triangles around a vertex's star (every vertex
  /// of the surface; hyperbolic: SU(1,1) entries, about half the angle
  /// defect; flat: max(|rotation − 1|, |translation| / longest star edge)),
  /// and the faces that, carried into a neighbour's chart by their
  /// transition, are not counter-clockwise or fold over the common edge.
  /// Trivial holonomy at every vertex is what the single chart's interior,
  /// deck and corner checks test (layout.cpp, local_checks).
  double max_vertex_holonomy = 0;
  int num_flipped_local = 0;
  /// Sum of the triangle areas of the metric (hyperbolic: 4π(g−1) when the
  /// metric has zero curvature at every vertex).
  double area = 0;
  double time_s = 0;
};

/// Lays out the disk cut along `loops`. `conn` must be Connectivity(loops.mesh.F)
/// and `edge_lengths` (#E, edge order of conn) a flat or hyperbolic metric with
/// zero angle defect at every vertex (e.g. RicciFlowResult::edge_lengths).
/// Throws InputError on size mismatches or a face violating the triangle
/// inequality (naming it), SolveError when the layout is inconsistent (the
/// boundary is not one 4g-gon of loop sides).
DiskLayout layout_disk(const Connectivity& conn, const Eigen::VectorXd& edge_lengths,
                       Background background, const SystemOfLoops& loops,
                       const LayoutOptions& options = {});

/// A hyperbolic surface in per-face charts (issue 13): every face's
/// canonical triangle (corner 0 at 0, corner 1 on the positive real axis,
/// corner 2 above it) and, per halfedge h, the isometry taking the canonical
/// coordinates of face(twin(h)) to those of face(h): the same transitions
/// layout_disk composes its charts from. Nothing here depends on a global
/// chart or on a cut: a point of the surface is a face and a point in its
/// canonical chart, and two nearby points are compared by composing the
/// transitions along the faces between them (all of size ~1), so surfaces
/// whose fundamental domain reaches farther than double coordinates resolve
/// (CAD plates of genus 13 .. 24, layout radius 28 .. 55) lose no digits.
struct FaceAtlas {
  std::vector<std::array<Complex, 3>> corners;   ///< #F canonical triangles
  std::vector<hyperbolic::Mobius> transition;    ///< #3F, face(twin(h)) -> face(h)
  std::vector<int> twin;                         ///< #3F, Connectivity::twin
  int num_faces() const { return static_cast<int>(corners.size()); }
};

/// The atlas of a hyperbolic metric (`edge_lengths`: #E, edge order of
/// `conn`). InputError on a size mismatch or a face violating the triangle
/// inequality (naming it).
FaceAtlas hyperbolic_face_atlas(const Connectivity& conn, const Eigen::VectorXd& edge_lengths);

/// Conformal modulus of a flat torus with lattice ω1 Z + ω2 Z.
struct TorusModulus {
  Complex omega1, omega2;
  /// τ = ω2/ω1, with ω2 negated if needed so that Im τ > 0.
  Complex tau;
  bool omega2_negated = false;
  /// τ reduced to the modular fundamental domain |Re τ| <= ½, |τ| >= 1, and
  /// the SL(2,Z) matrix [[a, b], [c, d]] (row-major) with
  /// tau_reduced = (a τ + b) / (c τ + d).
  Complex tau_reduced;
  int sl2z[4] = {1, 0, 0, 1};
};

TorusModulus torus_modulus(Complex omega1, Complex omega2);

/// Reduces τ (Im τ > 0) to the modular fundamental domain; writes the
/// SL(2,Z) matrix (row-major) to `matrix` when non-null.
Complex reduce_modulus(Complex tau, int* matrix = nullptr);

}  // namespace surfmap
