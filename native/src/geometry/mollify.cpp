#include "surfmap/geometry/mollify.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "surfmap/error.h"

namespace surfmap {
namespace {

// Smallest margin l_a + l_b - l_c over the three corners of face f.
double face_margin(const Eigen::VectorXd& l, const Connectivity& c, int f) {
  const double a = l[c.edge(3 * f)], b = l[c.edge(3 * f + 1)], d = l[c.edge(3 * f + 2)];
  return std::min({a + b - d, b + d - a, d + a - b});
}

}  // namespace

MollifyResult mollify_edge_lengths(const Eigen::VectorXd& lengths, const Connectivity& c,
                                   double relative_margin) {
  const int ne = c.num_edges();
  if (lengths.size() != ne)
    throw InputError("mollify_edge_lengths: " + std::to_string(lengths.size()) + " edge lengths for " +
                     std::to_string(ne) + " edges");
  if (!(relative_margin >= 0.0 && relative_margin < 0.5))
    throw InputError("mollify_edge_lengths: relative margin " + std::to_string(relative_margin) +
                     " is outside [0, 0.5)");
  for (int e = 0; e < ne; ++e)
    if (!(lengths[e] >= 0.0) || !std::isfinite(lengths[e]))
      throw InputError("mollify_edge_lengths: edge " + std::to_string(e) + " (" +
                       std::to_string(c.edge_vertex(e, 0)) + ", " + std::to_string(c.edge_vertex(e, 1)) +
                       ") has length " + std::to_string(lengths[e]));
  MollifyResult r;
  r.lengths = lengths;
  if (ne == 0) return r;
  const double mean = lengths.mean();
  // With every length + eps, a corner margin m becomes m + eps and the mean
  // becomes mean + eps, so we need m_min + eps >= relative_margin (mean + eps):
  // eps = (relative_margin mean - m_min) / (1 - relative_margin).
  double min_margin = INFINITY;
  for (int f = 0; f < c.num_faces(); ++f) min_margin = std::min(min_margin, face_margin(lengths, c, f));
  const double delta = relative_margin * mean;
  if (!(min_margin < delta)) return r;
  // A hair more than the exact value so round-off cannot leave a face just
  // below the margin (and a second pass finds nothing to do).
  r.epsilon = (delta - min_margin) / (1.0 - relative_margin) * (1.0 + 1e-9);
  r.epsilon = std::max(r.epsilon, 4.0 * std::numeric_limits<double>::epsilon() * std::max(mean, 1e-300));
  for (int f = 0; f < c.num_faces(); ++f)
    if (face_margin(lengths, c, f) < delta) ++r.faces_touched;
  r.lengths.array() += r.epsilon;
  return r;
}

}  // namespace surfmap
