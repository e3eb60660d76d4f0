// The common subdivision of the input faces and the genus-0 intrinsic
// triangulation (uniformize/spherical_subdivision.h).
#include "surfmap/uniformize/spherical_subdivision.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>

#include <Eigen/Dense>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap {
namespace {

// The vector of slot m in the basis of the old triangle (k, s, t): the
// exact linear relation v_m = μ_k v_k + μ_s v_s + μ_t v_t between the
// quad's corner vectors. Ptolemy flips: null vectors with Gram entries
// −x²/2 (the quad spans a 3-space: Ptolemy's relation is det G = 0), so
// −λ_km² = μ_s (−λ_ks²) + μ_t (−λ_tk²) and so on;
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
  // Closed form of the 3 x 3 Gram solve (Ptolemy: λ_km λ_st = λ_ks λ_mt +
  // λ_tk λ_sm): products and quotients of lengths keep their relative
  // precision where the flow's lengths span many orders of magnitude (a
  // linear solve lost it, and the error grew with every flip after).
  const auto& L = fl.lengths;
  const double ks = L[0], sm = L[1], mt = L[2], tk = L[3], st = L[4], km = L[5];
  return Eigen::Vector3d(-sm * mt / (ks * tk), mt * km / (ks * st), sm * km / (tk * st));
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
      if (X[c].c >= 0) X[c].wc *= std::exp(-g[X[c].c]);
    }
    G += g;
  };
  // A point of a piece in the flip's quad chart: a corner (its slot), a
  // crossing on a side (the slots of its a and b), or a bend.
  struct ChartPoint {
    Eigen::Vector3d h;
    double t = 0;
    int vertex = -1, crossing = -1;
    int slot = -1;               // corner
    int slot_a = -1, slot_b = -1;  // crossing on a side
    bool bend = false;
  };
  size_t frame = 0;
  const auto& frames = s.frame_log;
  const auto& flips = s.flip_log;
  for (int j = 0; j <= static_cast<int>(flips.size()); ++j) {
    for (; frame < frames.size() && frames[frame].time <= j; ++frame) apply_frame(frames[frame].log_scale);
    if (j == static_cast<int>(flips.size())) break;
    const SphereFlip& fl = flips[j];
    const int f0 = fl.face0, f1 = fl.face1;
    const std::string at = " of flip " + std::to_string(j);
    if (f0 < 0 || f1 < 0 || f0 >= nf || f1 >= nf || f0 == f1)
      throw SolveError("common subdivision: flip " + std::to_string(j) + " names wrong faces");
    const std::array<int, 4>& q = fl.quad;
    // The faces' rows must hold the flip's old triangles (up to rotation);
    // slot_at[p]: the quad slot of row position p. Slots, not vertex ids,
    // place every point: a Δ-complex quad can hold a vertex twice.
    auto row_slots = [&](int f, const std::array<int, 3>& slots) {
      std::array<int, 3> slot_at{-1, -1, -1};
      int found = 0;
      for (int r = 0; r < 3; ++r) {
        bool same = true;
        for (int c = 0; c < 3; ++c) same = same && rows(f, (c + r) % 3) == q[slots[c]];
        if (same && found++ == 0)
          for (int c = 0; c < 3; ++c) slot_at[(c + r) % 3] = slots[c];
      }
      if (found == 0) throw SolveError("common subdivision: flip " + std::to_string(j) + " does not match the faces before it");
      if (found > 1 && (q[slots[0]] != q[slots[1]] || q[slots[1]] != q[slots[2]]))
        throw SolveError("common subdivision: flip " + std::to_string(j) + " has an ambiguous face");
      return slot_at;
    };
    const std::array<int, 3> slots0 = row_slots(f0, fl.before0), slots1 = row_slots(f1, fl.before1);
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
    // σ(h) = det(e_k, μ, h): zero on k–m, the sign of s on the new face (k, s, m).
    auto sigma = [&](const Eigen::Vector3d& h) { return mu[1] * h[2] - mu[2] * h[1]; };
    const double sigma_s = sigma(basis(1)), sigma_t = sigma(basis(3));
    // A bend on k–m (a flip back to the edge it bent on) is a crossing again.
    // Only that edge can hold it: the same two corners as the exact flip's
    // new edge that made it, and σ zero to round-off, i.e. relative to its
    // two products, not to |μ| |h|: in a thin quad (μ_s, μ_t ~ 1e-7 against
    // μ_k ~ 2, the jittered 42-vertex bent sphere's flip 502) every point has
    // σ below 1e-12 |μ| |h|, and that rule put five bends inside the quad
    // onto k–m (|σ| was 11-90% of its two terms; bends truly back on their
    // edge leave at most 9.3e-9 of them on the bent spheres measured, bends
    // of the same two corners not on it at least 76%: the bound 1e-5 sits
    // far from both; docs/uniformization.md "The map on the common subdivision").
    auto on_new_edge = [&](const ChartPoint& p) {
      const std::array<int, 4>& made_on = flips[X[p.crossing].flip].quad;
      if (!((made_on[0] == q[0] && made_on[2] == q[2]) || (made_on[0] == q[2] && made_on[2] == q[0]))) return false;
      const double terms = std::abs(mu[1] * p.h[2]) + std::abs(mu[2] * p.h[1]);
      return std::abs(sigma(p.h)) <= 1e-5 * terms;
    };
    auto on_k_m = [&](const Eigen::Vector3d& h) {  // h = wk e_k + wm μ
      const double n2 = mu[1] * mu[1] + mu[2] * mu[2];
      const double wm = (mu[1] * h[1] + mu[2] * h[2]) / n2;
      return std::pair<double, double>(h[0] - wm * mu[0], wm);
    };
    if (!(sigma_s * sigma_t < 0))
      throw SolveError("common subdivision: flip " + std::to_string(j) + " has a quad that is not convex in its chart");
    // A segment of face f (row slots sl) as chart points, in order of t.
    auto chart_points = [&](const SubdivisionSegment& sg, const std::array<int, 3>& sl) {
      std::vector<ChartPoint> pts;
      auto end_point = [&](const SubdivisionEnd& e) {
        ChartPoint p;
        if (e.vertex >= 0) {
          p.vertex = e.vertex;
          p.slot = sl[e.corner];
          p.h = std::exp(-G[e.vertex]) * basis(p.slot);  // the input frame's v, now
          p.t = e.vertex == sg.A ? 0.0 : 1.0;
          return p;
        }
        const SubdivisionCrossing& c = X[e.crossing];
        p.crossing = e.crossing;
        p.slot_a = sl[e.reversed ? (e.corner + 1) % 3 : e.corner];
        p.slot_b = sl[e.reversed ? e.corner : (e.corner + 1) % 3];
        p.h = c.wa * basis(p.slot_a) + c.wb * basis(p.slot_b);
        p.t = c.t;
        return p;
      };
      pts.push_back(end_point(sg.ends[0]));
      for (int b : sg.bends) {
        const SubdivisionCrossing& c = X[b];
        ChartPoint p;
        p.crossing = b, p.bend = true, p.t = c.t;
        p.h = c.wa * basis(sl[0]) + c.wb * basis(sl[1]) + c.wc * basis(sl[2]);
        pts.push_back(p);
      }
      pts.push_back(end_point(sg.ends[1]));
      return pts;
    };
    auto on_diagonal = [](const ChartPoint& p) {
      return p.crossing >= 0 && !p.bend && std::min(p.slot_a, p.slot_b) == 1 && std::max(p.slot_a, p.slot_b) == 3;
    };
    struct Polyline {
      int A = -1, B = -1;
      std::vector<ChartPoint> pts;
    };
    std::vector<Polyline> merged;
    // An input edge that was the diagonal itself now runs from corner s to
    // corner t across the quad.
    if (const int e = whole_edge(q[1], q[3], f0, f1); e >= 0) {
      whole[e] = 0;
      Polyline d;
      d.A = std::min(q[1], q[3]), d.B = std::max(q[1], q[3]);
      for (int slot : {d.A == q[1] ? 1 : 3, d.A == q[1] ? 3 : 1}) {
        ChartPoint p;
        p.vertex = q[slot], p.slot = slot, p.t = slot == (d.A == q[1] ? 1 : 3) ? 0.0 : 1.0;
        p.h = std::exp(-G[p.vertex]) * basis(slot);
        d.pts.push_back(p);
      }
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
    const std::array<int, 3> new_slots_s = face0_has_s ? fl.after0 : fl.after1;
    const std::array<int, 3> new_slots_t = face0_has_s ? fl.after1 : fl.after0;
    const bool ks = on_face(0, 1, f0), sm = on_face(1, 2, f1), mt = on_face(2, 3, f1), tk = on_face(3, 0, f0);
    if (ks) move_side(0, 1, f0, fs);
    if (sm) move_side(1, 2, f1, fs);
    if (mt) move_side(2, 3, f1, ft);
    if (tk) move_side(3, 0, f0, ft);
    // Merge the two old faces' pieces of each input edge across s–t. Where
    // the crossing was made by an exact flip and this flip is a Ptolemy one,
    // the pieces are straight in different pictures: it stays as a bend.
    std::vector<Polyline> open;  // pieces of the two old faces, joined below
    for (int f : {f0, f1})
      for (const SubdivisionSegment& sg : out.segments[f]) {
        Polyline pl;
        pl.A = sg.A, pl.B = sg.B;
        pl.pts = chart_points(sg, f == f0 ? slots0 : slots1);
        open.push_back(std::move(pl));
      }
    // Join pieces (in order of t) that meet on s–t; a piece with a bend can
    // leave and re-enter its face through s–t, so chains can be longer.
    for (bool joined = true; joined;) {
      joined = false;
      for (size_t i = 0; i < open.size() && !joined; ++i) {
        if (!on_diagonal(open[i].pts.back())) continue;
        const int c = open[i].pts.back().crossing;
        for (size_t k = 0; k < open.size() && !joined; ++k) {
          if (k == i || !on_diagonal(open[k].pts.front()) || open[k].pts.front().crossing != c) continue;
          Polyline& first = open[i];
          const Polyline& second = open[k];
          // Straight after all (three rays in one plane: e.g. a cocircular
          // quad of the start, where both pictures agree): no bend.
          const Eigen::Vector3d &hp = first.pts[first.pts.size() - 2].h, &hc = first.pts.back().h, &hn = second.pts[1].h;
          const bool straight = std::abs(hp.dot(hc.cross(hn))) <= 1e-15 * hp.norm() * hc.norm() * hn.norm();
          if (!fl.exact && flips[X[c].flip].exact && !straight) {
            first.pts.back().bend = true;  // the same ray, now inside the quad
          } else {
            first.pts.pop_back();
            alive[c] = 0;
          }
          first.pts.insert(first.pts.end(), second.pts.begin() + 1, second.pts.end());
          open.erase(open.begin() + static_cast<long>(k));
          joined = true;
        }
      }
    }
    for (Polyline& pl : open) {
      if (on_diagonal(pl.pts.front()) || on_diagonal(pl.pts.back()))
        throw SolveError("common subdivision: an input edge crosses the flipped edge" + at + " on one side only");
      merged.push_back(std::move(pl));
    }
    out.segments[f0].clear();
    out.segments[f1].clear();
    // Which new face a point belongs to: 0 = (k, s, m), 1 = (m, t, k), 2 =
    // on k–m (corner k or m, or a crossing made on it by this flip).
    auto side = [&](const ChartPoint& p) {
      if (p.vertex >= 0) return p.slot == 1 ? 0 : p.slot == 3 ? 1 : 2;
      if (!p.bend) {
        if (p.slot_a == 0 && p.slot_b == 2) return 2;
        const int lo = std::min(p.slot_a, p.slot_b), hi = std::max(p.slot_a, p.slot_b);
        return (lo == 0 && hi == 1) || (lo == 1 && hi == 2) ? 0 : 1;
      }
      if (on_new_edge(p)) return 2;
      return sigma(p.h) * sigma_s >= 0 ? 0 : 1;
    };
    // A piece of a polyline inside one new face, as a segment of its rows.
    auto store = [&](const Polyline& pl, const std::vector<ChartPoint>& pts) {
      int face_side = -1;
      for (const ChartPoint& p : pts)
        if (side(p) != 2) {
          face_side = side(p);
          break;
        }
      if (face_side < 0) {
        if (pts.size() == 2 && pts[0].vertex >= 0 && pts[1].vertex >= 0) {  // the input edge k–m is now the diagonal itself
          const int e = conn.edge(conn.find_halfedge(pl.A, pl.B));
          whole[e] = 1;
          whole_faces[e] = {f0, f1};
          return;
        }
        throw SolveError("common subdivision: a piece of an input edge runs along the new edge" + at);
      }
      const int f = face_side == 0 ? fs : ft;
      const std::array<int, 3>& sl = face_side == 0 ? new_slots_s : new_slots_t;
      auto position = [&](int slot) {
        for (int p = 0; p < 3; ++p)
          if (sl[p] == slot) return p;
        throw SolveError("common subdivision: a point" + at + " is not on its new face");
      };
      auto end_of = [&](const ChartPoint& p) {
        SubdivisionEnd e;
        if (p.vertex >= 0) {
          e.vertex = p.vertex, e.corner = position(p.slot);
          return e;
        }
        e.crossing = p.crossing;
        const int pa = position(p.slot_a), pb = position(p.slot_b);
        if (pb == (pa + 1) % 3) e.corner = pa, e.reversed = false;
        else if (pa == (pb + 1) % 3) e.corner = pb, e.reversed = true;
        else throw SolveError("common subdivision: a crossing" + at + " is not on a side of its new face");
        return e;
      };
      SubdivisionSegment sg;
      sg.A = pl.A, sg.B = pl.B;
      sg.ends[0] = end_of(pts.front());
      sg.ends[1] = end_of(pts.back());
      if (pts.front().bend || pts.back().bend) throw SolveError("common subdivision: a piece" + at + " ends on a bend");
      if (pts.size() > 2) {
        Eigen::Matrix3d M;
        for (int p = 0; p < 3; ++p) M.col(p) = basis(sl[p]);
        const Eigen::FullPivLU<Eigen::Matrix3d> lu(M);
        for (size_t i = 1; i + 1 < pts.size(); ++i) {
          const ChartPoint& p = pts[i];
          if (!p.bend) throw SolveError("common subdivision: a crossing" + at + " lies inside a piece");
          const Eigen::Vector3d w = lu.solve(p.h);
          if (!w.allFinite()) throw SolveError("common subdivision: a bend" + at + " has no weights");
          SubdivisionCrossing& c = X[p.crossing];
          c.a = q[sl[0]], c.b = q[sl[1]], c.c = q[sl[2]];
          c.wa = std::max(w[0], 0.0), c.wb = std::max(w[1], 0.0), c.wc = std::max(w[2], 0.0);
          if (!(c.wa + c.wb + c.wc > 0)) throw SolveError("common subdivision: a bend" + at + " has no weight");
          sg.bends.push_back(p.crossing);
        }
      }
      out.segments[f].push_back(std::move(sg));
    };
    for (const Polyline& pl : merged) {
      // Split where a straight part crosses k–m (from one new face to the other).
      std::vector<ChartPoint> cur{pl.pts[0]};
      for (size_t i = 1; i < pl.pts.size(); ++i) {
        const ChartPoint &P = pl.pts[i - 1], &Q = pl.pts[i];
        const int a = side(P), b = side(Q);
        if (a != 2 && b != 2 && a != b) {
          const double sp = sigma(P.h), sq = sigma(Q.h);
          double lambda = sp / (sp - sq);
          if (!std::isfinite(lambda)) lambda = 0.5;
          lambda = std::clamp(lambda, 0.0, 1.0);
          const Eigen::Vector3d h = (1 - lambda) * P.h + lambda * Q.h;
          const auto [wk, wm] = on_k_m(h);
          SubdivisionCrossing c;
          c.A = pl.A, c.B = pl.B;
          c.t = (1 - lambda) * P.t + lambda * Q.t;
          c.a = q[0], c.b = q[2];
          c.flip = j;
          c.wa = std::max(wk, 0.0), c.wb = std::max(wm, 0.0);
          if (!(c.wa + c.wb > 0) || !std::isfinite(c.wa + c.wb))
            throw SolveError("common subdivision: flip " + std::to_string(j) + " gives a crossing without weight");
          X.push_back(c);
          alive.push_back(1);
          ChartPoint x;
          x.h = h, x.t = c.t, x.crossing = static_cast<int>(X.size()) - 1, x.slot_a = 0, x.slot_b = 2;
          cur.push_back(x);
          store(pl, cur);
          cur = {x};
        }
        if (Q.bend && b == 2) {  // now a crossing of k–m (it keeps the flip that made it)
          SubdivisionCrossing& c = X[Q.crossing];
          const auto [wk, wm] = on_k_m(Q.h);
          c.a = q[0], c.b = q[2], c.c = -1;
          c.wa = std::max(wk, 0.0), c.wb = std::max(wm, 0.0), c.wc = 0;
          if (!(c.wa + c.wb > 0)) throw SolveError("common subdivision: a bend on the new edge" + at + " has no weight");
          ChartPoint x = Q;
          x.bend = false, x.slot_a = 0, x.slot_b = 2;
          cur.push_back(x);
          store(pl, cur);
          cur = {x};
          continue;
        }
        cur.push_back(Q);
      }
      store(pl, cur);
    }
    for (int c = 0; c < 3; ++c) rows(f0, c) = q[fl.after0[c]], rows(f1, c) = q[fl.after1[c]];
    ++out.flips_replayed;
  }
  // The faces must now be intrinsic_faces (rows up to rotation); positions
  // in the rows follow the rotation.
  for (int f = 0; f < nf; ++f) {
    int rot = -1;
    for (int r = 0; r < 3 && rot < 0; ++r)
      if (rows(f, r) == s.intrinsic_faces(f, 0) && rows(f, (r + 1) % 3) == s.intrinsic_faces(f, 1) &&
          rows(f, (r + 2) % 3) == s.intrinsic_faces(f, 2))
        rot = r;
    if (rot < 0) throw SolveError("common subdivision: the flip log does not end on intrinsic face " + std::to_string(f));
    if (rot == 0) continue;
    for (SubdivisionSegment& sg : out.segments[f]) {
      for (SubdivisionEnd& e : sg.ends) e.corner = (e.corner - rot + 3) % 3;
      for (int b : sg.bends) {
        SubdivisionCrossing& c = X[b];
        const double w[3] = {c.wa, c.wb, c.wc};
        c.a = s.intrinsic_faces(f, 0), c.b = s.intrinsic_faces(f, 1), c.c = s.intrinsic_faces(f, 2);
        c.wa = w[rot], c.wb = w[(rot + 1) % 3], c.wc = w[(rot + 2) % 3];
      }
    }
  }
  // Compact the live crossings and list them per input edge.
  std::vector<int> new_id(X.size(), -1);
  std::vector<SubdivisionCrossing> kept;
  for (size_t c = 0; c < X.size(); ++c)
    if (alive[c]) new_id[c] = static_cast<int>(kept.size()), kept.push_back(X[c]);
  auto renumber = [&](int& c) {
    c = new_id[c];
    if (c < 0) throw SolveError("common subdivision: a segment ends on a removed crossing");
  };
  for (auto& list : out.segments)
    for (SubdivisionSegment& sg : list) {
      for (SubdivisionEnd& e : sg.ends)
        if (e.crossing >= 0) renumber(e.crossing);
      for (int& b : sg.bends) renumber(b);
    }
  X = std::move(kept);
  out.bends = 0;
  for (int c = 0; c < static_cast<int>(X.size()); ++c) {
    const int h = conn.find_halfedge(X[c].A, X[c].B);
    if (h < 0) throw SolveError("common subdivision: a crossing names no input edge");
    out.crossings_of_edge[conn.edge(h)].push_back(c);
    out.bends += X[c].bend();
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
    const std::string in_face = " in intrinsic face " + std::to_string(g);
    if (segs.empty()) {  // inside one input face, with its corners: that face
      const int h = conn.find_halfedge(corner[0], corner[1]);
      if (h < 0 || conn.opposite_vertex(h) != corner[2])
        throw SolveError("common subdivision: intrinsic face " + std::to_string(g) +
                         " crosses no input edge but is no input face");
      SubdivisionPiece p;
      p.input_face = Connectivity::face(h), p.intrinsic_face = g;
      for (int k = 0; k < 3; ++k) p.corners.push_back(SubdivisionEnd{corner[k], -1, k, false});
      out.push_back(std::move(p));
      continue;
    }
    // The boundary cycle: corner, the crossings on its side in order, next
    // corner ... (points 0..n-1); the bends inside are points n, n+1, ...
    std::vector<SubdivisionEnd> cycle;
    std::vector<std::pair<double, SubdivisionEnd>> on_side[3];
    for (const SubdivisionSegment& sg : segs)
      for (const SubdivisionEnd& e : sg.ends) {
        if (e.crossing < 0) continue;
        if (e.corner < 0 || e.corner > 2) throw SolveError("common subdivision: a crossing" + in_face + " has no side");
        const SubdivisionCrossing& c = X[e.crossing];
        const double from_corner = e.reversed ? c.wa / (c.wa + c.wb) : c.wb / (c.wa + c.wb);
        on_side[e.corner].emplace_back(from_corner, e);
      }
    for (int k = 0; k < 3; ++k) {
      cycle.push_back(SubdivisionEnd{corner[k], -1, k, false});
      std::sort(on_side[k].begin(), on_side[k].end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
      for (const auto& [x, e] : on_side[k]) cycle.push_back(e);
    }
    const int n = static_cast<int>(cycle.size());
    std::vector<SubdivisionEnd> point = cycle;
    auto position = [&](const SubdivisionEnd& e) {
      for (int i = 0; i < n; ++i)
        if (e.vertex >= 0 ? cycle[i].vertex == e.vertex && cycle[i].corner == e.corner : cycle[i].crossing == e.crossing)
          return i;
      throw SolveError("common subdivision: a segment end is not on intrinsic face " + std::to_string(g) + "'s boundary");
    };
    // Chords (A -> B, through their bends) cut the cycle; they do not cross.
    // Each directed step of a chord names the input face on its left.
    std::vector<std::vector<int>> chords;
    std::map<std::pair<int, int>, int> face_left;
    for (const SubdivisionSegment& sg : segs) {
      std::vector<int> ch{position(sg.ends[0])};
      for (int b : sg.bends) {
        ch.push_back(static_cast<int>(point.size()));
        point.push_back(SubdivisionEnd{-1, b, -1, false});
      }
      ch.push_back(position(sg.ends[1]));
      const int hab = conn.find_halfedge(sg.A, sg.B), hba = conn.find_halfedge(sg.B, sg.A);
      if (hab < 0 || hba < 0) throw SolveError("common subdivision: a segment" + in_face + " names no input edge");
      for (size_t i = 0; i + 1 < ch.size(); ++i) {
        face_left[{ch[i], ch[i + 1]}] = Connectivity::face(hab);
        face_left[{ch[i + 1], ch[i]}] = Connectivity::face(hba);
      }
      chords.push_back(std::move(ch));
    }
    std::vector<std::vector<int>> polys{std::vector<int>(n)};
    for (int i = 0; i < n; ++i) polys[0][i] = i;
    for (const std::vector<int>& ch : chords) {
      bool cut = false;
      const int from = ch.front(), to = ch.back();
      for (size_t p = 0; p < polys.size() && !cut; ++p) {
        const std::vector<int>& poly = polys[p];
        const auto i = std::find(poly.begin(), poly.end(), from), j = std::find(poly.begin(), poly.end(), to);
        if (i == poly.end() || j == poly.end()) continue;
        const int a = static_cast<int>(i - poly.begin()), b = static_cast<int>(j - poly.begin()), m = static_cast<int>(poly.size());
        if (ch.size() == 2 && ((a + 1) % m == b || (b + 1) % m == a)) {  // already a side of this polygon
          cut = true;
          break;
        }
        // one: a .. b along the polygon, back to a through the bends;
        // two: b .. a, then to b through the bends.
        std::vector<int> one, two;
        for (int x = a;; x = (x + 1) % m) {
          one.push_back(poly[x]);
          if (x == b) break;
        }
        for (size_t k = ch.size() - 2; k >= 1; --k) one.push_back(ch[k]);
        for (int x = b;; x = (x + 1) % m) {
          two.push_back(poly[x]);
          if (x == a) break;
        }
        for (size_t k = 1; k + 1 < ch.size(); ++k) two.push_back(ch[k]);
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
        const auto it = face_left.find({poly[i], poly[(i + 1) % m]});
        if (it == face_left.end()) continue;
        if (face >= 0 && face != it->second)
          throw SolveError("common subdivision: a piece of intrinsic face " + std::to_string(g) + " lies in two input faces");
        face = it->second;
      }
      if (face < 0 || m < 3) throw SolveError("common subdivision: a piece of intrinsic face " + std::to_string(g) + " has no input face");
      SubdivisionPiece p;
      p.input_face = face, p.intrinsic_face = g;
      for (int i : poly) p.corners.push_back(point[i]);
      out.push_back(std::move(p));
    }
  }
  return out;
}

}  // namespace surfmap
