#include "core/simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <thread>

#include "core/text.h"

namespace mjsysid {
namespace {

// deterministic cost of a step that skips stages, relative to a full step (used only to choose a
// Jacobian mode; BENCHMARKS.md has the measured values)
constexpr double kCostSkipPos = 0.6;
constexpr double kCostSkipVel = 0.4;

// a perturbation h*|S| past this (in state units) is no longer a local finite difference
constexpr double kGrowthLimit = kSensitivityGrowthLimit;

// the tenths of one step loop reported to a StepProgress hook: one compare per step
class Tenths {
 public:
  Tenths(StepProgress* hook, const char* what, int total)
      : hook_(hook),
        what_(what),
        total_(total),
        stride_(std::max(1, total / 10)),
        next_(hook ? 0 : std::numeric_limits<int>::max()) {}
  void At(int done) {
    if (done < next_) return;
    hook_->Step(what_, done, total_);
    next_ = (done / stride_ + 1) * stride_;
  }

 private:
  StepProgress* hook_;
  const char* what_;
  int total_, stride_, next_;
};

// forward and backward differences further apart than this (relative) straddle a kink
constexpr double kKinkTolerance = 0.1;

double StageCost(int skipstage) {
  if (skipstage == mjSTAGE_VEL) return kCostSkipVel;
  if (skipstage == mjSTAGE_POS) return kCostSkipPos;
  return 1.0;
}

// dst = src for two models of the same sizes (mj_copyModel into existing storage)
void CopyModelInto(mjModel* dst, const mjModel* src) {
  CallMujoco([=] { mj_copyModel(dst, src); });
}

// Chooses between one-sided differences of a column (states dx and sensors dy, each forward
// [fx, fy] and backward [bx, by]). Returns true when the sides disagree (a kink): then out = the
// smaller side; else out = their mean (central) or the forward side.
template <typename X, typename Y, typename OX, typename OY>
bool CombineSides(const X& fx, const X& bx, const Y& fy, const Y& by, bool central, OX&& out_x,
                  OY&& out_y) {
  const double nfx = fx.template lpNorm<Eigen::Infinity>();
  const double nbx = bx.template lpNorm<Eigen::Infinity>();
  const double nfy = fy.size() ? fy.template lpNorm<Eigen::Infinity>() : 0.0;
  const double nby = by.size() ? by.template lpNorm<Eigen::Infinity>() : 0.0;
  const double dx = (fx - bx).template lpNorm<Eigen::Infinity>();
  const double dy = fy.size() ? (fy - by).template lpNorm<Eigen::Infinity>() : 0.0;
  const bool kink = dx > kKinkTolerance * std::max(nfx, nbx) + 1e-10 ||
                    dy > kKinkTolerance * std::max(nfy, nby) + 1e-10;
  if (kink) {
    const bool forward = nfx + nfy <= nbx + nby;
    out_x = forward ? fx : bx;
    out_y = forward ? fy : by;
  } else if (central) {
    out_x = 0.5 * (fx + bx);
    out_y = 0.5 * (fy + by);
  } else {
    out_x = fx;
    out_y = fy;
  }
  return kink;
}

// Pipelined columns (Simulator::RolloutAndJacobians): a rollout publishes how many state rows it
// has recorded; kRolloutFailed when it threw
constexpr int kRolloutFailed = -1;

// waits until the rollout behind ready has recorded `rows` state rows (and everything of the steps
// before them); false when the rollout failed (its exception is the one ParallelFor rethrows)
bool WaitForRows(const std::atomic<int>* ready, int rows) {
  if (!ready) return true;
  for (;;) {
    const int r = ready->load(std::memory_order_acquire);
    if (r == kRolloutFailed) return false;
    if (r >= rows) return true;
    std::this_thread::yield();
  }
}

}  // namespace

double ContactFraction(const std::vector<Trajectory>& trajectories) {
  long near = 0, total = 0;
  for (const Trajectory& tr : trajectories) {
    for (int k = 0; k < tr.T && k < static_cast<int>(tr.ncon.size()); ++k) {
      near += tr.ncon[k] > 0 || (k + 1 < tr.T && tr.ncon[k + 1] != tr.ncon[k]);
      ++total;
    }
  }
  return total ? static_cast<double>(near) / static_cast<double>(total) : 0.0;
}

const char* JacobianModeName(JacobianMode mode) {
  switch (mode) {
    case JacobianMode::kAuto:
      return "auto";
    case JacobianMode::kDirectional:
      return "directional";
    case JacobianMode::kMatrix:
      return "matrix";
    case JacobianMode::kWholeRollout:
      return "whole_rollout";
  }
  return "?";
}

void RestoreInputs(const mjModel& m, const StateDims& dims, const Trajectory& tr, mjData* d) {
  if (dims.ninput == 0) return;
  CallMujoco([&] { mj_setState(&m, d, tr.inputs.data(), static_cast<int>(dims.input_sig)); });
}

// per-worker scratch, allocated once and reused (no allocation in the step loops)
struct Simulator::Worker {
  DataPtr data;
  ModelPtr plus, minus;                           // perturbed copies of the model
  std::vector<ModelPtr> param_plus, param_minus;  // matrix mode: one per parameter
  Eigen::VectorXd s, s_next, xp, xm, yp, ym, e;
  RowMatrix states_p, sensors_p, states_m, sensors_m;
  long long steps = 0;  // step calls made by this worker (see Simulator::StepCount)
};

// what one Jacobian task reports besides its column
struct Simulator::TaskReport {
  std::string warning;  // empty: none
  int kinks = 0;
  SolverStats solver;  // constraint solves of its perturbed steps
};

template <class Task>
void Simulator::OnWorker(Worker& w, Task&& task) const {
  try {
    task();
  } catch (...) {
    ResetWorker(w);
    throw;
  }
}

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

template <class Call>
void Simulator::Guarded(Call&& call) {
  guard_tripped_.store(false, std::memory_order_relaxed);
  // a trip: the reduced model may have missed a contact; the full model simulates the call again
  auto drop = [&] {
    RevertReduction(reduction_, model_.get());
    reduced_ = false;
    ++reduction_trips_;
    guard_tripped_.store(false, std::memory_order_relaxed);
  };
  try {
    call();
  } catch (const Cancelled&) {
    throw;
  } catch (...) {
    if (!guard_tripped_.load(std::memory_order_relaxed)) throw;
    drop();
    call();
    return;
  }
  if (!guard_tripped_.load(std::memory_order_relaxed)) return;
  drop();
  call();
}

long long Simulator::StepCount() const {
  long long n = 0;
  for (const auto& w : workers_) n += w->steps;
  return n;
}

void Simulator::ResetStepCount() {
  for (auto& w : workers_) w->steps = 0;
  pool_.ResetLoad();
}

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

void Simulator::RolloutOne(Worker& w, const mjModel* m, const SequenceInput& seq, int seq_index,
                           RowMatrix* states, RowMatrix* sensors, RowMatrix* step,
                           std::vector<int>* ncon, SolverStats* solver, std::atomic<int>* progress,
                           int k0, int k1) const {
  mjData* d = w.data.get();
  const int T = static_cast<int>(seq.ctrl.rows());
  if (k1 < 0) k1 = T;
  const bool want_sensors = options_.sensors && sensors && dims_.ns > 0;
  // step the model, recording x_k (and the step state) before and y_k after each step
  Tenths tenths(step_progress_, "rollout", T);
  for (int k = k0; k < k1; ++k) {
    CheckCancel();
    tenths.At(k);
    const double* u = seq.ctrl.row(k).data();
    for (int i = 0; i < dims_.nu; ++i) d->ctrl[i] = u[i];
    if (step) GetStepState(*m, dims_, *d, step->row(k).data());
    GetPhysics(*m, *d, states->row(k).data());
    // rows 0..k recorded, with the sensors and contacts of the steps before
    if (progress) progress->store(k + 1, std::memory_order_release);
    const double t = d->time;
    Step(m, d, mjSTAGE_NONE);
    ++w.steps;
    CheckStep(*d, t, seq_index, k, "simulation");
    CountSolve(*m, *d, solver);
    // the reduced model's guard: the pairs switched off stay away (core/reduced_model.h)
    if (reduced_ && !ReductionGuardClear(reduction_, *m, *d)) {
      guard_tripped_.store(true, std::memory_order_relaxed);
    }
    if (want_sensors) {
      double* y = sensors->row(k).data();
      for (int i = 0; i < dims_.ns; ++i) y[i] = d->sensordata[i];
    }
    if (ncon) (*ncon)[k] = d->ncon;
  }
  // a piece that is not the last: the state row the next piece starts from
  if (k1 < T) {
    GetPhysics(*m, *d, states->row(k1).data());
    if (step) GetStepState(*m, dims_, *d, step->row(k1).data());
    if (progress) progress->store(k1 + 1, std::memory_order_release);
    return;
  }
  GetPhysics(*m, *d, states->row(T).data());
  if (step) GetStepState(*m, dims_, *d, step->row(T).data());
  if (progress) progress->store(T + 1, std::memory_order_release);
  if (!states->row(T).allFinite()) {
    throw SimulationError(
        "simulation: sequence " + std::to_string(seq_index) + ": non-finite final state", seq_index,
        T);
  }
}

void Simulator::SizeTrajectories(const std::vector<SequenceInput>& sequences,
                                 std::vector<Trajectory>* out) const {
  CheckInputs(sequences);
  out->resize(sequences.size());
  for (size_t i = 0; i < sequences.size(); ++i) {
    Trajectory& tr = (*out)[i];
    tr.T = static_cast<int>(sequences[i].ctrl.rows());
    tr.states.resize(tr.T + 1, dims_.nphys);
    tr.sensors.resize(tr.T, options_.sensors ? dims_.ns : 0);
    tr.step.resize(tr.T + 1, dims_.nstep);
    tr.inputs.resize(dims_.ninput);
    tr.ncon.assign(tr.T, 0);
    tr.solver = SolverStats();
  }
}

void Simulator::RolloutTask(Worker& w, const SequenceInput& seq, int seq_index, Trajectory* tr,
                            std::atomic<int>* progress, const mjModel* m) const {
  RolloutPiece(w, seq, seq_index, tr, progress, 0, 1, m);
}

void Simulator::RolloutPiece(Worker& w, const SequenceInput& seq, int seq_index, Trajectory* tr,
                             std::atomic<int>* progress, int piece, int pieces,
                             const mjModel* m) const {
  if (!m) m = model_.get();
  const int k0 = static_cast<int>(static_cast<long long>(tr->T) * piece / pieces);
  const int k1 = static_cast<int>(static_cast<long long>(tr->T) * (piece + 1) / pieces);
  OnWorker(w, [&] {
    try {
      mjData* d = w.data.get();
      if (piece == 0) {
        // the first piece (or the whole rollout) starts from x0 and records the inputs
        SetInitialState(d, seq.x0);
        if (dims_.ninput) {
          CallMujoco(
              [&] { mj_getState(m, d, tr->inputs.data(), static_cast<int>(dims_.input_sig)); });
        }
      } else {
        // a later piece: once the piece before has recorded state row k0 (a failed one has thrown
        // the batch's error), everything step k0 reads, as a perturbed step restores it
        if (!WaitForRows(progress, k0 + 1)) return;
        RestoreInputs(*m, dims_, *tr, d);
        RestoreStep(*m, dims_, *tr, k0, seq.ctrl.row(k0).data(), d);
      }
      RolloutOne(w, m, seq, seq_index, &tr->states, &tr->sensors, &tr->step, &tr->ncon, &tr->solver,
                 progress, k0, k1);
    } catch (...) {
      if (progress) progress->store(kRolloutFailed, std::memory_order_release);
      throw;
    }
  });
}

int Simulator::RolloutPieces(int n, int min_steps) const {
  const int workers = pool_.size();
  if (n <= workers || n % workers == 0) return 1;
  const int pieces = workers / std::gcd(n, workers);
  return min_steps / pieces >= kMinPieceSteps ? pieces : 1;
}

void Simulator::Rollout(const std::vector<SequenceInput>& sequences, std::vector<Trajectory>* out) {
  // size outputs up front, then fill them in parallel across sequences: task p n + i is piece p of
  // sequence i (one piece each unless the workers would be left idle in the last round)
  const int n = static_cast<int>(sequences.size());
  int min_steps = std::numeric_limits<int>::max();
  for (const SequenceInput& s : sequences) {
    min_steps = std::min(min_steps, static_cast<int>(s.ctrl.rows()));
  }
  const int pieces = RolloutPieces(n, min_steps);
  Guarded([&] {
    SizeTrajectories(sequences, out);
    if (pieces == 1) {
      pool_.ParallelFor(n, [&](int worker, int i) {
        RolloutTask(*workers_[worker], sequences[i], i, &(*out)[i], nullptr);
      });
      return;
    }
    // state rows recorded per sequence: what a later piece waits for
    std::vector<std::atomic<int>> progress(n);
    for (auto& p : progress) p.store(0, std::memory_order_relaxed);
    std::vector<int> after(static_cast<size_t>(n) * pieces, -1);
    for (int t = n; t < n * pieces; ++t) after[t] = t - n;
    pool_.SetNextAfter(std::move(after));
    pool_.ParallelFor(n * pieces, [&](int worker, int t) {
      const int i = t % n;
      RolloutPiece(*workers_[worker], sequences[i], i, &(*out)[i], &progress[i], t / n, pieces);
    });
  });
}

void Simulator::RolloutAt(const std::vector<SequenceInput>& sequences,
                          const std::vector<Eigen::VectorXd>& values,
                          std::vector<std::vector<Trajectory>>* out) {
  for (const Eigen::VectorXd& v : values) {
    if (v.size() != params_.size()) {
      throw std::invalid_argument("RolloutAt: expected " + std::to_string(params_.size()) +
                                  " values per point, got " + std::to_string(v.size()));
    }
  }
  const int n = static_cast<int>(sequences.size()), npoint = static_cast<int>(values.size());
  Guarded([&] {
    out->assign(npoint, std::vector<Trajectory>());
    for (std::vector<Trajectory>& o : *out) SizeTrajectories(sequences, &o);
    // task k * n + i: sequence i on the worker's model copy with the values of point k written
    // as SetParameters writes them
    pool_.ParallelFor(npoint * n, [&](int worker, int t) {
      const int k = t / n, i = t % n;
      Worker& w = *workers_[worker];
      OnWorker(w, [&] {
        CopyModelInto(w.plus.get(), model_.get());
        params_.Write(w.plus.get(), w.data.get(), values[k].data());
      });
      RolloutTask(w, sequences[i], i, &(*out)[k][i], nullptr, w.plus.get());
    });
  });
}

Trajectory Simulator::Rollout(const SequenceInput& sequence) {
  std::vector<Trajectory> out;
  Rollout({sequence}, &out);
  return std::move(out[0]);
}

Eigen::VectorXd Simulator::ParameterSteps(const JacobianOptions& opt) const {
  const int np = params_.size();
  if (!opt.parameter_steps.empty() && static_cast<int>(opt.parameter_steps.size()) != np) {
    throw std::invalid_argument("JacobianOptions::parameter_steps has " +
                                std::to_string(opt.parameter_steps.size()) + " entries, expected " +
                                std::to_string(np));
  }
  Eigen::VectorXd p = GetParameters();
  Eigen::VectorXd h(np);
  for (int j = 0; j < np; ++j) {
    h[j] = opt.parameter_steps.empty()
               ? opt.relative_step * std::max(std::abs(p[j]), opt.step_floor)
               : opt.parameter_steps[j];
    if (!(h[j] > 0)) throw std::invalid_argument("parameter step must be positive");
  }
  return h;
}

double Simulator::JacobianCostPerStep(JacobianMode mode, const JacobianOptions& opt,
                                      double contact_fraction) const {
  if (contact_fraction < 0) contact_fraction = ContactsPossible() ? 1.0 : 0.0;
  const int np = params_.size();
  const int ncol = np + (opt.initial_state ? dims_.nx : 0);
  const double sides = opt.central ? 2.0 : 1.0;
  switch (mode) {
    case JacobianMode::kDirectional:
    case JacobianMode::kWholeRollout:
      return sides * ncol;
    case JacobianMode::kMatrix: {
      // transitionFD: nominal step, qpos columns (full), qvel (skip POS), act (skip VEL); run on
      // both sides for central differences, and for forward ones too where contacts may change
      // (the kink check); one base forward; one perturbed step per parameter skipping its stages
      const double fd_sides = opt.central ? 2.0 : 1.0 + contact_fraction;
      double cost = 2.0 + fd_sides * (dims_.nv + kCostSkipPos * dims_.nv + kCostSkipVel * dims_.na);
      for (int j = 0; j < np; ++j) cost += sides * StageCost(params_[j].stage());
      return cost;
    }
    case JacobianMode::kAuto:
      break;
  }
  return JacobianCostPerStep(ChooseJacobianMode(opt, contact_fraction), opt, contact_fraction);
}

bool Simulator::ContactsPossible() const {
  // contacts need collisions enabled and two geoms that may collide (in the full model)
  if (reduced_) return contacts_possible_full_;
  if (model_->opt.disableflags & mjDSBL_CONTACT) return false;
  int colliding = 0;
  for (int g = 0; g < model_->ngeom; ++g) {
    if (model_->geom_contype[g] || model_->geom_conaffinity[g]) ++colliding;
  }
  return colliding >= 2 || model_->npair > 0;
}

JacobianMode Simulator::ChooseJacobianMode(const JacobianOptions& opt,
                                           double contact_fraction) const {
  if (opt.mode != JacobianMode::kAuto) return opt.mode;
  // native delays: the history buffer is state that the one-step modes do not carry
  if (model_->nhistory > 0) return JacobianMode::kWholeRollout;
  // mjd_transitionFD rejects RK4 and history (delays)
  const bool matrix_ok = model_->opt.integrator != mjINT_RK4 && model_->nhistory == 0;
  if (matrix_ok && JacobianCostPerStep(JacobianMode::kMatrix, opt, contact_fraction) <
                       JacobianCostPerStep(JacobianMode::kDirectional, opt, contact_fraction)) {
    return JacobianMode::kMatrix;
  }
  return JacobianMode::kDirectional;
}

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

