// Simulator: construction, parameter values, the reduced model's switch, step accounting, and the
// per-step helpers every rollout and Jacobian unit shares (input checks, worker reset, initial
// state, cancel, one step and its warning check). Rollouts: simulator_rollout.cc; the Jacobian
// mode and steps: simulator_mode.cc; Jacobians: simulator_jacobians.cc, simulator_columns.cc,
// simulator_matrix.cc; columns computed ahead: simulator_ahead.cc.
#include "core/simulator.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "core/simulator_internal.h"
#include "core/text.h"

namespace mjsysid {

// construction: the private model with the solver and sensor options, its parameter writers, and
// one mjData and two model copies per worker
Simulator::Simulator(const mjModel& m, const std::vector<ParameterSpec>& params,
                     const SimulatorOptions& options)
    : model_(CopyModel(m)),
      params_(*model_, params),
      dims_(*model_),
      options_(options),
      pool_(options.threads) {
  InstallMujocoHandlers();
  // private model options: fixed solver iterations, sensors only when asked for
  if (options_.fixed_solver_iterations) {
    model_->opt.tolerance = 0;
  } else if (options_.solver_tolerance > 0) {
    model_->opt.tolerance = std::min(model_->opt.tolerance, options_.solver_tolerance);
  }
  if (!options_.sensors) model_->opt.disableflags |= mjDSBL_SENSOR;
  if (options_.sensors && options_.copy_state_sensors) state_sensors_ = PlanStateSensors(*model_);
  params_.Prepare(model_.get());
  scratch_ = MakeData(*model_);
  for (int w = 0; w < pool_.size(); ++w) {
    auto worker = std::make_unique<Worker>();
    worker->data = MakeData(*model_);
    worker->plus = CopyModel(*model_);
    worker->minus = CopyModel(*model_);
    workers_.push_back(std::move(worker));
  }
  // the pool's task model counts in step calls (ParallelLoad)
  pool_.SetMeter([this](int worker) { return workers_[worker]->steps; });
}

Simulator::~Simulator() = default;

void Simulator::SetReduction(const ModelReduction& r) {
  if (reduced_) RevertReduction(reduction_, model_.get());
  reduced_ = false;
  contacts_possible_full_ = ContactsPossible();
  ApplyReduction(r, model_.get());
  reduction_ = r;
  reduced_ = !r.Empty();
}

// step accounting (the pool's task model meters the same per-worker counters)
long long Simulator::StepCount() const {
  long long n = 0;
  for (const auto& w : workers_) n += w->steps;
  return n;
}

void Simulator::ResetStepCount() {
  for (auto& w : workers_) w->steps = 0;
  pool_.ResetLoad();
}

// parameter values and the reference state
Eigen::VectorXd Simulator::GetParameters() const {
  Eigen::VectorXd p(params_.size());
  params_.Read(*model_, p.data());
  return p;
}

void Simulator::SetParameters(const Eigen::VectorXd& values) {
  if (values.size() != params_.size()) {
    throw std::invalid_argument("SetParameters: expected " + std::to_string(params_.size()) +
                                " values, got " + std::to_string(values.size()));
  }
  // a MuJoCo error in mj_setConst leaves model_ with raw values and stale derived constants:
  // write back the values that last gave a consistent model, then report the error
  const Eigen::VectorXd previous = GetParameters();
  try {
    params_.Write(model_.get(), scratch_.get(), values.data());
  } catch (const MujocoError&) {
    ResetData(scratch_.get());
    params_.Write(model_.get(), scratch_.get(), previous.data());
    throw;
  }
}

InitialState Simulator::ReferenceState() const {
  InitialState x0;
  x0.qpos = Eigen::Map<const Eigen::VectorXd>(model_->qpos0, dims_.nq);
  x0.qvel = Eigen::VectorXd::Zero(dims_.nv);
  x0.act = Eigen::VectorXd::Zero(dims_.na);
  return x0;
}

// shapes and finiteness of a batch's inputs
void Simulator::CheckInputs(const std::vector<SequenceInput>& sequences) const {
  for (size_t i = 0; i < sequences.size(); ++i) {
    const SequenceInput& s = sequences[i];
    const std::string where = "sequence " + std::to_string(i) + ": ";
    if (s.ctrl.rows() < 1) throw std::invalid_argument(where + "no samples (ctrl has 0 rows)");
    if (s.ctrl.cols() != dims_.nu) {
      throw std::invalid_argument(where + "ctrl has " + std::to_string(s.ctrl.cols()) +
                                  " columns, the model has nu = " + std::to_string(dims_.nu));
    }
    if (s.x0.qpos.size() != 0 && s.x0.qpos.size() != dims_.nq) {
      throw std::invalid_argument(where + "initial qpos has " + std::to_string(s.x0.qpos.size()) +
                                  " entries, expected nq = " + std::to_string(dims_.nq));
    }
    if (s.x0.qvel.size() != 0 && s.x0.qvel.size() != dims_.nv) {
      throw std::invalid_argument(where + "initial qvel has " + std::to_string(s.x0.qvel.size()) +
                                  " entries, expected nv = " + std::to_string(dims_.nv));
    }
    if (s.x0.act.size() != 0 && s.x0.act.size() != dims_.na) {
      throw std::invalid_argument(where + "initial act has " + std::to_string(s.x0.act.size()) +
                                  " entries, expected na = " + std::to_string(dims_.na));
    }
    if (!s.ctrl.allFinite() || !s.x0.qpos.allFinite() || !s.x0.qvel.allFinite() ||
        !s.x0.act.allFinite()) {
      throw std::invalid_argument(where + "controls or initial state contain NaN/Inf");
    }
  }
}

// a worker's mjData back to a fresh state, and a sequence's initial state written into one
void Simulator::ResetData(mjData* d) const {
  CallMujoco([&] { mj_resetData(model_.get(), d); });
  ClearSimulationWarnings(d);
}

void Simulator::ResetWorker(Worker& w) const {
  // the perturbed model copies need nothing: every use rebuilds them from model_ first
  ResetData(w.data.get());
}

void Simulator::SetInitialState(mjData* d, const InitialState& x0) const {
  ResetData(d);
  if (x0.qpos.size()) mju_copy(d->qpos, x0.qpos.data(), dims_.nq);
  if (x0.qvel.size()) mju_copy(d->qvel, x0.qvel.data(), dims_.nv);
  if (x0.act.size()) mju_copy(d->act, x0.act.data(), dims_.na);
  d->time = x0.time;
}

void Simulator::CheckCancel() const {
  if (cancel_ && cancel_->load(std::memory_order_relaxed)) {
    throw Cancelled("simulation cancelled (interrupted)");
  }
}

namespace {

// the SimulationError of a step that warned (out of line: the step loops only test the counters)
[[noreturn, gnu::noinline]] void ThrowStepWarning(const mjData& d, double t, int seq_index,
                                                  int step, const char* what) {
  // t comes from the caller: MuJoCo's reset after a bad acceleration sets d.time to 0
  throw SimulationError(std::string(what) + ": sequence " + std::to_string(seq_index) + ", step " +
                            std::to_string(step) + " (t = " + FormatDigits(t, 6) +
                            " s): MuJoCo warning: " + SimulationWarnings(d),
                        seq_index, step);
}

}  // namespace

void Simulator::Step(const mjModel* m, mjData* d, int skipstage) const {
  if (state_sensors_.complete) {
    // y_k from x_k, before the integrator moves it
    CopyStateSensors(state_sensors_, d);
    StepSkip(m, d, skipstage, true);
  } else {
    StepSkip(m, d, skipstage, !options_.sensors);
  }
}

void Simulator::CheckStep(const mjData& d, double t, int seq_index, int step,
                          const char* what) const {
  // every step passes here: the message is built only when a warning is set
  if (AnySimulationWarning(d)) ThrowStepWarning(d, t, seq_index, step, what);
}

// the inputs of a recorded trajectory written back before its steps are restored
void RestoreInputs(const mjModel& m, const StateDims& dims, const Trajectory& tr, mjData* d) {
  if (dims.ninput == 0) return;
  CallMujoco([&] { mj_setState(&m, d, tr.inputs.data(), static_cast<int>(dims.input_sig)); });
}

}  // namespace mjsysid
