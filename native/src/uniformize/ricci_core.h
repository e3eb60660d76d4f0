#pragma once
// Private core of the discrete Ricci flow, shared by ricci_flow.cpp and
// spherical.cpp. Works on a plain face/edge table so that it also handles a
// disk (the punctured sphere), which Connectivity (closed meshes only) cannot.
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/coarse_start.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap::detail {

constexpr double kPi = 3.14159265358979323846;

/// A number with 3 significant digits, for error messages.
inline std::string fmt(double x) {
  std::ostringstream s;
  s.precision(3);
  s << x;
  return s.str();
}

using RowMatrixX2i = Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>;

struct RicciDomain {
  int num_vertices = 0;
  RowMatrixX3i F;       ///< #F x 3
  RowMatrixX3i FE;      ///< #F x 3: edge of the side opposite corner k of face f
  RowMatrixX2i EV;      ///< #E x 2 edge endpoints
  /// #V: 2π at interior vertices, π at boundary vertices, so that
  /// K_i = full_angle_i − Σθ_i is the angle defect / geodesic curvature.
  Eigen::VectorXd full_angle;
};

RicciDomain domain_from_connectivity(const Connectivity& conn);
/// Any manifold oriented triangle list (boundary allowed).
RicciDomain domain_from_faces(int num_vertices, const RowMatrixX3i& F);

/// ricci_solve's check of u_start against u = 0 (uniformize/coarse_start.h
/// `ricci_flow_from_checked`): the overshoot allowed in, the account out.
struct StartCheck {
  double overshoot = 0.05;
  CheckedStart account;
};

/// fixed (optional, #V): vertices whose u stays at its start value
/// (Dirichlet); their curvature is excluded from the residual. check
/// (optional, with u_start, Newton, no fixed vertices): start from u_start
/// only when it beats u = 0 (see ricci_flow_from_checked).
RicciFlowResult ricci_solve(const RicciDomain& dom, const Eigen::VectorXd& lengths,
                            Background background, const RicciFlowOptions& options,
                            const Eigen::VectorXd& target, const Eigen::VectorXd* u_start,
                            const std::vector<char>* fixed = nullptr, StartCheck* check = nullptr);

RicciLinearization ricci_linearize(const RicciDomain& dom, const Eigen::VectorXd& lengths,
                                   Background background, RicciScheme scheme,
                                   const Eigen::VectorXd& u);

}  // namespace surfmap::detail
