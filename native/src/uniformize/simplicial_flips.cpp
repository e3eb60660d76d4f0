// Exact flips of the final metric to a simplicial triangulation
// (uniformize/simplicial_flips.h).
#include "surfmap/uniformize/simplicial_flips.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "surfmap/error.h"

namespace surfmap {
namespace {

std::pair<int, int> ends(const RicciFlowResult& flow, int e) {
  const int a = flow.edge_vertices(e, 0), b = flow.edge_vertices(e, 1);
  return {std::min(a, b), std::max(a, b)};
}

/// Angle at corner c of face f in the final metric (half-angle formula,
/// Euclidean or hyperbolic; face_edges(f, k) is the side opposite corner k).
double corner_angle(const RicciFlowResult& flow, int f, int c) {
  const double a = flow.edge_lengths[flow.face_edges(f, c)], b = flow.edge_lengths[flow.face_edges(f, (c + 1) % 3)],
               d = flow.edge_lengths[flow.face_edges(f, (c + 2) % 3)];
  const double s = 0.5 * (a + b + d);
  const double sa = s - a, sb = s - b, sd = s - d;
  if (!(sa > 0 && sb > 0 && sd > 0)) return NAN;
  if (flow.background == Background::Euclidean) return 2.0 * std::atan2(std::sqrt(sb * sd), std::sqrt(s * sa));
  return 2.0 * std::atan2(std::sqrt(std::sinh(sb) * std::sinh(sd)), std::sqrt(std::sinh(s) * std::sinh(sa)));
}

/// The chord (Penner) coordinate of a final length: Euclidean the length,
/// hyperbolic 2 sinh(l/2) (EdgeFlip::base_lengths' convention).
double chord(const RicciFlowResult& flow, double l) {
  return flow.background == Background::Euclidean ? l : 2.0 * std::sinh(0.5 * l);
}

class Flipper {
 public:
  explicit Flipper(RicciFlowResult& flow) : flow_(flow), ef_(flow.edge_vertices.rows(), 2) {
    ef_.setConstant(-1);
    for (int f = 0; f < flow.faces.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int e = flow.face_edges(f, k);
        ef_(e, ef_(e, 0) < 0 ? 0 : 1) = f;
      }
    for (int e = 0; e < flow.edge_vertices.rows(); ++e) ++count_[ends(flow, e)];
  }

  bool offending(int e) const {
    const auto p = ends(flow_, e);
    return p.first == p.second || count_.at(p) > 1;
  }

  /// Flips e exactly if allowed (see make_simplicial); true when flipped.
  bool flip(int e) {
    RicciFlowResult& fl = flow_;
    const int f0 = ef_(e, 0), f1 = ef_(e, 1);
    if (f0 < 0 || f1 < 0 || f0 == f1) return false;
    int a0 = 0, a1 = 0;
    while (fl.face_edges(f0, a0) != e) ++a0;
    while (fl.face_edges(f1, a1) != e) ++a1;
    const int vk = fl.faces(f0, a0), s = fl.faces(f0, (a0 + 1) % 3), t = fl.faces(f0, (a0 + 2) % 3);
    const int vm = fl.faces(f1, a1);
    if (fl.faces(f1, (a1 + 1) % 3) != t || fl.faces(f1, (a1 + 2) % 3) != s) return false;
    const int e_tk = fl.face_edges(f0, (a0 + 1) % 3), e_ks = fl.face_edges(f0, (a0 + 2) % 3);
    const int e_sm = fl.face_edges(f1, (a1 + 1) % 3), e_mt = fl.face_edges(f1, (a1 + 2) % 3);
    if (e_tk == e || e_ks == e || e_sm == e || e_mt == e) return false;
    const std::pair<int, int> new_ends{std::min(vk, vm), std::max(vk, vm)};
    if (vk == vm || count_.count(new_ends)) return false;
    // Strictly convex at s and at t (margin 1e-6 rad): the new diagonal lies inside.
    const double at_s = corner_angle(fl, f0, (a0 + 1) % 3) + corner_angle(fl, f1, (a1 + 2) % 3);
    const double at_t = corner_angle(fl, f0, (a0 + 2) % 3) + corner_angle(fl, f1, (a1 + 1) % 3);
    if (!(at_s < M_PI - 1e-6 && at_t < M_PI - 1e-6)) return false;
    // The new length by unfolding the quad at s.
    const double x = fl.edge_lengths[e_ks], y = fl.edge_lengths[e_sm];
    double lnew;
    if (fl.background == Background::Euclidean) {
      lnew = std::sqrt(std::max(0.0, x * x + y * y - 2.0 * x * y * std::cos(at_s)));
    } else {
      const double c = std::cosh(x) * std::cosh(y) - std::sinh(x) * std::sinh(y) * std::cos(at_s);
      lnew = std::acosh(std::max(1.0, c));
    }
    if (!(lnew > 0.0) || !std::isfinite(lnew)) return false;
    EdgeFlip rec;
    rec.face0 = f0, rec.face1 = f1, rec.corner0 = a0, rec.corner1 = a1;
    rec.base_lengths = {chord(fl, fl.edge_lengths[e_ks]), chord(fl, fl.edge_lengths[e_sm]),
                        chord(fl, fl.edge_lengths[e_mt]), chord(fl, fl.edge_lengths[e_tk]),
                        chord(fl, fl.edge_lengths[e]),    chord(fl, lnew)};
    rec.exact = true;
    rec.final_frame = true;
    fl.flip_history.push_back(rec);
    ++fl.flips;
    if (--count_[ends(fl, e)] == 0) count_.erase(ends(fl, e));
    ++count_[new_ends];
    fl.edge_lengths[e] = lnew;
    // The same rows as ricci_flow's flips (EdgeFlip's convention).
    fl.faces.row(f0) << vk, s, vm;
    fl.face_edges.row(f0) << e_sm, e, e_ks;
    fl.faces.row(f1) << vm, t, vk;
    fl.face_edges.row(f1) << e_tk, e, e_mt;
    fl.edge_vertices(e, 0) = new_ends.first;
    fl.edge_vertices(e, 1) = new_ends.second;
    for (int q : {e, e_tk, e_ks, e_sm, e_mt})
      for (int j = 0; j < 2; ++j)
        if (ef_(q, j) == f0 || ef_(q, j) == f1) ef_(q, j) = -2;
    for (int f : {f0, f1})
      for (int j = 0; j < 3; ++j) {
        const int q = fl.face_edges(f, j);
        ef_(q, ef_(q, 0) == -2 ? 0 : 1) = f;
      }
    return true;
  }

