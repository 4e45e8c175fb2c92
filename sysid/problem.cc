// Problem: its inputs (Add*), the equation-error starts and the rollouts a sharded start leaves
// out. PrepareFit (sysid/problem_prepare.cc) validates the inputs and builds what a fit runs on;
// Fit is the policy around one or two fit passes (sysid/fit/policy.cc, sysid/fit/pass.h);
// CheckJacobians is in sysid/fit/check_jacobians.cc.
#include "sysid/problem.h"

#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/data/equation_error.h"
#include "sysid/problem_impl.h"

namespace mjsysid {

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
  PrepareFit(impl_.get(), options);
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

std::vector<std::string> SolveAutoStarts(Problem::Impl* impl, int threads) {
  Problem::Impl& I = *impl;
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

const std::vector<FitParameter>& Problem::parameters() const { return impl_->params; }

}  // namespace mjsysid