  // one perturbed step from the nominal x_k moved along sign*h*S_k, parameter at p + sign*h:
  // leaves the one-sided difference quotients of x_{k+1} and y_k in dx, dy
  auto side = [&](mjModel* m, double sign, int k, Eigen::VectorXd& dx, Eigen::VectorXd& dy) {
    RestoreStep(*m, dims_, nom, k, ctrl.row(k).data(), d);
    TangentPerturb(*m, d, w.s.data(), sign * h);
    Step(m, d, mjSTAGE_NONE);
    ++w.steps;
    CheckStep(*d, nom.step(k, 0), seq_index, k, "perturbed step");  // step state: time first
    CountSolve(*m, *d, &report->solver);
    GetPhysics(*m, *d, w.xp.data());
    TangentDifference(*model_, nom.states.row(k + 1).data(), w.xp.data(), sign / h, dx.data());
    for (int i = 0; i < ns; ++i) dy[i] = (d->sensordata[i] - nom.sensors(k, i)) * (sign / h);
    return d->ncon;
  };

  Tenths tenths(step_progress_, "Jacobian column", T);
  for (int k = 0; k < T; ++k) {
    CheckCancel();
    tenths.At(k);
    if (!WaitForRows(ready, k + 2)) return;
    // forward side; the backward side too for central differences or a contact-set change
    const int ncon = side(w.plus.get(), 1.0, k, w.s_next, w.yp);
    if (opt.central || ncon != nom.ncon[k]) {
      side(w.minus.get(), -1.0, k, w.e, w.ym);
      if (CombineSides(w.s_next, w.e, w.yp, w.ym, opt.central, w.xm.head(nx), w.yp)) {
        ++report->kinks;
      }
      w.s_next = w.xm.head(nx);
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
                      ": finite differences are no longer local; shorten the horizon (multiple "
                      "shooting)";
  }
}

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

void Simulator::MatrixJacobian(const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                               const JacobianOptions& opt, const Eigen::VectorXd& steps,
                               Sensitivity* out, SolverStats* solver) {
  const int np = params_.size(), nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int ncol = out->ncol, T = nom.T;
  const int chunk = std::min(T, 64 * pool_.size());

  // parameters ordered so that each group's skipped stages were computed by the base forward or
  // recomputed by an earlier group: actuation first, then velocity, then position parameters
  std::vector<int> order(np);
  for (int j = 0; j < np; ++j) order[j] = j;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return params_[a].stage() > params_[b].stage(); });

  // per-step blocks of one chunk (A, C: forward side; Ab, Cb: backward side)
  const bool both_sides = opt.central;
  std::vector<double> A(static_cast<size_t>(chunk) * nx * nx);
  std::vector<double> C(static_cast<size_t>(chunk) * ns * nx);
  std::vector<double> Ab(A.size()), Cb(C.size());
  RowMatrix F(static_cast<size_t>(chunk) * nx, np), G(static_cast<size_t>(chunk) * ns, np);
  std::vector<int> chunk_kinks(chunk, 0);
  std::vector<SolverStats> chunk_solver(chunk);

  // S_0 = [0 | I]
  RowMatrix S = RowMatrix::Zero(nx, ncol), S_next(nx, ncol);
  if (opt.initial_state) S.rightCols(nx).setIdentity();

  // growth of each column, h*|S| as in DirectionalColumn: the chain of one-step linearisations
  // stays finite where directional differences stop being local, but past kGrowthLimit the
  // derivative describes the trajectory only for parameter changes far below any useful step (a
  // chaotic horizon): warn the same way instead of returning huge values silently
  Eigen::VectorXd col_step(ncol), max_growth = Eigen::VectorXd::Zero(ncol);
  std::vector<int> growth_step(ncol, -1);
  for (int c = 0; c < ncol; ++c) col_step[c] = c < np ? steps[c] : opt.state_step;

  Tenths tenths(step_progress_, "Jacobians", T);
  for (int k0 = 0; k0 < T; k0 += chunk) {
    tenths.At(k0);
    const int kn = std::min(chunk, T - k0);
    // step Jacobians of this chunk, in parallel over time steps
    pool_.ParallelFor(kn, [&](int worker, int kk) {
      Worker& w = *workers_[worker];
      OnWorker(w, [&] {
        mjData* d = w.data.get();
        CheckCancel();
        const int k = k0 + kk;
        const double t = nom.step(k, 0);
        const double* u = ctrl.row(k).data();
        ClearSimulationWarnings(d);
        RestoreInputs(*model_, dims_, nom, d);
        chunk_kinks[kk] = 0;
        chunk_solver[kk] = SolverStats();

        // state columns: forward differences (eps), and backward ones (-eps) for central, so that
        // each column can be checked for a kink (centered mjd_transitionFD cannot)
        double* Ak = A.data() + static_cast<size_t>(kk) * nx * nx;
        double* Ck = ns ? C.data() + static_cast<size_t>(kk) * ns * nx : nullptr;
        CallMujoco([&] {
          RestoreStep(*model_, dims_, nom, k, u, d);
          mjd_transitionFD(model_.get(), d, opt.state_step, 0, Ak, nullptr, Ck, nullptr);
        });
        w.steps += 1 + nx;
        CheckStep(*d, t, seq_index, k, "mjd_transitionFD");
        // forward differences are checked too where the contact set may change near x_k
        const bool contact_near = nom.ncon[k] > 0 ||
                                  (k + 1 < T && nom.ncon[k + 1] != nom.ncon[k]) ||
                                  (k > 0 && nom.ncon[k - 1] != nom.ncon[k]);
        if (both_sides || contact_near) {
          double* Abk = Ab.data() + static_cast<size_t>(kk) * nx * nx;
          double* Cbk = ns ? Cb.data() + static_cast<size_t>(kk) * ns * nx : nullptr;
          CallMujoco([&] {
            RestoreStep(*model_, dims_, nom, k, u, d);
            mjd_transitionFD(model_.get(), d, -opt.state_step, 0, Abk, nullptr, Cbk, nullptr);
          });
          w.steps += 1 + nx;
          CheckStep(*d, t, seq_index, k, "mjd_transitionFD");
          Eigen::Map<RowMatrix> Af(Ak, nx, nx), Abm(Abk, nx, nx);
          Eigen::Map<RowMatrix> Cf(Ck, ns, nx), Cbm(Cbk, ns, nx);
          for (int c = 0; c < nx; ++c) {
            if (CombineSides(Af.col(c), Abm.col(c), Cf.col(c), Cbm.col(c), opt.central, Af.col(c),
                             Cf.col(c))) {
              ++chunk_kinks[kk];
            }
          }
        }
        if (np == 0) return;

        // parameter columns: base pass at x_k with the nominal model, then one step per parameter
        // that skips the stages before the one the parameter enters
        CallMujoco([&] {
          RestoreStep(*model_, dims_, nom, k, u, d);
          mj_forward(model_.get(), d);
        });
        ++w.steps;
        auto side = [&](mjModel* m, int skip, double sign, double h, Eigen::VectorXd& dx,
                        Eigen::VectorXd& dy) {
          RestoreStep(*m, dims_, nom, k, u, d);
          Step(m, d, skip);
          ++w.steps;
          CheckStep(*d, t, seq_index, k, "perturbed step");
          CountSolve(*m, *d, &chunk_solver[kk]);
          GetPhysics(*model_, *d, w.xp.data());
          TangentDifference(*model_, nom.states.row(k + 1).data(), w.xp.data(), sign / h,
                            dx.data());
          for (int i = 0; i < ns; ++i) dy[i] = (d->sensordata[i] - nom.sensors(k, i)) * (sign / h);
          return d->ncon;
        };
        for (int j : order) {
          const double h = steps[j];
          const int skip = params_[j].stage();
          const int ncon = side(w.param_plus[j].get(), skip, 1.0, h, w.s_next, w.yp);
          if (opt.central || ncon != nom.ncon[k]) {
            side(w.param_minus[j].get(), skip, -1.0, h, w.e, w.ym);
            if (CombineSides(w.s_next, w.e, w.yp, w.ym, opt.central, w.xm.head(nx), w.yp)) {
              ++chunk_kinks[kk];
            }
            w.s_next = w.xm.head(nx);
          }
          F.block(static_cast<Eigen::Index>(kk) * nx, j, nx, 1) = w.s_next;
          if (ns) G.block(static_cast<Eigen::Index>(kk) * ns, j, ns, 1) = w.yp;
        }
      });
    });
    for (int kk = 0; kk < kn; ++kk) {
      out->kinks += chunk_kinks[kk];
      *solver += chunk_solver[kk];
    }

    // chain through the chunk: dy_k = C_k S_k + G_k, S_{k+1} = A_k S_k + F_k
    for (int kk = 0; kk < kn; ++kk) {
      const int k = k0 + kk;
      Eigen::Map<const RowMatrix> Ak(A.data() + static_cast<size_t>(kk) * nx * nx, nx, nx);
      if (opt.state_jacobians) out->DxDp.middleRows(k * nx, nx) = S;
      if (ns) {
        Eigen::Map<const RowMatrix> Ck(C.data() + static_cast<size_t>(kk) * ns * nx, ns, nx);
        auto dy = out->DyDp.middleRows(k * ns, ns);
        dy.noalias() = Ck * S;
        dy.leftCols(np) += G.middleRows(kk * ns, ns);
      }
      S_next.noalias() = Ak * S;
      S_next.leftCols(np) += F.middleRows(kk * nx, nx);
      S.swap(S_next);
      for (int c = 0; c < ncol; ++c) {
        const double growth = col_step[c] * S.col(c).lpNorm<Eigen::Infinity>();
        if (growth > max_growth[c]) {
          max_growth[c] = growth;
          if (growth > kGrowthLimit && growth_step[c] < 0) growth_step[c] = k + 1;
        }
      }
    }
  }
  for (int c = 0; c < ncol; ++c) {
    if (growth_step[c] < 0) continue;
    out->warnings.push_back(
        "column " + std::to_string(c) +
        ": sensitivity grew so that h*|S| = " + FormatDigits(max_growth[c], 6) + " (> " +
        FormatDigits(kGrowthLimit, 6) + ") from step " + std::to_string(growth_step[c]) +
        ": the linearisation holds only for far smaller changes; shorten the horizon (multiple "
        "shooting)");
  }
  if (opt.state_jacobians) out->DxDp.middleRows(T * nx, nx) = S;
  if (!S.allFinite()) {
    throw SimulationError(
        "matrix chain: sequence " + std::to_string(seq_index) + ": non-finite sensitivity",
        seq_index, T);
  }
}

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

