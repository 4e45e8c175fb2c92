#include "sysid/types.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/text.h"

namespace mjsysid {

const char* ControlHoldName(ControlHold hold) {
  return hold == ControlHold::kLinear ? "linear" : "zoh";
}

const char* ControlBeforeName(ControlBefore before) {
  return before == ControlBefore::kZero ? "zero" : "hold";
}

const char* LossTypeName(LossType loss) {
  switch (loss) {
    case LossType::kHuber:
      return "huber";
    case LossType::kCauchy:
      return "cauchy";
    default:
      return "none";
  }
}

namespace {
constexpr FitStatus kAllStatuses[] = {FitStatus::kConverged,     FitStatus::kNotConverged,
                                      FitStatus::kModelMismatch, FitStatus::kJacobianUnreliable,
                                      FitStatus::kDidNotMove,    FitStatus::kInterrupted,
                                      FitStatus::kSolverFailed,  FitStatus::kLocalMinimum};
}  // namespace

const char* FitStatusName(FitStatus status) {
  switch (status) {
    case FitStatus::kConverged:
      return "converged";
    case FitStatus::kNotConverged:
      return "not_converged";
    case FitStatus::kModelMismatch:
      return "model_mismatch";
    case FitStatus::kJacobianUnreliable:
      return "jacobian_unreliable";
    case FitStatus::kDidNotMove:
      return "did_not_move";
    case FitStatus::kInterrupted:
      return "interrupted";
    case FitStatus::kSolverFailed:
      return "solver_failed";
    case FitStatus::kLocalMinimum:
      return "local_minimum";
  }
  return "not_converged";
}

std::optional<FitStatus> FitStatusFromName(const std::string& name) {
  for (FitStatus s : kAllStatuses) {
    if (name == FitStatusName(s)) return s;
  }
  return std::nullopt;
}

double FitParameter::ToVariable(double p) const {
  switch (transform) {
    case Transform::kLog:
      return p > 0 ? std::log(p) : -std::numeric_limits<double>::infinity();
    case Transform::kScale:
      return p / scale;
    default:
      return p;
  }
}

double FitParameter::FromVariable(double z) const {
  switch (transform) {
    case Transform::kLog:
      return std::exp(z);
    case Transform::kScale:
      return z * scale;
    default:
      return z;
  }
}

bool FitParameter::AppliesTo(const std::string& model_name) const {
  return models.empty() || model_name.empty() ||
         std::find(models.begin(), models.end(), model_name) != models.end();
}

SequenceResult WithStateColumns(const SequenceResult& s) {
  if (s.state_names.empty()) return s;
  SequenceResult out = s;
  out.sensor_names.insert(out.sensor_names.end(), s.state_names.begin(), s.state_names.end());
  out.sensor_dims.insert(out.sensor_dims.end(), s.state_dims.begin(), s.state_dims.end());
  // [sensors | states] side by side, sample by sample
  const auto join = [](const RowMatrix& a, const RowMatrix& b) {
    RowMatrix m(a.rows(), a.cols() + b.cols());
    m << a, b;
    return m;
  };
  out.measured = join(s.measured, s.state_measured);
  out.simulated_initial = join(s.simulated_initial, s.state_simulated_initial);
  out.simulated_final = join(s.simulated_final, s.state_simulated_final);
  if (s.simulated_one_piece.rows() > 0) {
    out.simulated_one_piece = join(
        s.simulated_one_piece,
        s.state_simulated_one_piece.rows() > 0
            ? s.state_simulated_one_piece
            : RowMatrix::Constant(s.state_simulated_final.rows(), s.state_simulated_final.cols(),
                                  std::numeric_limits<double>::quiet_NaN()));
  }
  for (Eigen::Index c = 0; c < s.state_measured.cols(); ++c) {
    out.missing.push_back(static_cast<int>(s.state_measured.col(c).array().isNaN().count()));
  }
  return out;
}

namespace {
constexpr FitTermination::Kind kAllTerminations[] = {FitTermination::Kind::kNone,
                                                     FitTermination::Kind::kSolverConvergence,
                                                     FitTermination::Kind::kIterationLimit,
                                                     FitTermination::Kind::kSolverFailure,
                                                     FitTermination::Kind::kCallbackStop,
                                                     FitTermination::Kind::kCallbackAbort,
                                                     FitTermination::Kind::kGaussNewtonStop,
                                                     FitTermination::Kind::kInterrupted,
                                                     FitTermination::Kind::kCheckpoint,
                                                     FitTermination::Kind::kUnknown};
constexpr IntervalCheckRecord::Kind kAllIntervalChecks[] = {
    IntervalCheckRecord::Kind::kNotRun, IntervalCheckRecord::Kind::kRanRugged,
    IntervalCheckRecord::Kind::kRanSmooth, IntervalCheckRecord::Kind::kSkippedSmooth,
    IntervalCheckRecord::Kind::kUnknown};
}  // namespace

std::string TerminationText(const FitTermination& t) {
  if (!t.read_text.empty()) return t.read_text;
  switch (t.kind) {
    case FitTermination::Kind::kNone:
    case FitTermination::Kind::kUnknown:
      return "";
    case FitTermination::Kind::kGaussNewtonStop: {
      std::string text = "converged: predicted Gauss-Newton step below " +
                         FormatDigits(100 * t.fraction, 3) +
                         " % of every standard error (largest " + FormatDigits(100 * t.largest, 2) +
                         " %, iteration " + std::to_string(t.iteration) + ")";
      if (t.jacobian_iteration >= 0) {
        text += "; with the Jacobian of iteration " + std::to_string(t.jacobian_iteration) + ", " +
                FormatDigits(t.step_std_errors, 2) +
                " standard errors from the estimate (the standard errors too; the estimate's own "
                "not simulated)";
      }
      return text;
    }
    case FitTermination::Kind::kInterrupted:
      return "interrupted (a stop signal) after iteration " + std::to_string(t.iteration);
    case FitTermination::Kind::kCheckpoint:
      return "checkpoint after iteration " + std::to_string(t.iteration);
    default:  // the solver's kinds
      return t.solver_message;
  }
}

const char* TerminationKindName(FitTermination::Kind kind) {
  switch (kind) {
    case FitTermination::Kind::kNone:
      return "none";
    case FitTermination::Kind::kSolverConvergence:
      return "solver_convergence";
    case FitTermination::Kind::kIterationLimit:
      return "iteration_limit";
    case FitTermination::Kind::kSolverFailure:
      return "solver_failure";
    case FitTermination::Kind::kCallbackStop:
      return "callback_stop";
    case FitTermination::Kind::kCallbackAbort:
      return "callback_abort";
    case FitTermination::Kind::kGaussNewtonStop:
      return "gauss_newton_stop";
    case FitTermination::Kind::kInterrupted:
      return "interrupted";
    case FitTermination::Kind::kCheckpoint:
      return "checkpoint";
    case FitTermination::Kind::kUnknown:
      return "unknown";
  }
  return "unknown";
}

std::optional<FitTermination::Kind> TerminationKindFromName(const std::string& name) {
  for (FitTermination::Kind k : kAllTerminations) {
    if (name == TerminationKindName(k)) return k;
  }
  return std::nullopt;
}

std::string IntervalCheckText(const IntervalCheckRecord& r) {
  if (!r.read_text.empty()) return r.read_text;
  const std::string wide = FormatDigits(100 * r.wide_fraction, 3) + " % of the value";
  switch (r.kind) {
    case IntervalCheckRecord::Kind::kRanRugged:
      return "ran: " + std::to_string(r.evaluations) + " cost evaluations (" + r.rugged + ")" +
             (r.envelope.empty() ? ""
                                 : "; the cost is rugged at the intervals' scale: " + r.envelope);
    case IntervalCheckRecord::Kind::kRanSmooth:
      return "ran: " + std::to_string(r.evaluations) +
             " cost evaluations (smooth rollouts, standard errors above " + wide + ")";
    case IntervalCheckRecord::Kind::kSkippedSmooth:
      return "skipped along " + std::to_string(r.skipped) + " of the " +
             std::to_string(r.parameters) + " simulator parameters (standard error <= " + wide +
             "): the rollouts at the estimate have no contact, no constraint row that comes, "
             "goes or changes state, no kink and no Jacobian warning (a smooth cost); " +
             std::to_string(r.evaluations) + " cost evaluations along the other variables";
    default:  // not run, unknown
      return "";
  }
}

const char* IntervalCheckKindName(IntervalCheckRecord::Kind kind) {
  switch (kind) {
    case IntervalCheckRecord::Kind::kNotRun:
      return "not_run";
    case IntervalCheckRecord::Kind::kRanRugged:
      return "ran_rugged";
    case IntervalCheckRecord::Kind::kRanSmooth:
      return "ran_smooth";
    case IntervalCheckRecord::Kind::kSkippedSmooth:
      return "skipped_smooth";
    case IntervalCheckRecord::Kind::kUnknown:
      return "unknown";
  }
  return "unknown";
}

std::optional<IntervalCheckRecord::Kind> IntervalCheckKindFromName(const std::string& name) {
  for (IntervalCheckRecord::Kind k : kAllIntervalChecks) {
    if (name == IntervalCheckKindName(k)) return k;
  }
  return std::nullopt;
}

std::string SegmentReasonText(const SegmentRecord& r) {
  std::string text = r.choice;
  if (!r.start_source.empty()) text += "; segment states from " + r.start_source;
  if (!r.weights.empty()) text += "; " + r.weights;
  if (r.held_iterations >= 0) {
    text += "; first " + std::to_string(r.held_iterations) +
            " iterations with the segment states held on the data (cost " +
            FormatDigits(r.held_initial_cost, 3) + " -> " + FormatDigits(r.held_final_cost, 3) +
            ")";
  }
  return text;
}

std::string ReductionText(const FitResult::Diagnostics::Reduction& r) {
  if (!r.used) return "off (solver.reduce_model: false)";
  std::string s = "collision pairs off " + std::to_string(r.collision_pairs_off) + " of " +
                  std::to_string(r.collision_pairs) + ", geoms off " + std::to_string(r.geoms_off) +
                  ", disabled [";
  for (size_t i = 0; i < r.disabled.size(); ++i) s += (i ? ", " : "") + r.disabled[i];
  s += "], guard trips " + std::to_string(r.guard_trips);
  if (r.guard_trips > 0) s += " (the full model was used from the first trip on)";
  return s;
}

}  // namespace mjsysid
