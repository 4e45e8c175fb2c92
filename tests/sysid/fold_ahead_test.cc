// Compressed blocks folded ahead on worker threads (sysid/solve/compressed_cost.h, "Folds ahead";
// FitOptions::advanced.fold_ahead).
//
// Unit: a real nonlinear cost (tests/sysid/decay_cost.h: r_i = a exp(-b t_i) + c t_i - y_i, m =
// 2500 rows > kChunkRows, blocks of sizes 2 and 1, automatic derivatives; y from a = 2, b = 3, c =
// 0.5 with Gaussian noise sigma 0.01, seed 5) as a FoldableCost that counts its calls. Folded
// ahead, by one thread or by a 2-worker ThreadPool (several blocks at once), a block's Evaluate
// with Jacobians writes out the same bits as a fold at Evaluate (tolerance 0) without calling the
// inner cost, notes the inner cost's side effects once, at that first write-out, and counts one
// fold (ahead_folds 1); rows that fail ahead leave no fold (Evaluate evaluates and fails as
// before); a block already holding its fold at the values, or whose PrepareRows declines, is not
// folded ahead. Whole fits: the shipped single-shooting experiments (their `simulate` block: truth,
// noise and seed as shipped; 3 sequences of 1000 samples, so that 3 blocks share 2 workers) from
// the shipped start, folds ahead on and off at 1 thread and on at 2 threads: estimates, standard
// errors, final cost, iterations, status, warnings, folds and reused folds identical bit for bit
// (tolerance 0), and the steps at 1 thread; on, the solve's Jacobians folded ahead, 3 blocks
// each; off, none. And one multiple-shooting fit (arm5, 5 segment blocks) the same way.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "core/thread_pool.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/solve/compressed_cost.h"
#include "tests/experiment_log.h"
#include "tests/sysid/decay_cost.h"
#include "tests/sysid/same_fit.h"

namespace mjsysid {
namespace {

// the decay as a FoldableCost: Rows is the inner Evaluate; counts every call; fails while fail
class Foldable : public FoldableCost {
 public:
  explicit Foldable(int seed) : inner_(test::NewDecayCost(test::DecayData(seed))) {
    set_num_residuals(inner_->num_residuals());
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    ++(jacobians ? with_jacobians : residuals_only);
    return !fail && inner_->Evaluate(p, residuals, jacobians);
  }
  bool PrepareRows(double const* const*) const override {
    ++prepared;
    return prepare;
  }
  bool Rows(double const* const* p, double* residuals, double** jacobians) const override {
    ++rows;  // (blocks are folded by one task each: no race)
    return !fail && inner_->Evaluate(p, residuals, jacobians);
  }
  void NoteRows() const override { ++notes; }
  mutable int with_jacobians = 0, residuals_only = 0, prepared = 0, rows = 0, notes = 0;
  bool fail = false, prepare = true;

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
};

// blocks compressed decays (seeds 5, 6, ..) at their own values x0 = (1.7 + 0.1 b, 2.6), x1 = 0.4
struct Fixture {
  CompressedBlocks blocks;
  std::uint64_t epoch = 0;
  std::vector<Foldable*> inner;  // owned by cost
  std::vector<std::unique_ptr<ceres::CostFunction>> cost;
  std::vector<std::vector<double>> x0, x1;

