#include "hyperbolic_quality.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

namespace surfmap::detail {

using hyperbolic::Mobius;

MapInPolygon place_in_polygon(const TriMesh& source, const Connectivity& sc, const FundamentalPolygon& polygon,
                              const DeckGroup& group, const std::vector<Word>& side_word_edge,
                              const std::vector<Mobius>& rho_edge, const SolverEdgeIndex& index, int num_solver_edges,
                              HyperbolicHarmonicResult& hr) {
  const DeckGroup& deck_group = group;
  MapInPolygon out;
  // Every vertex in P, with its chart change as a side word (the solve's
  // moves were side pairings too).
  // (A solver that keeps no deck words, the relaxation, falls back to the
  // products of its deck matrices, and to local charts built from points.)
  const int nv = source.num_vertices();
  const bool have_words = static_cast<int>(hr.vertex_deck_word.size()) == nv;
  std::vector<Complex>& zp = out.zp;
  zp = hr.z;
  std::vector<Word> deck(nv);
  std::vector<Mobius> deck_matrix(nv);
  for (int i = 0; i < nv; ++i) {
    const Word into_P = polygon.reduce(zp[i]);
    if (have_words)
      deck[i] = deck_group.reduce(concat(into_P, hr.vertex_deck_word[i]));
    else
      deck_matrix[i] = (deck_group.evaluate_side_word(into_P) * hr.vertex_deck[i]).normalized();
  }
  // Effective element of every source edge after the chart moves, as a
  // reduced side word (short: the tile next to P holding the edge's far end).
  std::vector<Mobius>& eff_edge = out.eff_edge;
  eff_edge.resize(side_word_edge.size());
  for (size_t e = 0; e < side_word_edge.size(); ++e) {
    const int h = sc.edge_halfedge(static_cast<int>(e));
    eff_edge[e] = have_words ? deck_group.evaluate_side_word(deck_group.reduce(
                                   concat({deck[sc.tail(h)], side_word_edge[e], inverse(deck[sc.head(h)])})))
                             : (deck_matrix[sc.tail(h)] * rho_edge[e] * deck_matrix[sc.head(h)].inverse()).normalized();
  }
  if (static_cast<int>(hr.edge_local.size()) != num_solver_edges) {
    hr.edge_local.resize(num_solver_edges);
    for (int e = 0; e < sc.num_edges(); ++e) {
      const int h = sc.edge_halfedge(e);
      const Mobius A = (Mobius::centring(zp[sc.tail(h)]) * eff_edge[e] * Mobius::translation_to(zp[sc.head(h)])).normalized();
      hr.edge_local[index.solver_edge[e]] = index.forward[e] ? A : A.inverse();
    }
  }
  auto eff = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? eff_edge[e] : eff_edge[e].inverse();
  };
  // Image triangles: corners in the Poincaré disk, anchored at corner 0.
  ImageCorners& img = out.image;
  img.resize(source.num_faces(), 3);
  for (int f = 0; f < source.num_faces(); ++f) {
    img(f, 0) = zp[source.F(f, 0)];
    img(f, 1) = eff(3 * f).apply(zp[source.F(f, 1)]);
    img(f, 2) = eff(3 * f + 2).inverse().apply(zp[source.F(f, 2)]);
  }
  return out;
}

namespace {

// Source halfedge h's element in the solve's charts of its ends (edge_local):
// its head's chart -> its tail's.
Mobius source_side(const Connectivity& sc, const std::vector<Mobius>& edge_local, const SolverEdgeIndex& index, int h) {
  const int e = sc.edge(h);
  const Mobius& A = edge_local[index.solver_edge[e]];
  return (sc.edge_halfedge(e) == h) == static_cast<bool>(index.forward[e]) ? A : A.inverse();
}

// The elements of intrinsic triangle f's sides in the solve's charts,
// oriented along it (side[k]: corner k + 1's chart -> corner k's); false
// when idt does not record its faces' orientation.
bool intrinsic_sides(const IntrinsicDelaunayResult& idt, const std::vector<Mobius>& edge_local, int f, Mobius side[3]) {
  bool known = true;
  for (int k = 0; k < 3; ++k) {
    const int e = idt.face_edges(f, k);
    if (idt.face_edge_forward.rows() != idt.F.rows()) known = false;  // orientation not recorded
    else if (idt.face_edge_forward(f, k)) side[k] = edge_local[e];
    else side[k] = edge_local[e].inverse();
  }
  return known;
}

// Corner k's chart of a triangle whose side j is side(j) (corner j + 1's
// chart -> corner j's): corner k at 0, corner k + 1 through side k, corner
// k + 2 through side k + 2 inverted; returns those two corners.
template <class Side>
std::pair<Complex, Complex> corner_chart(const Side& side, int k) {
  return {side(k).apply(Complex(0.0)), side((k + 2) % 3).inverse().apply(Complex(0.0))};
}

// How far the product of a triangle's three side elements is from ±identity.
double closure_gap(const Mobius& s0, const Mobius& s1, const Mobius& s2) {
  return hyperbolic::distance_from_identity((s0 * s1 * s2).normalized());
}

}  // namespace

