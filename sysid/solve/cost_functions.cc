#include "sysid/solve/cost_functions.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/fit_observer.h"
#include "sysid/solve/gn_convergence.h"

namespace mjsysid {

void ZeroJacobians(const ceres::CostFunction& cost, double** jacobians) {
  const std::vector<int32_t>& sizes = cost.parameter_block_sizes();
  for (size_t i = 0; i < sizes.size(); ++i) {
    if (jacobians[i]) std::fill(jacobians[i], jacobians[i] + cost.num_residuals() * sizes[i], 0.0);
  }
}
namespace {

// rows r0 .. r0 + 2 of a row-major Jacobian block with `cols` columns (nullptr: none) replaced by
// A (3 x 3, row-major) or its transpose times them
void MixRotationRows(const double* A, bool transpose, int r0, double* block, int cols) {
  if (block == nullptr) return;
  for (int c = 0; c < cols; ++c) {
    const double v[3] = {block[r0 * cols + c], block[(r0 + 1) * cols + c],
                         block[(r0 + 2) * cols + c]};
    for (int i = 0; i < 3; ++i) {
      double sum = 0;
      for (int t = 0; t < 3; ++t) sum += (transpose ? A[t * 3 + i] : A[i * 3 + t]) * v[t];
      block[(r0 + i) * cols + c] = sum;
    }
  }
}

}  // namespace

// -----------------------------------------------------------------------------------------------
// segment residuals

// residual count: one row per measured (not NaN) cell of the segment's samples x channels, nx
// continuity rows; blocks z, m, x_0, x_next when present
SegmentCost::SegmentCost(const FitParts& parts, int segment)
    : fit_(parts.fit),
      vars_(parts.vars),
      diag_(parts.diag),
      solve_(parts.solve),
      segment_(segment) {
  const Segment& seg = fit_->segments[segment];
  const StateDims& dims = fit_->models[seg.model].sim->dims();
  set_num_residuals(fit_->MeasuredRows(segment) + (seg.next >= 0 ? dims.nx : 0));
  if (!vars_->z.empty()) mutable_parameter_block_sizes()->push_back(vars_->z.size());
  if (!vars_->m.empty()) mutable_parameter_block_sizes()->push_back(vars_->m.size());
  if (seg.block >= 0) mutable_parameter_block_sizes()->push_back(dims.nphys);
  if (seg.next >= 0) mutable_parameter_block_sizes()->push_back(dims.nphys);
}

// a divergent or warning trial point is rejected, not an error: the trust region shrinks
bool SegmentCost::Evaluate(double const* const* parameters, double* residuals,
                           double** jacobians) const {
  return diag_->EvaluateOrReject("non-finite residual",
                                 [&] { return EvaluateOrThrow(parameters, residuals, jacobians); });
}

// the blocks present, in the order the constructor declared them
SegmentCost::Blocks SegmentCost::Unpack(double const* const* parameters) const {
  const Segment& seg = fit_->segments[segment_];
  Blocks k;
  int b = 0;
  if (!vars_->z.empty()) k.zv = parameters[k.zb = b++];
  if (!vars_->m.empty()) k.mv = parameters[k.mb = b++];
  k.x0 = seg.block >= 0 ? parameters[k.xb = b++] : fit_->fixed_x0[seg.seq].data();
  if (seg.next >= 0) k.xn = parameters[k.nb = b++];
  return k;
}

bool SegmentCost::EvaluateOrThrow(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const Segment& seg = fit_->segments[segment_];
  const Blocks k = Unpack(parameters);
  // the controls at the fitted control delays in mv (a no-op when unchanged)
  if (k.mv) solve_->SyncControlDelays(fit_, seg.seq, k.mv);

  // rollout (and Jacobians only when asked for), from the cache when Prefetch or an earlier
  // evaluation at this point computed them; a failed one is rejected in Evaluate
  const bool want = jacobians != nullptr;
  const Sensitivity* sens = nullptr;
  const Trajectory& tr = solve_->CostEntry(segment_, k.zv, k.x0, want, &sens).tr;
  if (want && !sens->warnings.empty()) diag_->NoteJacobianWarning(segment_, sens->warnings[0]);
  FillRows(k, tr, sens, residuals, jacobians);
  // fitted control delays: whole-rollout central differences
  if (want && k.mb >= 0 && jacobians[k.mb] && fit_->HasControlDelay(seg.seq)) {
    ControlDelayColumns(k.zv, k.mv, k.x0, k.xn, jacobians[k.mb]);
  }
  return Finite(residuals);
}

bool SegmentCost::Finite(const double* residuals) const {
  for (int i = 0; i < num_residuals(); ++i) {
    if (!std::isfinite(residuals[i])) return false;
  }
  return true;
}

// ready: the entry CostEntry would give with Jacobians, without simulating or syncing controls
bool SegmentCost::PrepareRows(double const* const* parameters) const {
  ready_ = nullptr;
  if (solve_->previous_jacobian || fit_->HasControlDelay(fit_->segments[segment_].seq))
    return false;
  const Blocks k = Unpack(parameters);
  ready_ = solve_->cache->Ready(segment_, k.zv, k.x0, true);
  if (ready_ == nullptr) return false;
  ready_warning_ = ready_->s.warnings.empty() ? std::string() : ready_->s.warnings[0];
  return true;
}

bool SegmentCost::Rows(double const* const* parameters, double* residuals,
                       double** jacobians) const {
  if (ready_ == nullptr) return false;
  FillRows(Unpack(parameters), ready_->tr, &ready_->s, residuals, jacobians);
  return Finite(residuals);
}

void SegmentCost::NoteRows() const {
  if (!ready_warning_.empty()) diag_->NoteJacobianWarning(segment_, ready_warning_);
}

void SegmentCost::FillRows(const Blocks& blocks, const Trajectory& tr, const Sensitivity* sens,
                           double* residuals, double** jacobians) const {
  const auto [seg, sq, mo] = fit_->SegmentRefs(segment_);
  const Simulator& sim = *mo.sim;
  const StateDims& dims = sim.dims();
  const int nx = dims.nx, npm = sim.parameters().size();
  const auto& chans = fit_->channels[seg.seq];
  const int nch = static_cast<int>(chans.size());
  const double dt = sim.model().opt.timestep;
  const double *zv = blocks.zv, *mv = blocks.mv, *x0 = blocks.x0, *xn = blocks.xn;
  const int zb = blocks.zb, mb = blocks.mb, xb = blocks.xb, nb = blocks.nb;
  const bool want = jacobians != nullptr;
  const Sensitivity& s = *sens;
  const int ns = dims.ns;
  const int ncol = want ? s.ncol : 0;
  std::vector<double> row_t(want ? ncol : 0);  // d(simulated)/d(column) of one residual
  // dp/dz of the model's parameters at z, once per evaluation instead of per row (an exp each for
  // log variables: serial time between the simulator's batches)
  std::vector<double> dpdz(want && zb >= 0 && jacobians[zb] ? npm : 0);
  for (size_t j = 0; j < dpdz.size(); ++j) {
    const int g = mo.global[j];
    dpdz[j] = fit_->DpDz(g, zv[g]);
  }

  if (want) ZeroJacobians(*this, jacobians);
  // P^+ at x_0: tangent columns to the ambient block
  const std::vector<double> pinv = want && xb >= 0 && jacobians[xb]
                                       ? mo.manifold->PlusJacobianPseudoInverse(x0)
                                       : std::vector<double>();

  // sensor residuals (sysid/solve/residual_model.h) of the segment's measured samples, each read at
  // its position on the grid (sysid/data/sample_grid.h), NaN cells masked out; chained to the
  // blocks: z through dp/dz, the measurement terms directly, x_0 through P^+
  int first = 0, count = 0;
  fit_->SamplesOf(segment_, &first, &count);
  const std::vector<double>& position = fit_->grids[seg.seq].position;
  int row = -1;
  for (int k = first; k < first + count; ++k) {
    // where the sample is read without a delay: once per sample, shared by its channels that have
    // no measurement terms (the same DelayedSample their delay 0 gives)
    const DelayedSample at0(position[k] - seg.k0, tr.T, 0.0, dt);
    for (int c = 0; c < nch; ++c) {
      const Channel& ch = chans[c];
      const double measured = sq.measured(k, ch.column);
      if (std::isnan(measured)) continue;
      ++row;
      const MeasurementTerms terms =
          ch.measurement >= 0 ? fit_->Terms(ch.measurement, mv) : MeasurementTerms();
      const DelayedSample at =
          ch.measurement >= 0 ? DelayedSample(position[k] - seg.k0, tr.T, terms.delay, dt) : at0;
      const SensorResidual r =
          EvaluateSensorResidual(at, {tr.sensors.data() + ch.column, tr.sensors.cols()}, measured,
                                 ch.weight, terms, fit_->options.loss, fit_->options.loss_scale);
      residuals[row] = r.value;
      if (!want) continue;
      InterpolatedRow(at, s.DyDp.data(), ns, ch.column, ncol, row_t.data());
      if (zb >= 0 && jacobians[zb]) {
        const int nz = static_cast<int>(vars_->z.size());
        for (int j = 0; j < npm; ++j) {
          const int g = mo.global[j];
          jacobians[zb][row * nz + g] = r.d_simulated * row_t[j] * dpdz[j];
        }
      }
      if (mb >= 0 && jacobians[mb] && ch.measurement >= 0) {
        const int nm = static_cast<int>(vars_->m.size());
        const TermIndex& ix = fit_->term_index[ch.measurement];
        if (ix.delay >= 0) jacobians[mb][row * nm + ix.delay] = r.d_delay;
        if (ix.gain >= 0) jacobians[mb][row * nm + ix.gain] = r.d_gain;
        if (ix.bias >= 0) jacobians[mb][row * nm + ix.bias] = r.d_bias;
      }
      if (xb >= 0 && jacobians[xb]) {
        for (int a = 0; a < dims.nphys; ++a) {
          double v = 0;
          for (int i = 0; i < nx; ++i) v += row_t[npm + i] * pinv[i * dims.nphys + a];
          jacobians[xb][row * dims.nphys + a] = r.d_simulated * v;
        }
      }
    }
  }

  // continuity: w_i * (x_end (-) x_next)_i in tangent space (w per row: ContinuityWeights,
  // equal over an orientation's 3 rows; the difference is MuJoCo's mj_differentiatePos); its
  // Jacobian is w_i times the end-state rows of DxDp for the core's
  // columns and -w_i I for the next x_0's tangent, exact off orientations; the 3 rows of a ball or
  // free joint's orientation d = log(q_next^-1 q_end) are then mixed by Jr^-1(d) (end state)
  // and Jr^-1(d)^T (next state) (InverseRightJacobianSO3, core/state.h)
  if (seg.next >= 0) {
    const std::vector<double>& w = fit_->continuity_weights[seg.model];  // per tangent row
    const int r0 = row + 1;
    std::vector<double> d(nx);
    TangentDifference(sim.model(), xn, tr.states.row(seg.T).data(), 1.0, d.data());
    for (int i = 0; i < nx; ++i) residuals[r0 + i] = w[i] * d[i];
    if (want) {
      const auto S = s.DxDp.middleRows(static_cast<Eigen::Index>(seg.T) * nx, nx);
      if (zb >= 0 && jacobians[zb]) {
        const int nz = static_cast<int>(vars_->z.size());
        for (int i = 0; i < nx; ++i) {
          for (int j = 0; j < npm; ++j) {
            const int g = mo.global[j];
            jacobians[zb][(r0 + i) * nz + g] = w[i] * S(i, j) * dpdz[j];
          }
        }
      }
      if (xb >= 0 && jacobians[xb]) {
        for (int i = 0; i < nx; ++i) {
          for (int a = 0; a < dims.nphys; ++a) {
            double v = 0;
            for (int t = 0; t < nx; ++t) v += S(i, npm + t) * pinv[t * dims.nphys + a];
            jacobians[xb][(r0 + i) * dims.nphys + a] = w[i] * v;
          }
        }
      }
      if (nb >= 0 && jacobians[nb]) {
        std::vector<double> pn(static_cast<size_t>(nx) * dims.nphys);
        mo.manifold->PlusJacobianPseudoInverse(xn, pn.data());
        for (int i = 0; i < nx; ++i) {
          for (int a = 0; a < dims.nphys; ++a) {
            jacobians[nb][(r0 + i) * dims.nphys + a] = -w[i] * pn[i * dims.nphys + a];
          }
        }
      }
      const mjModel& mm = sim.model();
      for (int j = 0; j < mm.njnt; ++j) {
        const int type = mm.jnt_type[j];
        if (type != mjJNT_BALL && type != mjJNT_FREE) continue;
        const int k = mm.jnt_dofadr[j] + (type == mjJNT_FREE ? 3 : 0);
        double A[9];
        InverseRightJacobianSO3(d.data() + k, 1.0, A);
        MixRotationRows(A, false, r0 + k, zb >= 0 ? jacobians[zb] : nullptr,
                        static_cast<int>(vars_->z.size()));
        MixRotationRows(A, false, r0 + k, xb >= 0 ? jacobians[xb] : nullptr, dims.nphys);
        MixRotationRows(A, true, r0 + k, nb >= 0 ? jacobians[nb] : nullptr, dims.nphys);
      }
    }
  }
}

void SegmentCost::Residuals(const Trajectory& tr, const double* mv, const double* xn,
                            double* out) const {
  const Segment& seg = fit_->segments[segment_];
  const FitSequence& sq = fit_->sequences[seg.seq];
  const Simulator& sim = *fit_->models[seg.model].sim;
  const double dt = sim.model().opt.timestep;
  // sensor rows: measured cells in sample-major order, as EvaluateOrThrow
  int first = 0, count = 0;
  fit_->SamplesOf(segment_, &first, &count);
  const std::vector<double>& position = fit_->grids[seg.seq].position;
  int row = 0;
  for (int k = first; k < first + count; ++k) {
    for (const Channel& ch : fit_->channels[seg.seq]) {
      const double measured = sq.measured(k, ch.column);
      if (std::isnan(measured)) continue;
      const MeasurementTerms terms =
          ch.measurement >= 0 ? fit_->Terms(ch.measurement, mv) : MeasurementTerms();
      const DelayedSample at(position[k] - seg.k0, tr.T, terms.delay, dt);
      out[row++] =
          EvaluateSensorResidual(at, {tr.sensors.data() + ch.column, tr.sensors.cols()}, measured,
                                 ch.weight, terms, fit_->options.loss, fit_->options.loss_scale)
              .value;
    }
  }
  // continuity rows
  if (seg.next >= 0) {
    const int nx = sim.dims().nx;
    TangentDifference(sim.model(), xn, tr.states.row(seg.T).data(), 1.0, out + row);
    for (int i = 0; i < nx; ++i) out[row + i] *= fit_->continuity_weights[seg.model][i];
  }
}

// per fitted delay driving this sequence: its controls held again at delay +- h, both rollouts in
// one batch from the segment's x_0 at the current parameters, the residuals differenced
void SegmentCost::ControlDelayColumns(const double* zv, const double* mv, const double* x0,
                                      const double* xn, double* jm) const {
  const Segment& seg = fit_->segments[segment_];
  const FitSequence& sq = fit_->sequences[seg.seq];
  FitModel& mo = fit_->models[seg.model];
  Simulator& sim = *mo.sim;
  const StateDims& dims = sim.dims();
  const double dt = sim.model().opt.timestep;
  const SampleGrid& grid = fit_->grids[seg.seq];
  const int steps = grid.SimulatedSteps(seg.k0, seg.T);
  const int nm = static_cast<int>(vars_->m.size()), nr = num_residuals();
  const double h = kControlDelayStep * dt;
  if (zv) ApplyVariables(fit_->params, mo.global, zv, &sim);
  std::vector<SequenceInput> ins(2);
  for (SequenceInput& in : ins) {
    in.x0.qpos = Eigen::Map<const Eigen::VectorXd>(x0, dims.nq);
    in.x0.qvel = Eigen::Map<const Eigen::VectorXd>(x0 + dims.nq, dims.nv);
    in.x0.act = Eigen::Map<const Eigen::VectorXd>(x0 + dims.nq + dims.nv, dims.na);
    in.x0.time = seg.k0 * dt;  // as the evaluation cache's rollouts
  }
  std::vector<Trajectory> trs;
  std::vector<double> plus(nr), minus(nr);
  std::vector<int> done;
  for (const int v : fit_->ctrl_delay_var[seg.seq]) {
    if (v < 0 || std::find(done.begin(), done.end(), v) != done.end()) continue;
    done.push_back(v);
    for (int side = 0; side < 2; ++side) {
      HoldControls(grid, sq.ctrl, sq.ctrl_hold, fit_->ControlDelays(seg.seq, mv, v, side ? -h : h),
                   dt, &ins[side].ctrl, seg.k0, steps);
    }
    sim.Rollout(ins, &trs);  // throws on a divergent rollout: the trial point is rejected
    Residuals(trs[0], mv, xn, plus.data());
    Residuals(trs[1], mv, xn, minus.data());
    for (int r = 0; r < nr; ++r) jm[r * nm + v] = (plus[r] - minus[r]) / (2 * h);
  }
}

// -----------------------------------------------------------------------------------------------
// priors

PriorCost::PriorCost(const PreparedFit* fit, int g) : fit_(fit), g_(g) {
  set_num_residuals(1);
  mutable_parameter_block_sizes()->push_back(static_cast<int>(fit->params.size()));
}

// (p - mean) / sigma on the z block, one nonzero derivative
bool PriorCost::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  const FitParameter& p = fit_->params[g_];
  const double zg = parameters[0][g_];
  double derivative = 0;
  residuals[0] = PriorResidual(fit_->Physical(g_, zg), p.prior_mean, p.prior_sigma,
                               fit_->DpDz(g_, zg), &derivative);
  if (jacobians && jacobians[0]) {
    std::fill(jacobians[0], jacobians[0] + fit_->params.size(), 0.0);
    jacobians[0][g_] = derivative;
  }
  return std::isfinite(residuals[0]);
}

