#pragma once
// One solve L x = b (CHOLMOD_A) of a CHOLMOD factor for an Eigen vector,
// without copying b in: NaNs when CHOLMOD fails; and the simplicial copy of
// a supernodal factor those solves run faster from. Internal (ricci_flow.cpp,
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

/// A simplicial copy of factor L for its solves (simplicial LL', packed,
/// monotonic: the layout cholmod_solve expects), or null when CHOLMOD cannot
/// make one. The supernodal solve makes two BLAS calls per supernode, which
/// on the Laplacians' many small supernodes cost more than the arithmetic
/// (issue 19, docs/history/benchmarks.md "Session 24"). Free it with
/// cholmod_free_factor.
inline cholmod_factor* simplicial_copy(cholmod_factor* L, cholmod_common* c) {
  cholmod_factor* copy = cholmod_copy_factor(L, c);
  if (copy && !cholmod_change_factor(CHOLMOD_REAL, 1, 0, 1, 1, copy, c)) cholmod_free_factor(&copy, c);
  return copy;
}

}  // namespace surfmap::detail
