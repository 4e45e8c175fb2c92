// The status of a fit (FitStatus, sysid/types.h): real fits of real models on data simulated from a
// stated truth, each stating truth, start, noise and what the status must be; the result file and
// exit code that carry it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/assess/metrics.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "sysid/problem.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"
#include "tools/report/report.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

const std::string kModels = MJSYSID_MODELS_DIR;

using test::Estimate;
using test::Excitation;
using test::Measure;
using test::Spec;
using test::Truth;

bool HasWarning(const FitResult& r, const std::string& text) {
  for (const auto& w : r.warnings) {
    if (w.find(text) != std::string::npos) return true;
  }
  return false;
}

void Print(const char* label, const FitResult& r) {
  std::printf(
      "[ measured ] %s: status %s, intervals %s, cost %.4e -> %.4e in %d iterations, chi2 ratio "
      "%.4g, %.2f s\n",
      label, FitStatusName(r.outcome), r.intervals_valid ? "valid" : "NOT valid", r.initial_cost,
      r.final_cost, r.iterations, r.chi2_ratio, r.seconds);
  for (const auto& [sensor, ratio] : r.sensor_chi2_ratio) {
    std::printf("[ measured ]   chi2 ratio of %s: %.4g\n", sensor.c_str(), ratio);
  }
  for (const auto& [sensor, ratio] : r.sensor_noise_ratio) {
    std::printf("[ measured ]   residual / estimated noise of %s: %.4g\n", sensor.c_str(), ratio);
  }
  for (const auto& p : r.parameters) {
    std::printf("[ measured ]   %-10s %.9g (from %.4g) +- %.3g\n", p.name.c_str(), p.value,
                p.initial, p.std_error);
  }
  for (const auto& w : r.warnings) std::printf("[ measured ]   warning: %s\n", w.c_str());
}

// the pendulum (sensors angle and rate) released at 0.3 rad under a 1.5 Nm multi-sine, 2000
// steps, Gaussian noise sigma 0.01 on every channel, with the fit told that sigma
struct PendulumData {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  InitialState x0;
  RowMatrix u, y;
  static constexpr double kSigma = 0.01;
  explicit PendulumData(const std::vector<Truth>& truth) {
    x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
    u = Excitation(*m, 2000, 1.5, 3);
    y = Measure(*m, truth, x0, u, kSigma, 7);
  }
  FitOptions Options() const {
    FitOptions opt;
    for (const char* s : {"angle", "rate"}) {
      opt.sensor_weights[s] = 1 / kSigma;
      opt.sensors_with_sigma.push_back(s);
    }
    return opt;
  }
  // the model and this sequence in `problem`, with the damping fitted from 0.4 (log transform,
  // bounds 1e-4 .. 10)
  void AddDampingFit(const ParameterSpec& damping, Problem* problem) const {
    problem->AddModel("pendulum", *m);
    problem->AddParameter(FitParameter("damping", damping, 0.4).Bounds(1e-4, 10).Log());
    problem->AddSequence(FitSequence("seq0", "pendulum", x0, u, y));
  }
};

// truth damping 0.2, friction loss 0.01 (the model's); start damping 0.4 (100 % off); noise 0.01
// and sigma 0.01: the model explains the data, so the status is converged with valid intervals,
// the weighted residual variance is 1 within 0.1 (its standard deviation is sqrt(2 / 4000) =
// 0.022), and the truth is inside 4 standard errors
TEST(FitStatusTest, RightModelWithSigmaIsConverged) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const PendulumData data({damping});
  Problem problem;
  data.AddDampingFit(damping.spec, &problem);
  const FitResult r = problem.Fit(data.Options());
  Print("right model", r);
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
  EXPECT_TRUE(r.intervals_valid);
  EXPECT_NEAR(r.chi2_ratio, 1.0, 0.1);
  const ParameterEstimate& e = Estimate(r, "damping");
  EXPECT_LE(std::abs(e.value - damping.value), 4 * e.std_error);
  EXPECT_EQ(run::ExitCodeOf(r.outcome), 0);
}

