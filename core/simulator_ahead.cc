// Speculation: Jacobian columns computed ahead of being asked for, behind the rollouts of a batch
// on the workers those rollouts leave idle (RolloutWithColumnsAhead), kept with the parameter
// values and options they belong to, and taken by the next Jacobians call that matches them.
#include <algorithm>
#include <utility>
#include <vector>

#include "core/simulator.h"
#include "core/simulator_internal.h"

namespace mjsysid {
namespace {

// whether columns computed with options a are those options b ask for
bool SameColumns(const JacobianOptions& a, const JacobianOptions& b) {
  return a.mode == b.mode && a.central == b.central && a.relative_step == b.relative_step &&
         a.step_floor == b.step_floor && a.parameter_steps == b.parameter_steps &&
         a.state_step == b.state_step && a.initial_state == b.initial_state &&
         a.state_jacobians == b.state_jacobians;
}

}  // namespace

void Simulator::RolloutWithColumnsAhead(const std::vector<SequenceInput>& sequences,
                                        const JacobianOptions& opt, const std::vector<int>& columns,
                                        std::vector<Trajectory>* nominal,
                                        std::vector<ColumnsAhead>* ahead) {
  const int ncol = params_.size() + (opt.initial_state ? dims_.nx : 0);
  ahead->assign(sequences.size(), ColumnsAhead());
  std::vector<int> end(sequences.size(), 0);
  bool any = false;
  for (size_t i = 0; i < sequences.size() && i < columns.size(); ++i) {
    end[i] = std::clamp(columns[i], 0, ncol);
    any = any || end[i] > 0;
  }
  if (!any || !CanPipeline(opt, ncol)) {
    Rollout(sequences, nominal);
    return;
  }
  try {
    Guarded([&] {
      SizeTrajectories(sequences, nominal);
      std::vector<Sensitivity> out;
      JacobiansImpl(sequences, *nominal, opt, &out, nominal, ahead, &end);
    });
  } catch (const Cancelled&) {
    throw;
  } catch (...) {
    // a failed rollout or column: the rollouts alone again, so that only a rollout's own failure
    // reaches the caller, as from Rollout (a column's would fail the Jacobians, if asked for)
    ahead->assign(sequences.size(), ColumnsAhead());
    Rollout(sequences, nominal);
  }
}

void Simulator::Jacobians(const std::vector<SequenceInput>& sequences,
                          const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                          std::vector<ColumnsAhead>* ahead, std::vector<Sensitivity>* out) {
  Guarded([&] { JacobiansImpl(sequences, nominal, opt, out, nullptr, ahead); });
}

namespace internal {

void TakeColumnsAhead(const Eigen::VectorXd& p, const JacobianOptions& opt, int ncol,
                      std::vector<ColumnsAhead>* ahead, std::vector<Sensitivity>* out,
                      std::vector<SolverStats>* perturbed, std::vector<int>* begin) {
  for (size_t i = 0; i < out->size(); ++i) {
    ColumnsAhead& a = (*ahead)[i];
    if (a.columns <= 0 || a.s.ncol != ncol || a.at.size() != p.size() || a.at != p ||
        !SameColumns(a.options, opt) || a.s.DyDp.rows() != (*out)[i].DyDp.rows() ||
        a.s.DxDp.rows() != (*out)[i].DxDp.rows()) {
      continue;
    }
    (*out)[i] = std::move(a.s);
    (*perturbed)[i] = a.perturbed;
    (*begin)[i] = a.columns;
    a = ColumnsAhead();  // taken
  }
}

void KeepColumnsAhead(const Eigen::VectorXd& p, const JacobianOptions& opt, int ncol,
                      const std::vector<int>& end, const std::vector<long long>& task_steps,
                      std::vector<SolverStats>* perturbed, std::vector<Sensitivity>* out,
                      std::vector<ColumnsAhead>* ahead) {
  for (size_t i = 0; i < out->size(); ++i) {
    ColumnsAhead& a = (*ahead)[i];
    a.columns = end[i];
    a.at = p;
    a.options = opt;
    a.s = std::move((*out)[i]);
    a.perturbed = (*perturbed)[i];
    for (int col = 0; col < end[i]; ++col) a.steps += task_steps[i * ncol + col];
  }
}

}  // namespace internal
}  // namespace mjsysid
