// DecideFitStatus (sysid/assess/fit_status.h) on hand-made results: a Ceres failure is its own
// status, solver_failed, whatever steps were accepted before it, never did_not_move or
// not_converged, with Ceres' message and the way out in its warning.
#include "sysid/assess/fit_status.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace mjsysid