// data simulated with friction loss 0.3 (the model has 0.01) and damping 0.2; the fit has only
// damping (start 0.4), sigma 0.01 = the noise: no damping explains the friction, so the status
// is model_mismatch (exit 3), the intervals not valid, the warning names the sensors
TEST(FitStatusTest, MissingParameterWithSigmaIsModelMismatch) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const Truth friction{"friction", Spec("joint_frictionloss", "hinge"), 0.3};
  const PendulumData data({damping, friction});
  Problem problem;
  data.AddDampingFit(damping.spec, &problem);
  const FitResult r = problem.Fit(data.Options());
  Print("missing parameter", r);
  EXPECT_TRUE(r.converged) << "the optimiser converges: " << TerminationText(r.termination);
  EXPECT_EQ(r.outcome, FitStatus::kModelMismatch);
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_GT(r.chi2_ratio, 2.0);
  EXPECT_TRUE(HasWarning(r, "model mismatch")) << "no model-mismatch warning";
  EXPECT_EQ(run::ExitCodeOf(r.outcome), 3);

  // the same fit without sigmas (weights only): no chi-square test, but the noise test (residual
  // RMS vs the noise the log itself shows, sysid/assess/noise_estimate.h) sees the friction's
  // residual on the rate (measured 9.6 x its noise; the chi-square above says 99.9 = 10^2):
  // model_mismatch, exit 3, naming the rate. (It was converged, exit 0, before that test.)
  FitOptions weights_only = data.Options();
  weights_only.sensors_with_sigma.clear();
  const FitResult w = problem.Fit(weights_only);
  Print("missing parameter, weights only", w);
  EXPECT_EQ(w.outcome, FitStatus::kModelMismatch);
  EXPECT_TRUE(HasWarning(w, "noise estimated from the log itself")) << "no noise-test warning";
  EXPECT_TRUE(HasWarning(w, "rate 9.")) << "the rate named with its ratio";
  EXPECT_FALSE(w.intervals_valid);
  EXPECT_TRUE(std::isnan(w.chi2_ratio));
}

// The missing-friction fit above and the right model's fit (RightModelWithSigmaIsConverged) in
// multiple shooting, the global stage off. Right model: converged with valid intervals in 20-,
// 50- and 200-step segments (measured chi2 ratio 0.97-1.00), although its segments do not join
// by 1e-3 (largest gaps 0.0063, 0.0040, 0.0017 at noise 0.01): a gap is no evidence of another
// minimum. Missing friction in 50- and 200-step segments: model_mismatch (chi2 ratio 2.8, 9.1;
// gaps 0.085, 0.19). In 20-step segments the gaps (0.053) absorb the friction and the segmented
// fit converges at chi2 ratio 1.34; the estimate simulated in one piece does not explain the data,
// so the status is model_mismatch too (sysid/fit/policy.cc, CheckInOnePiece); the right model
// passes that check at every length.
TEST(FitStatusTest, SegmentsThatDoNotJoinAreNoEvidenceOfAnotherMinimum) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const Truth friction{"friction", Spec("joint_frictionloss", "hinge"), 0.3};
  const PendulumData right_data({damping});
  const PendulumData missing_data({damping, friction});
  Problem right, missing;
  right_data.AddDampingFit(damping.spec, &right);
  missing_data.AddDampingFit(damping.spec, &missing);
  for (const int steps : {20, 50, 200}) {
    FitOptions opt = right_data.Options();
    opt.segment_steps = steps;
    opt.global_stage = false;
    const std::string label = std::to_string(steps) + "-step segments";
    const FitResult r = right.Fit(opt);
    Print(("right model, " + label).c_str(), r);
    EXPECT_EQ(r.outcome, FitStatus::kConverged) << label;
    const ParameterEstimate& e = Estimate(r, "damping");
    EXPECT_LE(std::abs(e.value - damping.value), 4 * e.std_error) << label;
    EXPECT_FALSE(HasWarning(r, "model mismatch in one piece")) << label;
    // its gaps (above 1e-3) are said to be within the noise: the one-piece check passed
    EXPECT_TRUE(HasWarning(r, "the gaps are within what the noise explains")) << label;
    EXPECT_FALSE(HasWarning(r, "it describes no single trajectory")) << label;
    const FitResult w = missing.Fit(opt);
    Print(("missing parameter, " + label).c_str(), w);
    EXPECT_EQ(w.outcome, FitStatus::kModelMismatch) << label;
    EXPECT_FALSE(w.intervals_valid) << label;
    // 20 steps: converged in segments, model_mismatch in one piece (sysid/fit/policy.cc)
    EXPECT_EQ(HasWarning(w, "model mismatch in one piece"), steps == 20) << label;
    // the % fit of a fit in segments is the estimate simulated in one piece, the segments' beside
    // it (sysid/assess/metrics.h)
    for (const FitResult* f : {&r, &w}) {
      ASSERT_EQ(f->sequences.size(), 1u);
      const SequenceResult& sr = f->sequences[0];
      ASSERT_EQ(sr.simulated_one_piece.rows(), sr.measured.rows()) << label;
      for (const ChannelFit& c : ChannelFits(sr)) {
        std::printf("[ measured ]   %s, %s: %% fit %.2f in one piece, %.2f in segments\n",
                    f == &r ? "right model" : "missing parameter", c.channel.c_str(), c.fit_final,
                    c.fit_segments);
        EXPECT_TRUE(std::isfinite(c.fit_final) && std::isfinite(c.fit_segments)) << label;
        // measured: the right model's two within 0.15 points; without the friction the segments
        // read 3.9-14 points better than the one piece the identified model would give
        if (f == &r) {
          EXPECT_NEAR(c.fit_final, c.fit_segments, 0.5) << label;
        } else {
          EXPECT_GT(c.fit_segments - c.fit_final, 2.0) << label;
        }
      }
    }
  }
}

