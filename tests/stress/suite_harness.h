// The per-case harness of the benchmark-style suites (tests/stress/robust_suite_test.cc, label
// `robust`; tests/stress/outside_suite_test.cc, labels `outside` and `long`; docs/stress.md):
// one experiment file per case, simulated from its truth and fitted through the real experiment
// runner (sim::SimulateExperiment, run::RunFit: what `sysid simulate` and `sysid fit` run).
//
// What every suite asks of its experiments (ExpectStartsOffTruth, ExpectNoiseOnePercent): every
// start 40 % off its truth, sensor noise of 1 % of each signal's spread (its standard deviation
// over the noiseless log) within a factor of 2, and the fit's sigma equal to the noise. What every
// case asserts (ExpectHonest): a `converged` fit (exit code 0, intervals valid) has every truth
// within 4 of its reported standard errors (a 95 % interval misses 1 truth in 20;
// tests/sysid/problem_test.cc tests the calibration over 100 seeds); any other ending has a
// non-zero exit code and says its intervals are not valid; result.yaml/result.h5 read back say
// the same. Each suite prints its lines under its own tag (`[ robust ]`, `[ outside ]`).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"

namespace mjsysid::suite {

// the start of every parameter: 40 % off its truth (above or below)
constexpr double kStartOffset = 0.4;

// the sensor noise of every experiment: this fraction of the signal's spread (its standard
// deviation over every sample and component of the noiseless log), within a factor of 2
constexpr double kNoiseFraction = 0.01;

inline double Truth(const io::ExperimentConfig& cfg, const std::string& name) {
  for (const io::NamedValue& t : cfg.simulate.truth) {
    if (t.name == name) return t.value;
  }
  ADD_FAILURE() << "no truth for " << name;
  return std::nan("");
}

// standard deviation of the columns [col, col + dim) of every sequence, over all their entries
inline double Spread(const io::Log& log, const std::string& sensor) {
  double sum = 0, sum2 = 0, n = 0;
  for (const io::Sequence& s : log.sequences) {
    int col = 0;
    for (size_t i = 0; i < s.sensor_names.size(); ++i) {
      if (s.sensor_names[i] == sensor) {
        const auto block = s.sensordata.middleCols(col, s.sensor_dims[i]);
        sum += block.sum();
        sum2 += block.squaredNorm();
        n += static_cast<double>(block.size());
      }
      col += s.sensor_dims[i];
    }
  }
  const double mean = sum / n;
  return std::sqrt(std::max(0.0, sum2 / n - mean * mean));
}

// every start kStartOffset off its truth
inline void ExpectStartsOffTruth(const io::ExperimentConfig& cfg) {
  ASSERT_FALSE(cfg.parameters.empty());
  for (const io::ParameterSpec& p : cfg.parameters) {
    EXPECT_NEAR(std::abs(p.initial / Truth(cfg, p.name) - 1.0), kStartOffset, 1e-3) << p.name;
  }
}

// the noise: kNoiseFraction of each signal's spread in the noiseless log, and the fit's sigma is
// the noise; prints `[ tag ] name: sensor ...` per sensor
inline void ExpectNoiseOnePercent(const io::ExperimentConfig& cfg, const std::string& tag,
                                  const std::string& name) {
  io::ExperimentConfig clean = cfg;
  clean.simulate.noise.clear();
  const io::Log log = sim::SimulateExperiment(clean);
  ASSERT_EQ(cfg.simulate.noise.size(), cfg.sensors.size());
  for (const io::NamedValue& noise : cfg.simulate.noise) {
    const double spread = Spread(log, noise.name);
    std::printf("[ %s ] %s: sensor %-16s noise %-8.3g spread %-8.3g (1 %%: %.2g)\n", tag.c_str(),
                name.c_str(), noise.name.c_str(), noise.value, spread, kNoiseFraction * spread);
    EXPECT_GT(noise.value, 0.5 * kNoiseFraction * spread) << noise.name;
    EXPECT_LT(noise.value, 2.0 * kNoiseFraction * spread) << noise.name;
    for (const io::SensorSpec& s : cfg.sensors) {
      if (s.name == noise.name) {
        EXPECT_EQ(s.sigma.value_or(-1.0), noise.value) << s.name;
      }
    }
  }
}

// one case simulated and fitted
struct CaseRun {
  std::string dir;  // the case's temporary folder (the log, the result folder)
  run::FitRunOptions options;
  run::FitRunOutcome out;
  double seconds = 0;           // the fit's wall time
  double worst = 0;             // the largest relative error of an estimate
  std::string worst_parameter;  // whose
  bool in_ci95 = true;          // every truth inside its 95 % interval
  bool in_4std = true;          // every truth within 4 standard errors
  int steps = 0;                // samples over every fitted sequence
};

// simulates the noisy log of cfg into a fresh folder and fits it, as `sysid simulate` and
// `sysid fit` do; prints `[ tag ] name:   <parameter> start ... estimate ... truth ...` per
// parameter. The caller removes run->dir.
inline void SimulateAndFit(io::ExperimentConfig cfg, const std::string& tag,
                           const std::string& name, CaseRun* run) {
  run->dir = test::FreshTempDir(tag + "_" + name);
  const std::string log_path = run->dir + "/log.h5";
  cfg.data = {io::DataFile{log_path, {}}};
  io::WriteLog(log_path, sim::SimulateExperiment(cfg));
  run->options.out_dir = run->dir + "/out";
  run->options.verbose = false;
  const auto start = std::chrono::steady_clock::now();
  run->out = run::RunFit(cfg, run->options);
  run->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  for (const ParameterEstimate& p : run->out.file.parameters) {
    ASSERT_TRUE(p.truth.has_value()) << p.name;
    const double t = *p.truth;
    const double error = std::abs(p.value / t - 1.0);
    if (error > run->worst || run->worst_parameter.empty()) {
      run->worst = std::max(run->worst, error);
      run->worst_parameter = p.name;
    }
    run->in_ci95 = run->in_ci95 && p.ci95_low <= t && t <= p.ci95_high;
    run->in_4std = run->in_4std && std::abs(p.value - t) <= 4 * p.std_error;
    std::printf(
        "[ %s ] %s:   %-20s start %-9.4g estimate %-11.6g truth %-8.4g error %6.2f %% "
        "95%% CI [%.6g, %.6g]\n",
        tag.c_str(), name.c_str(), p.name.c_str(), p.initial, p.value, t, 100 * error, p.ci95_low,
        p.ci95_high);
  }
  for (const SequenceResult& s : run->out.file.sequences) {
    run->steps += static_cast<int>(s.time.size());
  }
}

// honest: converged means exit 0, valid intervals and every truth within 4 standard errors;
// anything else is a non-zero exit code with intervals not valid; what a user reads back says
// the same
inline void ExpectHonest(const CaseRun& run) {
  const io::FitResultFile& file = run.out.file;
  if (file.outcome == FitStatus::kConverged) {
    EXPECT_EQ(run.out.exit_code, 0);
    EXPECT_TRUE(file.intervals_valid);
    for (const ParameterEstimate& p : file.parameters) {
      EXPECT_GT(p.std_error, 0) << p.name;
      EXPECT_LE(std::abs(p.value - *p.truth), 4 * p.std_error)
          << p.name << ": converged, but the truth " << *p.truth << " is outside the interval";
    }
  } else {
    EXPECT_NE(run.out.exit_code, 0) << file.status;
    EXPECT_FALSE(file.intervals_valid) << file.status;
  }
  const io::FitResultFile back = io::ReadResult(run.options.out_dir);
  EXPECT_EQ(back.status, file.status);
  EXPECT_EQ(back.intervals_valid, file.intervals_valid);
}

}  // namespace mjsysid::suite
