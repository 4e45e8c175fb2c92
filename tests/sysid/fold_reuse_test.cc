// A compressed block's last fold written out instead of a re-fold (sysid/solve/compressed_cost.h,
// "The last fold"; FitOptions::advanced.reuse_folds).
//
// Unit: a real nonlinear cost (tests/sysid/decay_cost.h: r_i = a exp(-b t_i) + c t_i - y_i, m =
// 2500 rows > kChunkRows, blocks of sizes 2 and 1, automatic derivatives, noise seed 5) wrapped in
// a cost that counts the calls it forwards. A second request with Jacobians at the same values
// returns the same bits as the first, and as a re-fold (reuse off), without calling the inner cost;
// a value one ulp away, a residual-only evaluation at another point in between, and an advanced
// epoch each call it again; a failed evaluation keeps no fold. Whole fits: the shipped experiments
// (their `simulate` block: truth, noise and seed as shipped; 1 sequence of 1000 samples; single
// shooting as auto chooses it) from the shipped start and from `initial: auto`, with the reuse on
// and off: estimates, standard errors, final cost, iterations, status, simulator steps and the
// termination message identical bit for bit (tolerance 0), and with the reuse on at least one
// Jacobian request (the statistical stop's test or the covariance) answered by a last fold.
// cartpole with a shared control delay fitted too (from 4 ms; the log has none): the same fit bit
// for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "sysid/run/fit_experiment.h"
#include "sysid/solve/compressed_cost.h"
#include "tests/experiment_log.h"
#include "tests/sysid/decay_cost.h"
#include "tests/sysid/same_fit.h"

namespace mjsysid {
namespace {

// forwards to inner, counting the calls with and without Jacobians; fails while fail is set
class Counted : public ceres::CostFunction {
 public:
  explicit Counted(ceres::CostFunction* inner) : inner_(inner) {
    set_num_residuals(inner->num_residuals());
    *mutable_parameter_block_sizes() = inner->parameter_block_sizes();
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    ++(jacobians ? with_jacobians : residuals_only);
    return !fail && inner_->Evaluate(p, residuals, jacobians);
  }
  mutable int with_jacobians = 0, residuals_only = 0;
  bool fail = false;

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
};

struct Fixture {
  CompressedBlocks blocks;
  std::uint64_t epoch = 0;
  Counted* counted = nullptr;  // owned by cost
  std::unique_ptr<ceres::CostFunction> cost;

  Fixture() {
    counted = new Counted(test::NewDecayCost(test::DecayData(5)));
    blocks.epoch = &epoch;
    cost.reset(Compress(counted, &blocks));
  }
};

TEST(FoldReuseTest, TheSameValuesGiveTheLastFoldWithoutTheInnerCost) {
  Fixture f;
  ASSERT_NE(f.cost.get(), f.counted);
  const double x0[2] = {1.7, 2.6}, x1[1] = {0.4};
  test::DecayOut first, second, refold;
  ASSERT_TRUE(first.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 1);
  ASSERT_TRUE(second.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 1);  // not called
  EXPECT_TRUE(second.SameBits(first));
  EXPECT_EQ(f.blocks.folds, 1);
  EXPECT_EQ(f.blocks.reused_folds, 1);
  // the same bits as a re-fold
  f.blocks.reuse_folds = false;
  ASSERT_TRUE(refold.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 2);
  EXPECT_TRUE(refold.SameBits(first));
  // a residual-only evaluation at the same values keeps the fold; one block asked for only
  f.blocks.reuse_folds = true;
  const double* p[2] = {x0, x1};
  std::vector<double> r(4), j1(4);
  ASSERT_TRUE(f.cost->Evaluate(p, r.data(), nullptr));
  double* only_j1[2] = {nullptr, j1.data()};
  ASSERT_TRUE(f.cost->Evaluate(p, r.data(), only_j1));
  EXPECT_EQ(f.counted->with_jacobians, 2);
  EXPECT_EQ(std::memcmp(j1.data(), first.j1.data(), sizeof(double) * 4), 0);
  EXPECT_EQ(std::memcmp(r.data(), first.r.data(), sizeof(double) * 4), 0);
}

TEST(FoldReuseTest, AnotherValueAPointInBetweenOrAnEpochReFolds) {
  Fixture f;
  double x0[2] = {1.7, 2.6}, x1[1] = {0.4};
  test::DecayOut first, again;
  ASSERT_TRUE(first.Eval(*f.cost, x0, x1));
  // one ulp in the second block
  x1[0] = std::nextafter(0.4, 1.0);
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 2);
  EXPECT_FALSE(again.SameBits(first));
  x1[0] = 0.4;
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));  // the first values: the last fold is the ulp's
  EXPECT_EQ(f.counted->with_jacobians, 3);
  EXPECT_TRUE(again.SameBits(first));
  // a residual-only evaluation at another point in between
  const double y0[2] = {1.8, 2.6};
  const double* p[2] = {y0, x1};
  std::vector<double> r(4);
  ASSERT_TRUE(f.cost->Evaluate(p, r.data(), nullptr));
  EXPECT_EQ(f.counted->residuals_only, 1);
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 4);
  EXPECT_TRUE(again.SameBits(first));
  // the epoch advanced
  ++f.epoch;
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 5);
  EXPECT_TRUE(again.SameBits(first));
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));  // and kept in the new epoch
  EXPECT_EQ(f.counted->with_jacobians, 5);
  // a failed evaluation at the same values keeps no fold
  ++f.epoch;
  f.counted->fail = true;
  EXPECT_FALSE(again.Eval(*f.cost, x0, x1));
  f.counted->fail = false;
  ASSERT_TRUE(again.Eval(*f.cost, x0, x1));
  EXPECT_EQ(f.counted->with_jacobians, 7);
  EXPECT_TRUE(again.SameBits(first));
  EXPECT_EQ(f.blocks.reused_folds, 1);
}

