// SegmentEvaluator (sysid/fit/segment_evaluator.h): a shard's view of the fit state.
#include "sysid/fit/segment_evaluator.h"

#include <algorithm>

#include "sysid/fit/prepare.h"  // CheckParametersMove
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/fit_state.h"
#include "sysid/solve/state_residuals.h"

namespace mjsysid {

SegmentEvaluator::SegmentEvaluator(const FitParts& parts)
    : fit_(parts.fit), vars_(parts.vars), diag_(parts.diag), solve_(parts.solve) {}

FitParts SegmentEvaluator::Parts() const { return {fit_, vars_, diag_, solve_}; }

// -----------------------------------------------------------------------------------------------
// variables

int SegmentEvaluator::np() const { return static_cast<int>(vars_->z.size()); }
int SegmentEvaluator::nm() const { return static_cast<int>(vars_->m.size()); }
const std::vector<double>& SegmentEvaluator::z() const { return vars_->z; }
const std::vector<double>& SegmentEvaluator::m() const { return vars_->m; }

void SegmentEvaluator::SetVariables(const double* values) {
  std::copy(values, values + np(), vars_->z.begin());
  std::copy(values + np(), values + np() + nm(), vars_->m.begin());
}

// -----------------------------------------------------------------------------------------------
// data

int SegmentEvaluator::num_sequences() const { return static_cast<int>(fit_->sequences.size()); }
int SegmentEvaluator::num_segments() const { return static_cast<int>(fit_->segments.size()); }
const Segment& SegmentEvaluator::segment(int s) const { return fit_->segments[s]; }
const std::string& SegmentEvaluator::sequence_name(int q) const { return fit_->sequences[q].name; }
const StateDims& SegmentEvaluator::dims(int s) const {
  return fit_->models[fit_->segments[s].model].sim->dims();
}
const StateManifold& SegmentEvaluator::manifold(int s) const {
  return *fit_->models[fit_->segments[s].model].manifold;
}

double SegmentEvaluator::SequenceWork(int q) const { return fit_->SequenceWork(q); }

bool SegmentEvaluator::free_states() const {
  return std::any_of(fit_->segments.begin(), fit_->segments.end(),
                     [](const Segment& seg) { return seg.block >= 0; });
}

StateBlocks& SegmentEvaluator::states() { return vars_->states; }
const StateBlocks& SegmentEvaluator::states() const { return vars_->states; }
const double* SegmentEvaluator::X0(int s) const { return fit_->X0(vars_->states, s); }

// -----------------------------------------------------------------------------------------------
// evaluation

void SegmentEvaluator::Prefetch(const std::vector<const double*>& x0, bool jacobians) {
  solve_->cache->Prefetch(np() ? vars_->z.data() : nullptr, x0, jacobians);
}

std::unique_ptr<ceres::CostFunction> SegmentEvaluator::SensorCost(int s) const {
  return std::make_unique<SegmentCost>(Parts(), s);
}

std::unique_ptr<ceres::CostFunction> SegmentEvaluator::StateCost(int s) const {
  if (!fit_->segments[s].state_rows) return nullptr;
  return std::make_unique<mjsysid::StateCost>(Parts(), s);
}

// -----------------------------------------------------------------------------------------------
// diagnostics

const std::string* SegmentEvaluator::JacobianWarning(int s) const {
  const auto it = diag_->jacobian_warnings.find(s);
  return it == diag_->jacobian_warnings.end() ? nullptr : &it->second;
}

void SegmentEvaluator::NoteRejection(const std::string& what) { diag_->NoteRejection(what); }

void SegmentEvaluator::NoteJacobianWarning(int s, const std::string& what) {
  diag_->NoteJacobianWarning(s, what);
}

SegmentEvaluator::Rejections SegmentEvaluator::rejections() const {
  return {diag_->rejected_evaluations, diag_->first_rejection};
}

void SegmentEvaluator::RestoreRejections(const Rejections& r) {
  diag_->rejected_evaluations = r.count;
  diag_->first_rejection = r.first;
}

// -----------------------------------------------------------------------------------------------
// the preparation's facts

const std::vector<bool>& SegmentEvaluator::moves() const { return fit_->moves; }

void SegmentEvaluator::CheckMoves(const std::vector<bool>& all) const {
  CheckParametersMove(*fit_, all);
}

std::vector<double> SegmentEvaluator::InitialValues() const {
  std::vector<double> values;
  for (const FitParameter& p : fit_->params) values.push_back(p.initial);
  return values;
}

int SegmentEvaluator::segment_steps() const { return fit_->options.segment_steps; }

}  // namespace mjsysid
