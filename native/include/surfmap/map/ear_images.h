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
// Nothing else moves, and no face is turned that was not. An ear whose arc
// holds no convex vertex of the other boundary (a fine ear on one straight
// edge: degenerate; a dense rim on a coarser jagged loop) stays as it was,
// counted: righting it would move its neighbours' images too (the add-on
// rights the transferred UVs of such ears in the UV chart instead,
// uv_transfer.right_ear_uvs).
#include <vector>

#include <Eigen/Core>

#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/open_surface.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct EarImagesResult {
  int ears = 0;          ///< faces of `mesh` with three boundary corners
  int turned = 0;        ///< of them, images turned (or degenerate) before
  int moved = 0;         ///< of them, righted by sliding the middle corner's image
  int turned_after = 0;  ///< images still turned or degenerate afterwards
};

/// images: per vertex of `mesh` a point of `other` (boundary vertices on
/// other's boundary), changed in place. reversing: an orientation-reversing
/// map (an image then counts as turned when it is positively oriented
/// against other's normals). An image is turned when its chord triangle's
/// normal does not point along the sum of other's face normals at the faces
/// holding its corners (degenerate: its area at most 1e-12 of the squared
/// longest side).
EarImagesResult slide_ear_images(const TriMesh& mesh, const OpenSurfaceTopology& mesh_topology, const TriMesh& other,
                                 const OpenSurfaceTopology& other_topology, std::vector<PointOnSurface>& images,
                                 bool reversing = false);

}  // namespace surfmap
