// The ledger of a fit (sysid/solve/fit_ledger.h) on a real spring-mass fit: its rows add up to the
// fit's simulation steps, every phase of the fit is in it, and the evaluation at the estimate after
// the solve simulates nothing (the evaluation cache keeps the last iterate's rollout and Jacobians,
// sysid/solve/evaluation_cache.h); a hand-driven ledger charges steps and time to the phase
// entered.
#include "sysid/solve/fit_ledger.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/problem.h"
#include "tests/file_util.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

TEST(FitLedgerTest, ChargesStepsToTheCurrentPhase) {
  long long steps = 5;  // before the first phase: charged to nothing
  FitLedger ledger([&steps] { return steps; });
  ledger.Enter("a");
  steps += 10;
  ledger.Enter("b");
  steps += 3;
  ledger.Enter("a");
  steps = 1;  // the counter restarted (new simulators): 1 step since, charged to "a"
  const std::vector<LedgerRow> rows = ledger.Finish();
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].phase, "a");
  EXPECT_EQ(rows[0].entries, 2);
  EXPECT_EQ(rows[0].steps, 11);
  EXPECT_EQ(rows[1].phase, "b");
  EXPECT_EQ(rows[1].entries, 1);
  EXPECT_EQ(rows[1].steps, 3);
  EXPECT_GE(rows[0].seconds, 0.0);
  const std::string table = FormatLedger(rows, 2);
  EXPECT_NE(table.find("total"), std::string::npos);
}

// truth mass 1.0, damping 0.3, start 2.0 / 0.1 (log), sensor noise sigma 1e-3 (seed 3), one
// sequence of 1000 samples; xml: the model (default: models/spring_mass.xml)
void SpringMassProblem(Problem* problem, const std::string& xml = "") {
  ModelPtr m = xml.empty() ? LoadModel(kModels + "/spring_mass.xml") : LoadModelFromString(xml);
  const RowMatrix u = test::Excitation(*m, 1000, 2.0, 1);
  InitialState x0;
  const std::vector<test::Truth> truth = {{"mass", test::Spec("body_mass", "mass"), 1.0},
                                          {"damping", test::Spec("joint_damping", "slide"), 0.3}};
  const RowMatrix y = test::Measure(*m, truth, x0, u, 1e-3, 3);
  problem->AddModel("spring", *m);
  problem->AddParameter(
      FitParameter("mass", test::Spec("body_mass", "mass"), 2.0).Bounds(0.01, 100).Log());
  problem->AddParameter(
      FitParameter("damping", test::Spec("joint_damping", "slide"), 0.1).Bounds(1e-3, 10).Log());
  problem->AddSequence(FitSequence("seq0", "spring", x0, u, y));
}

// the spring-mass fit (SpringMassProblem above) with the product's options at
// `threads` simulator threads
FitResult SpringMassFit(Problem* problem, int threads) {
  SpringMassProblem(problem);
  FitOptions o;
  o.threads = threads;
  return problem->Fit(o);
}

