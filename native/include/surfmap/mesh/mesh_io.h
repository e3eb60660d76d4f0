#pragma once
// Mesh files in and out. OBJ, OFF and PLY are parsed here (every count
// bounded by the file's actual contents; see docs/robustness.md), STL by
// OpenMesh's reader (which welds its corners), into a raw polygon soup, so
// that intake can report problems with the file's own indices instead of the
// reader silently dropping faces.
#include <string>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

/// Polygons exactly as in the file (0-based indices, not yet checked).
struct PolygonSoup {
  RowMatrixX3d V;
  std::vector<std::vector<int>> polygons;
};

/// Reads OBJ/OFF/PLY/STL. Throws InputError if the file is missing,
/// unreadable or of an unknown format.
PolygonSoup read_polygon_soup(const std::string& path);

/// Writes an OBJ file atomically (temporary file, then rename), so an
/// existing file is never left half-written. Throws Error on failure.
void write_obj(const std::string& path, const RowMatrixX3d& V, const RowMatrixX3i& F);

/// Writes a text file atomically (same guarantee as write_obj).
void write_text_file(const std::string& path, const std::string& text);

}  // namespace surfmap