// -----------------------------------------------------------------------------------------------
// callbacks

// every segment at the point Ceres is about to evaluate (Ceres has written it into z, m and the
// state blocks); the cache compares keys itself, so unchanged segments are kept
void PrefetchCallback::PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) {
  // the statistical stop before the last Jacobian (sysid/solve/gn_convergence.h): Ceres asks for
  // the Jacobians at the point it just accepted (HandleSuccessfulStep: not a new point); the test
  // on [J_k r_{k+1}] runs first, the cost functions answering with J_k. Fired: Ceres' request is
  // answered the same way and the stop's callback ends the solve, nothing simulated; else the
  // Jacobians are simulated as always. (An evaluation within the test: all cached.)
  if (solve_->previous_jacobian) return;
  const bool solving = solve_->ledger && solve_->ledger->solving;
  bool previous = evaluate_jacobians && !new_evaluation_point && solving && solve_->gn_stop;
  for (size_t s = 0; s < fit_->segments.size() && previous; ++s) {  // J_k of every segment held
    const EvaluationCache::Entry& e = solve_->cache->Cached(static_cast<int>(s));
    previous = !e.failed && (e.has_jacobians || solve_->cache->Previous(static_cast<int>(s)));
  }
  if (previous) {
    solve_->SetPreviousJacobian(true);
    if (solve_->gn_stop->TestBeforeJacobian()) return;
    solve_->SetPreviousJacobian(false);
  }
  if (!vars_->m.empty())
    solve_->SyncControlDelays(fit_, vars_->m.data());  // the controls at the fitted delays
  std::vector<const double*> x0(fit_->segments.size());
  for (size_t s = 0; s < fit_->segments.size(); ++s)
    x0[s] = fit_->X0(vars_->states, static_cast<int>(s));
  const bool charge = solving;
  if (charge) solve_->ledger->Enter(evaluate_jacobians ? kPhaseJacobians : kPhaseTrials);
  solve_->cache->Prefetch(vars_->z.empty() ? nullptr : vars_->z.data(), x0, evaluate_jacobians);
  // the compressed blocks' folds at this point on the simulator's workers, one task per block
  // (Ceres' Evaluate calls then write them out); the pool of the first model (every simulator has
  // the fit's threads; the tasks do not simulate)
  if (evaluate_jacobians && solve_->compressed && !fit_->models.empty() && fit_->models[0].sim) {
    if (charge) solve_->ledger->Enter(kPhaseFolds);
    Simulator& sim = *fit_->models[0].sim;
    FoldAhead(
        solve_->compressed, sim.threads(),
        [&sim](int n, const std::function<void(int, int)>& task) { sim.ParallelFor(n, task); });
  }
  if (charge) solve_->ledger->Enter(kPhaseSolver);
}

