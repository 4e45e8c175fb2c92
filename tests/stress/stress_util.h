// Shared helpers of the stress suite (tests/stress/*): models, excitation, synthetic data, error
// measures, and the long mode switch.
//
// Every stress test prints its measured numbers as lines starting with "[ stress ]" (the table
// in docs/stress.md is regenerated from them: ctest -L stress -V | grep '\[ stress \]').
// MJSYSID_STRESS_LONG=1 (ctest -L long) extends horizons, seeds and ranges.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/problem.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace stress {

inline const std::string kModels = MJSYSID_MODELS_DIR;

// true when MJSYSID_STRESS_LONG=1: the long mode (horizons to 10,000 steps, more seeds)
inline bool LongMode() {
  const char* v = std::getenv("MJSYSID_STRESS_LONG");
  return v && std::string(v) == "1";
}

using test::Estimate;
using test::Excitation;
using test::Measure;
using test::Spec;
using test::Truth;

// worst relative error of the estimates against the truth
inline double WorstRelativeError(const FitResult& r, const std::vector<Truth>& truth) {
  double worst = 0;
  for (const Truth& t : truth) {
    worst = std::max(worst, std::abs(Estimate(r, t.name).value / t.value - 1.0));
  }
  return worst;
}

inline bool AllFinite(const FitResult& r) {
  if (!std::isfinite(r.initial_cost) || !std::isfinite(r.final_cost)) return false;
  for (const auto& p : r.parameters) {
    if (!std::isfinite(p.value)) return false;
    if (std::isnan(p.std_error) || std::isnan(p.ci95_low) || std::isnan(p.ci95_high)) return false;
  }
  return true;
}

inline bool HasWarning(const FitResult& r, const std::string& text) {
  for (const auto& w : r.warnings) {
    if (w.find(text) != std::string::npos) return true;
  }
  return false;
}

inline void PrintFit(const char* label, const FitResult& r) {
  std::printf("[ stress ] %s: cost %.3e -> %.3e, %d iterations, %s, %.2f s, jacobian %s\n", label,
              r.initial_cost, r.final_cost, r.iterations,
              r.converged ? "converged" : "NOT converged", r.seconds,
              r.diagnostics.jacobian_mode.c_str());
  for (const auto& p : r.parameters) {
    std::printf("[ stress ]   %-10s %.9g (from %.4g) +- %.3g%s%s%s\n", p.name.c_str(), p.value,
                p.initial, p.std_error, p.identifiable ? "" : " UNIDENTIFIABLE",
                p.at_lower ? " AT-LOWER" : "", p.at_upper ? " AT-UPPER" : "");
  }
  for (const auto& w : r.warnings) std::printf("[ stress ]   warning: %s\n", w.c_str());
}

// error of J against the reference R, each column scaled by the reference's largest entry
inline double ColumnScaledError(const RowMatrix& J, const RowMatrix& R) {
  double worst = 0;
  for (Eigen::Index j = 0; j < R.cols(); ++j) {
    const double scale = std::max(R.col(j).lpNorm<Eigen::Infinity>(), 1e-300);
    worst = std::max(worst, (J.col(j) - R.col(j)).lpNorm<Eigen::Infinity>() / scale);
  }
  return worst;
}

}  // namespace stress
}  // namespace mjsysid
