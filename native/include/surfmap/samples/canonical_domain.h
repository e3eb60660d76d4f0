#pragma once
// Canonical domains: clean, symmetric closed surfaces of a given genus onto
// which many shapes are parameterized (`surfmap map SHAPE DOMAIN.obj`) and
// compared (docs/many_shapes.md; the paper's common-domain maps, Figs. 14-15).
#include <string>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::samples {

enum class DomainKind {
  NTorus,    ///< g round holes: in a row (tori of radius 1 merged side by side) or in a ring (a pancake)
  Polycube,  ///< rounded block with g square through-holes in a row (samples::polycube)
};

enum class DomainLayout {
  Row,   ///< holes along the x axis
  Ring,  ///< holes evenly spaced on a circle in the z = 0 plane (n-torus only)
};

struct CanonicalDomainOptions {
  int genus = 2;                          ///< 0..8 (0: unit icosphere, whatever the kind)
  DomainKind kind = DomainKind::NTorus;
  DomainLayout layout = DomainLayout::Row;
  int resolution = 24;                    ///< grid cells per hole tile (>= 16); #V grows like genus x resolution^2
  bool unit_area = true;                  ///< scale (about the centroid) to total area 1
};

struct CanonicalDomainResult {
  TriMesh mesh;              ///< closed, manifold, one component, outward oriented
  int genus = 0;             ///< checked: 2 - 2g = V - E + F
  std::string description;   ///< e.g. "n-torus (row) genus 3"
  double area = 0;           ///< total area after scaling
  double signed_volume = 0;  ///< > 0 (outward orientation)
  double min_angle_deg = 0;  ///< smallest corner angle over all triangles
  double mean_min_angle_deg = 0;  ///< mean over triangles of their smallest angle
  double fraction_below_20_deg = 0;  ///< fraction of triangles whose smallest angle is below 20 degrees
};

/// Canonical genus-g surface (genus 0..8). Implicit shapes meshed by marching
/// tetrahedra and improved on their level set (samples/shapes.h), so the
/// triangles are close to equilateral; the result is checked (closed,
/// manifold, genus, orientation, no zero-area face) and its triangle quality
/// is measured. Throws InputError on a genus outside 0..8, a resolution below
/// 16, or DomainLayout::Ring with DomainKind::Polycube.
CanonicalDomainResult canonical_domain(const CanonicalDomainOptions& options);

}  // namespace surfmap::samples