// sigma: auto (sysid/fit/sigma_from_log.h): the same pendulum data, each sensor's sigma estimated
// from the log at the fit's start. Right model: converged with valid intervals, the weighted
// residual variance 1 within 0.15 (the estimate's own 3-10 % error squared), the truth inside 4
// standard errors, the residual diagnostics marking both sigmas as the log's. Missing friction:
// model_mismatch, exit 3, as with the stated sigma: the status judges the model, not the guess
TEST(FitStatusTest, SigmaFromTheLogJudgesTheModel) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const Truth friction{"friction", Spec("joint_frictionloss", "hinge"), 0.3};
  FitOptions opt;
  opt.sensors_sigma_from_log = {"angle", "rate"};
  const PendulumData right_data({damping});
  Problem right;
  right_data.AddDampingFit(damping.spec, &right);
  const FitResult r = right.Fit(opt);
  Print("right model, sigma auto", r);
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
  EXPECT_TRUE(r.intervals_valid);
  EXPECT_NEAR(r.chi2_ratio, 1.0, 0.15);
  const ParameterEstimate& e = Estimate(r, "damping");
  EXPECT_LE(std::abs(e.value - damping.value), 4 * e.std_error);
  ASSERT_EQ(r.sigma_from_log.size(), 2u);
  for (const auto& [sensor, sigma] : r.sigma_from_log) {
    std::printf("[ measured ]   sigma of %s from the log: %.4g (noise 0.01)\n", sensor.c_str(),
                sigma);
    EXPECT_NEAR(sigma, PendulumData::kSigma, 0.1 * PendulumData::kSigma) << sensor;
  }
  ASSERT_EQ(r.residuals.size(), 2u);
  for (const ResidualDiagnostics& d : r.residuals) {
    EXPECT_TRUE(d.sigma_from_log) << d.channel;
    EXPECT_DOUBLE_EQ(d.sigma, r.sigma_from_log.at(d.channel)) << d.channel;
  }

  const PendulumData missing_data({damping, friction});
  Problem missing;
  missing_data.AddDampingFit(damping.spec, &missing);
  const FitResult w = missing.Fit(opt);
  Print("missing parameter, sigma auto", w);
  EXPECT_EQ(w.outcome, FitStatus::kModelMismatch);
  EXPECT_FALSE(w.intervals_valid);
  EXPECT_GT(w.chi2_ratio, 2.0);
  EXPECT_EQ(run::ExitCodeOf(w.outcome), 3);
}

