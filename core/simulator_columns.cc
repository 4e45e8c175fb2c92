// Jacobian columns one task each: directional columns (one perturbed step per time step, from the
// nominal state moved along the column's sensitivity; pipelined behind their rollout where one is
// still running) and whole-rollout columns (whole perturbed rollouts), and the batch that hands
// them out on the workers (ColumnJacobians).
#include <atomic>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "core/simulator_internal.h"
#include "core/text.h"

namespace mjsysid {

using internal::CombineSides;
using internal::CopyModelInto;
using internal::kGrowthLimit;
using internal::kSplitGrowth;
using internal::Tenths;
using internal::WaitForRows;

// one directional column of one sequence: S_{k+1} from one perturbed step per side at each k
void Simulator::DirectionalColumn(Worker& w, const RowMatrix& ctrl, int seq_index,
                                  const Trajectory& nom, const JacobianOptions& opt, int col,
                                  const Eigen::VectorXd& steps, Sensitivity* out,
                                  TaskReport* report, const std::atomic<int>* ready) const {
  const int np = params_.size(), nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int T = nom.T;
  mjData* d = w.data.get();
  const bool is_param = col < np;
  const double h = is_param ? steps[col] : opt.state_step;

  // perturbed models: parameter col at p + h and p - h (state columns use the nominal values)
  CopyModelInto(w.plus.get(), model_.get());
  CopyModelInto(w.minus.get(), model_.get());
  if (is_param) {
    const double p = params_[col].Read(*model_);
    params_.WriteOne(w.plus.get(), d, col, p + h);
    params_.WriteOne(w.minus.get(), d, col, p - h);
  }

  // S_0: zero for a parameter, the unit tangent direction for an initial-state column
  w.s.setZero(nx);
  if (!is_param) w.s[col - np] = 1.0;
  if (opt.state_jacobians) out->DxDp.block(0, col, nx, 1) = w.s;
  ClearSimulationWarnings(d);
  // a pipelined column follows its rollout: the inputs first, then step k once x_{k+1} is there
  if (!WaitForRows(ready, 1)) return;
  RestoreInputs(*model_, dims_, nom, d);
  double max_growth = 0;
  int growth_step = -1;
  int split_steps = 0;  // steps past kSplitGrowth

  // one perturbed step of model m from the nominal x_k moved along x_scale*S_k: leaves the
  // difference quotients of x_{k+1} and y_k, times inv, in dx, dy; returns its contact count
  auto side = [&](const mjModel* m, double x_scale, double inv, int k, Eigen::VectorXd& dx,
                  Eigen::VectorXd& dy) {
    RestoreStep(*m, dims_, nom, k, ctrl.row(k).data(), d);
    if (x_scale != 0) TangentPerturb(*m, d, w.s.data(), x_scale);
    Step(m, d, mjSTAGE_NONE);
    ++w.steps;
    CheckStep(*d, nom.step(k, 0), seq_index, k, "perturbed step");  // step state: time first
    CountSolve(*m, *d, &report->solver);
    GetPhysics(*m, *d, w.xp.data());
    TangentDifference(*model_, nom.states.row(k + 1).data(), w.xp.data(), inv, dx.data());
    for (int i = 0; i < ns; ++i) dy[i] = (d->sensordata[i] - nom.sensors(k, i)) * inv;
    return d->ncon;
  };
  // the difference of models (plus, minus) with the state moved by +-x_scale*S_k, divided by
  // +-step: forward, and backward too for central differences or a contact-set change; the
  // result in dx_out, dy_out (w.s_next and w.yp may be passed)
  auto difference = [&](const mjModel* plus, const mjModel* minus, double x_scale, double step,
                        int k, Eigen::VectorXd& dx_out, Eigen::VectorXd& dy_out) {
    const int ncon = side(plus, x_scale, 1.0 / step, k, dx_out, dy_out);
    if (opt.central || ncon != nom.ncon[k]) {
      side(minus, -x_scale, -1.0 / step, k, w.e, w.ym);
      if (CombineSides(dx_out, w.e, dy_out, w.ym, opt.central, w.xm.head(nx), dy_out)) {
        ++report->kinks;
      }
      dx_out = w.xm.head(nx);
    }
  };

  Tenths tenths(step_progress_, "Jacobian column", T);
  for (int k = 0; k < T; ++k) {
    CheckCancel();
    tenths.At(k);
    if (!WaitForRows(ready, k + 2)) return;
    const double s_norm = w.s.lpNorm<Eigen::Infinity>();
    if (h * s_norm <= kSplitGrowth) {
      // one step: parameter at p +- h and state moved by +-h*S_k
      difference(w.plus.get(), w.minus.get(), h, h, k, w.s_next, w.yp);
    } else {
      // A_k S_k: the state moved along S_k scaled to the state step, the nominal model
      ++split_steps;
      const double a = opt.state_step / s_norm;
      difference(model_.get(), model_.get(), a, a, k, w.s_next, w.yp);
      if (is_param) {
        // + F_k, G_k: the parameter at p +- h from the nominal state
        difference(w.plus.get(), w.minus.get(), 0.0, h, k, w.fx, w.fy);
        w.s_next += w.fx;
        w.yp += w.fy;
      }
    }
    for (int i = 0; i < ns; ++i) out->DyDp(k * ns + i, col) = w.yp[i];

    // S_{k+1}
    w.s.swap(w.s_next);
    if (opt.state_jacobians) out->DxDp.block((k + 1) * nx, col, nx, 1) = w.s;
    const double growth = h * w.s.lpNorm<Eigen::Infinity>();
    if (growth > max_growth) {
      max_growth = growth;
      if (growth > kGrowthLimit && growth_step < 0) growth_step = k + 1;
    }
  }
  if (!w.s.allFinite()) {
    throw SimulationError("perturbed step: sequence " + std::to_string(seq_index) +
                              ": non-finite sensitivity in column " + std::to_string(col),
                          seq_index, T);
  }
  if (growth_step >= 0) {
    report->warning = "column " + std::to_string(col) +
                      ": sensitivity grew so that h*|S| = " + FormatDigits(max_growth, 6) + " (> " +
                      FormatDigits(kGrowthLimit, 6) + ") from step " + std::to_string(growth_step) +
                      ": the rollout is so sensitive that a linear model of it holds only for "
                      "parameter changes far below the step" +
                      (split_steps > 0 ? " (from there the state and parameter parts were "
                                         "differenced apart, " +
                                             std::to_string(split_steps) + " steps)"
                                       : std::string()) +
                      "; shorten the horizon (multiple shooting)";
  }
}

// one whole-rollout column of one sequence: differences of whole perturbed rollouts
void Simulator::WholeRolloutColumn(Worker& w, const SequenceInput& seq, int seq_index,
                                   const Trajectory& nom, const JacobianOptions& opt, int col,
                                   const Eigen::VectorXd& steps, Sensitivity* out,
                                   TaskReport* report) const {
  const int np = params_.size(), nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int T = nom.T;
  mjData* d = w.data.get();
  const bool is_param = col < np;
  const double h = is_param ? steps[col] : opt.state_step;
  w.e.setZero(nx);
  if (!is_param) w.e[col - np] = 1.0;

  // one whole rollout per side, from x_0 (+-) h e with the parameter at p +- h
  auto side = [&](mjModel* m, double sign, RowMatrix* states, RowMatrix* sensors) {
    CopyModelInto(m, model_.get());
    if (is_param) params_.WriteOne(m, d, col, params_[col].Read(*model_) + sign * h);
    SetInitialState(d, seq.x0);
    TangentPerturb(*m, d, w.e.data(), sign * h);
    RolloutOne(w, m, seq, seq_index, states, sensors, nullptr, nullptr, &report->solver);
  };
  side(w.plus.get(), 1.0, &w.states_p, &w.sensors_p);
  if (opt.central) side(w.minus.get(), -1.0, &w.states_m, &w.sensors_m);
  const RowMatrix& base_states = opt.central ? w.states_m : nom.states;
  const RowMatrix& base_sensors = opt.central ? w.sensors_m : nom.sensors;
  const double inv = opt.central ? 0.5 / h : 1.0 / h;

  // differences of the whole trajectories
  for (int k = 0; k <= T; ++k) {
    TangentDifference(*model_, base_states.row(k).data(), w.states_p.row(k).data(), inv,
                      w.s.data());
    if (opt.state_jacobians) out->DxDp.block(k * nx, col, nx, 1) = w.s;
    if (k < T) {
      for (int i = 0; i < ns; ++i) {
        out->DyDp(k * ns + i, col) = (w.sensors_p(k, i) - base_sensors(k, i)) * inv;
      }
    }
  }
}

// the columns [col_begin[i], col_end[i]) of every sequence, one task each, behind the rollouts
// when they are given (pipelined)
void Simulator::ColumnJacobians(const std::vector<SequenceInput>& sequences,
                                const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                                JacobianMode mode, const Eigen::VectorXd& steps,
                                std::vector<Sensitivity>* out, std::vector<SolverStats>* solver,
                                std::vector<Trajectory>* rollouts,
                                const std::vector<int>* col_begin, const std::vector<int>* col_end,
                                std::vector<long long>* task_steps) {
  const int ncol = (*out)[0].ncol, ns = options_.sensors ? dims_.ns : 0;

  // directional and whole-rollout: one task per (sequence, column)
  if (mode == JacobianMode::kWholeRollout) {
    for (size_t i = 0; i < sequences.size(); ++i) {
      for (auto& w : workers_) {
        const Eigen::Index rows = nominal[i].T + 1;
        if (w->states_p.rows() < rows) {
          w->states_p.resize(rows, dims_.nphys);
          w->states_m.resize(rows, dims_.nphys);
          w->sensors_p.resize(rows, ns);
          w->sensors_m.resize(rows, ns);
        }
      }
    }
  }
  // each task writes its own column and its own report slot, so no two tasks share an output
  const int nseq = static_cast<int>(sequences.size());
  std::vector<TaskReport> reports(static_cast<size_t>(nseq) * ncol);
  // pipelined (rollouts given, directional mode only): the rollouts are the first tasks, so every
  // column is handed out after its rollout started on another worker, and follows it step by step
  const int nroll = rollouts ? nseq : 0;
  // the tasks (i * ncol + col): the columns [col_begin[i], col_end[i]) of each sequence, in order
  std::vector<int> tasks;
  for (int i = 0; i < nseq; ++i) {
    const int b = col_begin ? (*col_begin)[i] : 0, e = col_end ? (*col_end)[i] : ncol;
    for (int col = b; col < e; ++col) tasks.push_back(i * ncol + col);
  }
  const int ntask = static_cast<int>(tasks.size());
  if (task_steps) task_steps->assign(static_cast<size_t>(nseq) * ncol, 0);
  std::unique_ptr<std::atomic<int>[]> ready(new std::atomic<int>[nroll]);
  for (int i = 0; i < nroll; ++i) ready[i].store(0);
  std::vector<std::exception_ptr> rollout_error(nroll);
  // for the task model: a pipelined column follows its rollout
  if (nroll > 0) {
    std::vector<int> follows(nroll + ntask, -1);
    for (int t = nroll; t < nroll + ntask; ++t) follows[t] = tasks[t - nroll] / ncol;
    pool_.SetNextFollows(std::move(follows));
  }
  try {
    pool_.ParallelFor(nroll + ntask, [&](int worker, int t) {
      Worker& w = *workers_[worker];
      if (t < nroll) {
        try {
          RolloutTask(w, sequences[t], t, &(*rollouts)[t], &ready[t]);
        } catch (...) {
          rollout_error[t] = std::current_exception();
          throw;
        }
        return;
      }
      const int task = tasks[t - nroll], i = task / ncol, col = task % ncol;
      const long long steps0 = w.steps;
      OnWorker(w, [&] {
        if (mode == JacobianMode::kDirectional) {
          DirectionalColumn(w, sequences[i].ctrl, i, nominal[i], opt, col, steps, &(*out)[i],
                            &reports[task], rollouts ? &ready[i] : nullptr);
        } else {
          WholeRolloutColumn(w, sequences[i], i, nominal[i], opt, col, steps, &(*out)[i],
                             &reports[task]);
        }
      });
      if (task_steps) (*task_steps)[task] = w.steps - steps0;
    });
  } catch (...) {
    // a failed rollout is reported as Rollout would (every rollout ran: they are the first tasks),
    // before a perturbed step that failed next to it
    for (const std::exception_ptr& e : rollout_error) {
      if (e) std::rethrow_exception(e);
    }
    throw;
  }
  for (int task : tasks) {
    Sensitivity& s = (*out)[task / ncol];
    const TaskReport& r = reports[task];
    if (!r.warning.empty()) s.warnings.push_back(r.warning);
    s.kinks += r.kinks;
    (*solver)[task / ncol] += r.solver;
  }
}

}  // namespace mjsysid
