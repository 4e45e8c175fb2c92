#include "sysid/types.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {

const char* ControlHoldName(ControlHold hold) {
  return hold == ControlHold::kLinear ? "linear" : "zoh";
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
                                      FitStatus::kDidNotMove,    FitStatus::kInterrupted};
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
  for (Eigen::Index c = 0; c < s.state_measured.cols(); ++c) {
    out.missing.push_back(static_cast<int>(s.state_measured.col(c).array().isNaN().count()));
  }
  return out;
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
