// The common subdivision of the input faces and the genus-0 intrinsic
// triangulation (uniformize/spherical_subdivision.h).
#include "surfmap/uniformize/spherical_subdivision.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap {
namespace {

// Quad slots (k, s, m, t) = 0..3; SphereFlip::lengths order of the pairs
// (EdgeFlip::base_lengths): k–s, s–m, m–t, t–k, s–t, k–m.
constexpr int kPairs[6][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {1, 3}, {0, 2}};

// The vector of slot m in the basis of the old triangle (k, s, t): the
// exact linear relation v_m = μ_k v_k + μ_s v_s + μ_t v_t between the
// quad's corner vectors. Ptolemy flips: null vectors with Gram entries
// −x²/2 (the quad spans a 3-space: Ptolemy's relation is det G = 0);
// exact flips: the quad unfolded in the plane, vectors (p, 1).
Eigen::Vector3d m_in_old_basis(const SphereFlip& fl) {
  if (fl.exact) {
    const auto& L = fl.lengths;
    const double st = L[4];
    const Eigen::Vector2d s(0, 0), t(st, 0);
    const double kx = (L[0] * L[0] - L[3] * L[3] + st * st) / (2 * st);
    const Eigen::Vector2d k(kx, std::sqrt(std::max(0.0, L[0] * L[0] - kx * kx)));
    const double mx = (L[1] * L[1] - L[2] * L[2] + st * st) / (2 * st);
    const Eigen::Vector2d m(mx, -std::sqrt(std::max(0.0, L[1] * L[1] - mx * mx)));
    auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
    // Affine barycentrics of m in (k, s, t) (they sum to 1).
    const double area = cross(s - k, t - k);
    return Eigen::Vector3d(cross(s - m, t - m), cross(t - m, k - m), cross(k - m, s - m)) / area;
  }
  Eigen::Matrix4d G = Eigen::Matrix4d::Zero();
  for (int p = 0; p < 6; ++p) {
    const double x = fl.lengths[p];
    G(kPairs[p][0], kPairs[p][1]) = G(kPairs[p][1], kPairs[p][0]) = -0.5 * x * x;
  }
  constexpr int tri[3] = {0, 1, 3};
  Eigen::Matrix3d A;
  Eigen::Vector3d rhs;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) A(a, b) = G(tri[a], tri[b]);
    rhs[a] = G(tri[a], 2);
  }
  return A.fullPivLu().solve(rhs);
}

}  // namespace