// 1 thread: the estimate within 1e-3 relative, the ledger adds up to the step count exactly
TEST(FitLedgerTest, SpringMassFitLedgerAddsUpAndTheEstimateCostsNoSteps) {
  Problem problem;
  SpringMassProblem(&problem);
  FitOptions o;
  o.threads = 1;
  const FitResult r = problem.Fit(o);
  ASSERT_TRUE(r.converged) << TerminationText(r.termination);
  EXPECT_NEAR(test::Estimate(r, "mass").value, 1.0, 1e-3);
  EXPECT_NEAR(test::Estimate(r, "damping").value, 0.3, 3e-4);
  long long steps = 0;
  std::map<std::string, LedgerRow> by_phase;
  for (const LedgerRow& row : r.diagnostics.ledger) {
    steps += row.steps;
    by_phase[row.phase] = row;
  }
  EXPECT_EQ(steps, r.diagnostics.simulation_steps);
  for (FitPhase phase : {kPhasePrepare, kPhaseJacobians, kPhaseTrials, kPhaseSolver, kPhaseEstimate,
                         kPhaseIntervalCheck, kPhaseSignals}) {
    EXPECT_EQ(by_phase.count(FitPhaseName(phase)), 1u) << FitPhaseName(phase);
  }
  // the input checks: one rollout and two directional columns of 1000 steps (the horizon probe
  // adds its own); their Jacobian is the solve's first, so the solve's Jacobians cost only
  // columns at accepted points: 2 x 1000 steps each
  EXPECT_GE(by_phase[FitPhaseName(kPhasePrepare)].steps, 3000);
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseJacobians)].steps % 2000, 0);
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseTrials)].steps % 1000, 0);
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseEstimate)].steps, 0);  // the last iterate, from the cache
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseSignals)].steps, 0);   // the final signals, from the cache
  // the interval check: the rollouts have no constraint row (a smooth cost), so it is skipped
  // along both simulator parameters and says so (the limited spring below runs it)
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseIntervalCheck)].steps, 0);
  EXPECT_EQ(
      IntervalCheckText(r.interval_check).rfind("skipped along 2 of the 2 simulator parameters", 0),
      0u)
      << IntervalCheckText(r.interval_check);
  // fitted again (new simulators, step counts from 0): the same ledger, no negative row
  const FitResult again = problem.Fit(o);
  long long again_steps = 0;
  for (const LedgerRow& row : again.diagnostics.ledger) {
    EXPECT_GE(row.steps, 0) << row.phase;
    again_steps += row.steps;
  }
  EXPECT_EQ(again_steps, again.diagnostics.simulation_steps);
  EXPECT_EQ(again.diagnostics.simulation_steps, r.diagnostics.simulation_steps);
}

// The time inside the simulators' batches (core/thread_pool.h, PoolTime) in the ledger: a phase
// that simulates has batches and spends part of its time in them, one that does not has none; at
// 1 thread nothing is handed off (no wake-up, no wait); the spring-mass fit above, 1 and 2 threads
TEST(FitLedgerTest, BatchTimeIsPartOfThePhaseThatSimulates) {
  for (int threads : {1, 2}) {
    Problem problem;
    const FitResult r = SpringMassFit(&problem, threads);
    ASSERT_TRUE(r.converged) << TerminationText(r.termination);
    long long batches = 0, folds = 0;
    for (const LedgerRow& row : r.diagnostics.ledger) {
      batches += row.batches;
      // (the subset start's rows: its phases prefixed "subset start: ")
      const std::string folds_phase = FitPhaseName(kPhaseFolds);
      if (row.phase.size() >= folds_phase.size() &&
          row.phase.compare(row.phase.size() - folds_phase.size(), folds_phase.size(),
                            folds_phase) == 0) {
        // the compressed blocks' folds ahead: one batch per Jacobian, without steps
        EXPECT_EQ(row.steps, 0);
        EXPECT_GT(row.batches, 0) << "at " << threads;
        EXPECT_LE(row.batches, row.entries);  // (none when every block holds its fold)
        folds = row.batches;
      } else {
        EXPECT_EQ(row.steps > 0, row.batches > 0) << row.phase << " at " << threads;
      }
      EXPECT_GE(row.batch_seconds, 0.0) << row.phase;
      EXPECT_LE(row.batch_seconds, row.seconds) << row.phase << " at " << threads;
      // each inside the batch; not their sum: a worker that starts after the caller's own last
      // task (a loaded machine) is waited for while it wakes
      EXPECT_LE(row.wake_seconds, row.batch_seconds) << row.phase;
      EXPECT_LE(row.wait_seconds, row.batch_seconds) << row.phase;
      if (row.steps > 0) {
        EXPECT_GT(row.batch_seconds, 0.0) << row.phase;
        EXPECT_GT(row.batch_cpu_seconds, 0.0) << row.phase;
      }
      if (threads == 1) {
        EXPECT_EQ(row.wake_seconds, 0.0) << row.phase;
        EXPECT_EQ(row.wait_seconds, 0.0) << row.phase;
      }
    }
    EXPECT_GT(batches, 0);
    EXPECT_GT(folds, 0);
    EXPECT_LE(folds, r.diagnostics.ahead_folds);  // each batch at least one block's fold
    EXPECT_NE(FormatLedger(r.diagnostics.ledger, 1000).find("serial s"), std::string::npos);
  }
}

