// Private to core/simulator*.cc (not part of the public API): the per-worker scratch, the guard
// and worker wrappers every unit of the simulator shares, the one-sided difference rule, the
// progress tenths, the pipelining handshake and the rollout-piece schedule.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"

namespace mjsysid {

// per-worker scratch, allocated once and reused (no allocation in the step loops)
struct Simulator::Worker {
  DataPtr data;
  ModelPtr plus, minus;                           // perturbed copies of the model
  std::vector<ModelPtr> param_plus, param_minus;  // matrix mode: one per parameter
  Eigen::VectorXd s, s_next, xp, xm, yp, ym, e;
  Eigen::VectorXd fx, fy;  // directional columns past kSplitGrowth: the parameter part
  RowMatrix states_p, sensors_p, states_m, sensors_m;
  RowMatrix Ab, Cb, Bb, Db;  // matrix mode: the backward side of one step (SizeMatrixScratch)
  long long steps = 0;       // step calls made by this worker (see Simulator::StepCount)
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

// Runs call(); when the reduced model's guard tripped during it (or it threw after a trip), drops
// the reduction for good and runs call() again on the full model. Cancelled always propagates.
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

namespace internal {

// a perturbation h*|S| past this (in state units) is no longer a local finite difference
constexpr double kGrowthLimit = kSensitivityGrowthLimit;
// past this h*|S| a directional column differences the state part (x_k moved along S_k scaled to
// the state step, nominal model: A_k S_k) and the parameter part (nominal x_k, parameter at p +- h:
// F_k) apart, one more step per side; below it one combined step. Measured on a chaotic double
// pendulum (tests/core/simulator_test.cc): combined steps up to h*|S| = 3e4 left the columns off by
// 100 %, split past 1e-2 by 0.6 % (forward) and 0.006 % (central); a falling humanoid's combined
// perturbed step diverged (bad qacc) where the split steps stay local
constexpr double kSplitGrowth = kGrowthLimit;

// forward and backward differences further apart than this (relative) straddle a kink
constexpr double kKinkTolerance = 0.1;

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

// dst = src for two models of the same sizes (mj_copyModel into existing storage)
inline void CopyModelInto(mjModel* dst, const mjModel* src) {
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

// Pipelined columns (Simulator::RolloutAndJacobians) and rollout pieces (Simulator::Rollout): a
// rollout publishes how many state rows it has recorded; kRolloutFailed when it threw
constexpr int kRolloutFailed = -1;

// waits until the rollout behind ready has recorded `rows` state rows (and everything of the steps
// before them); false when the rollout failed (its exception is the one ParallelFor rethrows);
// ready == nullptr: true at once
inline bool WaitForRows(const std::atomic<int>* ready, int rows) {
  if (!ready) return true;
  for (;;) {
    const int r = ready->load(std::memory_order_acquire);
    if (r == kRolloutFailed) return false;
    if (r >= rows) return true;
    std::this_thread::yield();
  }
}

// Scheduling of a batch of rollouts (Simulator::Rollout): the pieces each of n rollouts runs in on
// `workers` workers: q = workers / gcd(n, workers) when n > workers and workers does not divide n
// (so that n q pieces fill whole rounds), else 1; 1 also when the shortest of the sequences
// (min_steps) has fewer than kMinPieceSteps steps per piece.
constexpr int kMinPieceSteps = 50;
int RolloutPieces(int n, int workers, int min_steps);

// Speculation (simulator_ahead.cc). Take: the entries of ahead computed at the parameter values p
// with options opt (and ncol columns, sized as out) moved into out, their perturbed solves into
// perturbed and their column count into begin; the entries taken are left empty. Keep: the first
// end[i] columns of out[i] moved into ahead[i] with p, opt, perturbed[i] and the step calls of
// their tasks (task_steps[i * ncol + col]).
void TakeColumnsAhead(const Eigen::VectorXd& p, const JacobianOptions& opt, int ncol,
                      std::vector<ColumnsAhead>* ahead, std::vector<Sensitivity>* out,
                      std::vector<SolverStats>* perturbed, std::vector<int>* begin);
void KeepColumnsAhead(const Eigen::VectorXd& p, const JacobianOptions& opt, int ncol,
                      const std::vector<int>& end, const std::vector<long long>& task_steps,
                      std::vector<SolverStats>* perturbed, std::vector<Sensitivity>* out,
                      std::vector<ColumnsAhead>* ahead);

}  // namespace internal
}  // namespace mjsysid
