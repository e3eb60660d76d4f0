#pragma once
// Internal to the samples layer: meshing the zero set of an implicit function
// (negative inside) by marching tetrahedra, and improving the result on the
// level set. Not part of the public API.
#include <functional>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::samples::detail {

using Implicit = std::function<double(const Eigen::Vector3d&)>;

/// Marching tetrahedra (Kuhn/Freudenthal split of each grid cube into 6
/// tetrahedra) of {f = 0} on a grid covering [lo, hi] (plus padding) with
/// `resolution` cells along the longest axis. Crossing vertices are welded by
/// grid edge; grid values that are exactly 0 are nudged outside so every
/// crossing is transversal; crossing parameters are clamped to [1e-3, 1-1e-3]
/// so no triangle has zero area. Faces are oriented towards f > 0. Throws
/// Error if f < 0 on the grid boundary (the surface must stay inside).
TriMesh marching_tetrahedra(const Implicit& f, const Eigen::Vector3d& lo,
                            const Eigen::Vector3d& hi, int resolution);

/// Improves triangle shapes while staying on {f = 0}: rounds of
/// angle-improving edge flips and tangential umbrella relaxation followed by
/// Newton projection back to the level set. A vertex move that would turn a
/// face away from the outward surface normal (cosine with grad f below 0.1
/// and lower than before) or shrink it to (near) zero area is reverted, and
/// flips are only made when both new faces agree with grad f, so no face
/// ever ends up flipped or degenerate.
/// `h` is the grid spacing (length scale for tolerances).
void improve_on_level_set(TriMesh& mesh, const Implicit& f, double h, int rounds);

/// Throws Error unless `mesh` is closed, manifold, one component, of genus
/// `genus`, outward oriented and free of zero-area faces; `what` names the
/// shape in the message (e.g. "vase at resolution 20").
void check_closed_surface(const TriMesh& mesh, int genus, const std::string& what);

}  // namespace surfmap::samples::detail
