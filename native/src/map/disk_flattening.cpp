#include "disk_flattening.h"

#include <algorithm>
#include <cmath>
#include <mutex>

#include <Eigen/CholmodSupport>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/Sparse>

#include "concurrency.h"
#include "surfmap/work_counters.h"

namespace surfmap::detail {

using Complex = std::complex<double>;

std::unordered_map<long long, DiskEdge> mean_value_disk_edges(const TriMesh& disk) {
  const int nd = disk.num_vertices(), nf = disk.num_faces();
  std::unordered_map<long long, DiskEdge> edges;
  edges.reserve(3 * static_cast<size_t>(nf));
  auto half_tan = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return a.cross(b).norm() / std::max(a.norm() * b.norm() + a.dot(b), 1e-300);
  };
  for (int f = 0; f < nf; ++f)
    for (int q = 0; q < 3; ++q) {
      const int i = disk.F(f, q), j = disk.F(f, (q + 1) % 3), o = disk.F(f, (q + 2) % 3);
      const Eigen::Vector3d pi = disk.V.row(i), pj = disk.V.row(j), po = disk.V.row(o);
      const double len = std::max((pj - pi).norm(), 1e-300);
      DiskEdge& de = edges[disk_edge_key(i, j, nd)];
      // tan(α/2) at both ends of the edge, over its length: Floater's
      // mean-value weight, summed over the edge's two faces (symmetric).
      de.w += (half_tan(pj - pi, po - pi) + half_tan(pi - pj, po - pj)) / len;
      if (de.faces < 2) de.opposite[de.faces] = o;
      ++de.faces;
    }
  return edges;
}

KleinTurns klein_turns(const std::vector<std::complex<double>>& kq) {
  const int ns = static_cast<int>(kq.size());
  KleinTurns t;
  for (int s = 0; s < ns; ++s) {
    const std::complex<double> e0 = kq[s] - kq[(s + ns - 1) % ns], e1 = kq[(s + 1) % ns] - kq[s];
    const double turn = std::arg(e1 / e0);
    t.total += turn;
    t.min = std::min(t.min, turn);
    t.max = std::max(t.max, turn);
  }
  return t;
}

bool flatten_in_klein(const std::vector<FlatteningEdge>& graph, const std::vector<char>& fixed, int hyperboloid_rounds,
                      std::vector<Complex>& k, std::string* why) {
  const int nn = static_cast<int>(k.size());
  std::vector<int> unknown(nn, -1);
  int nu = 0;
  for (int n = 0; n < nn; ++n)
    if (!fixed[n]) unknown[n] = nu++;
  if (nu == 0) return true;
  auto gamma = [&](int node) { return 1.0 / std::sqrt(std::max(1e-300, 1.0 - std::norm(k[node]))); };
  // Every round has the same sparsity pattern: one symbolic analysis.
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
  for (int round = 0; round <= hyperboloid_rounds; ++round) {
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(2 * graph.size() + nu);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nu, 2);
    std::vector<double> diag(nu, 0.0);
    for (const auto& [a, b, w0] : graph) {
      // Row i scaled by γ_i: symmetric.
      const double w = round == 0 ? w0 : w0 * gamma(a) * gamma(b);
      const int ua = unknown[a], ub = unknown[b];
      if (ua >= 0) diag[ua] += w;
      if (ub >= 0) diag[ub] += w;
      if (ua >= 0 && ub >= 0) {
        trip.emplace_back(ua, ub, -w), trip.emplace_back(ub, ua, -w);
      } else if (ua >= 0) {
        rhs(ua, 0) += w * k[b].real(), rhs(ua, 1) += w * k[b].imag();
      } else if (ub >= 0) {
        rhs(ub, 0) += w * k[a].real(), rhs(ub, 1) += w * k[a].imag();
      }
    }
    for (int u = 0; u < nu; ++u) trip.emplace_back(u, u, diag[u]);
    Eigen::SparseMatrix<double> L(nu, nu);
    L.setFromTriplets(trip.begin(), trip.end());
    if (round == 0) {
      std::lock_guard<std::mutex> lock(ordering_mutex());  // CHOLMOD may try METIS
      llt.analyzePattern(L);
      ++work::analyses;
    }
    llt.factorize(L);
    ++work::factorisations;

    if (llt.info() != Eigen::Success) {
      if (why) *why = "the flattening's Laplacian could not be factorised";
      return false;
    }
    const Eigen::MatrixXd X = llt.solve(rhs);
    for (int n = 0; n < nn; ++n)
      if (unknown[n] >= 0) k[n] = Complex(X(unknown[n], 0), X(unknown[n], 1));
  }
  return true;
}

