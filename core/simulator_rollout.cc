// Nominal rollouts: one step loop (RolloutOne), whole rollouts or consecutive pieces of them
// scheduled on the workers (Rollout, internal::RolloutPieces), and rollouts at several parameter
// vectors in one pass (RolloutAt).
#include <algorithm>
#include <atomic>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "core/simulator_internal.h"

namespace mjsysid {

using internal::kRolloutFailed;
using internal::Tenths;
using internal::WaitForRows;

// steps [k0, k1) of one rollout on worker w
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

// the trajectories of a batch sized (and their inputs checked) before any task writes them
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

// one rollout task, or one piece of it
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

namespace internal {

int RolloutPieces(int n, int workers, int min_steps) {
  if (n <= workers || n % workers == 0) return 1;
  const int pieces = workers / std::gcd(n, workers);
  return min_steps / pieces >= kMinPieceSteps ? pieces : 1;
}

}  // namespace internal

void Simulator::Rollout(const std::vector<SequenceInput>& sequences, std::vector<Trajectory>* out) {
  // size outputs up front, then fill them in parallel across sequences: task p n + i is piece p of
  // sequence i (one piece each unless the workers would be left idle in the last round)
  const int n = static_cast<int>(sequences.size());
  int min_steps = std::numeric_limits<int>::max();
  for (const SequenceInput& s : sequences) {
    min_steps = std::min(min_steps, static_cast<int>(s.ctrl.rows()));
  }
  const int pieces = internal::RolloutPieces(n, pool_.size(), min_steps);
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
        internal::CopyModelInto(w.plus.get(), model_.get());
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

}  // namespace mjsysid
