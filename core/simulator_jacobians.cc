// Jacobians of a batch: the entry points (Jacobians, RolloutAndJacobians), the checks and sizes
// they share, and the dispatch to the column tasks (simulator_columns.cc) or the matrix chain
// (simulator_matrix.cc); the columns computed ahead are taken and kept by simulator_ahead.cc.
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/simulator.h"
#include "core/simulator_internal.h"

namespace mjsysid {

void Simulator::Jacobians(const std::vector<SequenceInput>& sequences,
                          const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                          std::vector<Sensitivity>* out) {
  Guarded([&] { JacobiansImpl(sequences, nominal, opt, out, nullptr); });
}

void Simulator::RolloutAndJacobians(const std::vector<SequenceInput>& sequences,
                                    const JacobianOptions& opt, std::vector<Trajectory>* nominal,
                                    std::vector<Sensitivity>* out) {
  const int ncol = params_.size() + (opt.initial_state ? dims_.nx : 0);
  if (!CanPipeline(opt, ncol)) {
    Rollout(sequences, nominal);
    Jacobians(sequences, *nominal, opt, out);
    return;
  }
  Guarded([&] {
    SizeTrajectories(sequences, nominal);
    JacobiansImpl(sequences, *nominal, opt, out, nominal);
  });
}

Sensitivity Simulator::Jacobians(const SequenceInput& sequence, const Trajectory& nominal,
                                 const JacobianOptions& options) {
  std::vector<Sensitivity> out;
  Jacobians({sequence}, {nominal}, options, &out);
  return std::move(out[0]);
}

// the outputs of a batch sized and zeroed, after checking each nominal trajectory against its
// sequence
void Simulator::SizeSensitivities(const std::vector<SequenceInput>& sequences,
                                  const std::vector<Trajectory>& nominal,
                                  const JacobianOptions& opt, JacobianMode mode, int ncol,
                                  std::vector<Sensitivity>* out) const {
  const int nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  out->assign(sequences.size(), Sensitivity());
  for (size_t i = 0; i < sequences.size(); ++i) {
    const Trajectory& tr = nominal[i];
    if (tr.T != sequences[i].ctrl.rows() || tr.step.rows() != tr.T + 1 ||
        tr.inputs.size() != dims_.ninput) {
      throw std::invalid_argument("Jacobians: nominal trajectory " + std::to_string(i) +
                                  " does not match its sequence (call Rollout first)");
    }
    Sensitivity& s = (*out)[i];
    s.mode = mode;
    s.ncol = ncol;
    s.DyDp.setZero(static_cast<Eigen::Index>(tr.T) * ns, ncol);
    if (opt.state_jacobians) s.DxDp.setZero(static_cast<Eigen::Index>(tr.T + 1) * nx, ncol);
  }
}

// the workers' vectors of one perturbed step (a column's or a matrix step's), before the parallel
// tasks: no allocation inside them
void Simulator::SizeColumnScratch() {
  const int nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  for (auto& w : workers_) {
    w->s.resize(nx);
    w->s_next.resize(nx);
    w->e.resize(nx);
    w->xp.resize(dims_.nphys);
    w->xm.resize(dims_.nphys);
    w->yp.resize(ns);
    w->ym.resize(ns);
    w->fx.resize(nx);
    w->fy.resize(ns);
  }
}

void Simulator::JacobiansImpl(const std::vector<SequenceInput>& sequences,
                              const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                              std::vector<Sensitivity>* out, std::vector<Trajectory>* rollouts,
                              std::vector<ColumnsAhead>* ahead, const std::vector<int>* ahead_end) {
  CheckInputs(sequences);
  if (nominal.size() != sequences.size()) {
    throw std::invalid_argument("Jacobians: " + std::to_string(sequences.size()) +
                                " sequences but " + std::to_string(nominal.size()) +
                                " nominal trajectories");
  }
  const int np = params_.size(), nx = dims_.nx;
  const int ncol = np + (opt.initial_state ? nx : 0);
  // pipelined: the rollouts are still to come, and the mode is the same for any contact share
  const JacobianMode mode = CheckedJacobianMode(opt, rollouts ? 0.0 : ContactFraction(nominal));
  const Eigen::VectorXd steps = ParameterSteps(opt);
  SizeSensitivities(sequences, nominal, opt, mode, ncol, out);
  if (ncol == 0) return;

  SizeColumnScratch();

  // constraint solves of the perturbed steps, per sequence
  std::vector<SolverStats> perturbed(sequences.size());

  // columns computed ahead: only the first ahead_end[i] now; or the columns of ahead[i] that
  // belong to these parameter values and options taken (moved: a call without rollouts is never
  // simulated again by Guarded), the rest computed
  std::vector<int> begin(sequences.size(), 0), end(sequences.size(), ncol);
  if (ahead && ahead_end) {
    end = *ahead_end;
  } else if (ahead && ahead->size() == sequences.size() && mode == JacobianMode::kDirectional) {
    internal::TakeColumnsAhead(GetParameters(), opt, ncol, ahead, out, &perturbed, &begin);
  }
  if (mode == JacobianMode::kMatrix) {
    PrepareMatrixModels(steps);
    for (size_t i = 0; i < sequences.size(); ++i) {
      MatrixJacobian(sequences[i].ctrl, static_cast<int>(i), nominal[i], opt, steps, &(*out)[i],
                     &perturbed[i]);
    }
  } else {
    std::vector<long long> task_steps;
    ColumnJacobians(sequences, nominal, opt, mode, steps, out, &perturbed, rollouts, &begin, &end,
                    ahead_end ? &task_steps : nullptr);
    if (ahead_end) {
      // the columns ahead are kept for Jacobians; no warnings and checks before the rest is there
      internal::KeepColumnsAhead(GetParameters(), opt, ncol, end, task_steps, &perturbed, out,
                                 ahead);
      return;
    }
  }
  for (size_t i = 0; i < sequences.size(); ++i) {
    for (std::string& w : SolverWarnings(*model_, nominal[i].solver, perturbed[i])) {
      (*out)[i].warnings.push_back(std::move(w));
    }
  }
  if (opt.zero_column_is_error) CheckZeroColumns(*out);
}

void Simulator::CheckZeroColumns(const std::vector<Sensitivity>& out) const {
  // a parameter that moves nothing in any sequence cannot be fitted: say so, by name
  for (int j = 0; j < params_.size(); ++j) {
    bool zero = true;
    for (const Sensitivity& s : out) {
      zero = zero && (s.DyDp.rows() == 0 || s.DyDp.col(j).isZero(0)) &&
             (s.DxDp.rows() == 0 || s.DxDp.col(j).isZero(0));
    }
    if (zero) {
      throw ParameterError("parameter '" + params_[j].label() +
                           "' has no effect on the simulated states or sensors of these "
                           "sequences (its Jacobian column is exactly zero): e.g. contact "
                           "friction without contact, or a joint that never moves. Remove it "
                           "or add data that excites it.");
    }
  }
}

}  // namespace mjsysid