// the noise test of a fit without sigmas: the right model, noise 0.01, no sigmas given
// (weights 1/0.01 only): converged, and the residual over the noise the log shows is about 1 for
// both sensors (sysid/assess/noise_estimate.h)
TEST(FitStatusTest, RightModelWithoutSigmasIsConvergedAtTheLogsNoise) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const PendulumData data({damping});
  Problem problem;
  data.AddDampingFit(damping.spec, &problem);
  FitOptions opt = data.Options();
  opt.sensors_with_sigma.clear();
  const FitResult r = problem.Fit(opt);
  Print("right model, no sigmas", r);
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
  ASSERT_EQ(r.sensor_noise_ratio.size(), 2u);
  for (const auto& [sensor, ratio] : r.sensor_noise_ratio) EXPECT_NEAR(ratio, 1.0, 0.2) << sensor;
}

// issue 32's case: the pendulum driven over the top (released at 0.3 rad with 10 rad/s, 4.5 Nm
// multi-sine seed 3, 3000 steps = 6 s), noise-free log with damping 0.35, fitted from 0.1 with no
// sigma given. Before the noise test it ended converged (exit 0) in another minimum; a fit that
// leaves the data unexplained must not be converged, sigmas or not: model_mismatch, exit 3,
// intervals not valid, the warning naming the sensors and the noise the log shows
TEST(FitStatusTest, UnexplainedDataWithoutSigmasIsNotConverged) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.35};
  InitialState x0;
  x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
  x0.qvel = Eigen::VectorXd::Constant(1, 10.0);
  const RowMatrix u = Excitation(*m, 3000, 4.5, 3);
  const RowMatrix y = Measure(*m, {damping}, x0, u, 0, 0);
  Problem problem;
  problem.AddModel("pendulum", *m);
  problem.AddParameter(FitParameter("damping", damping.spec, 0.1).Bounds(1e-4, 10).Log());
  problem.AddSequence(FitSequence("seq0", "pendulum", x0, u, y));
  FitOptions opt;
  opt.segment_steps = 0;     // single shooting: the fit
  opt.global_stage = false;  // the local fit's verdict
  const FitResult r = problem.Fit(opt);
  Print("over the top, no sigmas", r);
  const double err = std::abs(Estimate(r, "damping").value / 0.35 - 1);
  std::printf("[ measured ] over the top: relative error %.3g\n", err);
  ASSERT_GT(err, 0.05) << "the case: single shooting from 0.1 stops in another minimum";
  EXPECT_EQ(r.outcome, FitStatus::kModelMismatch);
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_TRUE(HasWarning(r, "noise estimated from the log itself"));
  EXPECT_EQ(run::ExitCodeOf(r.outcome), 3);
  // the global stage (sysid/fit/global_stage.h, the default) goes on from there and finds the
  // truth of the noise-free log (measured: relative error 2.3e-12), saying so
  opt.global_stage = true;
  const FitResult g = problem.Fit(opt);
  Print("over the top, no sigmas, global stage", g);
  EXPECT_LT(std::abs(Estimate(g, "damping").value / 0.35 - 1), 1e-6);
  EXPECT_TRUE(HasWarning(g, "global stage: the local fit ended model_mismatch"));
  EXPECT_LT(g.final_cost, 1e-6 * r.final_cost);
}

// the double pendulum at high energy (released at 2.5, -2.0 rad, 0 and 6 rad/s, 3 Nm multi-sine
// seed 5; chaotic), 3000 steps, truth link masses 1.0 and 0.8, start 1.2 and 0.6, noise-free,
// single shooting (tests/stress/horizon_stress_test.cc "high": measured, it does not recover):
// the fit must not be converged, its intervals not valid and the exit code not 0
TEST(FitStatusTest, ChaoticLongHorizonIsNotConverged) {
  Problem problem;
  test::AddHighEnergyDoublePendulum(3000, 0, 1.2, 0.6, &problem);
  FitOptions opt;
  opt.segment_steps = 0;  // single shooting (the default, auto, splits this horizon and recovers)
  opt.threads = 2;
  opt.max_iterations = 50;
  const FitResult r = problem.Fit(opt);
  Print("chaotic single shooting", r);
  const double err = std::max(std::abs(Estimate(r, "m1").value - 1.0),
                              std::abs(Estimate(r, "m2").value / 0.8 - 1.0));
  std::printf("[ measured ] chaotic: worst relative error %.3g\n", err);
  EXPECT_NE(r.outcome, FitStatus::kConverged);
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_NE(run::ExitCodeOf(r.outcome), 0);
}

