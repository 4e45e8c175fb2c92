// Helpers shared by tests that build synthetic data (core, sysid and stress tests): parameter
// specs, multi-sine controls, and noisy sensor measurements from the true parameter values.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/parameters.h"
#include "core/simulator.h"

namespace mjsysid::test {

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

}  // namespace mjsysid::test
