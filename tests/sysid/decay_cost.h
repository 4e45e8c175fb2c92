// The compressed blocks' unit-test cost (tests of sysid/solve/compressed_cost.h: fold reuse, folds
// ahead): a real nonlinear residual r_i = x0[0] exp(-x0[1] t_i) + x1[0] t_i - y_i, t_i = i / m,
// m = kDecayRows = 2500 rows (more than RowTriangle::kChunkRows), blocks of sizes 2 and 1, its
// data y from a = 2, b = 3, c = 0.5 with Gaussian noise sigma 0.01 (DecayData(seed)); and one
// evaluation's output (n + 1 = 4 residuals, the blocks' Jacobians row-major) compared bit for bit.
#pragma once

#include <ceres/ceres.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace mjsysid::test {

constexpr int kDecayRows = 2500;

// the residual above for Ceres' automatic derivatives
struct Decay {
  std::vector<double> y;
  template <typename T>
  bool operator()(const T* x0, const T* x1, T* r) const {
    for (int i = 0; i < kDecayRows; ++i) {
      const double t = static_cast<double>(i) / kDecayRows;
      r[i] = x0[0] * exp(-x0[1] * t) + x1[0] * t - y[i];
    }
    return true;
  }
};

// y_i = 2 exp(-3 t_i) + 0.5 t_i + noise (sigma 0.01, seed)
inline std::vector<double> DecayData(int seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<double> y;
  for (int i = 0; i < kDecayRows; ++i) {
    const double t = static_cast<double>(i) / kDecayRows;
    y.push_back(2.0 * std::exp(-3.0 * t) + 0.5 * t + noise(rng));
  }
  return y;
}

// a new automatic-derivative cost of the decay with data y (ownership to the caller)
inline ceres::CostFunction* NewDecayCost(std::vector<double> y) {
  return new ceres::AutoDiffCostFunction<Decay, ceres::DYNAMIC, 2, 1>(new Decay{std::move(y)},
                                                                      kDecayRows);
}

// one evaluation's output of a compressed decay block: n + 1 residuals, the blocks' Jacobians
struct DecayOut {
  std::vector<double> r = std::vector<double>(4), j0 = std::vector<double>(8),
                      j1 = std::vector<double>(4);
  bool Eval(const ceres::CostFunction& cost, const double* x0, const double* x1) {
    const double* p[2] = {x0, x1};
    double* jac[2] = {j0.data(), j1.data()};
    return cost.Evaluate(p, r.data(), jac);
  }
  bool SameBits(const DecayOut& o) const {
    return std::memcmp(r.data(), o.r.data(), sizeof(double) * r.size()) == 0 &&
           std::memcmp(j0.data(), o.j0.data(), sizeof(double) * j0.size()) == 0 &&
           std::memcmp(j1.data(), o.j1.data(), sizeof(double) * j1.size()) == 0;
  }
};

}  // namespace mjsysid::test