struct Case {
  std::string experiment;
  bool auto_start;     // every parameter `initial: auto`
  bool delay = false;  // a shared control delay fitted too (from 4 ms; the log has none)
};
void PrintTo(const Case& c, std::ostream* os) {
  *os << c.experiment << (c.auto_start ? " +auto" : "") << (c.delay ? " +delay" : "");
}

FitResult FitWith(const io::ExperimentConfig& cfg, bool reuse) {
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  FitOptions options = built.options;
  options.verbose = false;
  options.threads = 1;
  options.advanced.reuse_folds = reuse;
  return built.problem->Fit(options);
}

class FoldReuseFitTest : public ::testing::TestWithParam<Case> {};

TEST_P(FoldReuseFitTest, TheSameFitBitForBit) {
  const Case& c = GetParam();
  io::ExperimentConfig cfg = test::ShippedExperimentWithLog(c.experiment, 1, 1000, "fold_reuse");
  for (io::ParameterSpec& p : cfg.parameters) p.initial_auto = p.initial_auto || c.auto_start;
  if (c.delay) {
    io::ExperimentConfig::ControlDelaySpec d;
    d.term = {0.004, true, 0.0, 0.05};
    cfg.control_delays.push_back(d);
  }
  const FitResult on = FitWith(cfg, true);
  const FitResult off = FitWith(cfg, false);
  std::printf(
      "%s%s: %d iterations, %lld steps, folds %lld + %lld reused (off: %lld + %lld)\n  %s\n",
      c.experiment.c_str(), c.auto_start ? " +auto" : "", on.iterations,
      on.diagnostics.simulation_steps, on.diagnostics.folds, on.diagnostics.reused_folds,
      off.diagnostics.folds, off.diagnostics.reused_folds, TerminationText(on.termination).c_str());
  EXPECT_EQ(on.segment_steps_used, 0);  // single shooting: compressed blocks
  // (with a fitted control delay the statistical stop is off and Ceres ends after trials at other
  // points, so the estimate's Jacobian is a new fold: the same fit is all there is to test)
  if (!c.delay) {
    EXPECT_GT(on.diagnostics.reused_folds, 0);
  }
  EXPECT_EQ(off.diagnostics.reused_folds, 0);
  EXPECT_EQ(on.diagnostics.folds + on.diagnostics.reused_folds,
            off.diagnostics.folds);  // each reused fold is one fold fewer
  test::ExpectSameFit(on, off, true);
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

INSTANTIATE_TEST_SUITE_P(
    Shipped, FoldReuseFitTest,
    ::testing::Values(Case{"spring_mass.yaml", false}, Case{"spring_mass.yaml", true},
                      Case{"pendulum.yaml", false}, Case{"pendulum.yaml", true},
                      Case{"cartpole.yaml", false}, Case{"cartpole.yaml", true},
                      Case{"double_pendulum.yaml", false}, Case{"double_pendulum.yaml", true},
                      Case{"arm7.yaml", false}, Case{"arm7.yaml", true},
                      Case{"cartpole.yaml", false, true}),
    [](const ::testing::TestParamInfo<Case>& p) {
      std::string name = p.param.experiment;
      name = name.substr(0, name.find('.'));
      return name + (p.param.auto_start ? "_auto" : "") + (p.param.delay ? "_delay" : "");
    });

}  // namespace
}  // namespace mjsysid