  /// The edges of the faces next to e (other than e), for a second try.
  std::vector<int> neighbours(int e) const {
    std::vector<int> out;
    for (int j = 0; j < 2; ++j) {
      const int f = ef_(e, j);
      if (f < 0) continue;
      for (int k = 0; k < 3; ++k)
        if (flow_.face_edges(f, k) != e) out.push_back(flow_.face_edges(f, k));
    }
    return out;
  }

 private:
  RicciFlowResult& flow_;
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> ef_;
  std::map<std::pair<int, int>, int> count_;
};

}  // namespace

bool is_simplicial(const RicciFlowResult& flow) {
  // Issue 19: the edges' end pairs sorted, not counted in a map (a node
  // allocated per edge: 115 M instructions on a 56k target, on the map's
  // path; now ~20 M).
  std::vector<std::pair<int, int>> pairs(flow.edge_vertices.rows());
  for (int e = 0; e < flow.edge_vertices.rows(); ++e) {
    pairs[e] = ends(flow, e);
    if (pairs[e].first == pairs[e].second) return false;
  }
  std::sort(pairs.begin(), pairs.end());
  return std::adjacent_find(pairs.begin(), pairs.end()) == pairs.end();
}

SimplicialFlipsResult make_simplicial(RicciFlowResult& flow, const SimplicialFlipsOptions& options) {
  if (flow.faces.rows() == 0 || flow.face_edges.rows() != flow.faces.rows() ||
      flow.edge_lengths.size() != flow.edge_vertices.rows())
    throw InputError("make_simplicial: the flow result has no triangulation");
  SimplicialFlipsResult out;
  Flipper flipper(flow);
  std::vector<int> bad;
  {
    std::map<std::pair<int, int>, int> seen;
    for (int e = 0; e < flow.edge_vertices.rows(); ++e) {
      const auto p = ends(flow, e);
      if (p.first == p.second) ++out.loop_edges, bad.push_back(e);
      else if (seen[p]++ > 0) ++out.multiple_edges, bad.push_back(e);
    }
  }
  const int budget = options.max_flips >= 0 ? options.max_flips : 4 * static_cast<int>(bad.size()) + 16;
  // Rounds: flip every offending edge that may be flipped, else a flippable
  // edge of its two faces (which changes its quad), until none is left or
  // a round makes no flip.
  for (bool progress = true; progress && out.flips < budget;) {
    progress = false;
    std::vector<int> now;
    for (int e = 0; e < flow.edge_vertices.rows(); ++e)
      if (flipper.offending(e)) now.push_back(e);
    if (now.empty()) break;
    for (int e : now) {
      if (out.flips >= budget) break;
      if (!flipper.offending(e)) continue;
      if (flipper.flip(e)) {
        ++out.flips, progress = true;
        continue;
      }
      for (int q : flipper.neighbours(e))
        if (!flipper.offending(q) && flipper.flip(q)) {
          ++out.flips, progress = true;
          break;
        }
    }
  }
  out.simplicial = is_simplicial(flow);
  return out;
}

}  // namespace surfmap
