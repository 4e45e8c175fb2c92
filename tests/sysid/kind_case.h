// Helpers of the kinds' synthetic recovery tests (tests/sysid/kinds_*recovery_test.cc): one
// kind's recovery case (model, truth, start, bounds, excitation, noise) fitted noise-free or from
// noisy data, and the checks every case makes.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/problem.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"

namespace mjsysid::test {

inline const std::string& KindModels() {
  static const std::string dir = MJSYSID_MODELS_DIR;
  return dir;
}

// prints a fit's cost, status and every estimate with its interval
inline void Print(const FitResult& r) {
  std::printf("[ measured ] cost %.3e -> %.3e in %d iterations (%s), %.2f s, jacobian %s\n",
              r.initial_cost, r.final_cost, r.iterations,
              r.converged ? "converged" : "NOT converged", r.seconds,
              r.diagnostics.jacobian_mode.c_str());
  for (const auto& p : r.parameters) {
    std::printf("[ measured ]   %-10s %.9g (from %.4g) +- %.3g [%.6g, %.6g]\n", p.name.c_str(),
                p.value, p.initial, p.std_error, p.ci95_low, p.ci95_high);
  }
}

// a press force of three sines (1.1, 5 and 9 Hz, 2 N each; below the pressed sphere's 9.81 N
// weight, models/sphere_press*.xml)
inline RowMatrix PressForce(const mjModel& m, int T) {
  RowMatrix u(T, 1);
  for (int k = 0; k < T; ++k) {
    const double t = k * m.opt.timestep;
    u(k, 0) = 2 * std::sin(2 * M_PI * 1.1 * t) + 2 * std::sin(2 * M_PI * 5 * t + 1) +
              2 * std::sin(2 * M_PI * 9 * t + 2);
  }
  return u;
}

// One kind's recovery case: a model, its true values, the start and bounds of each (log transform
// where the lower bound is positive), the excitation (test::Excitation's amplitude and offset, or
// controls when set), and the noise (per sensor) of the noisy variant.
struct KindCase {
  std::string model;
  std::vector<Truth> truth;
  std::vector<double> start, lower, upper;
  double amplitude = 1, offset = 0;
  std::function<RowMatrix(const mjModel&, int T, int seed)> controls;  // replaces Excitation
  std::vector<std::pair<std::string, double>> sigma;                   // sensor name, noise level
  int steps = 1500;
};

// adds the case's parameters to problem: start, bounds, log transform where the lower bound is
// positive
inline void AddCaseParameters(const KindCase& c, Problem* problem) {
  for (size_t i = 0; i < c.truth.size(); ++i) {
    FitParameter p(c.truth[i].name, c.truth[i].spec, c.start[i]);
    p.Bounds(c.lower[i], c.upper[i]);
    if (c.lower[i] > 0) p.Log();
    problem->AddParameter(p);
  }
}

// fits the case from one sequence (seed), noise-free or with its noise (weighted by it)
inline FitResult FitCase(const KindCase& c, bool noisy, int seed, bool print = true) {
  ModelPtr m = LoadModel(KindModels() + "/" + c.model);
  Problem problem;
  problem.AddModel("m", *m);
  AddCaseParameters(c, &problem);
  const RowMatrix u = c.controls ? c.controls(*m, c.steps, seed)
                                 : Excitation(*m, c.steps, c.amplitude, seed, c.offset);
  InitialState x0;
  RowMatrix y = Measure(*m, c.truth, x0, u, 0, 0);
  FitOptions opt;
  if (noisy) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> n(0, 1);
    for (const auto& [sensor, sigma] : c.sigma) {
      const int id = mj_name2id(m.get(), mjOBJ_SENSOR, sensor.c_str());
      for (int col = m->sensor_adr[id]; col < m->sensor_adr[id] + m->sensor_dim[id]; ++col) {
        for (int k = 0; k < y.rows(); ++k) y(k, col) += sigma * n(rng);
      }
      opt.sensor_weights[sensor] = 1 / sigma;
      opt.sensors_with_sigma.push_back(sensor);
    }
  }
  problem.AddSequence(FitSequence("seq0", "m", x0, u, y));
  const FitResult r = problem.Fit(opt);
  if (print) Print(r);
  return r;
}

// noise-free: every value within relative 1e-6 of the truth
inline void ExpectNoiseFreeRecovery(const KindCase& c) {
  const FitResult r = FitCase(c, false, 50);
  EXPECT_TRUE(r.converged) << TerminationText(r.termination);
  for (const Truth& t : c.truth) {
    EXPECT_NEAR(Estimate(r, t.name).value / t.value, 1.0, 1e-6) << t.name;
  }
}

// noisy: status converged (intervals valid), residual variance that of the noise, and the truth
// inside every 95% interval
inline void ExpectNoisyRecovery(const KindCase& c, int seed = 51) {
  const FitResult r = FitCase(c, true, seed);
  EXPECT_EQ(r.outcome, FitStatus::kConverged)
      << FitStatusName(r.outcome) << ": " << TerminationText(r.termination);
  EXPECT_TRUE(r.intervals_valid);
  EXPECT_NEAR(r.uncertainty.residual_variance, 1.0, 0.15);
  for (const Truth& t : c.truth) {
    const ParameterEstimate& e = Estimate(r, t.name);
    EXPECT_GT(e.std_error, 0) << t.name;
    EXPECT_LE(e.ci95_low, t.value) << t.name;
    EXPECT_GE(e.ci95_high, t.value) << t.name;
  }
}

// Calibration of the noisy intervals over `seeds` noisy fits (seeds first, first + 1, ...): every
// fit converged, the 95% intervals of all parameters together cover the truth in at least
// pooled_min of the cases, and each parameter's in at least each_min fits. The thresholds sit
// below the binomial spread of a calibrated 95% interval (tests state theirs); the measured
// coverage is printed.
inline void ExpectCalibratedIntervals(const KindCase& c, int first, int seeds, double pooled_min,
                                      int each_min) {
  std::vector<int> covered(c.truth.size(), 0);
  int converged = 0;
  for (int s = first; s < first + seeds; ++s) {
    const FitResult r = FitCase(c, true, s, false);
    converged += r.outcome == FitStatus::kConverged && r.intervals_valid;
    for (size_t i = 0; i < c.truth.size(); ++i) {
      const ParameterEstimate& e = Estimate(r, c.truth[i].name);
      covered[i] += e.ci95_low <= c.truth[i].value && c.truth[i].value <= e.ci95_high;
    }
  }
  EXPECT_EQ(converged, seeds);
  int pooled = 0;
  for (size_t i = 0; i < c.truth.size(); ++i) {
    std::printf("[ measured ] %-12s truth inside its 95%% interval in %d of %d noisy fits\n",
                c.truth[i].name.c_str(), covered[i], seeds);
    EXPECT_GE(covered[i], each_min) << c.truth[i].name;
    pooled += covered[i];
  }
  const double fraction = static_cast<double>(pooled) / (seeds * c.truth.size());
  std::printf("[ measured ] pooled coverage %.3f (%d of %d)\n", fraction, pooled,
              static_cast<int>(seeds * c.truth.size()));
  EXPECT_GE(fraction, pooled_min);
}

}  // namespace mjsysid::test