// bench_multiple_shooting's chaotic case (tools/bench/ms_bench.cc): the double pendulum released
// at (2.0, -1.0) rad under a 0.5 Nm multi-sine, 5000 steps, truth link masses (1.0, 0.8), noise
// 1e-3 on every channel, weights 1/1e-3 but NO sigmas (no chi-square test), start (1.4, 0.5),
// single shooting. Measured: it stops ~44 % off the truth; before the fix it said `converged`.
// The status must not be converged, the intervals not valid, the exit code non-zero.
TEST(FitStatusTest, ChaoticSingleShootingWithoutSigmasIsNotConverged) {
  ModelPtr m = LoadModel(kModels + "/double_pendulum.xml");
  const int T = 5000;
  RowMatrix u(T, m->nu);
  const double freqs[3] = {0.4, 1.1, 2.3}, phase[3] = {0.3, 2.1, 4.4};
  for (int k = 0; k < T; ++k) {
    double v = 0;
    for (int f = 0; f < 3; ++f) v += std::sin(2 * M_PI * freqs[f] * k * m->opt.timestep + phase[f]);
    u(k, 0) = 0.5 * v / 3;
  }
  const std::vector<Truth> truth = {{"m1", Spec("body_mass", "link1"), 1.0},
                                    {"m2", Spec("body_mass", "link2"), 0.8}};
  InitialState x0;
  x0.qpos = Eigen::Vector2d(2.0, -1.0);
  x0.qvel = Eigen::Vector2d(0, 0);
  constexpr double kSigma = 1e-3;
  const RowMatrix y = Measure(*m, truth, x0, u, kSigma, 3);
  Problem problem;
  problem.AddModel("dp", *m);
  problem.AddParameter(FitParameter("m1", truth[0].spec, 1.4).Bounds(0.05, 20).Log());
  problem.AddParameter(FitParameter("m2", truth[1].spec, 0.5).Bounds(0.05, 20).Log());
  problem.AddSequence(FitSequence("seq0", "dp", x0, u, y));
  FitOptions opt;
  for (int i = 0; i < m->nsensor; ++i) {
    opt.sensor_weights[mj_id2name(m.get(), mjOBJ_SENSOR, i)] = 1.0 / kSigma;
  }
  opt.segment_steps = 0;  // single shooting (auto splits this horizon and recovers)
  opt.threads = 2;
  opt.max_iterations = 50;
  opt.global_stage = false;  // the local fit's verdict
  const FitResult r = problem.Fit(opt);
  Print("chaotic 5000 steps, single shooting, no sigmas", r);
  const double err = std::max(std::abs(Estimate(r, "m1").value - 1.0),
                              std::abs(Estimate(r, "m2").value / 0.8 - 1.0));
  std::printf("[ measured ] chaotic no sigmas: worst relative error %.3g\n", err);
  EXPECT_GT(err, 0.1);  // the case: single shooting does not recover
  // measured: jacobian_unreliable ("Jacobian unreliable at the estimate") while the directional
  // columns past h*|S| = 1e-2 were one nonlinear step; since they are split there
  // (core/simulator_internal.h) the solve runs into the iteration cap, 44 % off: not_converged
  EXPECT_EQ(r.outcome, FitStatus::kNotConverged);
  EXPECT_TRUE(HasWarning(r, "Jacobian not reliable in 1 of 1 segment(s)"));
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_NE(run::ExitCodeOf(r.outcome), 0);
  // the global stage goes on from there in the same single shooting and recovers (measured:
  // worst relative error 4.6e-7, converged); whatever its status, it is honest
  opt.global_stage = true;
  const FitResult g = problem.Fit(opt);
  Print("chaotic 5000 steps, single shooting, no sigmas, global stage", g);
  const double gerr = std::max(std::abs(Estimate(g, "m1").value - 1.0),
                               std::abs(Estimate(g, "m2").value / 0.8 - 1.0));
  EXPECT_LT(gerr, 1e-3);
  EXPECT_TRUE(HasWarning(g, "global stage: the local fit ended not_converged"));
  if (g.outcome == FitStatus::kConverged) {
    for (const ParameterEstimate& e : g.parameters) {
      EXPECT_LE(std::abs(e.value - (e.name == "m1" ? 1.0 : 0.8)), 4 * e.std_error) << e.name;
    }
  }
}

