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

namespace mjsysid {
namespace stress {

inline const std::string kModels = MJSYSID_MODELS_DIR;

// true when MJSYSID_STRESS_LONG=1: the long mode (horizons to 10,000 steps, more seeds)
inline bool LongMode() {
  const char* v = std::getenv("MJSYSID_STRESS_LONG");
  return v && std::string(v) == "1";
}

inline ParameterSpec Spec(const std::string& kind, const std::string& object, int index = 0) {
  ParameterSpec s;
  s.kind = kind;
  s.object = object;
  s.index = index;
  return s;
}

// multi-sine controls, different per actuator and per seed: offset + amplitude * mean of three
// sines at 0.4, 1.1, 2.3 Hz (scaled per actuator) with random phases
inline RowMatrix Excitation(const mjModel& m, int T, double amplitude, int seed,
                            double offset = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI);
  RowMatrix u(T, m.nu);
  const double freqs[3] = {0.4, 1.1, 2.3};
  for (int i = 0; i < m.nu; ++i) {
    double ph[3];
    for (double& p : ph) p = phase(rng);
    for (int k = 0; k < T; ++k) {
      double v = 0;
      for (int f = 0; f < 3; ++f) {
        v += std::sin(2 * M_PI * freqs[f] * (1 + 0.2 * i) * k * m.opt.timestep + ph[f]) / 3;
      }
      u(k, i) = offset + amplitude * v;
    }
  }
  return u;
}

struct Truth {
  std::string name;
  ParameterSpec spec;
  double value;
};

// sensors of m with the true parameter values, plus Gaussian noise sigma (all channels)
inline RowMatrix Measure(const mjModel& m, const std::vector<Truth>& truth, const InitialState& x0,
                         const RowMatrix& ctrl, double sigma, int seed) {
  std::vector<ParameterSpec> specs;
  Eigen::VectorXd values(truth.size());
  for (size_t i = 0; i < truth.size(); ++i) {
    specs.push_back(truth[i].spec);
    values[i] = truth[i].value;
  }
  Simulator sim(m, specs);
  if (!truth.empty()) sim.SetParameters(values);
  RowMatrix y = sim.Rollout(SequenceInput{x0, ctrl}).sensors;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, sigma);
  if (sigma > 0) {
    for (Eigen::Index i = 0; i < y.size(); ++i) y.data()[i] += noise(rng);
  }
  return y;
}

inline const ParameterEstimate& Estimate(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters) {
    if (p.name == name) return p;
  }
  throw std::runtime_error("no estimate " + name);
}

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
              r.converged ? "converged" : "NOT converged", r.seconds, r.jacobian_mode.c_str());
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
