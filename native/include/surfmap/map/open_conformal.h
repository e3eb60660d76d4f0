#pragma once
// Conformal maps of open surfaces onto their canonical domains (issue 16;
// docs/open_surfaces.md):
//  - a disk (genus 0, one boundary loop) onto the unit disk, boundary free
//    (the Riemann map: the boundary lands on the unit circle wherever the
//    conformal structure puts it), normalised by the disk Möbius map that
//    centres the area: the classic free-boundary harmonic disk map;
//  - an annulus (genus 0, two boundary loops) onto the flat cylinder
//    R/Z x [0, m] of circumference 1 and height m, its conformal modulus.
// Both from two linear solves with the cotangent weights of the source's
// intrinsic Delaunay triangulation (edge flips on lengths; the mesh's own
// cotangent weights are negative across obtuse triangles and fold the map): a
// harmonic function u (disk: the Green's function with its pole at the
// vertex farthest from the boundary, u = 0 on the boundary; annulus: u = 0
// on loop 0 and 1 on loop 1) and its harmonic conjugate, a harmonic
// function with Neumann boundary conditions and a prescribed jump (period)
// across a dual cut path.
#include <array>
#include <complex>
#include <vector>

#include "surfmap/mesh/open_surface.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

enum class OpenConformalWeights {
  /// intrinsic; where the mesh's own faces fold under it, those faces
  /// (from the second round their neighbours too) keep their own edges
  /// (negative weights raised to the floor) and the solve is repeated; then positive_own if faces still
  /// fold, keeping the map with fewer flipped faces.
  automatic,
  /// Cotangent weights of the intrinsic Delaunay triangulation: the mesh's
  /// own weights on a Delaunay mesh, >= 0 on every interior edge otherwise.
  intrinsic,
  /// The mesh's own cotangent weights (negative across obtuse triangles).
  own,
  /// The mesh's own cotangent weights raised to own_weights_floor.
  positive_own,
};

struct OpenConformalOptions {
  /// Disk: the area-centring Möbius iteration stops when the weighted
  /// centroid of the images is below this (default 1e-12) or after
  /// max_centring_iterations (default 100).
  double centring_tolerance = 1e-12;
  int max_centring_iterations = 100;
  /// Energy weights (default automatic): see OpenConformalWeights.
  OpenConformalWeights weights = OpenConformalWeights::automatic;
  /// positive_own: least weight, times the mean positive cotangent weight
  /// (default 0.1, as the closed maps' --own-weights-floor).
  double own_weights_floor = 0.1;
  /// automatic: rounds of keeping the faces around folded ones unflipped
  /// before trying positive_own (default 3).
  int max_kept_rounds = 3;
};

struct OpenConformalResult {
  /// Per vertex (#V): disk: a point of the closed unit disk (boundary
  /// vertices exactly on the circle, the pole's image before centring at 0);
  /// cylinder: x + i y with x in [0, 1) (the seam along the dual cut) and
  /// y in [0, modulus] (loop 0 at y = 0, loop 1 at y = modulus).
  std::vector<std::complex<double>> uv;
  bool cylinder = false;
  /// Annulus: conformal modulus height / circumference, the geometric mean
  /// of the two discrete estimates below (Dirichlet's principle: the P1
  /// energies over-estimate, so they bracket the true modulus).
  double modulus = 0;
  double modulus_from_u = 0;      ///< 1 / E(u): a lower bound
  double modulus_from_theta = 0;  ///< E(conjugate of period 1): an upper bound
  /// Disk: the pole vertex, the Möbius centre applied (the image of the
  /// area centroid before centring) and the centring iterations.
  int pole = -1;
  std::complex<double> centring;
  int centring_iterations = 0;
  /// Faces whose image is flipped (negative orientation; cylinder faces
  /// unwrapped across the seam); 0 for a discrete embedding.
  int flipped_faces = 0;
  /// The weights solved with (never automatic).
  OpenConformalWeights weights = OpenConformalWeights::intrinsic;
  /// Intrinsic Delaunay edge flips made (0 on a Delaunay mesh).
  int intrinsic_flips = 0;
  /// automatic: flipped faces of the first intrinsic map, the rounds that
  /// kept faces unflipped after it, and the faces kept.
  int intrinsic_flipped_faces = 0;
  int kept_rounds = 0;
  int kept_faces = 0;
  /// Edges with a negative cotangent weight: in the mesh's own triangulation,
  /// and in the one solved with (only boundary edges opposite an obtuse angle
  /// and edges of the disk pole's star, which is kept, when intrinsic).
  int own_negative_weights = 0;
  int negative_weights = 0;
  /// Faces whose image has zero area (|area| <= 1e-12 of the squared edge
  /// lengths): an annulus's ears (three corners on one loop); not flipped.
  int degenerate_faces = 0;
};

/// Genus 0, one boundary loop (topology from open_surface_topology):
/// conformal map onto the unit disk, area-centred. Throws SolveError when a
/// solve fails, InputError when the topology is not a disk.
OpenConformalResult disk_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                       const OpenConformalOptions& options = {});

/// Genus 0, two boundary loops: conformal map onto the flat cylinder of
/// circumference 1 and height `modulus` (loop 0 at y = 0). Throws like
/// disk_conformal_map.
OpenConformalResult annulus_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                          const OpenConformalOptions& options = {});

/// "automatic", "intrinsic", "own" or "positive_own" (report field `weights`).
const char* open_conformal_weights_name(OpenConformalWeights weights);

/// Images of face f's corners, cylinder x coordinates unwrapped to within
/// 1/2 of corner 0's.
std::array<std::complex<double>, 3> face_image(const OpenConformalResult& map, const TriMesh& mesh, int f);

}  // namespace surfmap