DiskDevelopment develop_disk(const TriMesh& disk, const Connectivity& conn, const std::vector<char>& cut,
                             const DeckGroup& group, const std::function<Word(int, int)>& corner_word) {
  const int nd = disk.num_vertices(), nf = disk.num_faces();
  DiskDevelopment out;
  out.c.resize(nd);
  out.b.resize(nf);
  std::vector<char> has_c(nd, 0), seen(nf, 0);
  auto assign_corners = [&](int f) {
    for (int k = 0; k < 3; ++k) {
      const int d = disk.F(f, k);
      const Word p = corner_word(f, k);
      Word w = p.empty() ? out.b[f] : group.reduce(concat(out.b[f], p));  // b_f is reduced
      if (!has_c[d]) {
        out.c[d] = std::move(w), has_c[d] = 1;
      } else if (w != out.c[d]) {
        const hyperbolic::Mobius m1 = group.evaluate_side_word(w), m2 = group.evaluate_side_word(out.c[d]);
        const double size = std::max(m1.size(), m2.size());
        out.mismatch = std::max(out.mismatch, hyperbolic::mobius_distance(m1, m2) / (size * size));
      }
    }
  };
  if (nf == 0) return out;
  std::vector<int> queue{0};
  seen[0] = 1;
  assign_corners(0);
  for (size_t q = 0; q < queue.size(); ++q) {
    const int f = queue[q];
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k;
      if (cut[conn.edge(h)]) continue;
      const int t = conn.twin(h), g = Connectivity::face(t);
      if (seen[g]) continue;
      seen[g] = 1;
      const int kg = (t % 3 + 1) % 3;  // corner of g at tail(h)
      out.b[g] = group.reduce(concat(out.c[disk.F(f, k)], inverse(corner_word(g, kg))));
      assign_corners(g);
      queue.push_back(g);
    }
  }
  out.faces_reached = static_cast<int>(queue.size());
  return out;
}

std::string read_disk_vertices(const std::vector<int>& original_vertex, int inputs,
                               const std::vector<std::complex<double>>& k, const std::vector<Word>& c,
                               const hyperbolic::Mobius& chart,
                               const std::function<Word(std::complex<double>&)>& reduce_point,
                               const DeckGroup& group, const std::string& vertex_noun,
                               const std::string& disk_noun, std::vector<std::complex<double>>& z,
                               std::vector<hyperbolic::Mobius>& vertex_deck, std::vector<Word>& vertex_deck_word) {
  const int nd = static_cast<int>(original_vertex.size());
  std::vector<int> copy_of(inputs, -1);
  for (int d = 0; d < nd; ++d)  // copies of vertices added by a refinement (>= inputs) are not read
    if (const int o = original_vertex[d]; o < inputs && copy_of[o] < 0) copy_of[o] = d;
  const hyperbolic::Mobius unchart = chart.inverse();
  z.resize(inputs);
  vertex_deck.resize(inputs);
  vertex_deck_word.resize(inputs);
  for (int i = 0; i < inputs; ++i) {
    const int d = copy_of[i];
    if (d < 0) return vertex_noun + " " + std::to_string(i) + " is missing from " + disk_noun;
    std::complex<double> zi = unchart.apply(hyperbolic::klein_to_poincare(k[d]));
    if (!(std::isfinite(zi.real()) && std::isfinite(zi.imag()) && std::abs(zi) < 1 - 1e-12))
      return vertex_noun + " " + std::to_string(i) + " lands at the disk's boundary (no digits left)";
    Word w = c[d];
    if (reduce_point) w = group.reduce(concat(reduce_point(zi), w));
    z[i] = zi;
    vertex_deck[i] = group.evaluate_side_word(w);
    vertex_deck_word[i] = std::move(w);
  }
  return "";
}

}  // namespace surfmap::detail
