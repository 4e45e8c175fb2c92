// Stages 2 and 3 of a fit pass (sysid/fit/pass.h): the Ceres problem and the solver's options.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "sysid/data/contact_channels.h"
#include "sysid/fit/pass.h"
#include "sysid/solve/multiple_shooting.h"
#include "sysid/solve/state_residuals.h"

namespace mjsysid {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

// 2. The Ceres problem: the z block (with its bounds in z and, where the nominal rollouts are
// smooth, the relative step of log variables, sysid/solve/variable_manifold.h), the m block, and
// per segment its sensor and continuity rows and its fitted states, each handed to Ceres as its
// thin-QR triangle (sysid/solve/compressed_cost.h: Ceres then holds n + 1 rows per block) unless
// the residuals are evaluated by shards (sysid/mpi/); then the priors.
void FitPass::BuildCeres() {
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  prefetch_ = std::make_unique<PrefetchCallback>(parts_);
  po.evaluation_callback = fit_.shards ? fit_.shards->Callback() : prefetch_.get();
  // log variables of kinds that enter the dynamics linearly take the relative step where the
  // nominal rollouts are smooth (no contact: with contacts the residuals are not near-linear in p
  // either)
  const bool smooth = ContactFraction(plan_.initial) == 0;
  std::vector<bool> relative;
  for (const FitParameter& p : fit_.params) relative.push_back(smooth && RelativeStep(p));
  variable_manifold_ = std::make_unique<VariableManifold>(std::move(relative));
  compressed_.reuse_folds = options_.advanced.reuse_folds;
  compressed_.epoch = &solve_.cost_inputs_epoch;  // (the epoch outlives the problem)
  compress_ = options_.advanced.compress_blocks && !fit_.shards;
  problem_ = std::make_unique<ceres::Problem>(po);
  ceres::Problem& problem = *problem_;
  double* z = vars_.z.data();
  double* m = vars_.m.data();
  if (np_) {
    problem.AddParameterBlock(z, np_);
    if (variable_manifold_->any_relative()) problem.SetManifold(z, variable_manifold_.get());
    for (int g = 0; g < np_; ++g) {
      const FitParameter& p = fit_.params[g];
      const double zl = fit_.ToZ(g, p.lower), zu = fit_.ToZ(g, p.upper);
      const double lo = p.transform == Transform::kScale ? std::min(zl, zu) : zl;
      const double hi = p.transform == Transform::kScale ? std::max(zl, zu) : zu;
      if (std::isfinite(lo) && p.lower > -kInf) problem.SetParameterLowerBound(z, g, lo);
      if (std::isfinite(hi) && p.upper < kInf) problem.SetParameterUpperBound(z, g, hi);
    }
  }
  if (nm_) {
    problem.AddParameterBlock(m, nm_);
    for (int i = 0; i < nm_; ++i) {
      if (std::isfinite(plan_.mbounds[i].first)) {
        problem.SetParameterLowerBound(m, i, plan_.mbounds[i].first);
      }
      if (std::isfinite(plan_.mbounds[i].second)) {
        problem.SetParameterUpperBound(m, i, plan_.mbounds[i].second);
      }
    }
  }
  // segment residuals evaluated elsewhere (sysid/mpi/): their blocks replace the segments'
  if (fit_.shards) {
    std::vector<double*> blocks;
    if (np_) blocks.push_back(z);
    if (nm_) blocks.push_back(m);
    fit_.shards->AddResidualBlocks(SegmentEvaluator(parts_), &problem, blocks);
  }
  for (size_t s = 0; s < fit_.segments.size() && !fit_.shards; ++s) {
    const Segment& seg = fit_.segments[s];
    std::vector<double*> blocks;
    if (np_) blocks.push_back(z);
    if (nm_) blocks.push_back(m);
    if (seg.block >= 0) blocks.push_back(vars_.states[seg.block].data());
    if (seg.next >= 0) blocks.push_back(vars_.states[seg.next].data());
    auto* cost = new SegmentCost(parts_, static_cast<int>(s));
    if (cost->num_residuals() > 0 && !blocks.empty()) {
      problem.AddResidualBlock(compress_ ? Compress(cost, &compressed_, blocks) : cost, nullptr,
                               blocks);
    } else {
      delete cost;  // e.g. a model without sensors fitted from its states alone
    }
    // the fitted states (sysid/solve/state_residuals.h): the z and x_0 blocks
    if (seg.state_rows) {
      std::vector<double*> state_blocks;
      if (np_) state_blocks.push_back(z);
      if (seg.block >= 0) state_blocks.push_back(vars_.states[seg.block].data());
      auto* state_cost = new StateCost(parts_, static_cast<int>(s));
      if (state_cost->num_residuals() > 0 && !state_blocks.empty()) {
        problem.AddResidualBlock(compress_ ? Compress(state_cost, &compressed_) : state_cost,
                                 nullptr, state_blocks);
      } else {
        delete state_cost;
      }
    }
    if (seg.block >= 0 && problem.HasParameterBlock(vars_.states[seg.block].data())) {
      problem.SetManifold(vars_.states[seg.block].data(), fit_.models[seg.model].manifold.get());
    }
  }
  for (int g = 0; g < np_; ++g) {
    if (fit_.params[g].has_prior) problem.AddResidualBlock(new PriorCost(&fit_, g), nullptr, z);
  }
  // every parameter block, in the order added: the estimate's triangle and the statistical stop
  if (np_) blocks_.push_back(z);
  if (nm_) blocks_.push_back(m);
  for (size_t b = 0; b < vars_.states.size(); ++b) {
    if (problem.HasParameterBlock(vars_.states[b].data()))
      blocks_.push_back(vars_.states[b].data());
  }
}

// 3. The solver: Levenberg-Marquardt with the linear solver the problem's shape calls for
// (sysid/solve/multiple_shooting.h), one thread (the evaluation cache is single-threaded by
// contract, sysid/solve/evaluation_cache.h; the simulators are parallel inside), and the callbacks:
// the progress (trace, observer, interruption) and, where its test is valid, the statistical stop.
void FitPass::Configure() {
  ceres::Solver::Options& so = solver_;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  int tangent = np_ + nm_;
  // (sharded: the states are eliminated by the shards, Ceres sees z and m)
  for (size_t b = 0; b < vars_.states.size(); ++b) {
    tangent += fit_.shards ? 0 : static_cast<int>(vars_.states[b].size());
  }
  ChooseLinearSolver(fit_, vars_, tangent, &so);
  so.max_num_iterations = options_.max_iterations;
  so.function_tolerance = options_.function_tolerance;
  so.gradient_tolerance = options_.gradient_tolerance;
  so.parameter_tolerance = options_.parameter_tolerance;
  so.num_threads = 1;
  // with bounds, Ceres runs a projected line search along every step: quadratic interpolation
  // needs cost values only, the default cubic one a full Jacobian per trial length
  // (docs/numerics.md, "Line search")
  so.line_search_interpolation_type = ceres::QUADRATIC;
  so.update_state_every_iteration = true;
  so.logging_type = ceres::SILENT;
  progress_ = std::make_unique<ProgressCallback>(parts_, &result_, start_);
  so.callbacks.push_back(progress_.get());
  // the rank tolerance follows the finite differences' accuracy (relative step h: O(h)
  // forward, O(h^2) central) unless the user's rank_tolerance is larger
  uncertainty_ = options_.uncertainty;
  const double h = options_.jacobian.relative_step;
  uncertainty_.jacobian_accuracy =
      std::max(uncertainty_.jacobian_accuracy, options_.jacobian.central ? h * h : h);
  // the statistical stop (sysid/solve/gn_convergence.h) where its test is valid: single shooting on
  // this process, no robust loss, no fitted control delay (their columns are rollouts), and only
  // where auto's probe measured bounded growth (at most kRefitGrowth beyond linear). On a chaotic
  // system the single-shooting cost is rugged and every local minimum is a stationary point that
  // passes the test: there the fit must run to Ceres' tolerances (or its iteration cap), so that
  // auto still refits it in multiple shooting (tests/stress/horizon_stress_test.cc). A set
  // segment_steps runs no probe: no evidence, no statistical stop.
  gn_valid_ = options_.gauss_newton_stop > 0 && !fit_.shards && options_.loss == LossType::kNone &&
              fit_.control_delay_index.empty() && !blocks_.empty() && options_.segment_steps < 0 &&
              plan_.probe_growth <= kRefitGrowth;
  for (const Segment& seg : fit_.segments) gn_valid_ = gn_valid_ && seg.next < 0;
  gn_stop_ = std::make_unique<GaussNewtonStop>(problem_.get(), blocks_, options_.gauss_newton_stop,
                                               uncertainty_, options_.observer, &ledger_);
  if (gn_valid_) so.callbacks.push_back(gn_stop_.get());
  // and before a point's Jacobians (the evaluation callback asks it, sysid/solve/cost_functions.h)
  solve_.gn_stop =
      gn_valid_ && options_.advanced.gauss_newton_stop_before_jacobian ? gn_stop_.get() : nullptr;
  solve_.SetPreviousJacobian(false);
}

}  // namespace mjsysid
