#pragma once
// Open surfaces (issue 16; docs/open_surfaces.md): intake of meshes with
// boundary, their topology (genus g and b boundary loops, chi = 2 - 2g - b),
// the boundary loops ordered and oriented, and the refusal of vertices that
// make the surface non-manifold (a vertex on two boundary loops or twice on
// one, a bowtie of two fans), each naming the vertex.
#include <string>
#include <vector>

#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct OpenSurfaceTopology {
  int genus = 0;
  int euler_characteristic = 0;
  /// Boundary loops, longest (3D length) first; each lists its vertices in
  /// the direction of its faces' boundary halfedges (the surface on the
  /// left), starting at the loop's smallest vertex index.
  std::vector<std::vector<int>> boundary_loops;
  std::vector<double> boundary_lengths;  ///< 3D length of each loop
  int num_boundary_loops() const { return static_cast<int>(boundary_loops.size()); }
  /// "genus 0 with 1 boundary loop"
  std::string describe() const;
};

/// Topology of a one-component, edge-manifold, consistently oriented
/// triangle mesh with or without boundary (#F x 3 faces). Throws InputError
/// naming the vertex when a vertex's faces form more than one fan (a vertex
/// on two boundary loops, twice on one loop, or an interior bowtie).
OpenSurfaceTopology open_surface_topology(const TriMesh& mesh);

struct OpenIntakeResult {
  IntakeResult intake;  ///< as intake() with allow_boundary (never flipped)
  OpenSurfaceTopology topology;
};

/// Reads a mesh that may be open: intake() with IntakeOptions::allow_boundary,
/// then open_surface_topology(). Errors name the file.
OpenIntakeResult load_open_mesh(const std::string& path);
OpenIntakeResult intake_open(const PolygonSoup& soup);

/// Throws InputError naming (g, b) of both when they differ.
void check_same_open_topology(const OpenSurfaceTopology& source, const OpenSurfaceTopology& target);

}  // namespace surfmap