bool Simulator::CanPipeline(const JacobianOptions& opt, int ncol) const {
  // pipelined only where it can change something and the mode does not depend on the contacts
  // the rollouts will find (ChooseJacobianMode at either end of the contact share)
  const JacobianMode mode = ChooseJacobianMode(opt, 0.0);
  return pool_.size() > 1 && ncol > 0 && mode == JacobianMode::kDirectional &&
         ChooseJacobianMode(opt, 1.0) == mode && model_->nhistory == 0;
}

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
  const int np = params_.size(), nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int ncol = np + (opt.initial_state ? nx : 0);
  // pipelined: the rollouts are still to come, and the mode is the same for any contact share
  const JacobianMode mode = ChooseJacobianMode(opt, rollouts ? 0.0 : ContactFraction(nominal));
  if (mode == JacobianMode::kMatrix &&
      (model_->opt.integrator == mjINT_RK4 || model_->nhistory > 0)) {
    throw std::invalid_argument(
        "Jacobian mode 'matrix' needs mjd_transitionFD, which supports neither the RK4 "
        "integrator nor delays (history); use 'directional'");
  }
  // Native delays (actuator/sensor history buffers) make the delayed controls and sensor values
  // state that one-step differences over [qpos, qvel, act] leave out (measured on
  // models/servo_delay.xml with a 4 ms delayed angle sensor: the servo gain's sensor column off by
  // 0.09 after 200 steps, column-scaled): only whole rollouts differentiate them
  if (mode == JacobianMode::kDirectional && model_->nhistory > 0) {
    throw std::invalid_argument(
        "Jacobian mode 'directional' differentiates one step at a time over qpos, qvel and act, "
        "and this model has native delays (history buffers of " +
        std::to_string(model_->nhistory) +
        " numbers) that it would leave out; use 'whole_rollout' or 'auto'");
  }
  const Eigen::VectorXd steps = ParameterSteps(opt);

  // size outputs
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
  if (ncol == 0) return;

  // worker scratch
  for (auto& w : workers_) {
    w->s.resize(nx);
    w->s_next.resize(nx);
    w->e.resize(nx);
    w->xp.resize(dims_.nphys);
    w->xm.resize(dims_.nphys);
    w->yp.resize(ns);
    w->ym.resize(ns);
  }

  // constraint solves of the perturbed steps, per sequence
  std::vector<SolverStats> perturbed(sequences.size());

  // columns computed ahead: only the first ahead_end[i] now; or the columns of ahead[i] that
  // belong to these parameter values and options taken (moved: a call without rollouts is never
  // simulated again by Guarded), the rest computed
  std::vector<int> begin(sequences.size(), 0), end(sequences.size(), ncol);
  if (ahead && ahead_end) {
    end = *ahead_end;
  } else if (ahead && ahead->size() == sequences.size() && mode == JacobianMode::kDirectional) {
    const Eigen::VectorXd p = GetParameters();
    for (size_t i = 0; i < sequences.size(); ++i) {
      ColumnsAhead& a = (*ahead)[i];
      if (a.columns <= 0 || a.s.ncol != ncol || a.at.size() != p.size() || a.at != p ||
          !SameColumns(a.options, opt) || a.s.DyDp.rows() != (*out)[i].DyDp.rows() ||
          a.s.DxDp.rows() != (*out)[i].DxDp.rows()) {
        continue;
      }
      (*out)[i] = std::move(a.s);
      perturbed[i] = a.perturbed;
      begin[i] = a.columns;
      a = ColumnsAhead();  // taken
    }
  }
  if (mode == JacobianMode::kMatrix) {
    // one perturbed model per parameter and side, per worker (mj_setConst uses its mjData)
    for (auto& w : workers_) {
      OnWorker(*w, [&] {
        w->param_plus.resize(np);
        w->param_minus.resize(np);
        for (int j = 0; j < np; ++j) {
          const double p = params_[j].Read(*model_);
          if (!w->param_plus[j]) w->param_plus[j] = CopyModel(*model_);
          CopyModelInto(w->param_plus[j].get(), model_.get());
          params_.WriteOne(w->param_plus[j].get(), w->data.get(), j, p + steps[j]);
          if (!w->param_minus[j]) w->param_minus[j] = CopyModel(*model_);
          CopyModelInto(w->param_minus[j].get(), model_.get());
          params_.WriteOne(w->param_minus[j].get(), w->data.get(), j, p - steps[j]);
        }
      });
    }
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
      const Eigen::VectorXd p = GetParameters();
      for (size_t i = 0; i < sequences.size(); ++i) {
        ColumnsAhead& a = (*ahead)[i];
        a.columns = end[i];
        a.at = p;
        a.options = opt;
        a.s = std::move((*out)[i]);
        a.perturbed = perturbed[i];
        for (int col = 0; col < end[i]; ++col) a.steps += task_steps[i * ncol + col];
      }
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

Sensitivity Simulator::Jacobians(const SequenceInput& sequence, const Trajectory& nominal,
                                 const JacobianOptions& options) {
  std::vector<Sensitivity> out;
  Jacobians({sequence}, {nominal}, options, &out);
  return std::move(out[0]);
}

}  // namespace mjsysid
