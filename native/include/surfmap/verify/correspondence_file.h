#pragma once
// The correspondence file written by `surfmap map --correspondence CORR.txt`
// and read by `surfmap verify` (docs/verification.md):
//
//   one line per source vertex, in order:   target_face b0 b1 b2
//   # inverse: one line per target vertex, 'source_face b0 b1 b2'
//   one line per target vertex, in order:   source_face b0 b1 b2
//
// The forward lines come first and unchanged from the original format, so
// readers of the forward map alone can take the first #V_source lines. Blank
// lines and other '#' comments are skipped.
#include <string>
#include <vector>

#include "surfmap/verify/map_certificate.h"

namespace surfmap {

/// The line that starts the inverse section.
inline constexpr const char* kInverseSectionMarker = "# inverse: one line per target vertex, 'source_face b0 b1 b2'";

struct CorrespondenceFile {
  std::vector<SurfacePoint> forward, inverse;
  bool has_inverse = false;  ///< the file has the inverse section
};

/// The file's text for the given maps (17 significant digits).
std::string correspondence_text(const std::vector<SurfacePoint>& forward, const std::vector<SurfacePoint>& inverse);

/// Reads CORR.txt. Throws InputError naming the file and line for a line
/// that is not 'face b0 b1 b2', or when the file cannot be read. Face ranges
/// and counts are not checked here (certify_map reports them).
CorrespondenceFile read_correspondence(const std::string& path);

}  // namespace surfmap
