// The robust suite (ctest label `robust`; the table of cases is docs/stress.md): models written in
// the style of public control benchmark suites (models/robust/*.xml: cart-pole, acrobot, finger,
// planar hopper and walker, a free-floating crate), each with its experiment
// (experiments/robust/*.yaml: several parameter kinds, PRBS excitation, sensor noise of 1 % of
// each signal's spread, every start 40 % off its truth), simulated from the truth and fitted
// through the real experiment runner (sim::SimulateExperiment, run::RunFit: what `sysid simulate`
// and `sysid fit` run).
//
// Per case the test asserts honesty: a fit that says `converged` (exit code 0, intervals valid)
// has every truth within 4 of its reported standard errors (a 95 % interval misses 1 truth in 20
// and the suite has ~27 parameters; tests/sysid/problem_test.cc tests the calibration over 100
// seeds); any other ending has a non-zero exit code and says its intervals are not valid. Then,
// separately, kRecovery lists the cases that must also recover (converged, every estimate within
// 5 % of its truth): the goal is all of them; kWithin5Percent the cases whose every estimate
// must be within 5 % while their status honestly says the intervals are not valid.
//
// The shooting mode is the experiment's default (no multiple_shooting key); the environment
// variable MJSYSID_ROBUST_SEGMENT_STEPS=N overrides FitOptions::segment_steps for every case (the
// numbers of docs/stress.md for single and multiple shooting were measured that way).
// MJSYSID_STRESS_LONG=1 (ctest -L long: robust_suite_test.long) doubles every log's sequences
// and asserts honesty only (today single shooting does not recover on the added sequences).
// Every case prints `[ robust ]` lines: ctest -L robust -V | grep '\[ robust \]'.
// The per-case work (simulate, fit, the honesty checks) is tests/stress/suite_harness.h, shared
// with the outside suite (tests/stress/outside_suite_test.cc).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "tests/stress/suite_harness.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
const std::string kSuite = std::string(MJSYSID_EXPERIMENTS_DIR) + "/robust";

// the cases, one experiment file each
const std::vector<std::string> kCases = {"cartpole_swing", "acrobot", "finger",
                                         "hopper",         "walker",  "crate"};

// the cases that must recover today with the experiment default (`multiple_shooting: auto`):
// converged, every estimate within kTolerance of its truth. The goal is every case
// (docs/stress.md).
// (the hopper and walker since the envelope check of rugged costs, issue 32)
const std::vector<std::string> kRecovery = {"cartpole_swing", "acrobot", "finger", "hopper",
                                            "walker"};
// the cases whose every estimate must be within kTolerance of its truth although the fit is not
// `converged` (none since the envelope check; before it the hopper and walker, whose interval
// check found their contact costs jumping within one standard error)
const std::vector<std::string> kWithin5Percent = {};
constexpr double kTolerance = 0.05;  // relative

bool LongMode() {
  const char* v = std::getenv("MJSYSID_STRESS_LONG");
  return v && std::string(v) == "1";
}

// MJSYSID_ROBUST_SEGMENT_STEPS, or -2 when unset (keep the experiment's)
int SegmentStepsOverride() {
  const char* v = std::getenv("MJSYSID_ROBUST_SEGMENT_STEPS");
  return v && *v ? std::atoi(v) : -2;
}

class RobustSuiteTest : public ::testing::TestWithParam<std::string> {};