SphericalSubdivision spherical_common_subdivision(const SphericalUniformization& s, const RowMatrixX3i& input_faces) {
  const int nf = static_cast<int>(input_faces.rows());
  if (s.frame_log.empty() || s.intrinsic_faces.rows() != nf)
    throw SolveError("common subdivision: the uniformization has no flip log for its " + std::to_string(nf) + " faces");
  const int nv = static_cast<int>(s.positions.rows());
  const Connectivity conn(input_faces, nv);
  SphericalSubdivision out;
  out.segments.resize(nf);
  out.crossings_of_edge.resize(conn.num_edges());
  // At the start every input edge lies inside the faces it bounds: no
  // segments (a segment is a piece of an input edge crossing a face's interior).
  RowMatrixX3i rows = input_faces;
  Eigen::VectorXd G = Eigen::VectorXd::Zero(nv);  // accumulated log scales of the vertex vectors
  std::vector<char> alive;
  auto& X = out.crossings;
  // Input edges that are still whole edges of the current triangulation, and
  // the two current faces on their sides (a Δ-complex may have another edge
  // with the same two ends: the faces tell them apart).
  std::vector<char> whole(conn.num_edges(), 1);
  std::vector<std::array<int, 2>> whole_faces(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e) {
    const int h = conn.edge_halfedge(e);
    whole_faces[e] = {Connectivity::face(h), Connectivity::face(conn.twin(h))};
  }
  auto whole_edge = [&](int a, int b, int fa, int fb) {
    const int h = conn.find_halfedge(a, b);
    if (h < 0) return -1;
    const int e = conn.edge(h);
    const auto& w = whole_faces[e];
    return whole[e] && ((w[0] == fa && w[1] == fb) || (w[0] == fb && w[1] == fa)) ? e : -1;
  };

  auto apply_frame = [&](const Eigen::VectorXd& g) {
    for (size_t c = 0; c < X.size(); ++c) {
      if (!alive[c]) continue;
      X[c].wa *= std::exp(-g[X[c].a]);
      X[c].wb *= std::exp(-g[X[c].b]);
    }
    G += g;
  };
  size_t frame = 0;
  const auto& frames = s.frame_log;
  const auto& flips = s.flip_log;
  for (int j = 0; j <= static_cast<int>(flips.size()); ++j) {
    for (; frame < frames.size() && frames[frame].time <= j; ++frame) apply_frame(frames[frame].log_scale);
    if (j == static_cast<int>(flips.size())) break;
    const SphereFlip& fl = flips[j];
    const int f0 = fl.face0, f1 = fl.face1;
    if (f0 < 0 || f1 < 0 || f0 >= nf || f1 >= nf || f0 == f1)
      throw SolveError("common subdivision: flip " + std::to_string(j) + " names wrong faces");
    const std::array<int, 4>& q = fl.quad;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        if (q[a] == q[b])
          throw SolveError("common subdivision: flip " + std::to_string(j) + " has a repeated corner (vertex " +
                           std::to_string(q[a]) + ")");
    // The faces' rows must hold the flip's old triangles (up to rotation).
    auto holds = [&](int f, const std::array<int, 3>& slots) {
      for (int r = 0; r < 3; ++r) {
        bool same = true;
        for (int c = 0; c < 3; ++c) same = same && rows(f, (c + r) % 3) == q[slots[c]];
        if (same) return true;
      }
      return false;
    };
    if (!holds(f0, fl.before0) || !holds(f1, fl.before1))
      throw SolveError("common subdivision: flip " + std::to_string(j) + " does not match the faces before it");
    auto slot_of = [&](int v) {
      for (int a = 0; a < 4; ++a)
        if (q[a] == v) return a;
      return -1;
    };
    // Chart: homogeneous coordinates in the basis (v_k, v_s, v_t) of the
    // current frame; v_m = mu.
    const Eigen::Vector3d mu = m_in_old_basis(fl);
    if (!mu.allFinite())
      throw SolveError("common subdivision: flip " + std::to_string(j) + " has a degenerate quad");
    auto basis = [&](int slot) -> Eigen::Vector3d {
      switch (slot) {
        case 0: return Eigen::Vector3d::UnitX();
        case 1: return Eigen::Vector3d::UnitY();
        case 3: return Eigen::Vector3d::UnitZ();
        default: return mu;
      }
    };
    // An end's ray in the chart, and which new face it belongs to: 0 =
    // (k, s, m), 1 = (m, t, k), 2 = both (corner k or m).
    auto chart = [&](const SubdivisionEnd& e) -> Eigen::Vector3d {
      if (e.vertex >= 0) return std::exp(-G[e.vertex]) * basis(slot_of(e.vertex));  // the input frame's v, now
      const SubdivisionCrossing& c = X[e.crossing];
      return c.wa * basis(slot_of(c.a)) + c.wb * basis(slot_of(c.b));
    };
    auto side = [&](const SubdivisionEnd& e) {
      if (e.vertex >= 0) {
        const int sl = slot_of(e.vertex);
        return sl == 1 ? 0 : sl == 3 ? 1 : 2;
      }
      const SubdivisionCrossing& c = X[e.crossing];
      const int a = slot_of(c.a), b = slot_of(c.b);
      if (a < 0 || b < 0) throw SolveError("common subdivision: a segment of flip " + std::to_string(j) + " leaves its quad");
      const int lo = std::min(a, b), hi = std::max(a, b);
      if (lo == 1 && hi == 3) return 3;  // on the old diagonal
      return (lo == 0 && hi == 1) || (lo == 1 && hi == 2) ? 0 : 1;
    };
    // Merge the two old faces' pieces of each input edge across s–t.
    std::vector<SubdivisionSegment> merged;
    // An input edge that was the diagonal itself now runs from corner s to
    // corner t across the quad.
    if (const int e = whole_edge(q[1], q[3], f0, f1); e >= 0) {
      whole[e] = 0;
      SubdivisionSegment d;
      d.A = std::min(q[1], q[3]), d.B = std::max(q[1], q[3]);
      d.ends[0].vertex = d.A, d.ends[1].vertex = d.B;
      merged.push_back(d);
    }
    // Whole input edges on the quad's sides: s–m and t–k change faces.
    auto move_side = [&](int a, int b, int from, int to) {
      const int h = conn.find_halfedge(q[a], q[b]);
      if (h < 0) return;
      auto& w = whole_faces[conn.edge(h)];
      if (!whole[conn.edge(h)]) return;
      for (int& x : w)
        if (x == from) {
          x = to;
          return;
        }
    };
    // Which of them lies on this quad is read before any is moved.
    auto on_face = [&](int a, int b, int f) {
      const int h = conn.find_halfedge(q[a], q[b]);
      if (h < 0 || !whole[conn.edge(h)]) return false;
      const auto& w = whole_faces[conn.edge(h)];
      return w[0] == f || w[1] == f;
    };
    // The new triangles: fs holds s (k, s, m), ft holds t (m, t, k); which
    // of face0 / face1 becomes which is the flip's (after0 / after1).
    const bool face0_has_s = fl.after0[0] == 1 || fl.after0[1] == 1 || fl.after0[2] == 1;
    const int fs = face0_has_s ? f0 : f1, ft = face0_has_s ? f1 : f0;
    const bool ks = on_face(0, 1, f0), sm = on_face(1, 2, f1), mt = on_face(2, 3, f1), tk = on_face(3, 0, f0);
    if (ks) move_side(0, 1, f0, fs);
    if (sm) move_side(1, 2, f1, fs);
    if (mt) move_side(2, 3, f1, ft);
    if (tk) move_side(3, 0, f0, ft);
    std::vector<SubdivisionSegment> pending;  // pieces of f0 ending on s–t, waiting for f1's
    for (int f : {f0, f1}) {
      for (const SubdivisionSegment& sg : out.segments[f]) {
        int on_diag = -1;
        for (int e = 0; e < 2; ++e)
          if (sg.ends[e].crossing >= 0 && side(sg.ends[e]) == 3) on_diag = e;
        if (on_diag < 0) {
          merged.push_back(sg);
          continue;
        }
        const int c = sg.ends[on_diag].crossing;
        auto it = std::find_if(pending.begin(), pending.end(), [&](const SubdivisionSegment& p) {
          return p.ends[0].crossing == c || p.ends[1].crossing == c;
        });
        if (it == pending.end()) {
          pending.push_back(sg);
          continue;
        }
        SubdivisionSegment m;
        m.A = sg.A, m.B = sg.B;
        // Order by t: the piece whose crossing is its end 1 comes first.
        const SubdivisionSegment& first = it->ends[1].crossing == c ? *it : sg;
        const SubdivisionSegment& second = it->ends[1].crossing == c ? sg : *it;
        m.ends[0] = first.ends[0], m.ends[1] = second.ends[1];
        merged.push_back(m);
        alive[c] = 0;
        pending.erase(it);
      }
    }
    if (!pending.empty())
      throw SolveError("common subdivision: an input edge crosses the flipped edge of flip " + std::to_string(j) +
                       " on one side only");
    out.segments[f0].clear();
    out.segments[f1].clear();
    auto t_of = [&](const SubdivisionSegment& sg, int e) {
      const SubdivisionEnd& en = sg.ends[e];
      return en.vertex >= 0 ? (en.vertex == sg.A ? 0.0 : 1.0) : X[en.crossing].t;
    };
    for (const SubdivisionSegment& sg : merged) {
      const int s0 = side(sg.ends[0]), s1 = side(sg.ends[1]);
      if (s0 == 2 && s1 == 2) {  // the input edge k–m is now the diagonal itself
        const int h = conn.find_halfedge(sg.A, sg.B);
        whole[conn.edge(h)] = 1;
        whole_faces[conn.edge(h)] = {f0, f1};
        continue;
      }
      if (s0 == 2 || s1 == 2 || s0 == s1) {
        out.segments[s0 == 2 ? (s1 == 0 ? fs : ft) : (s0 == 0 ? fs : ft)].push_back(sg);
        continue;
      }
      // The segment crosses k–m: σ(h) = det(e_k, μ, h).
      const Eigen::Vector3d hp = chart(sg.ends[0]), hq = chart(sg.ends[1]);
      auto sigma = [&](const Eigen::Vector3d& h) { return mu[1] * h[2] - mu[2] * h[1]; };
      const double sp = sigma(hp), sq = sigma(hq);
      double lambda = sp / (sp - sq);
      if (!std::isfinite(lambda)) lambda = 0.5;
      lambda = std::clamp(lambda, 0.0, 1.0);
      const Eigen::Vector3d h = (1 - lambda) * hp + lambda * hq;
      // h = wk e_k + wm μ.
      const double n2 = mu[1] * mu[1] + mu[2] * mu[2];
      double wm = (mu[1] * h[1] + mu[2] * h[2]) / n2;
      double wk = h[0] - wm * mu[0];
      SubdivisionCrossing c;
      c.A = sg.A, c.B = sg.B;
      c.t = (1 - lambda) * t_of(sg, 0) + lambda * t_of(sg, 1);
      c.a = q[0], c.b = q[2];
      c.flip = j;
      c.wa = std::max(wk, 0.0), c.wb = std::max(wm, 0.0);
      if (!(c.wa + c.wb > 0) || !std::isfinite(c.wa + c.wb))
        throw SolveError("common subdivision: flip " + std::to_string(j) + " gives a crossing without weight");
      X.push_back(c);
      alive.push_back(1);
      SubdivisionSegment p = sg, r = sg;
      p.ends[1] = SubdivisionEnd{-1, static_cast<int>(X.size()) - 1};
      r.ends[0] = SubdivisionEnd{-1, static_cast<int>(X.size()) - 1};
      out.segments[s0 == 0 ? fs : ft].push_back(p);
      out.segments[s1 == 0 ? fs : ft].push_back(r);
    }
    for (int c = 0; c < 3; ++c) rows(f0, c) = q[fl.after0[c]], rows(f1, c) = q[fl.after1[c]];
    ++out.flips_replayed;
  }
  // The faces must now be intrinsic_faces (rows up to rotation).
  for (int f = 0; f < nf; ++f) {
    bool same = false;
    for (int r = 0; r < 3 && !same; ++r)
      same = rows(f, r) == s.intrinsic_faces(f, 0) && rows(f, (r + 1) % 3) == s.intrinsic_faces(f, 1) &&
             rows(f, (r + 2) % 3) == s.intrinsic_faces(f, 2);
    if (!same) throw SolveError("common subdivision: the flip log does not end on intrinsic face " + std::to_string(f));
  }
  // Compact the live crossings and list them per input edge.
  std::vector<int> new_id(X.size(), -1);
  std::vector<SubdivisionCrossing> kept;
  for (size_t c = 0; c < X.size(); ++c)
    if (alive[c]) new_id[c] = static_cast<int>(kept.size()), kept.push_back(X[c]);
  for (auto& list : out.segments)
    for (SubdivisionSegment& sg : list)
      for (SubdivisionEnd& e : sg.ends)
        if (e.crossing >= 0) {
          e.crossing = new_id[e.crossing];
          if (e.crossing < 0) throw SolveError("common subdivision: a segment ends on a removed crossing");
        }
  X = std::move(kept);
  for (int c = 0; c < static_cast<int>(X.size()); ++c) {
    const int h = conn.find_halfedge(X[c].A, X[c].B);
    if (h < 0) throw SolveError("common subdivision: a crossing names no input edge");
    out.crossings_of_edge[conn.edge(h)].push_back(c);
  }
  for (auto& list : out.crossings_of_edge)
    std::sort(list.begin(), list.end(), [&](int a, int b) { return X[a].t < X[b].t; });
  return out;
}

