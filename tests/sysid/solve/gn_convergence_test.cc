// The solve's statistical stop (sysid/solve/gn_convergence.h, FitOptions::gauss_newton_stop).
//
// TestGaussNewtonStep on linear least squares, where the Gauss-Newton step is exact: truth x*
// drawn once (seed 7), J 400 x 3 Gaussian, noise sigma 0.1 (seed 11); the test passes at the
// least-squares solution and at 0.5 % of a standard error from it, fails at 50 % (ratio 0.5 to
// 3 %), does not apply to a rank-deficient J or with a variable on its bound that the data pull
// inwards, and passes there when the data push it outwards.
//
// Whole fits of shipped experiments (their `simulate` block: truth, noise, seed as shipped, fewer
// sequences and steps), each twice, the stop on (0.03, the default) and off (0: Ceres' tolerances
// alone), from the shipped start and from `initial: auto`: with the stop the fit ends within 0.03
// standard errors (as the fit without it estimates them) of the fit without it, as converged, in no
// more iterations and simulated steps; from the shipped start (many standard errors away) it does
// not stop at the start. Where the test is not valid (a robust loss, multiple shooting) the fit is
// the same bit for bit with the option on or off.
#include "sysid/solve/gn_convergence.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/run/fit_experiment.h"
#include "tests/experiment_log.h"
#include "tests/sysid/linear_least_squares.h"