  explicit Fixture(int n) {
    blocks.epoch = &epoch;
    x0.resize(n);
    x1.resize(n);
    for (int b = 0; b < n; ++b) {
      x0[b] = {1.7 + 0.1 * b, 2.6};
      x1[b] = {0.4};
      inner.push_back(new Foldable(5 + b));
      cost.emplace_back(Compress(inner.back(), &blocks, {x0[b].data(), x1[b].data()}));
    }
  }
};

// FoldAhead's runner: in order on this thread (one worker), or a pool's ParallelFor
int FoldSerially(CompressedBlocks* blocks) {
  return FoldAhead(blocks, 1, [](int n, const std::function<void(int, int)>& task) {
    for (int i = 0; i < n; ++i) task(0, i);
  });
}
int FoldOn(ThreadPool* pool, CompressedBlocks* blocks) {
  return FoldAhead(blocks, pool->size(), [pool](int n, const std::function<void(int, int)>& task) {
    pool->ParallelFor(n, task);
  });
}

TEST(FoldAheadTest, AFoldAheadIsWrittenOutAsTheFoldAtEvaluateWithItsNotesOnce) {
  Fixture plain(1), ahead(1);
  plain.blocks.members.clear();  // folded at Evaluate only
  test::DecayOut at_evaluate, written, again;
  ASSERT_TRUE(at_evaluate.Eval(*plain.cost[0], plain.x0[0].data(), plain.x1[0].data()));
  EXPECT_EQ(plain.inner[0]->with_jacobians, 1);

  ASSERT_EQ(ahead.blocks.members.size(), 1u);
  EXPECT_EQ(FoldSerially(&ahead.blocks), 1);
  const Foldable& f = *ahead.inner[0];
  EXPECT_EQ(f.rows, 1);
  EXPECT_EQ(f.notes, 0);  // not before Ceres asks
  ASSERT_TRUE(written.Eval(*ahead.cost[0], ahead.x0[0].data(), ahead.x1[0].data()));
  EXPECT_TRUE(written.SameBits(at_evaluate));
  EXPECT_EQ(f.with_jacobians, 0);  // the inner cost not called again
  EXPECT_EQ(f.notes, 1);
  EXPECT_EQ(ahead.blocks.folds, 1);
  EXPECT_EQ(ahead.blocks.ahead_folds, 1);
  EXPECT_EQ(ahead.blocks.reused_folds, 0);
  // asked again: a reused fold, no second note; a second FoldAhead at the same values folds nothing
  ASSERT_TRUE(again.Eval(*ahead.cost[0], ahead.x0[0].data(), ahead.x1[0].data()));
  EXPECT_TRUE(again.SameBits(at_evaluate));
  EXPECT_EQ(f.notes, 1);
  EXPECT_EQ(ahead.blocks.reused_folds, 1);
  EXPECT_EQ(FoldSerially(&ahead.blocks), 0);
  EXPECT_EQ(f.rows, 1);
  // written out once even with reuse off, then re-folded
  ahead.blocks.reuse_folds = false;
  ahead.x1[0][0] = std::nextafter(0.4, 1.0);
  EXPECT_EQ(FoldSerially(&ahead.blocks), 1);
  ASSERT_TRUE(written.Eval(*ahead.cost[0], ahead.x0[0].data(), ahead.x1[0].data()));
  EXPECT_EQ(f.with_jacobians, 0);
  EXPECT_EQ(f.notes, 2);
  ASSERT_TRUE(again.Eval(*ahead.cost[0], ahead.x0[0].data(), ahead.x1[0].data()));
  EXPECT_EQ(f.with_jacobians, 1);
  EXPECT_TRUE(again.SameBits(written));
  EXPECT_EQ(ahead.blocks.ahead_folds, 2);
}

TEST(FoldAheadTest, FailedOrDeclinedRowsLeaveTheBlockToEvaluate) {
  Fixture f(1);
  Foldable& inner = *f.inner[0];
  test::DecayOut out;
  // rows that fail ahead: no fold; Evaluate evaluates (and fails) as without folds ahead
  inner.fail = true;
  EXPECT_EQ(FoldSerially(&f.blocks), 1);
  EXPECT_FALSE(out.Eval(*f.cost[0], f.x0[0].data(), f.x1[0].data()));
  EXPECT_EQ(inner.with_jacobians, 1);
  EXPECT_EQ(inner.notes, 0);
  EXPECT_EQ(f.blocks.ahead_folds, 0);
  // PrepareRows declines: not folded ahead
  inner.fail = false;
  inner.prepare = false;
  EXPECT_EQ(FoldSerially(&f.blocks), 0);
  EXPECT_EQ(inner.rows, 1);
  ASSERT_TRUE(out.Eval(*f.cost[0], f.x0[0].data(), f.x1[0].data()));
  EXPECT_EQ(inner.with_jacobians, 2);
  EXPECT_EQ(f.blocks.folds, 1);
  EXPECT_EQ(f.blocks.ahead_folds, 0);
  // a fold ahead then a new epoch: not written out (folded again at Evaluate)
  inner.prepare = true;
  f.x1[0][0] = 0.5;
  EXPECT_EQ(FoldSerially(&f.blocks), 1);
  ++f.epoch;
  ASSERT_TRUE(out.Eval(*f.cost[0], f.x0[0].data(), f.x1[0].data()));
  EXPECT_EQ(inner.with_jacobians, 3);
  EXPECT_EQ(inner.notes, 0);
  EXPECT_EQ(f.blocks.ahead_folds, 0);
}

TEST(FoldAheadTest, FiveBlocksOnTwoWorkersGiveTheSerialBits) {
  constexpr int kBlocks = 5;
  Fixture serial(kBlocks), parallel(kBlocks);
  ThreadPool pool(2);
  EXPECT_EQ(FoldSerially(&serial.blocks), kBlocks);
  EXPECT_EQ(FoldOn(&pool, &parallel.blocks), kBlocks);
  EXPECT_GE(parallel.blocks.scratch.size(), 2u);
  for (int b = 0; b < kBlocks; ++b) {
    test::DecayOut s, p;
    ASSERT_TRUE(s.Eval(*serial.cost[b], serial.x0[b].data(), serial.x1[b].data()));
    ASSERT_TRUE(p.Eval(*parallel.cost[b], parallel.x0[b].data(), parallel.x1[b].data()));
    EXPECT_TRUE(p.SameBits(s)) << "block " << b;
    EXPECT_EQ(parallel.inner[b]->with_jacobians, 0);
    EXPECT_EQ(parallel.inner[b]->notes, 1);
  }
  EXPECT_EQ(parallel.blocks.ahead_folds, kBlocks);
}

FitResult FitWith(const io::ExperimentConfig& cfg, bool ahead, int threads) {
  run::BuiltProblem built = run::BuildProblem(cfg, threads);
  FitOptions options = built.options;
  options.verbose = false;
  options.threads = threads;
  options.advanced.fold_ahead = ahead;
  return built.problem->Fit(options);
}

// steps: compared too (not across thread counts: at 2 threads trial points also simulate Jacobian
// columns ahead, sysid/solve/evaluation_cache.h); and the folds made and reused
void ExpectSameFit(const FitResult& a, const FitResult& b, bool steps) {
  test::ExpectSameFit(a, b, steps);
  EXPECT_EQ(a.diagnostics.folds, b.diagnostics.folds);
  EXPECT_EQ(a.diagnostics.reused_folds, b.diagnostics.reused_folds);
}

class FoldAheadFitTest : public ::testing::TestWithParam<std::string> {};

TEST_P(FoldAheadFitTest, TheSameFitBitForBitAtOneAndTwoThreads) {
  io::ExperimentConfig cfg = test::ShippedExperimentWithLog(GetParam(), 3, 1000, "fold_ahead");
  const FitResult on = FitWith(cfg, true, 1);
  const FitResult off = FitWith(cfg, false, 1);
  const FitResult on2 = FitWith(cfg, true, 2);
  std::printf(
      "%s: %d iterations, %lld steps, folds %lld (%lld ahead) + %lld reused; off: %lld "
      "(%lld ahead) + %lld; 2 threads: %lld (%lld ahead)\n  %s\n",
      GetParam().c_str(), on.iterations, on.diagnostics.simulation_steps, on.diagnostics.folds,
      on.diagnostics.ahead_folds, on.diagnostics.reused_folds, off.diagnostics.folds,
      off.diagnostics.ahead_folds, off.diagnostics.reused_folds, on2.diagnostics.folds,
      on2.diagnostics.ahead_folds, TerminationText(on.termination).c_str());
  EXPECT_EQ(on.segment_steps_used, 0);  // single shooting: compressed blocks
  // every Jacobian of the solve folds its 3 blocks ahead
  EXPECT_GE(on.diagnostics.ahead_folds, 3);
  EXPECT_EQ(on.diagnostics.ahead_folds % 3, 0);
  EXPECT_EQ(on2.diagnostics.ahead_folds, on.diagnostics.ahead_folds);
  EXPECT_EQ(off.diagnostics.ahead_folds, 0);
  ExpectSameFit(on, off, true);
  ExpectSameFit(on2, off, false);
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

// Multiple shooting (experiments/arm5.yaml: segments of 200 steps with free initial states; its
// `simulate` block's truth, noise and seed; 1 sequence of 1000 samples, so 5 compressed segment
// blocks, each over z, its x_0 and the next x_0): the segments' folds are made ahead too, and the
// fit is the same bit for bit on and off and at 2 threads.
TEST(FoldAheadMultipleShootingTest, TheSameFitBitForBitAtOneAndTwoThreads) {
  io::ExperimentConfig cfg = test::ShippedExperimentWithLog("arm5.yaml", 1, 1000, "fold_ahead_ms");
  const FitResult on = FitWith(cfg, true, 1);
  const FitResult off = FitWith(cfg, false, 1);
  const FitResult on2 = FitWith(cfg, true, 2);
  std::printf("arm5: %d iterations, folds %lld (%lld ahead); off %lld (%lld ahead)\n  %s\n",
              on.iterations, on.diagnostics.folds, on.diagnostics.ahead_folds,
              off.diagnostics.folds, off.diagnostics.ahead_folds,
              TerminationText(on.termination).c_str());
  EXPECT_GT(on.segment_steps_used, 0);  // multiple shooting
  EXPECT_GE(on.diagnostics.ahead_folds, 5);
  EXPECT_EQ(on2.diagnostics.ahead_folds, on.diagnostics.ahead_folds);
  EXPECT_EQ(off.diagnostics.ahead_folds, 0);
  ExpectSameFit(on, off, true);
  ExpectSameFit(on2, off, false);
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

INSTANTIATE_TEST_SUITE_P(Shipped, FoldAheadFitTest,
                         ::testing::Values("spring_mass.yaml", "pendulum.yaml", "cartpole.yaml",
                                           "double_pendulum.yaml", "arm7.yaml"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                           return p.param.substr(0, p.param.find('.'));
                         });

}  // namespace
}  // namespace mjsysid
