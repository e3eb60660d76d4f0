#include "surfmap/map/initial_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Geometry>

#include "surfmap/error.h"

namespace surfmap {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

HyperbolicInitialMapResult hyperbolic_initial_map(const Connectivity& sc, const std::vector<Mobius>& halfedge_rho,
                                                  const std::vector<Mobius>& generators,
                                                  const HyperbolicInitialMapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (static_cast<int>(halfedge_rho.size()) != 3 * sc.num_faces())
    throw InputError("hyperbolic_initial_map: one deck element per halfedge (3 x #F) needed");
  std::vector<WeightedEdge> edges(sc.num_edges());
  for (int e = 0; e < sc.num_edges(); ++e) {
    const int h = sc.edge_halfedge(e);
    edges[e].i = sc.tail(h);
    edges[e].j = sc.head(h);
    edges[e].w = 1.0;
    edges[e].rho = halfedge_rho[h];
  }
  HyperbolicHarmonicOptions ho;
  ho.tolerance = options.tolerance;
  ho.max_iterations = options.max_iterations;
  HyperbolicHarmonicResult hr =
      hyperbolic_harmonic_map(sc.num_vertices(), edges, generators, std::vector<Complex>(sc.num_vertices(), Complex(0.0)), ho);
  HyperbolicInitialMapResult r;
  r.converged = hr.converged;
  r.iterations = hr.iterations;
  r.z = std::move(hr.z);
  r.vertex_deck = std::move(hr.vertex_deck);
  r.vertex_deck_word = std::move(hr.vertex_deck_word);
  r.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

DistortionStats hyperbolic_distortion(const TriMesh& source, const std::vector<Mobius>& halfedge_rho,
                                      const std::vector<Complex>& z, const std::vector<Mobius>& deck,
                                      Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>* image) {
  const int nf = source.num_faces();
  if (static_cast<int>(halfedge_rho.size()) != 3 * nf || static_cast<int>(z.size()) != source.num_vertices() ||
      deck.size() != z.size())
    throw InputError("hyperbolic_distortion: sizes of halfedge_rho (3 x #F), z and vertex_deck (#V) do not match the mesh");
  auto eff = [&](int h) {
    const int f = h / 3, k = h % 3;
    return (deck[source.F(f, k)] * halfedge_rho[h] * deck[source.F(f, (k + 1) % 3)].inverse()).normalized();
  };
  Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor> img(nf, 3);
  DistortionStats out;
  out.per_face.assign(nf, std::numeric_limits<double>::infinity());
  double weighted = 0, total_area = 0;
  for (int f = 0; f < nf; ++f) {
    img(f, 0) = z[source.F(f, 0)];
    img(f, 1) = eff(3 * f).apply(z[source.F(f, 1)]);
    img(f, 2) = eff(3 * f + 2).inverse().apply(z[source.F(f, 2)]);
    // Möbius maps preserve orientation: test it in the chart centring corner 0.
    const Mobius T = Mobius::centring(img(f, 0));
    const Complex b = T.apply(img(f, 1)), c = T.apply(img(f, 2));
    const double cross = b.real() * c.imag() - b.imag() * c.real();
    if (!(std::abs(cross) > 1e-14 * std::max(std::norm(b), std::norm(c)))) {
      ++out.degenerate;
      continue;
    }
    if (cross < 0) {
      ++out.flipped;
      continue;
    }
    const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                          p2 = source.V.row(source.F(f, 2));
    const Eigen::Vector3d ss((p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm());
    const Eigen::Vector3d is(hyperbolic::distance(img(f, 0), img(f, 1)), hyperbolic::distance(img(f, 1), img(f, 2)),
                             hyperbolic::distance(img(f, 2), img(f, 0)));
    const double d = triangle_dilatation(ss, is);
    out.per_face[f] = d;
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    weighted += area * d;
    total_area += area;
    out.max = std::max(out.max, d);
  }
  out.mean = total_area > 0 ? weighted / total_area : std::numeric_limits<double>::infinity();
  if (image) *image = std::move(img);
  return out;
}

}  // namespace surfmap