namespace mjsysid {
namespace {

constexpr double kFraction = 0.03;

using test::LinearLeastSquares;

TEST(GaussNewtonStepTest, PassesAtTheOptimumAndFailsHalfAStandardErrorAway) {
  const LinearLeastSquares L(400, 3);
  const GaussNewtonTest at = TestGaussNewtonStep(L.At(L.xhat), L.Free(L.xhat), kFraction, {});
  EXPECT_TRUE(at.applies);
  EXPECT_TRUE(at.passed);
  EXPECT_LT(at.max_ratio, 1e-9);

  Eigen::VectorXd near = L.xhat;
  near[1] += 0.005 * L.se[1];
  const GaussNewtonTest close = TestGaussNewtonStep(L.At(near), L.Free(near), kFraction, {});
  EXPECT_TRUE(close.passed);
  EXPECT_NEAR(close.max_ratio, 0.005, 1e-5);

  Eigen::VectorXd far = L.xhat;
  far[2] -= 0.5 * L.se[2];
  const GaussNewtonTest away = TestGaussNewtonStep(L.At(far), L.Free(far), kFraction, {});
  EXPECT_TRUE(away.applies);
  EXPECT_FALSE(away.passed);
  // the residual variance at the point is larger by 0.25 / (m - n): the ratio a little below 0.5
  EXPECT_NEAR(away.max_ratio, 0.5, 1e-3);
}

TEST(GaussNewtonStepTest, RankDeficientJacobianDoesNotApply) {
  LinearLeastSquares L(400, 3);
  L.J.col(2) = 2.0 * L.J.col(0);
  Eigen::VectorXd at(3);
  at << L.J.leftCols(2).colPivHouseholderQr().solve(L.y), 0.0;
  const GaussNewtonTest t = TestGaussNewtonStep(L.At(at), L.Free(at), kFraction, {});
  EXPECT_FALSE(t.applies);
  EXPECT_FALSE(t.passed);
  EXPECT_NE(t.why_not.find("rank-deficient"), std::string::npos) << t.why_not;
}

TEST(GaussNewtonStepTest, AVariableOnItsBoundIsHeldWhenTheDataPushItOut) {
  const LinearLeastSquares L(400, 3);
  // variable 0 held on a lower bound 2 standard errors above its unconstrained optimum: the
  // optimum of the others given it, where the data push it down (outwards)
  for (const double offset : {2.0, -2.0}) {
    Eigen::VectorXd x(3);
    x[0] = L.xhat[0] + offset * L.se[0];
    x.tail(2) = L.J.rightCols(2).colPivHouseholderQr().solve(L.y - L.J.col(0) * x[0]);
    std::vector<ColumnBounds> b = L.Free(x);
    b[0].lower = x[0];
    const GaussNewtonTest t = TestGaussNewtonStep(L.At(x), b, kFraction, {});
    EXPECT_EQ(t.held, 1);
    if (offset > 0) {  // pushed outwards: held, the rest at their optimum
      EXPECT_TRUE(t.passed) << t.why_not;
      EXPECT_LT(t.max_ratio, 1e-9);
    } else {  // pulled inwards: the optimum is off the bound
      EXPECT_FALSE(t.applies);
      EXPECT_NE(t.why_not.find("leave"), std::string::npos) << t.why_not;
    }
  }
}

// whole fits of a shipped experiment with the stop on and off
struct Case {
  std::string experiment;
  int sequences, steps;
  bool auto_start;  // every parameter `initial: auto`
};

class GaussNewtonStopFitTest : public ::testing::TestWithParam<Case> {};

FitResult FitWith(const io::ExperimentConfig& cfg, double stop, const FitOptions* base = nullptr) {
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  FitOptions options = base ? *base : built.options;
  options.verbose = false;
  options.threads = 1;
  options.gauss_newton_stop = stop;
  return built.problem->Fit(options);
}

TEST_P(GaussNewtonStopFitTest, EndsWithinTheFractionOfAStandardErrorInFewerSteps) {
  const Case& c = GetParam();
  io::ExperimentConfig cfg =
      test::ShippedExperimentWithLog(c.experiment, c.sequences, c.steps, "gn_stop");
  for (io::ParameterSpec& p : cfg.parameters) p.initial_auto = p.initial_auto || c.auto_start;
  const FitResult on = FitWith(cfg, kFraction);
  const FitResult off = FitWith(cfg, 0);
  std::printf("%s%s: on %d it, %lld steps (%s); off %d it, %lld steps (%s)\n", c.experiment.c_str(),
              c.auto_start ? " +auto" : "", on.iterations, on.diagnostics.simulation_steps,
              TerminationText(on.termination).c_str(), off.iterations,
              off.diagnostics.simulation_steps, TerminationText(off.termination).c_str());

  EXPECT_FALSE(off.gauss_newton_converged);
  EXPECT_TRUE(on.gauss_newton_converged);
  EXPECT_TRUE(on.converged);
  EXPECT_NE(TerminationText(on.termination).find("Gauss-Newton step below 3 %"), std::string::npos);
  EXPECT_EQ(on.outcome, off.outcome);
  EXPECT_EQ(on.outcome, FitStatus::kConverged);
  EXPECT_LE(on.iterations, off.iterations);
  EXPECT_LE(on.diagnostics.simulation_steps, off.diagnostics.simulation_steps);
  ASSERT_EQ(on.parameters.size(), off.parameters.size());
  double far = 0;  // the start's largest distance from the estimate, in standard errors
  for (size_t i = 0; i < on.parameters.size(); ++i) {
    const ParameterEstimate& a = on.parameters[i];
    const ParameterEstimate& b = off.parameters[i];
    ASSERT_GT(b.std_error, 0) << b.name;
    const double ratio = std::abs(a.value - b.value) / b.std_error;
    std::printf("  %s: |on - off| = %.3g std (on %.9g, off %.9g, std %.3g)\n", b.name.c_str(),
                ratio, a.value, b.value, b.std_error);
    EXPECT_LE(ratio, kFraction) << b.name;
    far = std::max(far, std::abs(b.initial - b.value) / b.std_error);
  }
  // from the shipped start, many standard errors away, the stop does not fire at the start
  if (!c.auto_start) {
    EXPECT_GT(far, 10.0);
    EXPECT_GE(on.iterations, 1);
  }
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

INSTANTIATE_TEST_SUITE_P(Shipped, GaussNewtonStopFitTest,
                         ::testing::Values(Case{"spring_mass.yaml", 1, 1000, false},
                                           Case{"pendulum.yaml", 1, 1000, false},
                                           Case{"cartpole.yaml", 1, 1000, false},
                                           Case{"cartpole.yaml", 1, 1000, true}),
                         [](const ::testing::TestParamInfo<Case>& p) {
                           std::string name = p.param.experiment;
                           name = name.substr(0, name.find('.'));
                           return name + (p.param.auto_start ? "_auto" : "");
                         });

// where the test is not valid the option changes nothing: the same fit bit for bit
TEST(GaussNewtonStopFitTest, RobustLossAndMultipleShootingAreUnchanged) {
  io::ExperimentConfig cfg = test::ShippedExperimentWithLog("pendulum.yaml", 1, 1000, "gn_stop");
  FitOptions options = run::BuildProblem(cfg, 1).options;
  for (int variant = 0; variant < 2; ++variant) {
    FitOptions o = options;
    if (variant == 0) o.loss = LossType::kHuber;
    if (variant == 1) o.segment_steps = 250;
    const FitResult on = FitWith(cfg, kFraction, &o);
    const FitResult off = FitWith(cfg, 0, &o);
    EXPECT_FALSE(on.gauss_newton_converged);
    EXPECT_EQ(on.iterations, off.iterations);
    EXPECT_EQ(on.final_cost, off.final_cost);
    EXPECT_EQ(TerminationText(on.termination), TerminationText(off.termination));
    EXPECT_EQ(on.outcome, off.outcome);
    ASSERT_EQ(on.parameters.size(), off.parameters.size());
    for (size_t i = 0; i < on.parameters.size(); ++i) {
      EXPECT_EQ(on.parameters[i].value, off.parameters[i].value) << on.parameters[i].name;
    }
  }
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

// `solver.gauss_newton_stop` reaches FitOptions: 0.03 by default, 0 turns the stop off
TEST(GaussNewtonStopFitTest, SolverKeyReachesTheOptions) {
  const std::string path = std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml";
  const io::ExperimentConfig shipped = io::LoadExperiment(path);
  EXPECT_EQ(shipped.options.gauss_newton_stop, kFraction);
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string solver = "solver:\n";
  ASSERT_NE(text.find(solver), std::string::npos);
  text.replace(text.find(solver), solver.size(), solver + "  gauss_newton_stop: 0\n");
  EXPECT_EQ(io::ParseExperiment(text, path).options.gauss_newton_stop, 0.0);
}

}  // namespace
}  // namespace mjsysid