std::vector<SubdivisionPiece> subdivision_pieces(const SphericalSubdivision& sub, const RowMatrixX3i& intrinsic_faces,
                                                 const RowMatrixX3i& input_faces, int num_vertices) {
  const Connectivity conn(input_faces, num_vertices);
  const auto& X = sub.crossings;
  std::vector<SubdivisionPiece> out;
  for (int g = 0; g < intrinsic_faces.rows(); ++g) {
    const int corner[3] = {intrinsic_faces(g, 0), intrinsic_faces(g, 1), intrinsic_faces(g, 2)};
    const std::vector<SubdivisionSegment>& segs = sub.segments[g];
    if (segs.empty()) {  // inside one input face, with its corners: that face
      const int h = conn.find_halfedge(corner[0], corner[1]);
      if (h < 0 || conn.opposite_vertex(h) != corner[2])
        throw SolveError("common subdivision: intrinsic face " + std::to_string(g) +
                         " crosses no input edge but is no input face");
      SubdivisionPiece p;
      p.input_face = Connectivity::face(h), p.intrinsic_face = g;
      for (int c : corner) p.corners.push_back(SubdivisionEnd{c, -1});
      out.push_back(std::move(p));
      continue;
    }
    // The boundary cycle: corner, the crossings on its side in order, next corner ...
    std::vector<SubdivisionEnd> cycle;
    std::vector<std::pair<double, int>> on_side[3];
    std::vector<int> seen;
    for (const SubdivisionSegment& sg : segs)
      for (const SubdivisionEnd& e : sg.ends) {
        if (e.crossing < 0) continue;
        const SubdivisionCrossing& c = X[e.crossing];
        int side = -1;
        for (int k = 0; k < 3; ++k)
          if ((c.a == corner[k] && c.b == corner[(k + 1) % 3]) || (c.b == corner[k] && c.a == corner[(k + 1) % 3]))
            side = k;
        if (side < 0)
          throw SolveError("common subdivision: a crossing in intrinsic face " + std::to_string(g) + " is on none of its sides");
        const double from_corner = c.a == corner[side] ? c.wb / (c.wa + c.wb) : c.wa / (c.wa + c.wb);
        on_side[side].emplace_back(from_corner, e.crossing);
      }
    for (int k = 0; k < 3; ++k) {
      cycle.push_back(SubdivisionEnd{corner[k], -1});
      std::sort(on_side[k].begin(), on_side[k].end());
      for (const auto& [x, c] : on_side[k]) cycle.push_back(SubdivisionEnd{-1, c});
    }
    const int n = static_cast<int>(cycle.size());
    auto position = [&](const SubdivisionEnd& e) {
      for (int i = 0; i < n; ++i)
        if (e.vertex >= 0 ? cycle[i].vertex == e.vertex : cycle[i].crossing == e.crossing) return i;
      throw SolveError("common subdivision: a segment end is not on intrinsic face " + std::to_string(g) + "'s boundary");
    };
    // Chords (directed A -> B) cut the cycle; they do not cross.
    std::vector<std::array<int, 2>> chords;
    std::vector<std::array<int, 2>> chord_edge;  // (A, B)
    for (const SubdivisionSegment& sg : segs) {
      chords.push_back({position(sg.ends[0]), position(sg.ends[1])});
      chord_edge.push_back({sg.A, sg.B});
    }
    std::vector<std::vector<int>> polys{std::vector<int>(n)};
    for (int i = 0; i < n; ++i) polys[0][i] = i;
    for (const auto& ch : chords) {
      bool cut = false;
      for (size_t p = 0; p < polys.size() && !cut; ++p) {
        const std::vector<int>& poly = polys[p];
        const auto i = std::find(poly.begin(), poly.end(), ch[0]), j = std::find(poly.begin(), poly.end(), ch[1]);
        if (i == poly.end() || j == poly.end()) continue;
        const int a = static_cast<int>(i - poly.begin()), b = static_cast<int>(j - poly.begin()), m = static_cast<int>(poly.size());
        if ((a + 1) % m == b || (b + 1) % m == a) {  // already a side of this polygon
          cut = true;
          break;
        }
        std::vector<int> one, two;
        for (int x = a;; x = (x + 1) % m) {
          one.push_back(poly[x]);
          if (x == b) break;
        }
        for (int x = b;; x = (x + 1) % m) {
          two.push_back(poly[x]);
          if (x == a) break;
        }
        polys[p] = std::move(one);
        polys.push_back(std::move(two));
        cut = true;
      }
      if (!cut) throw SolveError("common subdivision: the input edges inside intrinsic face " + std::to_string(g) + " cross");
    }
    for (const std::vector<int>& poly : polys) {
      const int m = static_cast<int>(poly.size());
      int face = -1;
      for (int i = 0; i < m; ++i) {
        const int x = poly[i], y = poly[(i + 1) % m];
        for (size_t c = 0; c < chords.size(); ++c) {
          int h = -1;
          if (chords[c][0] == x && chords[c][1] == y) h = conn.find_halfedge(chord_edge[c][0], chord_edge[c][1]);
          if (chords[c][0] == y && chords[c][1] == x) h = conn.find_halfedge(chord_edge[c][1], chord_edge[c][0]);
          if (h < 0) continue;
          if (face >= 0 && face != Connectivity::face(h))
            throw SolveError("common subdivision: a piece of intrinsic face " + std::to_string(g) + " lies in two input faces");
          face = Connectivity::face(h);
        }
      }
      if (face < 0 || m < 3) throw SolveError("common subdivision: a piece of intrinsic face " + std::to_string(g) + " has no input face");
      SubdivisionPiece p;
      p.input_face = face, p.intrinsic_face = g;
      for (int i : poly) p.corners.push_back(cycle[i]);
      out.push_back(std::move(p));
    }
  }
  return out;
}

}  // namespace surfmap