// The same spring with a slide range of +-0.2 m that its excitation (amplitude 2 N against 4 N/m)
// runs into: the limit row comes and goes, so the interval check runs, the cost at +-1 std of
// each of the 2 parameters, one 1000-step rollout each (truth and start as above)
TEST(FitLedgerTest, TheIntervalCheckRunsWhereConstraintRowsComeAndGo) {
  std::string xml = test::ReadFile(kModels + "/spring_mass.xml");
  const std::string joint = "damping=\"0.3\"";
  ASSERT_NE(xml.find(joint), std::string::npos);
  xml.replace(xml.find(joint), joint.size(), joint + " limited=\"true\" range=\"-0.2 0.2\"");
  Problem problem;
  SpringMassProblem(&problem, xml);
  FitOptions o;
  o.threads = 1;
  o.global_stage = false;  // one pass's ledger (the check fails: the global stage would follow)
  const FitResult r = problem.Fit(o);
  long long check_steps = -1;
  for (const LedgerRow& row : r.diagnostics.ledger) {
    if (row.phase == FitPhaseName(kPhaseIntervalCheck)) check_steps = row.steps;
  }
  EXPECT_EQ(check_steps, 4000);
  // the +- one standard error of each parameter in one batch: 2 rollouts, one round on 2 workers
  long long check_critical = -1;
  for (const LedgerRow& row : r.diagnostics.ledger) {
    if (row.phase == FitPhaseName(kPhaseIntervalCheck)) check_critical = row.critical_steps;
  }
  EXPECT_EQ(check_critical, 2000);
  EXPECT_EQ(IntervalCheckText(r.interval_check)
                .rfind("ran: 4 cost evaluations (constraint rows come, go", 0),
            0u)
      << IntervalCheckText(r.interval_check);
}

// The task model (core/thread_pool.h) in the ledger: the steps on the critical path at 2 workers
// follow from the batches' task lengths alone, so they are the same at 1 and 2 threads, and on
// one sequence with 2 Jacobian columns they are exact: a Jacobian batch (2 columns of 1000 steps)
// is 1000 steps long on 2 workers, a trial rollout (1 task) its own length, the input checks'
// rollout with its 2 columns behind it 2000 of 3000 (+ the probe)
TEST(FitLedgerTest, CriticalStepsAtTwoWorkersAreExactAndThreadIndependent) {
  std::vector<std::vector<LedgerRow>> ledgers;
  for (int threads : {1, 2}) {
    Problem problem;
    const FitResult r = SpringMassFit(&problem, threads);
    ASSERT_TRUE(r.converged) << TerminationText(r.termination);
    ledgers.push_back(r.diagnostics.ledger);
  }
  ASSERT_EQ(ledgers[0].size(), ledgers[1].size());
  for (size_t i = 0; i < ledgers[0].size(); ++i) {
    EXPECT_EQ(ledgers[0][i].phase, ledgers[1][i].phase);
    EXPECT_EQ(ledgers[0][i].steps, ledgers[1][i].steps) << ledgers[0][i].phase;
    EXPECT_EQ(ledgers[0][i].critical_steps, ledgers[1][i].critical_steps) << ledgers[0][i].phase;
  }
  std::map<std::string, LedgerRow> by_phase;
  for (const LedgerRow& row : ledgers[0]) by_phase[row.phase] = row;
  const LedgerRow& jac = by_phase[FitPhaseName(kPhaseJacobians)];
  ASSERT_GT(jac.steps, 0);
  EXPECT_EQ(jac.critical_steps * 2, jac.steps);
  const LedgerRow& trials = by_phase[FitPhaseName(kPhaseTrials)];
  EXPECT_GT(trials.steps, 0);
  EXPECT_EQ(trials.critical_steps, trials.steps);
  // the interval check is skipped on these smooth rollouts (its batches: the limited spring above)
  EXPECT_EQ(by_phase[FitPhaseName(kPhaseIntervalCheck)].steps, 0);
  EXPECT_EQ(by_phase[FitPhaseName(kPhasePrepare)].steps -
                by_phase[FitPhaseName(kPhasePrepare)].critical_steps,
            1000);
  const std::string table = FormatLedger(ledgers[0], 1000);
  EXPECT_NE(table.find("2w model"), std::string::npos);
}