DistortionStats chart_distortion(const TriMesh& source, const Connectivity& sc, const std::vector<Mobius>& edge_local,
                                 const SolverEdgeIndex& index) {
  auto local = [&](int h) { return source_side(sc, edge_local, index, h); };
  auto corners = [&](int f, int k) { return corner_chart([&](int j) { return local(3 * f + j); }, k); };
  // Dilatation from hyperbolic side lengths and orientation, both in the
  // chart of corner 0 where the corners are 0, A_01(0) and A_20^-1(0):
  // exact to round-off however close to |z| = 1 the triangle lies in P.
  return hyperbolic_image_distortion(
      source,
      [&](int f) { return corners(f, 0); },
      [&](int f) {
        return Eigen::Vector3d(local(3 * f).displacement_of_origin(), local(3 * f + 1).displacement_of_origin(),
                               local(3 * f + 2).displacement_of_origin());
      },
      true,
      // Corner k's chart (long thin images are read from their widest corner).
      corners);
}

ImageCover image_cover(const TriMesh&, const Connectivity& sc, const std::vector<Mobius>& edge_local,
                       const SolverEdgeIndex& index) {
  ImageCover out;
  const int nf = sc.num_faces(), nv = sc.num_vertices();
  const int chi = nv - sc.num_edges() + nf;
  if (chi >= 0 || index.solver_edge.size() != static_cast<size_t>(sc.num_edges())) return out;
  std::vector<double> angle_sum(nv, 0.0);
  double area = 0;
  for (int f = 0; f < nf; ++f) {
    double angles = 0;
    for (int k = 0; k < 3; ++k) {
      // Corner k's angle, signed, in its own chart (corners k + 1 and k + 2
      // as in chart_distortion): resolved however long the sides.
      const auto [b, c] = corner_chart([&](int j) { return source_side(sc, edge_local, index, 3 * f + j); }, k);
      const double angle = std::arg(c / b);
      angle_sum[sc.tail(3 * f + k)] += angle;
      angles += angle;
    }
    // A positive triangle's area is pi minus its angles; a flipped one's
    // angles are all negative, its signed area -(pi - their sizes).
    area += (angles < 0 ? -M_PI : M_PI) - angles;
  }
  out.triangles = nf;
  out.area_ratio = area / (-2 * M_PI * chi);
  for (int v = 0; v < nv; ++v) {
    const double gap = std::abs(angle_sum[v] - 2 * M_PI);
    if (!(gap <= 1e-6)) ++out.vertices_off;
    if (!(gap <= out.worst_angle_gap)) out.worst_angle_gap = gap;
  }
  return out;
}

int intrinsic_flipped_triangles(const IntrinsicDelaunayResult& idt, const std::vector<Mobius>& edge_local) {
  // The intrinsic Delaunay triangles (the energy's own triangulation): their
  // images from the solver's local charts, oriented by the face's corners.
  int flipped = 0;
  if (edge_local.size() >= idt.edges.size()) {
    for (int f = 0; f < static_cast<int>(idt.F.rows()); ++f) {
      Mobius side[3];
      if (!intrinsic_sides(idt, edge_local, f, side)) continue;
      auto sides = [&](int j) { return side[j]; };
      auto [p1, p2] = corner_chart(sides, 0);
      if (image_orientation(p1, p2) != 1) {
        // Not clearly positive from corner 0: read from the widest corner,
        // as chart_distortion does (a long thin image's far corners lie
        // within round-off of each other seen from its sharp ends).
        const int k = widest_corner(Eigen::Vector3d(side[0].displacement_of_origin(), side[1].displacement_of_origin(),
                                                    side[2].displacement_of_origin()));
        std::tie(p1, p2) = corner_chart(sides, k);
      }
      if (p1.real() * p2.imag() - p1.imag() * p2.real() <= 0) ++flipped;
    }
  }
  return flipped;
}

LayoutClosure intrinsic_layout_closure(const IntrinsicDelaunayResult& idt, const std::vector<Mobius>& edge_local) {
  const int nf = static_cast<int>(idt.F.rows());
  if (edge_local.size() < idt.edges.size() || idt.face_edge_forward.rows() != nf) return {};
  return layout_closure(nf, [&](int f) {
    Mobius side[3];
    intrinsic_sides(idt, edge_local, f, side);
    return closure_gap(side[0], side[1], side[2]);
  });
}

LayoutClosure source_layout_closure(const Connectivity& sc, const std::vector<Mobius>& edge_local,
                                    const SolverEdgeIndex& index) {
  return layout_closure(sc.num_faces(), [&](int f) {
    return closure_gap(source_side(sc, edge_local, index, 3 * f), source_side(sc, edge_local, index, 3 * f + 1),
                       source_side(sc, edge_local, index, 3 * f + 2));
  });
}

}  // namespace surfmap::detail