TEST_P(RobustSuiteTest, EndsHonestly) {
  const std::string name = GetParam();
  io::ExperimentConfig cfg = io::LoadExperiment(kSuite + "/" + name + ".yaml");
  if (LongMode()) cfg.simulate.sequences *= 2;
  const int segment_steps = SegmentStepsOverride();
  if (segment_steps >= -1) cfg.options.segment_steps = segment_steps;
  cfg.options.verbose = false;

  // every start 40 % off its truth; the noise 1 % of each signal's spread in the noiseless log,
  // and the fit's sigma is the noise
  suite::ExpectStartsOffTruth(cfg);
  suite::ExpectNoiseOnePercent(cfg, "robust", name);
  if (::testing::Test::HasFatalFailure()) return;

  // simulate the noisy log and fit it, as `sysid simulate` and `sysid fit` do
  suite::CaseRun run;
  suite::SimulateAndFit(cfg, "robust", name, &run);
  if (::testing::Test::HasFatalFailure()) return;
  const run::FitRunOutcome& out = run.out;
  const double worst = run.worst;

  // the numbers of the table (docs/stress.md)
  std::printf(
      "[ robust ] | %s | %zu | %d x %d | %s | %d | %.2f %% | %s (within 4 std: %s) | %d | %.1f s "
      "| segment_steps %d |\n",
      name.c_str(), out.file.parameters.size(), static_cast<int>(out.file.sequences.size()),
      out.file.sequences.empty() ? 0 : run.steps / static_cast<int>(out.file.sequences.size()),
      out.file.status.c_str(), out.exit_code, 100 * worst, run.in_ci95 ? "yes" : "no",
      run.in_4std ? "yes" : "no", out.file.iterations, run.seconds, cfg.options.segment_steps);
  std::printf("[ robust ] %s:   shooting: %s\n", name.c_str(),
              SegmentReasonText(out.file.segment_reason).c_str());
  for (const std::string& w : out.file.warnings) {
    std::printf("[ robust ] %s:   warning: %s\n", name.c_str(), w.c_str());
  }
  // fitted sensors that jump at contact events are named (sysid/data/contact_channels.h): the
  // finger's and hopper's touch sensors, the hopper's, walker's and crate's accelerometers; the
  // contact-free cart-pole and acrobot have none
  int jumping = 0;
  for (const std::string& w : out.file.warnings) {
    jumping += w.find("jumps when a contact switches") != std::string::npos ? 1 : 0;
  }
  const std::map<std::string, int> kJumping = {{"cartpole_swing", 0}, {"acrobot", 0}, {"finger", 1},
                                               {"hopper", 2},         {"walker", 1},  {"crate", 1}};
  EXPECT_EQ(jumping, kJumping.at(name)) << "sensors named as jumping at contact events";
  // auto (no override): the cases whose contacts change at events (finger, hopper, walker) get
  // contact segments started on the logged states and leave those sensors out of the fit, saying
  // so (sysid/solve/multiple_shooting.h); the crate's contacts chatter (~20 % of the steps) and the
  // contact-free cases have none: they keep single shooting
  if (segment_steps == -2) {
    int omitted = 0;
    for (const std::string& w : out.file.warnings) {
      omitted += w.find("left out of the fit") != std::string::npos ? 1 : 0;
    }
    const bool events = name == "finger" || name == "hopper" || name == "walker";
    EXPECT_EQ(omitted, events ? kJumping.at(name) : 0) << "jumping sensors left out of the fit";
    const bool contact_segments =
        SegmentReasonText(out.file.segment_reason).find("change their contact count") !=
        std::string::npos;
    EXPECT_EQ(contact_segments, events) << SegmentReasonText(out.file.segment_reason);
    // and start with the segment states held on the data (sysid/solve/multiple_shooting.h,
    // SolveWithStatesHeld), saying so; so does a global-stage pass in segments when it is the
    // result (the crate since auto keeps its 64-step refit: sysid/fit/policy.cc)
    const bool held =
        SegmentReasonText(out.file.segment_reason).find("held on the data") != std::string::npos;
    bool stage_kept = false;
    for (const std::string& w : out.file.warnings) {
      stage_kept = stage_kept || (w.rfind("global stage:", 0) == 0 &&
                                  w.find("this result is the lower point") != std::string::npos);
    }
    EXPECT_EQ(held, events || (stage_kept && out.file.segment_steps_used > 0))
        << SegmentReasonText(out.file.segment_reason);
  }

  // honest: converged means exit 0, valid intervals and every truth inside them; anything else
  // is a non-zero exit code with intervals not valid; what a user reads back says the same
  suite::ExpectHonest(run);

  // recovery where it is expected today, on the default logs (the long mode's added sequences
  // are recorded: docs/stress.md)
  if (!LongMode() && std::count(kRecovery.begin(), kRecovery.end(), name)) {
    EXPECT_EQ(out.file.outcome, FitStatus::kConverged) << TerminationText(out.file.termination);
    EXPECT_LE(worst, kTolerance) << "worst relative error";
  }
  if (!LongMode() && std::count(kWithin5Percent.begin(), kWithin5Percent.end(), name)) {
    EXPECT_LE(worst, kTolerance) << "worst relative error (" << out.file.status << ")";
  }
  fs::remove_all(run.dir);
}

INSTANTIATE_TEST_SUITE_P(Cases, RobustSuiteTest, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<std::string>& c) { return c.param; });

}  // namespace
}  // namespace mjsysid