// Columns ahead (sysid/solve/evaluation_cache.h) at 2 threads: 3 sequences x 3 columns leave one
// worker idle in a trial point's batch of 3 rollouts, filled with its first column. Truth mass
// 1.0, damping 0.3, stiffness 4.0; start 2.0 / 0.1 / 2.0 (log); noise sigma 1e-3 (seeds 3-5); 3 x
// 500 samples. The same estimates, costs and iterations as 1 thread bit for bit; the 2-thread fit
// simulates exactly the unused columns' steps more (every column taken is one its Jacobian
// does not simulate), and its Jacobian batches of 8 columns are 4 rounds on 2 workers.
TEST(FitLedgerTest, ColumnsAheadAreTheSameFitAndTheirUnusedStepsAreCounted) {
  ModelPtr m = LoadModel(kModels + "/spring_mass.xml");
  const std::vector<test::Truth> truth = {{"mass", test::Spec("body_mass", "mass"), 1.0},
                                          {"damping", test::Spec("joint_damping", "slide"), 0.3},
                                          {"k", test::Spec("joint_stiffness", "slide"), 4.0}};
  std::vector<FitResult> results;
  for (int threads : {1, 2}) {
    Problem problem;
    problem.AddModel("spring", *m);
    problem.AddParameter(
        FitParameter("mass", test::Spec("body_mass", "mass"), 2.0).Bounds(0.01, 100).Log());
    problem.AddParameter(
        FitParameter("damping", test::Spec("joint_damping", "slide"), 0.1).Bounds(1e-3, 10).Log());
    problem.AddParameter(
        FitParameter("k", test::Spec("joint_stiffness", "slide"), 2.0).Bounds(0.1, 100).Log());
    for (int i = 0; i < 3; ++i) {
      InitialState x0;
      const RowMatrix u = test::Excitation(*m, 500, 2.0, 1 + i);
      const RowMatrix y = test::Measure(*m, truth, x0, u, 1e-3, 3 + i);
      problem.AddSequence(FitSequence("seq" + std::to_string(i), "spring", x0, u, y));
    }
    FitOptions o;
    o.threads = threads;
    results.push_back(problem.Fit(o));
    ASSERT_TRUE(results.back().converged) << TerminationText(results.back().termination);
  }
  const FitResult &one = results[0], &two = results[1];
  EXPECT_EQ(one.iterations, two.iterations);
  EXPECT_EQ(one.final_cost, two.final_cost);
  for (size_t v = 0; v < one.parameters.size(); ++v) {
    EXPECT_EQ(one.parameters[v].value, two.parameters[v].value) << v;
    EXPECT_NEAR(one.parameters[v].value, truth[v].value, 1e-2 * truth[v].value) << v;
  }
  std::map<std::string, LedgerRow> by_phase;
  long long steps = 0;
  for (const LedgerRow& row : two.diagnostics.ledger) {
    by_phase[row.phase] = row;
    steps += row.steps;
  }
  EXPECT_EQ(steps, two.diagnostics.simulation_steps);
  for (const LedgerRow& row : one.diagnostics.ledger)
    EXPECT_NE(row.phase, FitPhaseName(kPhaseAheadUnused));
  ASSERT_EQ(by_phase.count(FitPhaseName(kPhaseAheadUnused)), 1u);
  const long long unused = by_phase[FitPhaseName(kPhaseAheadUnused)].steps;
  EXPECT_GT(unused, 0);  // the last trial's column at least
  EXPECT_EQ(unused % 500, 0);
  EXPECT_EQ(two.diagnostics.simulation_steps - one.diagnostics.simulation_steps, unused);
  const LedgerRow& jac = by_phase[FitPhaseName(kPhaseJacobians)];
  EXPECT_EQ(jac.steps % 4000, 0);  // 8 columns of 500 steps per Jacobian
  EXPECT_EQ(jac.critical_steps * 2, jac.steps);
}

}  // namespace
}  // namespace mjsysid
