#pragma once
// Ears of an open mesh whose images turn over (docs/open_surfaces.md, "Ears").
//
// An ear is a face with all three corners on the boundary. A map of open
// surfaces sends boundary onto boundary, so an ear's image is the chord
// triangle of three points of the other mesh's boundary polyline, whatever
// the solve did inside; it turns over wherever that polyline turns the wrong
// way between them (a concave stretch of the other's boundary, or a jagged
// loop). Seen by the user as a flipped triangle of the UVs transferred onto
// the ear (the add-on's UVs read the inverse map) or of the morph.
//
// A boundary vertex's image can slide along the other boundary between the
// images of its two neighbours on its own loop, and the map still sends
// boundary onto boundary in the same order. So the image of the ear's middle
// corner (between its two boundary edges) is slid within the arc of the
// other boundary between the images of the ear's other two corners, to the
// vertex of that arc where every face of its star (usually the ear alone) is
// positively oriented and the largest D' among them (distortion.h) is least.
// Nothing else moves, and no face is turned that was not.
//
// When no vertex of that arc rights the ear (the arc is concave all along, or
// holds no vertex at all: a dense rim onto a coarser loop), a window of
// boundary vertices centred on the middle corner (3, then 5, ...: up to
// 2 max_half_window + 1) is slid together, each image kept or put on a vertex
// of the arc between the images of the window's two outer neighbours, in the
// same order along it: the ear's corners can then take a convex stretch of
// the other boundary beside their own. This moves the ear's neighbours' images
// along the boundary too (their faces' D' changes), so it is only the fallback
// for the ears the middle corner alone cannot right: tried first for every
// turned ear it raised the generated shirt's mean D' from 2.35 to 2.52. An ear
// that no window rights (a fine ear on one straight edge of the other
// boundary: its image is degenerate wherever its corners go) stays as it was,
// counted in turned_after.
#include <vector>

#include <Eigen/Core>

#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/open_surface.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct EarImagesOptions {
  /// An orientation-reversing map: an image then counts as turned when it is
  /// positively oriented against the other mesh's normals.
  bool reversing = false;
  /// The largest window slid together when the middle corner alone cannot
  /// right an ear: 2 w + 1 boundary vertices, w = 1 .. max_half_window (0:
  /// the middle corner only). Default 2 (windows of 3 and 5 vertices).
  int max_half_window = 2;
  /// A window is taken only when the largest D' (distortion.h) of the faces
  /// of its vertices' stars stays below this bound (the middle corner alone:
  /// no bound). Without it the generated mask (subdivision 5) onto the head
  /// righted 2 more ears, one of them with a neighbour's D' at 103.
  double window_max_dilatation = 10.0;
  /// Vertices of `mesh` whose images never move (landmarks); empty: none.
  std::vector<int> held;
};

struct EarImagesResult {
  int ears = 0;          ///< faces of `mesh` with three boundary corners
  int turned = 0;        ///< of them, images turned (or degenerate) before
  int moved = 0;         ///< of them, righted (by the middle corner or a window)
  int moved_with_neighbours = 0;  ///< of `moved`, righted only by a window of 3 or more vertices
  int turned_after = 0;  ///< images still turned or degenerate afterwards
};

/// images: per vertex of `mesh` a point of `other` (boundary vertices on
/// other's boundary), changed in place. An image is turned when its chord
/// triangle's normal does not point along the sum of other's face normals at
/// the faces holding its corners (degenerate: its area at most 1e-12 of the
/// squared longest side). A move is taken only when it rights the ear and
/// turns no face of the moved vertices' stars that was not turned.
EarImagesResult slide_ear_images(const TriMesh& mesh, const OpenSurfaceTopology& mesh_topology, const TriMesh& other,
                                 const OpenSurfaceTopology& other_topology, std::vector<PointOnSurface>& images,
                                 const EarImagesOptions& options = {});

}  // namespace surfmap
