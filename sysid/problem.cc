// Problem: its inputs (Add*) and the state behind it, four parts (sysid/solve/fit_state.h) lent to
// the fit policy (sysid/fit/policy.h), the Jacobian check (sysid/fit/check_jacobians.h) and a
// sharded fit's workers (sysid/fit/prepare.h); PrepareFit (sysid/fit/prepare.cc) validates the
// inputs and builds what a fit runs on.
#include "sysid/problem.h"

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/fit/check_jacobians.h"
#include "sysid/fit/policy.h"
#include "sysid/fit/prepare.h"
#include "sysid/fit/segment_evaluator.h"
#include "sysid/fit/sigma_from_log.h"
#include "sysid/solve/fit_state.h"

namespace mjsysid {

// the four parts of the fit state; the solve context is declared last (destroyed first: its
// evaluation cache borrows the prepared fit's simulators)
struct Problem::Impl {
  PreparedFit fit;
  FitVariables vars;
  FitDiagnostics diag;
  SolveContext solve;
  FitParts Parts() { return {&fit, &vars, &diag, &solve}; }
};

FitParts PartsOf(Problem* problem) { return problem->impl_->Parts(); }

// -----------------------------------------------------------------------------------------------
// building

Problem::Problem() : impl_(std::make_unique<Impl>()) { InstallMujocoHandlers(); }
Problem::~Problem() = default;

void Problem::AddModel(const std::string& name, const mjModel& m) {
  for (const FitModel& mo : impl_->fit.models) {
    if (mo.name == name) throw std::invalid_argument("model '" + name + "' added twice");
  }
  FitModel mo;
  mo.name = name;
  mo.model = CopyModel(m);
  impl_->fit.models.push_back(std::move(mo));
}

void Problem::AddParameter(const FitParameter& p) {
  for (const FitParameter& q : impl_->fit.params) {
    if (q.name == p.name) throw std::invalid_argument("parameter '" + p.name + "' added twice");
  }
  impl_->fit.params.push_back(p);
}

void Problem::AddMeasurement(const FitMeasurement& me) { impl_->fit.measurements.push_back(me); }

void Problem::AddSequence(const FitSequence& s) { impl_->fit.sequences.push_back(s); }

void Problem::AddControlDelay(const FitControlDelay& delay) {
  for (const FitControlDelay& d : impl_->fit.control_delays) {
    if (d.actuator == delay.actuator) {
      throw std::invalid_argument("control delay '" + delay.Name() + "' added twice");
    }
  }
  impl_->fit.control_delays.push_back(delay);
}

void Problem::DistributeResiduals(ResidualShards* shards) {
  impl_->fit.shards = shards;
  if (shards) {
    impl_->fit.owned_sequences = [shards](const std::vector<double>& work) {
      return shards->OwnedSequences(work);
    };
  }
}

const std::vector<FitParameter>& Problem::parameters() const { return impl_->fit.params; }

// -----------------------------------------------------------------------------------------------
// fitting

FitResult Problem::Fit(const FitOptions& options) {
  std::map<std::string, double> sigmas;
  const FitOptions resolved = WithSigmasFromLog(impl_->fit, options, &sigmas);
  FitResult result = FitWithPolicy(impl_->Parts(), resolved);
  for (ResidualDiagnostics& d : result.residuals) {
    d.sigma_from_log = sigmas.count(d.channel.substr(0, d.channel.find('['))) > 0;
  }
  result.sigma_from_log = std::move(sigmas);
  return result;
}

JacobianCheck Problem::CheckJacobians(const FitOptions& options) {
  return CheckJacobiansAt(impl_->Parts(), WithSigmasFromLog(impl_->fit, options, nullptr));
}

// -----------------------------------------------------------------------------------------------
// a sharded fit's workers (sysid/fit/prepare.h)

SegmentEvaluator PrepareOnly(Problem* problem, const FitOptions& options) {
  const FitParts parts = PartsOf(problem);
  PrepareFit(parts, WithSigmasFromLog(*parts.fit, options, nullptr));
  return SegmentEvaluator(parts);
}

void ShardStart(Problem* problem,
                std::function<std::vector<bool>(const std::vector<double>& work)> owned) {
  PartsOf(problem).fit->owned_sequences = std::move(owned);
}

}  // namespace mjsysid