// truth mass 1.0, noise-free, a start on a bound is a warning. From 2.0 on the upper bound 2.0
// (log transform) the fit leaves it and recovers (relative 1e-6, converged). From 0.5 on the lower
// bound 0.5 (no transform) the gradient there points out of the bounds (measured: Ceres stops at
// iteration 0, "Gradient tolerance reached", projected gradient 0): the estimate is the start,
// so the status is did_not_move (exit 4) with intervals not valid, not converged
TEST(FitStatusTest, StartOnABoundIsAWarningAndAStuckStartDidNotMove) {
  ModelPtr m = LoadModel(kModels + "/spring_mass.xml");
  const RowMatrix u = Excitation(*m, 1000, 2.0, 1);
  InitialState x0;
  const RowMatrix y = Measure(*m, {{"mass", Spec("body_mass", "mass"), 1.0}}, x0, u, 0, 0);
  auto fit = [&](const FitParameter& p) {
    Problem problem;
    problem.AddModel("spring", *m);
    problem.AddParameter(p);
    problem.AddSequence(FitSequence("seq0", "spring", x0, u, y));
    return problem.Fit(FitOptions());
  };
  const FitResult up =
      fit(FitParameter("mass", Spec("body_mass", "mass"), 2.0).Bounds(0.01, 2.0).Log());
  Print("start on the upper bound", up);
  EXPECT_TRUE(HasWarning(up, "parameter 'mass' starts on its upper bound"));
  EXPECT_EQ(up.outcome, FitStatus::kConverged) << TerminationText(up.termination);
  EXPECT_NEAR(Estimate(up, "mass").value, 1.0, 1e-6);

  const FitResult low = fit(FitParameter("mass", Spec("body_mass", "mass"), 0.5).Bounds(0.5, 100));
  Print("start on the lower bound", low);
  std::printf("[ measured ] termination: %s\n", TerminationText(low.termination).c_str());
  EXPECT_TRUE(HasWarning(low, "parameter 'mass' starts on its lower bound"));
  EXPECT_EQ(Estimate(low, "mass").value, 0.5);
  EXPECT_EQ(low.outcome, FitStatus::kDidNotMove);
  EXPECT_FALSE(low.intervals_valid);
  EXPECT_TRUE(HasWarning(low, "did not move"));
  EXPECT_EQ(run::ExitCodeOf(low.outcome), 4);
}

// data with damping 0.2 and friction loss 0.3; the fit has both (starts 0.4 and 0.1) but the
// friction loss's upper bound is 0.2, below its truth: it stops on that bound, and the damping's
// interval, conditional on the friction loss fixed there, is not valid (the data pull the friction
// past the bound and the damping absorbs it: measured 0.307 +- 0.0007 for 0.2)
TEST(FitStatusTest, AParameterStoppedOnABoundInvalidatesTheIntervals) {
  const Truth damping{"damping", Spec("joint_damping", "hinge"), 0.2};
  const Truth friction{"friction", Spec("joint_frictionloss", "hinge"), 0.3};
  const PendulumData data({damping, friction});
  Problem problem;
  problem.AddModel("pendulum", *data.m);
  problem.AddParameter(FitParameter("damping", damping.spec, 0.4).Bounds(1e-4, 10).Log());
  problem.AddParameter(FitParameter("friction", friction.spec, 0.1).Bounds(1e-3, 0.2).Log());
  problem.AddSequence(FitSequence("seq0", "pendulum", data.x0, data.u, data.y));
  FitOptions weights_only = data.Options();
  weights_only.sensors_with_sigma.clear();  // no chi-square test: the bound rule alone
  const FitResult r = problem.Fit(weights_only);
  Print("friction stopped on its upper bound", r);
  EXPECT_TRUE(Estimate(r, "friction").at_upper);
  const ParameterEstimate& d = Estimate(r, "damping");
  EXPECT_GT(std::abs(d.value - damping.value), 4 * d.std_error) << "the case the rule is for";
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_TRUE(HasWarning(r, "conditional on friction fixed on a bound"));
}

