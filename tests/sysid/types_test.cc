// The records of a fit's result (sysid/types.h) rendered as text: every kind's line as the result
// files, the command line and the report have always shown it, and every kind's name read back.
#include "sysid/types.h"

#include <gtest/gtest.h>

#include <string>

namespace mjsysid {
namespace {

TEST(FitTerminationTest, TextOfEveryKind) {
  FitTermination t;
  EXPECT_EQ(TerminationText(t), "");  // kNone: no solve
  t.solver_message = "Function tolerance reached. |cost_change|/cost: 1e-12 <= 1e-10";
  for (FitTermination::Kind kind :
       {FitTermination::Kind::kSolverConvergence, FitTermination::Kind::kIterationLimit,
        FitTermination::Kind::kSolverFailure, FitTermination::Kind::kCallbackStop,
        FitTermination::Kind::kCallbackAbort}) {
    t.kind = kind;
    EXPECT_EQ(TerminationText(t), t.solver_message) << TerminationKindName(kind);
  }
  t.kind = FitTermination::Kind::kGaussNewtonStop;
  t.fraction = 0.03;
  t.largest = 0.0134;
  t.iteration = 1;
  EXPECT_EQ(TerminationText(t),
            "converged: predicted Gauss-Newton step below 3 % of every standard error (largest "
            "1.3 %, iteration 1)");
  t.jacobian_iteration = 0;
  t.step_std_errors = 0.1234;
  EXPECT_EQ(TerminationText(t),
            "converged: predicted Gauss-Newton step below 3 % of every standard error (largest "
            "1.3 %, iteration 1); with the Jacobian of iteration 0, 0.12 standard errors from the "
            "estimate (the standard errors too; the estimate's own not simulated)");
  t.kind = FitTermination::Kind::kInterrupted;
  t.iteration = 4;
  EXPECT_EQ(TerminationText(t), "interrupted (a stop signal) after iteration 4");
  t.kind = FitTermination::Kind::kCheckpoint;
  EXPECT_EQ(TerminationText(t), "checkpoint after iteration 4");
  // read from a file: the text as written, whatever the numbers
  t.read_text = "as written";
  EXPECT_EQ(TerminationText(t), "as written");
}

TEST(FitTerminationTest, KindNamesReadBack) {
  for (FitTermination::Kind kind :
       {FitTermination::Kind::kNone, FitTermination::Kind::kSolverConvergence,
        FitTermination::Kind::kIterationLimit, FitTermination::Kind::kSolverFailure,
        FitTermination::Kind::kCallbackStop, FitTermination::Kind::kCallbackAbort,
        FitTermination::Kind::kGaussNewtonStop, FitTermination::Kind::kInterrupted,
        FitTermination::Kind::kCheckpoint, FitTermination::Kind::kUnknown}) {
    EXPECT_EQ(TerminationKindFromName(TerminationKindName(kind)), kind);
  }
  EXPECT_EQ(std::string(TerminationKindName(FitTermination::Kind::kGaussNewtonStop)),
            "gauss_newton_stop");
  EXPECT_FALSE(TerminationKindFromName("converged").has_value());
}

TEST(IntervalCheckRecordTest, TextOfEveryKind) {
  IntervalCheckRecord r;
  EXPECT_EQ(IntervalCheckText(r), "");  // kNotRun
  r.evaluations = 4;
  r.wide_fraction = 0.1;
  r.kind = IntervalCheckRecord::Kind::kRanRugged;
  r.rugged = "constraint rows come, go or change state in 12 steps";
  EXPECT_EQ(IntervalCheckText(r),
            "ran: 4 cost evaluations (constraint rows come, go or change state in 12 steps)");
  r.kind = IntervalCheckRecord::Kind::kRanSmooth;
  EXPECT_EQ(IntervalCheckText(r),
            "ran: 4 cost evaluations (smooth rollouts, standard errors above 10 % of the value)");
  r.kind = IntervalCheckRecord::Kind::kSkippedSmooth;
  r.skipped = 2;
  r.parameters = 2;
  r.evaluations = 0;
  EXPECT_EQ(IntervalCheckText(r),
            "skipped along 2 of the 2 simulator parameters (standard error <= 10 % of the value): "
            "the rollouts at the estimate have no contact, no constraint row that comes, goes or "
            "changes state, no kink and no Jacobian warning (a smooth cost); 0 cost evaluations "
            "along the other variables");
  r.read_text = "as written";
  EXPECT_EQ(IntervalCheckText(r), "as written");
}

TEST(IntervalCheckRecordTest, KindNamesReadBack) {
  for (IntervalCheckRecord::Kind kind :
       {IntervalCheckRecord::Kind::kNotRun, IntervalCheckRecord::Kind::kRanRugged,
        IntervalCheckRecord::Kind::kRanSmooth, IntervalCheckRecord::Kind::kSkippedSmooth,
        IntervalCheckRecord::Kind::kUnknown}) {
    EXPECT_EQ(IntervalCheckKindFromName(IntervalCheckKindName(kind)), kind);
  }
  EXPECT_FALSE(IntervalCheckKindFromName("ran").has_value());
}

TEST(SegmentRecordTest, TextOfThePartsPresent) {
  SegmentRecord r;
  r.choice = "auto: contact segments";
  EXPECT_EQ(SegmentReasonText(r), "auto: contact segments");
  r.start_source = "the logged qpos/qvel";
  r.weights = "continuity weights 1 x S / state spread";
  r.held_iterations = 3;
  r.held_initial_cost = 12.345;
  r.held_final_cost = 0.5;
  EXPECT_EQ(SegmentReasonText(r),
            "auto: contact segments; segment states from the logged qpos/qvel; continuity "
            "weights 1 x S / state spread; first 3 iterations with the segment states held on the "
            "data (cost 12.3 -> 0.5)");
}

}  // namespace
}  // namespace mjsysid