// the iterate in physical units; progress line, trace, checkpoint callback, interruption
ceres::CallbackReturnType ProgressCallback::operator()(const ceres::IterationSummary& summary) {
  IterationInfo info;
  info.iteration = summary.iteration;
  info.cost = summary.cost;
  info.step_norm = summary.step_norm;
  info.gradient_norm = summary.gradient_max_norm;
  info.successful = summary.step_is_successful || summary.iteration == 0;
  info.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const int np = static_cast<int>(fit_->params.size());
  info.parameters.resize(np + static_cast<int>(vars_->m.size()));
  for (int g = 0; g < np; ++g) info.parameters[g] = fit_->Physical(g, vars_->z[g]);
  for (size_t i = 0; i < vars_->m.size(); ++i) info.parameters[np + i] = vars_->m[i];
  result_->trace.push_back(info);
  if (fit_->options.observer) fit_->options.observer->OnIteration(info);
  if (fit_->options.on_iteration && info.successful) fit_->options.on_iteration(info);
  // auto multiple shooting: the single-shooting Jacobian stopped being local (Problem::Fit refits)
  if (solve_->stop_on_jacobian_warning && !diag_->jacobian_warnings.empty())
    return ceres::SOLVER_ABORT;
  if (fit_->options.interrupt && fit_->options.interrupt->load()) {
    result_->interrupted = true;
    return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  return ceres::SOLVER_CONTINUE;
}

}  // namespace mjsysid