// every status: its name reads back to it, its exit code (docs/cli.md), and result.yaml keeps it
// with the intervals flag
TEST(FitStatusTest, NamesExitCodesAndResultFile) {
  const std::vector<std::pair<FitStatus, int>> codes = {
      {FitStatus::kConverged, 0},     {FitStatus::kNotConverged, 1},
      {FitStatus::kModelMismatch, 3}, {FitStatus::kJacobianUnreliable, 4},
      {FitStatus::kDidNotMove, 4},    {FitStatus::kInterrupted, 1},
      {FitStatus::kSolverFailed, 4},  {FitStatus::kLocalMinimum, 1}};
  const fs::path dir = fs::temp_directory_path() / ("status_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  for (const auto& [status, code] : codes) {
    SCOPED_TRACE(FitStatusName(status));
    EXPECT_EQ(FitStatusFromName(FitStatusName(status)), status);
    EXPECT_EQ(run::ExitCodeOf(status), code);
    io::FitResultFile f;
    f.name = "status";
    f.outcome = status;
    f.status = FitStatusName(status);
    f.intervals_valid = status == FitStatus::kConverged;
    io::WriteResultH5((dir / "result.h5").string(), f);
    io::WriteResultYaml((dir / "result.yaml").string(), f);
    const io::FitResultFile back =
        io::ReadResultFiles((dir / "result.yaml").string(), (dir / "result.h5").string());
    EXPECT_EQ(back.outcome, status);
    EXPECT_EQ(back.intervals_valid, status == FitStatus::kConverged);
    EXPECT_EQ(back.converged, status == FitStatus::kConverged);
  }
  EXPECT_FALSE(FitStatusFromName("running").has_value());
  fs::remove_all(dir);
}

// experiments/pendulum.yaml simulated as shipped (truth damping 0.08, frictionloss 0.03, bob_mass
// 1.2; noise 0.001 rad and 0.01 rad/s, the sigmas), then fitted without its frictionloss
// parameter (the model's 0.01 stays): RunFit writes every result file with status
// model_mismatch, intervals_valid false, exit code 3, and the report says the intervals are not
// valid
TEST(FitStatusTest, RunFitWritesAModelMismatchWithExitCode3) {
  const fs::path dir = fs::temp_directory_path() / ("status_run_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  io::ExperimentConfig cfg =
      io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml");
  const std::string log = (dir / "log.h5").string();
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.parameters.erase(
      std::remove_if(cfg.parameters.begin(), cfg.parameters.end(),
                     [](const io::ParameterSpec& p) { return p.name == "frictionloss"; }),
      cfg.parameters.end());
  cfg.options.verbose = false;
  run::FitRunOptions opt;
  opt.out_dir = (dir / "out").string();
  opt.verbose = false;
  opt.threads = 2;
  const run::FitRunOutcome out = run::RunFit(cfg, opt);
  Print("pendulum without frictionloss", out.file);
  EXPECT_EQ(out.file.status, "model_mismatch");
  EXPECT_EQ(out.exit_code, 3);
  const io::FitResultFile back = io::ReadResult(opt.out_dir);
  EXPECT_EQ(back.outcome, FitStatus::kModelMismatch);
  EXPECT_FALSE(back.intervals_valid);
  std::string summary;
  EXPECT_GT(report::WriteReport(opt.out_dir, &summary), 0);
  std::ifstream page(opt.out_dir + "/report.html");
  std::stringstream html;
  html << page.rdbuf();
  EXPECT_NE(html.str().find("intervals not valid"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid
