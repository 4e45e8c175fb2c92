// Problem: the fit orchestration. Prepare (sysid/problem_prepare.cc) validates the inputs and
// builds the simulators, the variables, the segments and the evaluation cache (Problem::Impl,
// sysid/problem_impl.h); Fit builds the Ceres problem from the cost functions
// (sysid/cost_functions.h), solves it and assembles the FitResult (estimates, uncertainty,
// warnings, final signals); CheckJacobians probes every residual block with
// ceres::GradientChecker. The residual arithmetic itself is in sysid/residual_model.h, the rollout
// reuse in sysid/evaluation_cache.h.
#include "sysid/problem.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>

#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

#include "core/text.h"
#include "sysid/compressed_cost.h"
#include "sysid/contact_channels.h"
#include "sysid/cost_functions.h"
#include "sysid/derived_inertials.h"
#include "sysid/equation_error.h"
#include "sysid/estimate_jacobian.h"
#include "sysid/evaluation_cache.h"
#include "sysid/fit_ledger.h"
#include "sysid/fit_status.h"
#include "sysid/gn_convergence.h"
#include "sysid/interval_check.h"
#include "sysid/multiple_shooting.h"
#include "sysid/problem_impl.h"
#include "sysid/progress.h"
#include "sysid/residual_model.h"
#include "sysid/state_manifold.h"
#include "sysid/state_residuals.h"
#include "sysid/variable_manifold.h"

namespace mjsysid {
namespace {

constexpr double kZ95 = 1.959963984540054;
constexpr double kInf = std::numeric_limits<double>::infinity();
// multiple shooting: a continuity gap (tangent space: m, rad, m/s, rad/s) above this at the
// estimate is reported as segments that do not join
constexpr double kContinuityGapWarning = 1e-3;

// Reduces the sequence's matrices (T x nsensordata, the model's layout) to the columns of the
// fitted sensors, in the order given, and fills their names, dimensions and the sample times.
void KeepFittedColumns(const mjModel& m, const std::vector<std::string>& fitted,
                       const FitSequence& sq, SequenceResult* sr) {
  std::vector<int> cols;
  for (const std::string& name : fitted) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
    sr->sensor_names.push_back(name);
    sr->sensor_dims.push_back(m.sensor_dim[id]);
    for (int c = 0; c < m.sensor_dim[id]; ++c) cols.push_back(m.sensor_adr[id] + c);
  }
  const Eigen::Index T = sr->measured.rows();
  for (RowMatrix* mat : {&sr->measured, &sr->simulated_initial, &sr->simulated_final}) {
    RowMatrix kept(T, static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) kept.col(c) = mat->col(cols[c]);
    *mat = std::move(kept);
  }
  sr->missing.assign(cols.size(), 0);
  for (size_t c = 0; c < cols.size(); ++c) {
    sr->missing[c] = static_cast<int>(sr->measured.col(c).array().isNaN().count());
  }
  if (sq.time.size() == T) {
    sr->time = sq.time;
  } else {
    sr->time = Eigen::VectorXd::LinSpaced(T, 0, static_cast<double>(T - 1)) * m.opt.timestep;
    sr->time.array() += sq.x0.time;
  }
}

// Rows [first, first + count) of *out: the simulated sensors (a rollout's T x ns rows from step
// k0) at those measured samples' positions, interpolated between steps like the residuals
void SensorsAtSamples(const RowMatrix& sensors, const SampleGrid& grid, int k0, int first,
                      int count, double dt, RowMatrix* out) {
  const int T = static_cast<int>(sensors.rows());
  for (int k = first; k < first + count; ++k) {
    const DelayedSample at(grid.position[k] - k0, T, 0.0, dt);
    for (Eigen::Index c = 0; c < sensors.cols(); ++c) {
      (*out)(k, c) = at.Value({sensors.data() + c, sensors.cols()});
    }
  }
}

// what the reduced models switched off, summed over the models (FitResult::reduction)
void RecordReduction(const Problem::Impl& I, const FitOptions& options, FitResult* result) {
  FitResult::Reduction& r = result->reduction;
  r = FitResult::Reduction();
  r.recorded = true;
  r.used = options.reduce_model;
  for (const auto& mo : I.models) {
    const ModelReduction& mr = mo.sim->reduction();
    r.collision_pairs += mr.candidate_pairs;
    r.collision_pairs_off += mr.pairs_off;
    r.geoms_off += static_cast<int>(mr.geoms_off.size());
    r.guard_trips += mo.sim->ReductionTrips();
    for (const std::string& name : DisabledNames(mr.disable)) {
      if (std::find(r.disabled.begin(), r.disabled.end(), name) == r.disabled.end()) {
        r.disabled.push_back(name);
      }
    }
  }
}

}  // namespace

// A sharded start (Problem::ShardStart) simulated only the owned sequences at the initial values:
// the others' rollouts there (no Jacobians), for the result's initial signals. Leaves the
// simulators at the initial parameters.
void RolloutUnowned(Problem::Impl* impl, std::vector<Trajectory>* initial) {
  Problem::Impl& I = *impl;
  std::vector<double> z0(I.params.size());
  for (size_t g = 0; g < z0.size(); ++g) z0[g] = I.ToZ(static_cast<int>(g), I.params[g].initial);
  for (auto& mo : I.models) {
    std::vector<SequenceInput> ins;
    std::vector<int> which;
    for (size_t q = 0; q < I.sequences.size(); ++q) {
      if (I.sequences[q].model != mo.name || (*initial)[q].states.rows() > 0) continue;
      ins.push_back({I.sequences[q].x0, I.grids[q].ctrl});
      which.push_back(static_cast<int>(q));
    }
    if (ins.empty()) continue;
    ApplyVariables(I.params, mo.global, z0.data(), mo.sim.get());
    std::vector<Trajectory> trs;
    mo.sim->Rollout(ins, &trs);
    for (size_t i = 0; i < which.size(); ++i) (*initial)[which[i]] = std::move(trs[i]);
  }
}

// -----------------------------------------------------------------------------------------------
// building

Problem::Problem() : impl_(std::make_unique<Impl>()) { InstallMujocoHandlers(); }
Problem::~Problem() = default;

void Problem::AddModel(const std::string& name, const mjModel& m) {
  for (const auto& mo : impl_->models) {
    if (mo.name == name) throw std::invalid_argument("model '" + name + "' added twice");
  }
  Impl::Model mo;
  mo.name = name;
  mo.model = CopyModel(m);
  impl_->models.push_back(std::move(mo));
}

void Problem::AddParameter(const FitParameter& p) {
  for (const auto& q : impl_->params) {
    if (q.name == p.name) throw std::invalid_argument("parameter '" + p.name + "' added twice");
  }
  impl_->params.push_back(p);
}

void Problem::AddMeasurement(const FitMeasurement& me) { impl_->measurements.push_back(me); }

void Problem::AddSequence(const FitSequence& s) { impl_->sequences.push_back(s); }

void Problem::DistributeResiduals(ResidualShards* shards) {
  impl_->shards = shards;
  if (shards) {
    ShardStart([shards](const Impl& impl) { return shards->OwnedSequences(impl); });
  }
}

void Problem::ShardStart(std::function<std::vector<bool>(const Impl&)> owned) {
  impl_->owned_sequences = std::move(owned);
}

Problem::Impl* Problem::PrepareOnly(const FitOptions& options) {
  Prepared prepared;
  Prepare(options, &prepared);
  return impl_.get();
}

void Problem::AddControlDelay(const FitControlDelay& delay) {
  for (const FitControlDelay& d : impl_->control_delays) {
    if (d.actuator == delay.actuator) {
      throw std::invalid_argument("control delay '" + delay.Name() + "' added twice");
    }
  }
  impl_->control_delays.push_back(delay);
}

// initial: auto (FitParameter::initial_auto): the equation-error start of each model's `auto`
// parameters from its sequences' logged qpos and qvel (sysid/equation_error.h); a parameter that
// cannot be solved starts at its model's value. The marks are cleared, so that a refit (auto
// multiple shooting) starts from the same values. Returns one line per model, for the warnings.
// threads: the fit's (FitOptions::threads), for the samples' inverse dynamics.
static std::vector<std::string> SolveAutoStarts(Problem::Impl& I, int threads) {
  std::vector<std::string> notes;
  std::vector<bool> done(I.params.size(), false);
  for (const Problem::Impl::Model& mo : I.models) {
    std::vector<FitParameter> params;
    std::vector<int> global, which;
    for (size_t g = 0; g < I.params.size(); ++g) {
      if (!I.params[g].AppliesTo(mo.name)) continue;
      if (I.params[g].initial_auto && !done[g]) which.push_back(static_cast<int>(params.size()));
      global.push_back(static_cast<int>(g));
      params.push_back(I.params[g]);
    }
    if (which.empty()) continue;
    std::vector<const FitSequence*> sequences;
    for (const FitSequence& s : I.sequences) {
      if (s.model == mo.name) sequences.push_back(&s);
    }
    const EquationErrorStart start =
        SolveEquationError(*mo.model, params, which, sequences, 5, 4000, threads);
    std::string kept;
    for (int i : which) {
      FitParameter& p = I.params[global[i]];
      p.initial = start.values[i];
      done[global[i]] = true;
      if (!start.solved[i]) kept += (kept.empty() ? "" : ", ") + p.name;
    }
    notes.push_back("initial: auto (model '" + mo.name + "'): " + start.note +
                    (kept.empty() ? "" : "; at the model's value: " + kept));
  }
  for (FitParameter& p : I.params) p.initial_auto = false;
  return notes;
}

FitResult Problem::Fit(const FitOptions& options) {
  Impl& I = *impl_;
  const auto start = std::chrono::steady_clock::now();
  FitResult result;
  // the ledger of steps and time by phase (sysid/fit_ledger.h); the simulators exist after Prepare
  FitLedger ledger(
      [&I] {
        long long steps = 0;
        for (const Impl::Model& mo : I.models) steps += mo.sim ? mo.sim->StepCount() : 0;
        return steps;
      },
      [&I] {
        // the task model's critical path at 2 workers (core/thread_pool.h)
        long long steps = 0;
        for (const Impl::Model& mo : I.models) steps += mo.sim ? mo.sim->ParallelLoad().span[2] : 0;
        return steps;
      });
  // the time inside the simulators' batches (serial time = the rest)
  ledger.MeasureBatches([&I] {
    PoolTime sum;
    for (const Impl::Model& mo : I.models) {
      if (mo.sim) sum += mo.sim->ParallelTime();
    }
    return sum;
  });
  I.ledger = &ledger;
  struct Unborrow {
    Impl* impl;
    ~Unborrow() { impl->ledger = nullptr; }
  } unborrow{&I};
  ledger.Enter(kPhaseAutoStart);
  I.fit_start = start;
  // the progress lines inside long rollouts (Prepare installs them on the simulators)
  if (!I.step_progress) I.step_progress = std::make_unique<StepProgressLines>(start, 0);
  I.step_progress->Reset(start, options.progress_seconds);
  const std::vector<std::string> start_notes = SolveAutoStarts(I, options.threads);
  ledger.Enter(kPhasePrepare);
  Prepared prepared;
  Prepare(options, &prepared);
  ledger.Enter(kPhaseSetup);
  const int np = static_cast<int>(I.params.size());
  const std::vector<Trajectory>& initial = prepared.initial;
  const std::vector<std::string>& names = prepared.names;
  const std::vector<std::pair<double, double>>& mbounds = prepared.mbounds;
  result.jacobian_mode = prepared.jacobian_mode;
  result.segment_steps_used = prepared.segment_steps;
  result.segment_reason = prepared.segment_reason;
  result.event_windows = prepared.event_windows;

  result.warnings = I.prepare_warnings;
  result.warnings.insert(result.warnings.end(), start_notes.begin(), start_notes.end());
  // a start on a bound: the first step may leave the bound at once or never (a projected
  // gradient pointing outwards)
  for (const FitParameter& p : I.params) {
    if (p.initial == p.lower || p.initial == p.upper) {
      result.warnings.push_back("parameter '" + p.name + "' starts on its " +
                                (p.initial == p.lower ? "lower" : "upper") + " bound " +
                                FormatDigits(p.initial, 3) +
                                ": start inside the bounds, or the fit may not leave it");
    }
  }

  // ceres problem
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  PrefetchCallback prefetch(&I);
  po.evaluation_callback = I.shards ? I.shards->Callback() : &prefetch;
  // log variables of kinds that enter the dynamics linearly take the relative step
  // (sysid/variable_manifold.h) where the nominal rollouts are smooth (no contact: with contacts
  // the residuals are not near-linear in p either); the manifold is declared before the problem,
  // which does not own it
  const bool smooth = ContactFraction(initial) == 0;
  std::vector<bool> relative;
  for (const FitParameter& p : I.params) relative.push_back(smooth && RelativeStep(p));
  VariableManifold variable_manifold(std::move(relative));
  // each segment's blocks to Ceres as their thin-QR triangles (memory: Ceres holds n + 1 rows
  // per block, sysid/compressed_cost.h; multiple shooting too: a block keeps its parameter blocks,
  // z, m, x_0 and x_next, so the Schur solver's structure is the same, with n + 1 rows per block);
  // declared before the problem, which uses it
  CompressedBlocks compressed;
  compressed.reuse_folds = options.reuse_folds;
  compressed.epoch = &I.cost_inputs_epoch;  // (the epoch outlives the problem)
  const bool compress = options.compress_blocks && !I.shards;
  ceres::Problem problem(po);
  if (np) {
    problem.AddParameterBlock(I.z.data(), np);
    if (variable_manifold.any_relative()) {
      problem.SetManifold(I.z.data(), &variable_manifold);
    }
    for (int g = 0; g < np; ++g) {
      const FitParameter& p = I.params[g];
      const double zl = I.ToZ(g, p.lower), zu = I.ToZ(g, p.upper);
      const double lo = p.transform == Transform::kScale ? std::min(zl, zu) : zl;
      const double hi = p.transform == Transform::kScale ? std::max(zl, zu) : zu;
      if (std::isfinite(lo) && p.lower > -kInf) problem.SetParameterLowerBound(I.z.data(), g, lo);
      if (std::isfinite(hi) && p.upper < kInf) problem.SetParameterUpperBound(I.z.data(), g, hi);
    }
  }
  if (!I.m.empty()) {
    problem.AddParameterBlock(I.m.data(), static_cast<int>(I.m.size()));
    for (size_t i = 0; i < I.m.size(); ++i) {
      if (std::isfinite(mbounds[i].first)) {
        problem.SetParameterLowerBound(I.m.data(), static_cast<int>(i), mbounds[i].first);
      }
      if (std::isfinite(mbounds[i].second)) {
        problem.SetParameterUpperBound(I.m.data(), static_cast<int>(i), mbounds[i].second);
      }
    }
  }
  // segment residuals evaluated elsewhere (sysid/mpi/): their blocks replace the segments'
  if (I.shards) {
    std::vector<double*> blocks;
    if (np) blocks.push_back(I.z.data());
    if (!I.m.empty()) blocks.push_back(I.m.data());
    I.shards->AddResidualBlocks(&I, &problem, blocks);
  }
  for (size_t s = 0; s < I.segments.size() && !I.shards; ++s) {
    const Segment& seg = I.segments[s];
    const Impl::Model& mo = I.models[seg.model];
    std::vector<double*> blocks;
    if (np) blocks.push_back(I.z.data());
    if (!I.m.empty()) blocks.push_back(I.m.data());
    if (seg.block >= 0) blocks.push_back(I.states[seg.block].data());
    if (seg.next >= 0) blocks.push_back(I.states[seg.next].data());
    auto* cost = new SegmentCost(&I, static_cast<int>(s));
    if (cost->num_residuals() > 0 && !blocks.empty()) {
      problem.AddResidualBlock(compress ? Compress(cost, &compressed, blocks) : cost, nullptr,
                               blocks);
    } else {
      delete cost;  // e.g. a model without sensors fitted from its states alone
    }
    // the fitted states (sysid/state_residuals.h): the z and x_0 blocks
    if (seg.state_rows) {
      std::vector<double*> state_blocks;
      if (np) state_blocks.push_back(I.z.data());
      if (seg.block >= 0) state_blocks.push_back(I.states[seg.block].data());
      auto* state_cost = new StateCost(&I, static_cast<int>(s));
      if (state_cost->num_residuals() > 0 && !state_blocks.empty()) {
        problem.AddResidualBlock(compress ? Compress(state_cost, &compressed) : state_cost, nullptr,
                                 state_blocks);
      } else {
        delete state_cost;
      }
    }
    if (seg.block >= 0 && problem.HasParameterBlock(I.states[seg.block].data())) {
      problem.SetManifold(I.states[seg.block].data(), mo.manifold.get());
    }
  }
  for (int g = 0; g < np; ++g) {
    if (I.params[g].has_prior) problem.AddResidualBlock(new PriorCost(&I, g), nullptr, I.z.data());
  }

  // solve
  ceres::Solver::Options so_ceres;
  so_ceres.minimizer_type = ceres::TRUST_REGION;
  so_ceres.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  int tangent = np + static_cast<int>(I.m.size());
  // (sharded: the states are eliminated by the shards, Ceres sees z and m)
  for (size_t b = 0; b < I.states.size(); ++b) {
    tangent += I.shards ? 0 : static_cast<int>(I.states[b].size());
  }
  ChooseLinearSolver(I, tangent, &so_ceres);
  so_ceres.max_num_iterations = options.max_iterations;
  so_ceres.function_tolerance = options.function_tolerance;
  so_ceres.gradient_tolerance = options.gradient_tolerance;
  so_ceres.parameter_tolerance = options.parameter_tolerance;
  // one thread: the evaluation cache is single-threaded by contract (sysid/evaluation_cache.h);
  // the simulators are parallel inside
  so_ceres.num_threads = 1;
  // with bounds, Ceres' trust region minimizer runs a projected Armijo line search along every
  // step. With its default cubic interpolation each trial length evaluates the gradient, i.e.
  // the full Jacobian (4-6 per iteration on the pendulum); quadratic interpolation needs cost
  // values only, one rollout each. Measured (bench_fit, simulation steps of whole fits; cubic /
  // quadratic / no line search): pendulum 918k / 558k / 528k, arm7 1722k / 1338k / 1212k, same
  // estimates; without the search two stress fits (tests/stress: chaotic multiple shooting,
  // dt 0.05 contact) no longer converge, so the search stays.
  so_ceres.line_search_interpolation_type = ceres::QUADRATIC;
  so_ceres.update_state_every_iteration = true;
  so_ceres.logging_type = ceres::SILENT;
  ProgressCallback progress(&I, &result, start);
  so_ceres.callbacks.push_back(&progress);
  // the rank tolerance follows the finite differences' accuracy (relative step h: O(h)
  // forward, O(h^2) central) unless the user's rank_tolerance is larger
  UncertaintyOptions uo = options.uncertainty;
  const double h = options.jacobian.relative_step;
  uo.jacobian_accuracy = std::max(uo.jacobian_accuracy, options.jacobian.central ? h * h : h);
  // the statistical stop (sysid/gn_convergence.h) where its test is valid: single shooting on
  // this process, no robust loss, no fitted control delay (their columns are rollouts), and only
  // where auto's probe measured bounded growth (at most kRefitGrowth beyond linear). On a chaotic
  // system the single-shooting cost is rugged and every local minimum is a stationary point that
  // passes the test: there the fit must run to Ceres' tolerances (or its iteration cap), so that
  // auto's third stage still refits it in multiple shooting (tests/stress/horizon_stress_test.cc,
  // moderate_start2: stopped at a local minimum 38 % off as `converged`). A set segment_steps
  // runs no probe: no evidence, no statistical stop.
  std::vector<double*> all_blocks;  // every parameter block, in the order added
  if (np) all_blocks.push_back(I.z.data());
  if (!I.m.empty()) all_blocks.push_back(I.m.data());
  for (size_t b = 0; b < I.states.size(); ++b) {
    if (problem.HasParameterBlock(I.states[b].data())) all_blocks.push_back(I.states[b].data());
  }
  bool gn_valid = options.gauss_newton_stop > 0 && !I.shards && options.loss == LossType::kNone &&
                  I.control_delay_index.empty() && !all_blocks.empty() &&
                  options.segment_steps < 0 && prepared.probe_growth <= kRefitGrowth;
  for (const Segment& seg : I.segments) gn_valid = gn_valid && seg.next < 0;
  GaussNewtonStop gn_stop(&problem, all_blocks, options.gauss_newton_stop, uo, options.verbose,
                          &ledger);
  if (gn_valid) so_ceres.callbacks.push_back(&gn_stop);
  // and before a point's Jacobians (the evaluation callback asks it, sysid/cost_functions.h)
  I.gn_stop = gn_valid && options.gauss_newton_stop_before_jacobian ? &gn_stop : nullptr;
  I.SetPreviousJacobian(false);
  ceres::Solver::Summary summary;
  I.rejected_evaluations = 0;
  I.jacobian_warnings.clear();
  ++I.cost_inputs_epoch;  // (jacobian_warnings cleared)
  ledger.solving = true;
  // auto's contact segments: a first solve with the segment states held on the data
  // (sysid/multiple_shooting.h, SolveWithStatesHeld); its accepted steps count as the fit's, its
  // initial cost is the fit's
  int held_accepted = 0;
  double held_initial_cost = -1;
  if (prepared.contact_segments && options.hold_states_first && !I.shards) {
    const ceres::Solver::Summary held = SolveWithStatesHeld(I, &problem, so_ceres);
    for (size_t i = 1; i < held.iterations.size(); ++i) {
      held_accepted += held.iterations[i].step_is_successful ? 1 : 0;
    }
    held_initial_cost = held.initial_cost;
    result.segment_reason += "; first " + std::to_string(held.iterations.size() - 1) +
                             " iterations with the segment states held on the data (cost " +
                             FormatDigits(held.initial_cost, 3) + " -> " +
                             FormatDigits(held.final_cost, 3) + ")";
  }
  I.cache->SetColumnsAhead(true);  // trial points' first columns on idle workers
  // the compressed blocks folded ahead (sysid/compressed_cost.h), in the solve and the
  // evaluation at the estimate
  struct Unlend {
    Impl* impl;
    ~Unlend() { impl->compressed = nullptr; }
  } unlend{&I};
  I.compressed = compress && options.fold_ahead ? &compressed : nullptr;
  ceres::Solve(so_ceres, &problem, &summary);
  I.cache->SetColumnsAhead(false);
  I.gn_stop = nullptr;
  I.SetPreviousJacobian(false);
  // fired before the last Jacobian: the estimate is evaluated with the previous iterate's
  // Jacobian below too (else, e.g. interrupted at that point, with its own)
  const bool previous_jacobian = gn_stop.fired_before_jacobian() && !result.interrupted;
  ledger.solving = false;
  // the columns computed ahead of points that were not taken (the last trial's at least)
  ledger.Move(kPhaseTrials, kPhaseAheadUnused, I.cache->AheadStepsUnused());

  // auto: single shooting whose Jacobian stopped being local is refitted in multiple shooting
  if (I.stop_on_jacobian_warning && !I.jacobian_warnings.empty() && !result.interrupted) {
    std::string reason;
    FitOptions segmented = options;
    segmented.segment_steps =
        SegmentStepsAfterWarning(I.jacobian_warnings.begin()->second, prepared.probe_rate, &reason);
    if (segmented.segment_steps > 0) {
      const double first_seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      FitResult refit = Fit(segmented);
      refit.segment_reason = reason + "; " +
                             refit.segment_reason.substr(
                                 refit.segment_reason.find("segment states") == std::string::npos
                                     ? refit.segment_reason.size()
                                     : refit.segment_reason.find("segment states"));
      refit.seconds += first_seconds;
      refit.trace.insert(refit.trace.begin(), result.trace.begin(), result.trace.end());
      return refit;
    }
  }

  result.initial_cost = held_initial_cost >= 0 ? held_initial_cost : summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.gauss_newton_converged = gn_stop.fired() && !result.interrupted;
  result.converged =
      (summary.termination_type == ceres::CONVERGENCE || result.gauss_newton_converged) &&
      !result.interrupted;
  result.termination = result.gauss_newton_converged ? gn_stop.Message() : summary.message;
  if (previous_jacobian) {
    result.covariance_jacobian_iteration = gn_stop.previous_iteration();
    result.last_step_std_errors = gn_stop.last().step_ratio;
  }
  // sharded (sysid/mpi/): the uncompressed rows, with the priors'; compressed blocks: the rows
  // they stand for
  int prior_rows = 0;
  for (const FitParameter& p : I.params) prior_rows += p.has_prior ? 1 : 0;
  result.num_residuals = I.shards
                             ? static_cast<int>(I.shards->NumResiduals()) + prior_rows
                             : summary.num_residuals + static_cast<int>(compressed.hidden_rows);
  if (summary.termination_type == ceres::FAILURE) {
    result.warnings.push_back("Ceres failed: " + summary.message);
  }
  if (I.rejected_evaluations > 0) {
    result.warnings.push_back(std::to_string(I.rejected_evaluations) +
                              " evaluation(s) rejected (trial points where the simulation "
                              "diverged or was not finite; the trust region shrank); first: " +
                              I.first_rejection);
  }
  if (!I.jacobian_warnings.empty()) {
    const auto& [segment, what] = *I.jacobian_warnings.begin();
    const Segment& seg = I.segments[segment];
    result.warnings.push_back(
        "Jacobian not reliable in " + std::to_string(I.jacobian_warnings.size()) + " of " +
        std::to_string(I.segments.size()) + " segment(s); first: sequence '" +
        I.sequences[seg.seq].name + "' from step " + std::to_string(seg.k0) + ": " + what);
  }

  // the estimate: values, starts, bound flags (no interval yet)
  const int nm = static_cast<int>(I.m.size());
  const int nvar = np + nm;
  auto on_bound = [&](int v, double val, bool lower) {
    const double lo = v < np ? I.params[v].lower : mbounds[v - np].first;
    const double hi = v < np ? I.params[v].upper : mbounds[v - np].second;
    return OnBound(val, lower ? lo : hi, lower);
  };
  result.parameters.resize(nvar);
  for (int v = 0; v < nvar; ++v) {
    ParameterEstimate& e = result.parameters[v];
    e.name = names[v];
    e.value = v < np ? I.Physical(v, I.z[v]) : I.m[v - np];
    e.initial = v < np ? I.params[v].initial : prepared.minitial[v - np];
    e.at_lower = on_bound(v, e.value, true);
    e.at_upper = on_bound(v, e.value, false);
    e.std_error = e.ci95_low = e.ci95_high = std::numeric_limits<double>::quiet_NaN();
  }

  // Jacobian at the estimate, in physical units (tangent space for states). An interrupt stops it
  // at once (the simulators check the flag every time step): the result keeps the estimate,
  // without intervals.
  auto interrupted_now = [&] { return options.interrupt && options.interrupt->load(); };
  bool cost_not_local = false;  // the cost jumps within the intervals (CheckIntervalScale)
  for (auto& mo : I.models) mo.sim->SetCancelFlag(options.interrupt);
  ceres::Problem::EvaluateOptions eo;
  eo.num_threads = 1;  // as the solve
  bool multiple = false;
  // (sharded: the shards eliminate the states, the sharded problem is single-shooting shaped)
  for (const Segment& seg : I.segments) multiple = multiple || (seg.next >= 0 && !I.shards);
  // single shooting: the Jacobian only as the thin-QR triangle of [J r], block by block
  // (sysid/estimate_jacobian.h); multiple shooting: the whole sparse Jacobian (compressed blocks:
  // their n + 1 rows each), whose state columns are eliminated below
  double cost = 0;
  ceres::CRSMatrix crs;
  std::vector<double> residuals;
  EstimateTriangle triangle;
  // the core's Jacobian warnings of this evaluation alone: the Jacobian the intervals come from
  std::map<int, std::string> solve_warnings;
  std::swap(solve_warnings, I.jacobian_warnings);
  if (!solve_warnings.empty()) ++I.cost_inputs_epoch;  // the estimate's folds note theirs anew
  if (options.verbose && !interrupted_now()) {
    PrintFitProgress("unc", "Jacobian at the estimate (uncertainty)", I.fit_start);
  }
  // the triangle's columns in the order the blocks were added (z, m, the state blocks)
  const std::vector<double*>& blocks = all_blocks;
  ledger.Enter(kPhaseEstimate);
  I.SetPreviousJacobian(previous_jacobian);
  const bool evaluated =
      !interrupted_now() && (multiple ? problem.Evaluate(eo, &cost, &residuals, nullptr, &crs)
                                      : EvaluateTriangle(problem, blocks, &triangle));
  ledger.Enter(kPhaseCovariance);
  I.SetPreviousJacobian(false);
  I.compressed = nullptr;
  result.reused_folds = compressed.reused_folds;
  result.folds = compressed.folds;
  result.ahead_folds = compressed.ahead_folds;
  const bool jacobian_warned_at_estimate = evaluated && !I.jacobian_warnings.empty();
  I.jacobian_warnings.insert(solve_warnings.begin(), solve_warnings.end());
  for (auto& mo : I.models) mo.sim->SetCancelFlag(nullptr);
  if (interrupted_now()) {
    result.interrupted = true;
    result.converged = false;
    result.warnings.push_back("interrupted: no uncertainty step, the estimate has no intervals");
  } else if (evaluated) {
    // parameters first (as Ceres ordered the blocks: z, m, states); those stopped on a bound are
    // not estimated. Multiple shooting: the state columns are eliminated (Schur complement,
    // AnalyzeUncertaintyReduced) instead of entering a dense analysis of every segment state.
    const int ncols = multiple ? crs.num_cols : triangle.n;
    Eigen::VectorXd values = Eigen::VectorXd::Zero(multiple ? nvar : ncols);
    std::vector<bool> fixed(values.size(), false);
    std::vector<std::string> all_names = names;
    for (int v = 0; v < nvar; ++v) {
      values[v] = result.parameters[v].value;
      fixed[v] = result.parameters[v].at_lower || result.parameters[v].at_upper;
    }
    // r_aug: the triangle [R q; 0 rho] of [J_p r] over the parameter columns J_p (physical
    // units), for the result's jacobian and the interval check
    Eigen::MatrixXd r_aug;
    if (multiple) {
      RowMatrix A;
      Eigen::SparseMatrix<double> B;
      SplitJacobian(crs, nvar, &A, &B);
      for (int g = 0; g < np; ++g) A.col(g) /= I.DpDz(g, I.z[g]);
      // the rows Ceres sees may be compressed blocks' (n + 1 each): the dof counts the real rows
      result.uncertainty =
          AnalyzeUncertaintyReduced(A, B, result.num_residuals, cost, all_names, values, fixed, uo);
      RowTriangle tri(nvar + 1);
      RowMatrix rows(std::min<Eigen::Index>(A.rows(), RowTriangle::kChunkRows), nvar + 1);
      for (Eigen::Index first = 0; first < A.rows(); first += rows.rows()) {
        const Eigen::Index count = std::min<Eigen::Index>(rows.rows(), A.rows() - first);
        rows.topLeftCorner(count, nvar) = A.middleRows(first, count);
        rows.topRightCorner(count, 1) =
            Eigen::Map<const Eigen::VectorXd>(residuals.data() + first, count);
        tri.Add(rows.topRows(count));
      }
      r_aug = tri.R();
    } else {
      // the physical units of the parameter columns: a column scaling of J is one of R
      const int n = triangle.n;
      for (int g = 0; g < np; ++g) triangle.r_aug.col(g) /= I.DpDz(g, I.z[g]);
      for (int c = nvar; c < n; ++c) all_names.push_back("x0[" + std::to_string(c - nvar) + "]");
      cost = triangle.cost;
      // residual rows less the states the shards eliminated (they enter the dof as columns)
      const long long residual_rows =
          result.num_residuals - (I.shards ? I.shards->EliminatedColumns() : 0);
      result.uncertainty = AnalyzeUncertaintyCompressed(triangle.r_aug.leftCols(n), residual_rows,
                                                        cost, all_names, values, fixed, uo);
      // [J_p r]'s triangle: the parameter columns come first, so R's leading block is J_p's
      RowTriangle tri(nvar + 1);
      RowMatrix rows(triangle.r_aug.rows(), nvar + 1);
      rows << triangle.r_aug.leftCols(nvar), triangle.r_aug.col(n);
      tri.Add(rows);
      r_aug = tri.R();
    }
    // keep the parameter block of the covariance
    Eigen::MatrixXd cov = result.uncertainty.covariance.topLeftCorner(nvar, nvar);
    result.uncertainty.covariance = cov;
    Eigen::VectorXd se = result.uncertainty.std_error.head(nvar);
    result.uncertainty.std_error = se;
    result.uncertainty.identifiable.resize(nvar);
    for (int v = 0; v < nvar; ++v) {
      ParameterEstimate& e = result.parameters[v];
      e.std_error = se[v];
      e.identifiable = result.uncertainty.identifiable[v];
      e.ci95_low = e.value - kZ95 * e.std_error;
      e.ci95_high = e.value + kZ95 * e.std_error;
    }
    // the result keeps J_p as its triangle R (R^T R = J_p^T J_p), not the per-sample rows
    result.jacobian = r_aug.topLeftCorner(std::min<Eigen::Index>(r_aug.rows(), nvar), nvar);
    // the intervals' quadratic model against the cost one standard error away: contacts can make
    // the cost jump far inside an interval (sysid/interval_check.h); the triangle's rows give the
    // same model 0.5 |r + J_v d|^2 as the residual rows
    ledger.Enter(kPhaseIntervalCheck);
    if (options.verbose) PrintFitProgress("unc", "interval check", I.fit_start);
    // along the simulator parameters only where the rollouts at the estimate can make the cost
    // rugged (RuggedReason); the measurement terms and control delays always
    CostSmoothness smoothness;
    smoothness.all_rollouts = !I.shards;
    smoothness.jacobian_warnings = static_cast<int>(I.jacobian_warnings.size());
    smoothness.robust_loss = options.loss != LossType::kNone;
    smoothness.fitted_delays = static_cast<int>(I.control_delay_index.size());
    for (const TermIndex& t : I.term_index) smoothness.fitted_delays += t.delay >= 0 ? 1 : 0;
    for (size_t g = 0; g < I.segments.size() && smoothness.all_rollouts; ++g) {
      const EvaluationCache::Entry& e = I.cache->Cached(static_cast<int>(g));
      if (e.key.empty() || e.failed) {
        smoothness.all_rollouts = false;
        break;
      }
      smoothness.steps += e.tr.T;
      for (int n : e.tr.ncon) smoothness.contact_steps += n > 0 ? 1 : 0;
      smoothness.row_changes += e.tr.solver.row_changes;
      smoothness.friction_changes += e.tr.solver.friction_changes;
      const mjModel& mm = I.models[I.segments[g].model].sim->model();
      smoothness.pgs_constraints |= mm.opt.solver == mjSOL_PGS && e.tr.solver.solved > 0;
      if (e.has_jacobians && !e.jacobians_failed) smoothness.kinks += e.s.kinks;
    }
    const std::string rugged = RuggedReason(smoothness);
    Eigen::VectorXd se_checked = se;
    int skipped = 0;
    for (int v = 0; v < np && rugged.empty(); ++v) {
      if (!std::isfinite(se[v]) || !(se[v] > 0)) continue;
      if (!CheckAlongSmooth(result.parameters[v].value, se[v])) {
        ++skipped;
        se_checked[v] = std::numeric_limits<double>::quiet_NaN();
      }
    }
    // the cost with variable v moved by delta (physical units), false outside its bounds
    auto cost_at = [&](int v, double delta, double* c) {
      const ParameterEstimate& e = result.parameters[v];
      const double value = e.value + delta;
      const double lo = v < np ? I.params[v].lower : mbounds[v - np].first;
      const double hi = v < np ? I.params[v].upper : mbounds[v - np].second;
      if (e.at_lower || e.at_upper || value < lo || value > hi) return false;
      // a fit parameter's +- one standard error in one batch of rollouts (2 n tasks instead of
      // two batches of n; 3 sequences on 2 workers: 3 rounds instead of 4); each evaluation
      // then finds its rollouts in the cache
      if (v < np && delta > 0) {
        const double minus = e.value - delta;
        std::vector<double> zp = I.z, zm = I.z;
        zp[v] = I.params[v].ToVariable(value);
        zm[v] = I.params[v].ToVariable(minus);
        if (minus >= lo && minus <= hi && std::isfinite(zp[v]) && std::isfinite(zm[v])) {
          std::vector<const double*> x0(I.segments.size());
          for (size_t s = 0; s < I.segments.size(); ++s) x0[s] = I.X0(static_cast<int>(s));
          I.cache->PrefetchPoints({zp.data(), zm.data()}, x0);
        }
      }
      double* slot = v < np ? &I.z[v] : &I.m[v - np];
      const double saved = *slot;
      *slot = v < np ? I.params[v].ToVariable(value) : value;
      const bool ok = std::isfinite(*slot) && problem.Evaluate(eo, c, nullptr, nullptr, nullptr);
      *slot = saved;
      return ok;
    };
    const IntervalCheck ic =
        CheckIntervalScale(r_aug.col(nvar), r_aug.leftCols(nvar), se_checked, names, cost_at);
    // what ran and why, for result.yaml (never silent)
    const std::string wide = FormatDigits(100 * kSmoothRelativeStd, 3) + " % of the value";
    if (!rugged.empty()) {
      result.interval_check =
          "ran: " + std::to_string(ic.checked) + " cost evaluations (" + rugged + ")";
    } else if (skipped == 0) {
      result.interval_check = "ran: " + std::to_string(ic.checked) +
                              " cost evaluations (smooth rollouts, standard errors above " + wide +
                              ")";
    } else {
      result.interval_check =
          "skipped along " + std::to_string(skipped) + " of the " + std::to_string(np) +
          " simulator parameters (standard error <= " + wide +
          "): the rollouts at the estimate have no contact, no constraint row that comes, goes or "
          "changes state, no kink and no Jacobian warning (a smooth cost); " +
          std::to_string(ic.checked) + " cost evaluations along the other variables";
    }
    if (!ic.local) {
      cost_not_local = true;
      result.warnings.push_back(
          "the cost is not smooth at the scale of the intervals: " + ic.worst +
          "; contacts, impacts or stick-slip make the rollouts jump when a parameter moves by less "
          "than its standard error, so the Jacobian describes the cost only very locally and the "
          "intervals are not valid (docs/numerics.md, \"Contact: a rugged cost\")");
    }
  } else {
    result.warnings.push_back("the residuals could not be evaluated at the estimate");
  }

  ledger.Enter(kPhaseSignals);
  // the physical quantities of bodies fitted through body_inertial (mass, centre of mass,
  // principal moments) with delta-method intervals from the parameters' covariance
  {
    Eigen::VectorXd values(np), se(np);
    for (int v = 0; v < np; ++v) {
      values[v] = result.parameters[v].value;
      se[v] = result.parameters[v].std_error;
    }
    Eigen::MatrixXd cov;
    if (result.uncertainty.covariance.rows() >= np) {
      cov = result.uncertainty.covariance.topLeftCorner(np, np);
    }
    for (const Impl::Model& mo : I.models) {
      const std::string prefix = I.models.size() > 1 ? mo.name + "/" : "";
      for (DerivedQuantity& d :
           DeriveInertials(*mo.model, mo.name, I.params, values, se, cov, prefix)) {
        result.derived.push_back(std::move(d));
      }
    }
  }
  for (const auto& p : result.parameters) {
    if (p.at_lower || p.at_upper) {
      result.warnings.push_back("parameter '" + p.name + "' stopped on its " +
                                (p.at_lower ? "lower" : "upper") +
                                " bound: not estimated (no interval); the data may prefer a value "
                                "outside the bounds");
    }
  }
  for (const std::string& line : result.uncertainty.unidentifiable) {
    result.warnings.push_back("unidentifiable: " + line);
  }

  // the controls at the fitted delays (the interval check above evaluated others)
  if (!I.m.empty()) I.SyncControlDelays(I.m.data());

  // simulated signals before and after, per sequence (segment-wise in multiple shooting); in
  // multiple shooting also the largest continuity gap at the estimate: segments that do not join
  // describe no single trajectory (a chaotic fit stuck far from the data), which the user must
  // be told (docs/stress.md)
  if (I.shards) I.shards->CollectStates(&I);
  RolloutUnowned(&I, &prepared.initial);
  double worst_gap = 0;
  std::string worst_gap_where;
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    const FitSequence& sq = I.sequences[q];
    const Impl::Model& mo = I.models[I.ModelIndex(sq.model)];
    SequenceResult sr;
    sr.name = sq.name;
    sr.model = sq.model;
    sr.measured = sq.measured;
    const SampleGrid& grid = I.grids[q];
    const double dt = mo.sim->model().opt.timestep;
    sr.simulated_initial.resize(sq.measured.rows(), sq.measured.cols());
    SensorsAtSamples(initial[q].sensors, grid, 0, 0, static_cast<int>(sq.measured.rows()), dt,
                     &sr.simulated_initial);
    sr.simulated_final.resize(sq.measured.rows(), sq.measured.cols());
    if (np) ApplyVariables(I.params, mo.global, I.z.data(), mo.sim.get());
    for (size_t s = 0; s < I.segments.size(); ++s) {
      const Segment& seg = I.segments[s];
      if (seg.seq != static_cast<int>(q)) continue;
      const double* x0 = I.X0(static_cast<int>(s));
      if (seg.k0 == 0) sr.x0_final = Eigen::Map<const Eigen::VectorXd>(x0, mo.sim->dims().nphys);
      try {
        // the rollout at the estimate, from the evaluation cache (the final evaluation above ran
        // it; simulated here only if that evaluation failed)
        const EvaluationCache::Entry& cached =
            I.cache->Evaluate(static_cast<int>(s), np ? I.z.data() : nullptr, x0, false);
        if (cached.failed) throw std::runtime_error(cached.error);
        const Trajectory& tr = cached.tr;
        int first = 0, count = 0;
        I.SamplesOf(static_cast<int>(s), &first, &count);
        SensorsAtSamples(tr.sensors, grid, seg.k0, first, count, dt, &sr.simulated_final);
        if (seg.next >= 0) {
          const int nx = mo.sim->dims().nx;
          Eigen::VectorXd gap(nx);
          TangentDifference(mo.sim->model(), I.states[seg.next].data(), tr.states.row(seg.T).data(),
                            1.0, gap.data());
          if (gap.lpNorm<Eigen::Infinity>() > worst_gap) {
            worst_gap = gap.lpNorm<Eigen::Infinity>();
            worst_gap_where =
                "sequence '" + sq.name + "' at step " + std::to_string(seg.k0 + seg.T);
          }
        }
        // apply the measurement terms to the fitted columns
        for (const Channel& ch : I.channels[q]) {
          if (ch.measurement < 0) continue;
          const MeasurementTerms terms =
              I.Terms(ch.measurement, I.m.empty() ? nullptr : I.m.data());
          const Signal simulated{tr.sensors.data() + ch.column, tr.sensors.cols()};
          for (int k = first; k < first + count; ++k) {
            const DelayedSample at(grid.position[k] - seg.k0, tr.T, terms.delay, dt);
            sr.simulated_final(k, ch.column) = terms.Apply(at.Value(simulated));
          }
        }
      } catch (const std::exception& e) {
        result.warnings.push_back("sequence '" + sq.name +
                                  "': final simulation failed: " + e.what());
      }
    }
    KeepFittedColumns(mo.sim->model(), I.fitted[q], sq, &sr);
    // fitted states: logged, at the initial values, at the estimate, weighted residuals
    if (!I.state_channels[q].empty()) {
      const std::vector<StateChannel>& chans = I.state_channels[q];
      const int T = static_cast<int>(sq.measured.rows());
      InitStateResult(chans, sq, &sr);
      StatesAtSamples(mo.sim->model(), chans, sq, initial[q].states, grid.position, 0, 0, T,
                      &sr.state_simulated_initial, nullptr);
      for (size_t s = 0; s < I.segments.size(); ++s) {
        const Segment& seg = I.segments[s];
        if (seg.seq != static_cast<int>(q)) continue;
        const EvaluationCache::Entry& cached = I.cache->Evaluate(
            static_cast<int>(s), np ? I.z.data() : nullptr, I.X0(static_cast<int>(s)), false);
        if (cached.failed) continue;  // warned above
        int first = 0, count = 0;
        I.SamplesOf(static_cast<int>(s), &first, &count);
        StatesAtSamples(mo.sim->model(), chans, sq, cached.tr.states, grid.position, seg.k0, first,
                        count, &sr.state_simulated_final, &sr.state_residual_final);
      }
      for (size_t i = 0; i < chans.size(); ++i) {
        if (I.state_missing[q][i] == 0) continue;
        result.warnings.push_back("sequence '" + sq.name + "': state '" + chans[i].name +
                                  "': " + std::to_string(I.state_missing[q][i]) + " of " +
                                  std::to_string(T) +
                                  " samples not measured (NaN), masked out of the fit");
      }
    }
    // masked samples, sensor by sensor
    for (size_t i = 0, col = 0; i < sr.sensor_names.size(); col += sr.sensor_dims[i++]) {
      int missing = 0;
      for (int c = 0; c < sr.sensor_dims[i]; ++c) missing += sr.missing[col + c];
      // event windows are said once (FitResult::event_windows), not as unmeasured samples
      for (int c = 0; c < sr.sensor_dims[i] && q < I.event_masked.size(); ++c) {
        if (col + c < I.event_masked[q].size()) missing -= I.event_masked[q][col + c];
      }
      if (missing == 0) continue;
      result.warnings.push_back("sequence '" + sq.name + "': sensor '" + sr.sensor_names[i] +
                                "': " + std::to_string(missing) + " of " +
                                std::to_string(sr.measured.rows() * sr.sensor_dims[i]) +
                                " values not measured (NaN), masked out of the fit");
    }
    result.sequences.push_back(std::move(sr));
  }
  if (worst_gap > kContinuityGapWarning) {
    result.warnings.push_back(
        std::string("multiple shooting: segments do not join at the estimate (largest continuity "
                    "gap ") +
        FormatDigits(worst_gap, 3) + " in state units, " + worst_gap_where +
        "): it describes no single trajectory; try shorter segments, a larger continuity_weight "
        "or a start closer to the data");
  }
  // the verdict (sysid/fit_status.h): accepted steps, Jacobian warnings, chi-square
  int accepted_steps = held_accepted;
  for (size_t i = 1; i < summary.iterations.size(); ++i) {
    accepted_steps += summary.iterations[i].step_is_successful ? 1 : 0;
  }
  DecideFitStatus(options, accepted_steps, !I.jacobian_warnings.empty(), &result, cost_not_local,
                  jacobian_warned_at_estimate);
  for (const auto& mo : I.models) result.simulation_steps += mo.sim->StepCount();
  RecordReduction(I, options, &result);
  result.ledger = ledger.Finish();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // auto: single shooting that did not converge on a system whose probe grew well beyond linear
  // is refitted in multiple shooting (sysid/multiple_shooting.h, SegmentStepsAfterFailure); the
  // refit is the result when it converges, else this one stays, saying so
  if (options.segment_steps < 0 && prepared.segment_steps == 0 && !result.converged &&
      !result.interrupted) {
    int shortest = std::numeric_limits<int>::max();
    for (const SampleGrid& g : I.grids) shortest = std::min(shortest, g.steps);
    std::string reason;
    FitOptions segmented = options;
    segmented.segment_steps =
        SegmentStepsAfterFailure(prepared.probe_growth, prepared.probe_rate, shortest, &reason);
    if (segmented.segment_steps > 0) {
      FitResult refit = Fit(segmented);
      if (refit.outcome == FitStatus::kConverged) {
        const size_t from = refit.segment_reason.find("segment states");
        refit.segment_reason =
            reason + (from == std::string::npos ? "" : "; " + refit.segment_reason.substr(from));
        refit.seconds += result.seconds;
        refit.simulation_steps += result.simulation_steps;
        // the ledger adds up to simulation_steps: the single-shooting fit's rows first
        for (LedgerRow& row : result.ledger) row.phase = "single-shooting fit: " + row.phase;
        refit.ledger.insert(refit.ledger.begin(), result.ledger.begin(), result.ledger.end());
        refit.trace.insert(refit.trace.begin(), result.trace.begin(), result.trace.end());
        return refit;
      }
      result.warnings.push_back("auto: " + reason + " were tried and ended " +
                                FitStatusName(refit.outcome) + "; the single-shooting fit stays");
      result.seconds += refit.seconds;
      result.simulation_steps += refit.simulation_steps;
      for (LedgerRow& row : refit.ledger) row.phase = "multiple-shooting refit: " + row.phase;
      result.ledger.insert(result.ledger.end(), refit.ledger.begin(), refit.ledger.end());
    }
  }
  return result;
}

const std::vector<FitParameter>& Problem::parameters() const { return impl_->params; }

JacobianCheck Problem::CheckJacobians(const FitOptions& options) {
  Impl& I = *impl_;
  SolveAutoStarts(I, options.threads);  // `initial: auto`: checked at the start the fit would take
  Prepared prepared;
  Prepare(options, &prepared);
  const int np = static_cast<int>(I.params.size());
  const int nm = static_cast<int>(I.m.size());
  JacobianCheck check;
  std::map<std::string, double> worst;
  std::vector<std::string> order = prepared.names;

  // each residual block against Ceres' central differences of the same block
  // GradientChecker extrapolates with Ridders' method, whose first step (1e-2 relative by default)
  // would straddle the kinks of the sensor-delay interpolation (one per timestep): start small
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-6;
  nd.ridders_relative_initial_step_size = 1e-5;
  for (size_t s = 0; s < I.segments.size(); ++s) {
    const Segment& seg = I.segments[s];
    const Impl::Model& mo = I.models[seg.model];
    SegmentCost cost(&I, static_cast<int>(s));
    std::vector<const double*> blocks;
    std::vector<const ceres::Manifold*> manifolds;
    std::vector<std::vector<std::string>> labels;
    if (np) {
      blocks.push_back(I.z.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin(), prepared.names.begin() + np);
    }
    if (nm) {
      blocks.push_back(I.m.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin() + np, prepared.names.end());
    }
    const std::string seq_name = I.sequences[seg.seq].name;
    for (int b : {seg.block, seg.next}) {
      if (b < 0) continue;
      blocks.push_back(I.states[b].data());
      manifolds.push_back(mo.manifold.get());
      const std::string label = "x0 of " + seq_name + (b == seg.block ? "" : " (next segment)");
      labels.emplace_back(mo.sim->dims().nx, label);
      if (std::find(order.begin(), order.end(), label) == order.end()) order.push_back(label);
    }
    // worst column-scaled error of each variable of one residual block (blocks as `which`)
    auto probe = [&](ceres::CostFunction* f, const std::vector<size_t>& which, const char* what) {
      std::vector<const double*> bs;
      std::vector<const ceres::Manifold*> ms;
      for (size_t b : which) {
        bs.push_back(blocks[b]);
        ms.push_back(manifolds[b]);
      }
      ceres::GradientChecker checker(f, &ms, nd);
      ceres::GradientChecker::ProbeResults results;
      checker.Probe(bs.data(), 1.0, &results);
      if (!results.return_value) {
        throw SimulationError("CheckJacobians: the residuals of sequence '" + seq_name +
                                  "' cannot be evaluated at the initial values",
                              seg.seq, seg.k0);
      }
      for (size_t i = 0; i < which.size(); ++i) {
        const auto& A = results.local_jacobians[i];
        const auto& N = results.local_numeric_jacobians[i];
        const std::vector<std::string>& lab = labels[which[i]];
        for (Eigen::Index c = 0; c < A.cols(); ++c) {
          const double scale = std::max(N.col(c).lpNorm<Eigen::Infinity>(), 1e-12);
          const double err = (A.col(c) - N.col(c)).lpNorm<Eigen::Infinity>() / scale;
          const std::string& label = lab[std::min<size_t>(c, lab.size() - 1)];
          worst[label] = std::max(worst[label], err);
          if (err > check.worst_relative_error) {
            check.worst_relative_error = err;
            check.worst_where = label + ", " + what + " residual block of sequence '" + seq_name +
                                "' from step " + std::to_string(seg.k0);
          }
        }
      }
    };
    std::vector<size_t> all(blocks.size());
    for (size_t b = 0; b < blocks.size(); ++b) all[b] = b;
    if (cost.num_residuals() > 0 && !blocks.empty()) probe(&cost, all, "sensor and continuity");
    // the fitted states: the z block and the segment's x_0 block (sysid/state_residuals.h)
    if (seg.state_rows) {
      StateCost state_cost(&I, static_cast<int>(s));
      std::vector<size_t> which;
      if (np) which.push_back(0);
      if (seg.block >= 0) which.push_back((np ? 1 : 0) + (nm ? 1 : 0));
      if (state_cost.num_residuals() > 0 && !which.empty()) probe(&state_cost, which, "state");
    }
  }
  for (const std::string& label : order) {
    if (worst.count(label)) check.per_variable.emplace_back(label, worst[label]);
  }
  return check;
}

}  // namespace mjsysid
