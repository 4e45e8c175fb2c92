// Variable projection of a sequence's free states (sysid/mpi/state_projection.h).
#include "sysid/mpi/state_projection.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sysid/solve/state_manifold.h"

namespace mjsysid::mpi {
namespace {

// the segments [*first, *last) of sequence q (segments are in sequence order) and the state
// blocks of q in order (each free segment's x_0 block)
void SequenceParts(const SegmentEvaluator& segments, int q, int* first, int* last,
                   std::vector<int>* blocks) {
  const int size = segments.num_segments();
  *first = 0;
  while (*first < size && segments.segment(*first).seq < q) ++*first;
  *last = *first;
  blocks->clear();
  while (*last < size && segments.segment(*last).seq == q) {
    if (segments.segment(*last).block >= 0) blocks->push_back(segments.segment(*last).block);
    ++*last;
  }
}

}  // namespace

StateProjection::StateProjection(const SegmentEvaluator& segments) : segments_(segments) {
  costs_.resize(segments_.num_segments());
  solved_.resize(segments_.num_sequences());
}

StateProjection::~StateProjection() = default;

int StateProjection::StateColumns(int q) const {
  int first = 0, last = 0;
  std::vector<int> blocks;
  SequenceParts(segments_, q, &first, &last, &blocks);
  if (blocks.empty()) return 0;
  return static_cast<int>(blocks.size()) * segments_.dims(first).nx;
}

bool StateProjection::Evaluate(int q, const std::vector<std::vector<double>>& x, bool jacobians,
                               double* sum) {
  const int np = segments_.np(), nm = segments_.nm();
  int first = 0, last = 0;
  std::vector<int> blocks;
  SequenceParts(segments_, q, &first, &last, &blocks);
  const StateManifold& manifold = segments_.manifold(first);
  const int nx = segments_.dims(first).nx, nphys = segments_.dims(first).nphys;
  const int k = static_cast<int>(blocks.size()) * nx, n = np + nm;
  // the column of each state block of q, and its values
  auto column_of = [&](int b) { return static_cast<int>(b - blocks.front()) * nx; };
  auto values_of = [&](int b) { return x[b - blocks.front()].data(); };
  // q's segments at the point, in the simulators' batches
  std::vector<const double*> x0(segments_.num_segments(), nullptr);
  for (int s = first; s < last; ++s) {
    const int block = segments_.segment(s).block;
    x0[s] = block >= 0 ? values_of(block) : segments_.X0(s);
  }
  segments_.Prefetch(x0, jacobians);
  *sum = 0;
  if (jacobians) block_.Reset(k + n);
  for (int s = first; s < last; ++s) {
    const Segment& seg = segments_.segment(s);
    auto& costs = costs_[s];
    if (!costs[0]) {
      costs[0] = segments_.SensorCost(s);
      costs[1] = segments_.StateCost(s);
    }
    for (int c = 0; c < 2; ++c) {
      const ceres::CostFunction* cost = costs[c].get();
      if (!cost || cost->num_residuals() == 0) continue;
      const int rows = cost->num_residuals();
      // the parameter blocks as Problem::Fit adds them: z, m (sensor cost only), x_0, next x_0
      std::vector<const double*> params;
      std::vector<double*> jac;
      Jz_.resize(rows, np);
      Jm_.resize(rows, nm);
      Jx0_.resize(rows, nphys);
      Jxn_.resize(rows, nphys);
      if (np) params.push_back(segments_.z().data()), jac.push_back(Jz_.data());
      if (nm && c == 0) params.push_back(segments_.m().data()), jac.push_back(Jm_.data());
      if (seg.block >= 0) params.push_back(values_of(seg.block)), jac.push_back(Jx0_.data());
      if (seg.next >= 0 && c == 0) {
        params.push_back(values_of(seg.next)), jac.push_back(Jxn_.data());
      }
      r_.resize(rows);
      if (!cost->Evaluate(params.data(), r_.data(), jacobians ? jac.data() : nullptr) ||
          !r_.allFinite()) {
        return false;  // noted by the cost function (FitDiagnostics::EvaluateOrReject)
      }
      *sum += r_.squaredNorm();
      if (!jacobians) continue;
      // [J_x J_z J_m] with the states in tangent space: J_ambient P
      J_ = RowMatrix::Zero(rows, k + n);
      auto tangent = [&](int b, const RowMatrix& Ja) {
        P_.resize(nphys, nx);
        manifold.PlusJacobian(values_of(b), P_.data());
        J_.middleCols(column_of(b), nx) = Ja * P_;
      };
      if (seg.block >= 0) tangent(seg.block, Jx0_);
      if (seg.next >= 0 && c == 0) tangent(seg.next, Jxn_);
      if (np) J_.middleCols(k, np) = Jz_;
      if (nm && c == 0) J_.middleCols(k + np, nm) = Jm_;
      block_.Add(J_, r_);
    }
  }
  return true;
}

bool StateProjection::Solve(int q, bool jacobians, Eigen::MatrixXd* reduced, double* sum) {
  const int n = segments_.np() + segments_.nm();
  int first = 0, last = 0;
  std::vector<int> blocks;
  SequenceParts(segments_, q, &first, &last, &blocks);
  const int k = StateColumns(q);
  // 1. the warm start; the last solve when it had the same point and warm start
  std::vector<std::vector<double>> x, trial;
  for (int b : blocks) x.emplace_back(segments_.states()[b].begin(), segments_.states()[b].end());
  std::vector<double> key(segments_.z().begin(), segments_.z().end());
  key.insert(key.end(), segments_.m().begin(), segments_.m().end());
  for (const std::vector<double>& xb : x) key.insert(key.end(), xb.begin(), xb.end());
  Solved& done = solved_[q];
  if (k > 0 && done.key == key) {
    *sum = done.sum;
    if (!jacobians) return true;
    *reduced = done.reduced;
    for (size_t i = 0; i < blocks.size(); ++i) {
      std::copy(done.x[i].begin(), done.x[i].end(), segments_.states()[blocks[i]].begin());
    }
    return true;
  }
  // 2. the triangle at x (residuals alone suffice without states to solve)
  if (!Evaluate(q, x, jacobians || k > 0, sum)) return false;
  if (k == 0 && !jacobians) return true;
  // 3. Gauss-Newton on the states alone, each step halved until the cost falls
  EliminatedBlock e = EliminateStates(block_.Augmented(), k);
  const StateManifold& manifold = segments_.manifold(first);
  const int nx = k > 0 ? k / static_cast<int>(blocks.size()) : 0;
  for (int step = 0; step < kMaxSteps && k > 0; ++step) {
    if (e.q_x.squaredNorm() <= kTolerance * *sum) break;
    if ((e.R_xx.diagonal().array() == 0).any()) {
      segments_.NoteRejection("a segment state of sequence '" + segments_.sequence_name(q) +
                              "' has no effect on its residuals (singular state block)");
      return false;
    }
    const Eigen::VectorXd dx = e.StateStep(Eigen::VectorXd::Zero(n));
    bool lower = false;
    double trial_sum = 0;
    // a failed trial of the inner search is not a point Ceres rejected: its diagnostics restored
    const SegmentEvaluator::Rejections rejected = segments_.rejections();
    for (int h = 0, scale = 1; h <= kHalvings && !lower; ++h, scale *= 2) {
      trial = x;
      const Eigen::VectorXd delta = dx / scale;
      for (size_t i = 0; i < blocks.size(); ++i) {
        manifold.Plus(x[i].data(), delta.data() + i * nx, trial[i].data());
      }
      lower = Evaluate(q, trial, false, &trial_sum) && trial_sum < *sum;
    }
    segments_.RestoreRejections(rejected);
    if (!lower) break;
    x.swap(trial);
    if (!Evaluate(q, x, true, sum)) return false;
    e = EliminateStates(block_.Augmented(), k);
  }
  // 4. the reduced triangle with the exact cost (kept with the solve); the states kept for the
  // next points after a Jacobian evaluation
  done.key = std::move(key);
  done.x = x;
  done.reduced = e.reduced;
  done.reduced(n, n) = std::hypot(e.reduced(n, n), e.q_x.norm());
  done.sum = *sum;
  if (!jacobians) return true;
  *reduced = done.reduced;
  for (size_t i = 0; i < blocks.size(); ++i) {
    std::copy(x[i].begin(), x[i].end(), segments_.states()[blocks[i]].begin());
  }
  return true;
}

}  // namespace mjsysid::mpi
