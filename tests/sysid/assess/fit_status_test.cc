// DecideFitStatus (sysid/assess/fit_status.h) on hand-made results: a Ceres failure is its own
// status, solver_failed, whatever steps were accepted before it, never did_not_move or
// not_converged, with Ceres' message and the way out in its warning. Without sigmas, a sensor
// whose noise the log does not show is not checked, and a warning says so with its % fit.
#include "sysid/assess/fit_status.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace mjsysid {
namespace {

// a result of two parameters as a solve leaves it; moved: the estimate left its start
FitResult Solved(bool moved) {
  FitResult r;
  r.initial_cost = 100;
  r.final_cost = moved ? 50 : 100;
  for (const char* name : {"mass", "damping"}) {
    ParameterEstimate e;
    e.name = name;
    e.initial = 1.0;
    e.value = moved ? 1.2 : 1.0;
    r.parameters.push_back(e);
  }
  return r;
}

bool HasWarning(const FitResult& r, const std::string& text) {
  for (const std::string& w : r.warnings) {
    if (w.find(text) != std::string::npos) return true;
  }
  return false;
}

// the message Ceres 2.1 gives when CHOLMOD cannot factorise (the humanoid of issue 32)
const char* const kCeresMessage =
    "Linear solver failed due to unrecoverable non-numeric causes. Please see the error log for "
    "clues. ";

TEST(DecideFitStatusTest, ACeresFailureIsSolverFailedWithItsMessage) {
  for (bool moved : {false, true}) {
    SCOPED_TRACE(moved ? "after accepted steps" : "at the start");
    FitResult r = Solved(moved);
    r.termination.kind = FitTermination::Kind::kSolverFailure;
    r.termination.solver_message = kCeresMessage;
    DecideFitStatus(FitOptions(), moved ? 3 : 0, false, &r);
    EXPECT_EQ(r.outcome, FitStatus::kSolverFailed);
    EXPECT_STREQ(FitStatusName(r.outcome), "solver_failed");
    EXPECT_FALSE(r.intervals_valid);
    // Ceres' trailing space dropped
    EXPECT_TRUE(HasWarning(r, std::string("solver failed: Ceres stopped with a failure (") +
                                  "Linear solver failed due to unrecoverable non-numeric causes. "
                                  "Please see the error log for clues.) after " +
                                  (moved ? "3" : "0") + " accepted steps"));
    EXPECT_TRUE(HasWarning(r, "segment_steps"));
    EXPECT_FALSE(HasWarning(r, "did not move"));
  }
}

// the same result without the failure: did_not_move at the start, converged after steps
TEST(DecideFitStatusTest, WithoutTheFailureTheUsualVerdicts) {
  FitResult still = Solved(false);
  DecideFitStatus(FitOptions(), 0, false, &still);
  EXPECT_EQ(still.outcome, FitStatus::kDidNotMove);
  FitResult moved = Solved(true);
  moved.converged = true;
  DecideFitStatus(FitOptions(), 3, false, &moved);
  EXPECT_EQ(moved.outcome, FitStatus::kConverged);
}

// an interrupt still comes first
TEST(DecideFitStatusTest, AnInterruptComesBeforeTheFailure) {
  FitResult r = Solved(true);
  r.interrupted = true;
  r.termination.kind = FitTermination::Kind::kSolverFailure;
  DecideFitStatus(FitOptions(), 3, false, &r);
  EXPECT_EQ(r.outcome, FitStatus::kInterrupted);
}

// a converged result with one sequence of `rows` samples of a 1-D sensor `angle`: measured a
// sine with white-ish noise 1e-3 (a fixed pattern), simulated the sine scaled by `scale`
FitResult WithSequence(int rows, double scale) {
  FitResult r = Solved(true);
  r.converged = true;
  SequenceResult s;
  s.name = "seq0";
  s.sensor_names = {"angle"};
  s.sensor_dims = {1};
  s.time.resize(rows);
  s.measured.resize(rows, 1);
  s.simulated_final.resize(rows, 1);
  for (int k = 0; k < rows; ++k) {
    s.time[k] = 0.01 * k;
    const double motion = std::sin(2.0 * s.time[k]);
    s.measured(k, 0) = motion + 1e-3 * ((k * 7919) % 13 - 6) / 6.0;
    s.simulated_final(k, 0) = scale * motion;
  }
  r.sequences.push_back(s);
  return r;
}

TEST(DecideFitStatusTest, WithoutANoiseEstimateTheModelCheckIsNotPossible) {
  // 9 samples: 7 triples of consecutive samples, too few for a noise estimate; half the motion
  // unexplained (% fit far below 90): converged (nothing tested it), and the warning says so
  FitResult r = WithSequence(9, 0.5);
  DecideFitStatus(FitOptions(), 3, false, &r);
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
  EXPECT_TRUE(r.sensor_noise_ratio.empty());
  EXPECT_TRUE(HasWarning(r, "model check not possible: no sigma"));
  EXPECT_TRUE(HasWarning(r, "for angle (% fit "));
  EXPECT_TRUE(HasWarning(r, "a % fit below 90 leaves a visible part of the motion unexplained"));
  // the same motion reproduced: still not checked, no low-fit clause
  FitResult good = WithSequence(9, 1.0);
  DecideFitStatus(FitOptions(), 3, false, &good);
  EXPECT_TRUE(HasWarning(good, "model check not possible: no sigma"));
  EXPECT_FALSE(HasWarning(good, "a % fit below 90"));
  // with a sigma the chi-square test applies: nothing to say about a check not made
  FitOptions sigma;
  sigma.sensor_weights["angle"] = 1e3;
  sigma.sensors_with_sigma = {"angle"};
  FitResult with_sigma = WithSequence(9, 1.0);
  DecideFitStatus(sigma, 3, false, &with_sigma);
  EXPECT_FALSE(HasWarning(with_sigma, "model check not possible"));
  // 200 samples: the noise is estimated and the unexplained half is a model mismatch
  FitResult longer = WithSequence(200, 0.5);
  DecideFitStatus(FitOptions(), 3, false, &longer);
  EXPECT_EQ(longer.outcome, FitStatus::kModelMismatch);
  EXPECT_EQ(longer.sensor_noise_ratio.count("angle"), 1u);
  EXPECT_FALSE(HasWarning(longer, "model check not possible"));
}

}  // namespace
}  // namespace mjsysid
