#pragma once
// One solve L x = b (CHOLMOD_A) of a CHOLMOD factor for an Eigen vector,
// without copying b in: NaNs when CHOLMOD fails. Internal (ricci_flow.cpp,
// hyperbolic_harmonic.cpp).
#include <algorithm>
#include <cstddef>
#include <limits>

#include <Eigen/Core>
#include <cholmod.h>

namespace surfmap::detail {

inline Eigen::VectorXd cholmod_vector_solve(cholmod_factor* L, const Eigen::VectorXd& b, cholmod_common* c) {
  cholmod_dense B;
  B.nrow = B.d = static_cast<size_t>(b.size());
  B.ncol = 1;
  B.nzmax = B.nrow;
  B.x = const_cast<double*>(b.data());
  B.z = nullptr;
  B.xtype = CHOLMOD_REAL;
  B.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* X = cholmod_solve(CHOLMOD_A, L, &B, c);
  Eigen::VectorXd x(b.size());
  if (!X) return x.setConstant(std::numeric_limits<double>::quiet_NaN());
  std::copy(static_cast<const double*>(X->x), static_cast<const double*>(X->x) + b.size(), x.data());
  cholmod_free_dense(&X, c);
  return x;
}

}  // namespace surfmap::detail
