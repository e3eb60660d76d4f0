#pragma once
// Stage "quality" of the genus >= 2 map (docs/method.md §2.11): the optimum moved
// into the fundamental polygon P, its image triangles, and its dilatation D'
// per source face from the solver's local charts, flipped / degenerate
// images of the source's faces and of its intrinsic Delaunay triangles.
// Internal to the pipeline (src/map/hyperbolic_map.cpp).
#include <vector>

#include "../map_support.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

using ImageCorners = Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Which solver edge carries each source edge (every source edge is a
/// solver edge, weight 0 when the intrinsic triangulation flipped it away):
/// #E solver edge index and whether it runs along the source edge's
/// edge_halfedge.
struct SolverEdgeIndex {
  std::vector<int> solver_edge;
  std::vector<char> forward;
};

/// The optimum with every vertex moved into P.
struct MapInPolygon {
  std::vector<Complex> zp;                 ///< #V points in P
  std::vector<hyperbolic::Mobius> eff_edge;  ///< #E element of each edge (its edge_halfedge), tail chart -> head chart
  ImageCorners image;                      ///< #F x 3 image corners anchored at corner 0 (in P)
};

/// Moves every vertex of `hr` into P, with its chart change as a reduced
/// side word (from the matrices when the solver kept no words: the
/// relaxation), and the effective element of every source edge (the class's
/// #E side words `side_word_edge` / matrices `rho_edge`). When `hr` has no
/// local charts (edge_local: the relaxation), builds them from the points.
MapInPolygon place_in_polygon(const TriMesh& source, const Connectivity& sc, const FundamentalPolygon& polygon,
                              const DeckGroup& group, const std::vector<Word>& side_word_edge,
                              const std::vector<hyperbolic::Mobius>& rho_edge, const SolverEdgeIndex& index,
                              int num_solver_edges, HyperbolicHarmonicResult& hr);

/// D' of every source face (docs/method.md §2.11) from the solver's local charts
/// `edge_local` (one element per solver edge): side lengths and orientation
/// in the chart of corner 0, exact to round-off however close to |z| = 1
/// the triangle lies; needle-thin images from the affine map seen from the
/// chart centring their centroid. per_face (#F, +inf for flipped and
/// degenerate images), area-weighted mean and max, the counts.
DistortionStats chart_distortion(const TriMesh& source, const Connectivity& sc,
                                 const std::vector<hyperbolic::Mobius>& edge_local, const SolverEdgeIndex& index);

/// The signed image areas and vertex angle sums of the source's faces in
/// the solver's local charts (surface_map.h ImageCover).
ImageCover image_cover(const TriMesh& source, const Connectivity& sc, const std::vector<hyperbolic::Mobius>& edge_local,
                       const SolverEdgeIndex& index);

/// Flipped images among the triangles of the intrinsic triangulation `idt`
/// (the energy's own), from the local charts; -> 0 when edge_local does not
/// cover idt's edges (not computable).
int intrinsic_flipped_triangles(const IntrinsicDelaunayResult& idt, const std::vector<hyperbolic::Mobius>& edge_local);

/// How well the intrinsic Delaunay triangles close in the solve's charts
/// (surface_map.h LayoutClosure): the product of each triangle's three
/// edge_local elements against the identity; not computed (0 triangles)
/// where intrinsic_flipped_triangles cannot count.
LayoutClosure intrinsic_layout_closure(const IntrinsicDelaunayResult& idt,
                                       const std::vector<hyperbolic::Mobius>& edge_local);

/// The same on the source's own faces, edge_local indexed through `index`
/// (the per-face charts' solve, whose edges are the source's own).
LayoutClosure source_layout_closure(const Connectivity& sc, const std::vector<hyperbolic::Mobius>& edge_local,
                                    const SolverEdgeIndex& index);

}  // namespace surfmap::detail
