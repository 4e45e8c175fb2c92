// Multiple shooting and estimated initial states in a fit sharded across MPI ranks
// (sysid/mpi/distributed_fit.h): a sequence's free states (the x_0 blocks of its segments,
// Segment::block, one per segment after the first and, with estimate_initial_state, the first)
// are eliminated on the rank that owns the sequence, by variable projection. Ceres on rank 0 sees
// only z and m.
//
// Algorithm, per sequence q at the point (z, m) rank 0 broadcast:
//   1. x = the states of q's last Jacobian evaluation (Ceres evaluates Jacobians only at the
//      start and at accepted points, so this is the last accepted point's solution; the data's
//      segment starts before the first one).
//   2. Evaluate q's sensor, continuity and fitted-state residuals r and their Jacobian at (x, z, m)
//      and compress [J_x J_z J_m r] (the k state columns first, in tangent space: J_ambient P,
//      P = StateManifold::PlusJacobian) to its (k + n + 1)^2 thin-QR triangle (CompressedBlock).
//   3. Gauss-Newton on x alone, at most kMaxSteps steps: the step dx = -R_xx^-1 q_x of
//      EliminateStates (shards.h) at dp = 0 (moves through StateManifold::Plus), halved up to
//      kHalvings times until |r|^2 falls; stop when the predicted decrease |q_x|^2 is at most
//      kTolerance |r|^2, or when no halving lowers the cost. Each accepted x is evaluated again
//      as in 2, so the triangle always belongs to the final x.
//   4. Residuals only (a trial point): hand on |r(x, z, m)|^2. With Jacobians: hand on
//      EliminateStates' reduced (n + 1)^2 corner [R_pp q_p; 0 rho] with its last entry replaced
//      by hypot(rho, |q_x|), so that its cost is exactly 0.5 |r(x, z, m)|^2 (the same cost as a
//      trial point at the same point: steps 1-3 are the same), and keep x as the warm start of
//      the next points. Its normal matrix R_pp^T R_pp is the Schur complement
//      J_p^T J_p - J_p^T J_x (J_x^T J_x)^-1 J_x^T J_p: the Gauss-Newton matrix of the reduced cost
//      min_x |r(x, p)|^2 (variable projection), and the parameters' normal matrix of the joint
//      fit with the states eliminated, so the covariance follows from it directly.
// Steps 1-3 compute the triangle at the solved states for a trial point too, so each sequence
// keeps its last solve keyed by (z, m, warm start): the Jacobian evaluation at an accepted trial
// point (Ceres evaluates it there next, from the same warm start) takes it instead of solving
// again; the same bits either way.
// Every step depends on the sequence's own data and the broadcast points only, so the states and
// blocks are bitwise the same whichever rank owns the sequence: the same estimates with any
// number of ranks. The joint one-process fit (Ceres' Schur solver over z, m and every state)
// reaches the same minimum by another path.
//
// Failure: a simulation that fails or is not finite, or a singular R_xx (a state column the
// residuals do not see), fails the evaluation (Solve returns false: rank 0 rejects the point).
// Threads: as the fit state (the caller's thread); the segments of a sequence are simulated in
// the simulators' batches (EvaluationCache::Prefetch).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "sysid/fit/segment_evaluator.h"
#include "sysid/mpi/shards.h"

namespace mjsysid::mpi {

class StateProjection {
 public:
  static constexpr int kMaxSteps = 8;
  static constexpr int kHalvings = 4;
  static constexpr double kTolerance = 1e-12;

  // segments: the prepared fit's (its state blocks hold the warm starts)
  explicit StateProjection(const SegmentEvaluator& segments);
  ~StateProjection();

  // the states of sequence q solved at the variables' z and m (steps 1-4 above). Residuals only:
  // *sum = |r|^2. With jacobians: also *reduced ((n + 1) x (n + 1), upper triangular,
  // column-major) and the state blocks of q updated. False when an evaluation failed (noted in
  // the diagnostics: FitDiagnostics::NoteRejection, by the cost functions or here for a singular
  // R_xx).
  bool Solve(int q, bool jacobians, Eigen::MatrixXd* reduced, double* sum);

  // the tangent columns of q's free states (k)
  int StateColumns(int q) const;

 private:
  // q's residuals at the states x (one vector per state block of q) into *sum and, with
  // jacobians, the triangle into block_
  bool Evaluate(int q, const std::vector<std::vector<double>>& x, bool jacobians, double* sum);

  // a sequence's last solve (see above): its key [z, m, warm start states] and results
  struct Solved {
    std::vector<double> key;
    std::vector<std::vector<double>> x;
    Eigen::MatrixXd reduced;
    double sum = 0;
  };

  SegmentEvaluator segments_;
  std::vector<Solved> solved_;  // per sequence
  // per segment: its sensor and continuity cost and its fitted-state cost (or nullptr)
  std::vector<std::array<std::unique_ptr<ceres::CostFunction>, 2>> costs_;
  CompressedBlock block_;
  // buffers, reused
  RowMatrix J_, Jz_, Jm_, Jx0_, Jxn_, P_;
  Eigen::VectorXd r_;
};

}  // namespace mjsysid::mpi
