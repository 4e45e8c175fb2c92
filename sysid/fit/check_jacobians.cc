// Problem::CheckJacobians: every residual block's analytic Jacobian at the initial point against
// Ceres' central differences (ceres::GradientChecker, whole rollouts).
#include "sysid/fit/check_jacobians.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "sysid/fit/prepare.h"
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/state_residuals.h"

namespace mjsysid {

JacobianCheck CheckJacobiansAt(const FitParts& parts, const FitOptions& options) {
  PreparedFit& fit = *parts.fit;
  const FitVariables& vars = *parts.vars;
  SolveAutoStarts(&fit,
                  options.threads);  // `initial: auto`: checked at the start the fit would take
  const FitPlan prepared = PrepareFit(parts, options);
  const int np = static_cast<int>(fit.params.size());
  const int nm = static_cast<int>(vars.m.size());
  JacobianCheck check;
  std::map<std::string, double> worst;
  std::vector<std::string> order = prepared.names;

  // each residual block against Ceres' central differences of the same block
  // GradientChecker extrapolates with Ridders' method, whose first step (1e-2 relative by default)
  // would straddle the kinks of the sensor-delay interpolation (one per timestep): start small
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-6;
  nd.ridders_relative_initial_step_size = 1e-5;
  for (size_t s = 0; s < fit.segments.size(); ++s) {
    const Segment& seg = fit.segments[s];
    const FitModel& mo = fit.models[seg.model];
    SegmentCost cost(parts, static_cast<int>(s));
    std::vector<const double*> blocks;
    std::vector<const ceres::Manifold*> manifolds;
    std::vector<std::vector<std::string>> labels;
    if (np) {
      blocks.push_back(vars.z.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin(), prepared.names.begin() + np);
    }
    if (nm) {
      blocks.push_back(vars.m.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin() + np, prepared.names.end());
    }
    const std::string seq_name = fit.sequences[seg.seq].name;
    for (int b : {seg.block, seg.next}) {
      if (b < 0) continue;
      blocks.push_back(vars.states[b].data());
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
    // the fitted states: the z block and the segment's x_0 block (sysid/solve/state_residuals.h)
    if (seg.state_rows) {
      StateCost state_cost(parts, static_cast<int>(s));
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
