// Reading and writing CORR.txt (verify/correspondence_file.h).
#include "surfmap/verify/correspondence_file.h"

#include <climits>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "surfmap/error.h"

namespace surfmap {
namespace {

void write_points(std::ostringstream& s, const std::vector<SurfacePoint>& points) {
  for (const auto& p : points)
    s << p.face << ' ' << p.barycentric[0] << ' ' << p.barycentric[1] << ' ' << p.barycentric[2] << '\n';
}

}  // namespace

std::string correspondence_text(const std::vector<SurfacePoint>& forward, const std::vector<SurfacePoint>& inverse) {
  std::ostringstream s;
  s << std::setprecision(17);
  write_points(s, forward);
  s << kInverseSectionMarker << '\n';
  write_points(s, inverse);
  return s.str();
}

CorrespondenceFile read_correspondence(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read correspondence file " + path);
  CorrespondenceFile file;
  const std::string marker = kInverseSectionMarker;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos) continue;
    if (line[first] == '#') {
      if (line.compare(first, std::string::npos, marker) == 0) {
        if (file.has_inverse) throw InputError(path + ":" + std::to_string(number) + ": a second inverse section");
        file.has_inverse = true;
      }
      continue;
    }
    std::istringstream s(line);
    long long face = 0;
    SurfacePoint p;
    std::string rest;
    if (!(s >> face >> p.barycentric[0] >> p.barycentric[1] >> p.barycentric[2]) || (s >> rest) || face < INT_MIN ||
        face > INT_MAX)
      throw InputError(path + ":" + std::to_string(number) + ": expected 'face b0 b1 b2', got '" + line + "'");
    p.face = static_cast<int>(face);
    (file.has_inverse ? file.inverse : file.forward).push_back(p);
  }
  return file;
}

}  // namespace surfmap
