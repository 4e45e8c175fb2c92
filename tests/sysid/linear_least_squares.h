// A linear least-squares problem for the statistical stop's tests (sysid/solve/gn_convergence.h),
// where the Gauss-Newton step is exact: y = J x* + noise, truth x*_i = 1 + i, J m x n Gaussian
// (seed 7), noise sigma 0.1 (seed 11); the least-squares solution xhat and its standard errors
// sqrt(s^2 (J'J)^-1_ii), s^2 = |J xhat - y|^2 / (m - n).
#pragma once

#include <Eigen/Core>
#include <Eigen/QR>
#include <random>
#include <vector>

#include "core/state.h"
#include "sysid/assess/estimate_jacobian.h"
#include "sysid/solve/gn_convergence.h"
#include "sysid/solve/row_triangle.h"

namespace mjsysid::test {

struct LinearLeastSquares {
  RowMatrix J;
  Eigen::VectorXd y, xhat, se;

  LinearLeastSquares(int m, int n) : J(m, n), y(m) {
    std::mt19937 rng(7);
    std::normal_distribution<double> unit(0.0, 1.0);
    Eigen::VectorXd truth(n);
    for (int i = 0; i < n; ++i) truth[i] = 1.0 + i;
    for (int k = 0; k < m; ++k) {
      for (int i = 0; i < n; ++i) J(k, i) = unit(rng);
    }
    std::mt19937 noise_rng(11);
    std::normal_distribution<double> noise(0.0, 0.1);
    y = J * truth;
    for (int k = 0; k < m; ++k) y[k] += noise(noise_rng);
    xhat = J.colPivHouseholderQr().solve(y);
    const double s2 = (J * xhat - y).squaredNorm() / (m - n);
    se = (s2 * (J.transpose() * J).inverse()).diagonal().cwiseSqrt();
  }

  // the triangle of [J, J x - y] at x (EvaluateTriangle's form)
  EstimateTriangle At(const Eigen::VectorXd& x) const {
    const Eigen::VectorXd r = J * x - y;
    RowTriangle tri(static_cast<int>(J.cols()) + 1);
    tri.Add(J, r);
    EstimateTriangle t;
    t.r_aug = tri.R();
    t.rows = J.rows();
    t.cost = 0.5 * r.squaredNorm();
    t.n = static_cast<int>(J.cols());
    return t;
  }
  // every variable free (no bounds) at x
  std::vector<ColumnBounds> Free(const Eigen::VectorXd& x) const {
    std::vector<ColumnBounds> b(x.size());
    for (int i = 0; i < x.size(); ++i) b[i].value = x[i];
    return b;
  }
};

}  // namespace mjsysid::test
