#pragma once
// Genus-0 uniformization (paper §V; DESIGN.md §2.4): a map of a closed genus-0
// mesh onto the unit sphere.
//
// Method: remove one vertex v0 (its star); flatten the remaining disk with the
// Euclidean discrete Ricci flow (vertex scaling, Newton): curvature 0 at the
// interior vertices and, at the boundary vertices, the geodesic curvature of
// a polygon inscribed in a circle with the current boundary edge lengths —
// recomputed from the solution and re-solved (warm start) until the boundary
// is a circle to `circle_tolerance`. Lay the disk out in the plane, scale the
// circle to the unit circle, project stereographically (unit circle ->
// equator, v0 -> the pole), then Möbius-centre: repeatedly apply the ball
// automorphism that moves the area-weighted centre of mass (vertex areas of
// the input mesh) to the origin.
#include <string>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct SphericalUniformizationOptions {
  /// Vertex sent to the pole before centring; -1 (default): the vertex of
  /// highest valence (a rounder hole).
  int removed_vertex = -1;
  /// Options of the inner Euclidean flow (scheme/method/tolerance/progress).
  RicciFlowOptions flow;
  /// Overrides flow.intrinsic_delaunay (default true): flatten with Ptolemy
  /// flips so that badly shaped meshes have a solution; the flattened
  /// intrinsic triangulation is laid out, and the input faces are then
  /// checked on the sphere (flipped_faces).
  bool intrinsic_delaunay = true;
  /// Max |geodesic curvature − inscribed-polygon curvature| on the boundary.
  double circle_tolerance = 1e-9;
  int max_boundary_iterations = 60;
  /// Stop centring when |centre of mass| <= centring_tolerance.
  double centring_tolerance = 1e-10;
  int max_centring_iterations = 500;
};

struct SphericalUniformization {
  /// #V positions on the unit sphere (same vertex order as the input).
  RowMatrixX3d positions;
  /// True when the flow converged, the boundary became a circle, the centre
  /// of mass reached the tolerance and no triangle is flipped.
  bool converged = false;
  int removed_vertex = -1;
  int boundary_iterations = 0;
  int flow_iterations = 0;             ///< Newton iterations summed over boundary rounds
  double max_curvature_error = 0;      ///< interior and boundary, last flow
  double circle_error = 0;             ///< as circle_tolerance
  double centre_of_mass_norm = 0;      ///< after centring
  int flipped_faces = 0;               ///< faces whose normal points inward on the sphere
  int edge_flips = 0;                  ///< intrinsic flips in the last flattening
  double time_s = 0;
  std::string message;                 ///< why it failed (names the element), empty on success
};

/// mesh: closed, manifold, oriented outward, genus 0 (InputError otherwise).
SphericalUniformization spherical_uniformization(const TriMesh& mesh,
                                                 const SphericalUniformizationOptions& options = {});

}  // namespace surfmap
