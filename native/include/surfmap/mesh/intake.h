#pragma once
// Mesh intake and validation (docs/robustness.md): counts, genus, and every
// problem that stops the pipeline, each naming the offending element.
// (Nearly) degenerate faces are accepted: the solvers mollify the intrinsic
// edge lengths (geometry/mollify.h), and intake reports what that touches.
#include <string>
#include <vector>

#include "surfmap/mesh/mesh_io.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct MeshInfo {
  int num_vertices = 0, num_edges = 0, num_faces = 0;
  int num_components = 0, num_boundary_loops = 0;
  int euler_characteristic = 0;
  /// (2 - chi)/2 for a closed orientable surface; -1 when undefined.
  int genus = -1;
  /// True when the mesh is a valid closed, manifold, one-component surface.
  bool valid = false;
  /// Human-readable problems, most fundamental first; empty when valid.
  std::vector<std::string> problems;
  /// Non-fatal remarks (e.g. "faces flipped to orient the surface outward").
  std::vector<std::string> notes;
  /// Signed volume of the input as given (negative: inward normals).
  double signed_volume = 0.0;
  /// Intrinsic mollification of the edge lengths (geometry/mollify.h): faces
  /// that were (nearly) degenerate and the epsilon added to every edge.
  /// Both 0 for a well-shaped mesh; reported in `notes` when nonzero.
  int mollified_faces = 0;
  double mollify_epsilon = 0.0;
  /// Faces of zero area (below area_tolerance) in the input, accepted
  /// through mollification.
  int zero_area_faces = 0;
};

struct IntakeOptions {
  /// Faces whose area is below area_tolerance * (bounding-box diagonal)^2
  /// count as zero-area (reported in the mollification note). Default 1e-14.
  double area_tolerance = 1e-14;
  /// Margin of the intrinsic mollification, relative to the mean edge length
  /// (the default of mollify_edge_lengths, which the solvers use too, so the
  /// note reports what they do). Default 1e-4.
  double mollify_margin = 1e-4;
  /// Orient the surface outward (signed volume > 0), flipping all faces.
  bool orient_outward = true;
  /// Accept boundary loops (open surfaces; default false: refused). The
  /// boundary loops, the genus (2 - chi - b)/2 and the vertex-manifold check
  /// of open meshes are in mesh/open_surface.h (load_open_mesh), which sets
  /// this; open meshes are never flipped (no signed volume).
  bool allow_boundary = false;
};

struct IntakeResult {
  TriMesh mesh;  ///< triangulated, oriented outward
  MeshInfo info;
  /// For every triangle of `mesh`, the input polygon it came from.
  std::vector<int> source_polygon;
  bool flipped = false;  ///< all faces were reversed to orient outward
};

/// Inspects a polygon soup without throwing: counts and problems.
MeshInfo inspect(const PolygonSoup& soup, const IntakeOptions& options = {});

/// Validates, triangulates (fan) and orients a polygon soup. Throws
/// InputError with the first problem found (message names the element).
IntakeResult intake(const PolygonSoup& soup, const IntakeOptions& options = {});
IntakeResult intake(const RowMatrixX3d& V, const RowMatrixX3i& F, const IntakeOptions& options = {});

/// Reads and validates a file; `what` prefixes messages (e.g. "source").
IntakeResult load_mesh(const std::string& path, const IntakeOptions& options = {});

/// For a pair: throws InputError naming both genera if they differ.
void check_same_genus(const MeshInfo& source, const MeshInfo& target);

}  // namespace surfmap
