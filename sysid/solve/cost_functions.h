// The Ceres side of a fit: the cost functions of the residual blocks and the callbacks around the
// solve, reading the parts of the fit state (sysid/solve/fit_state.h) they are given.
//
// - SegmentCost: the residuals of one segment, its sensor samples (sysid/solve/residual_model.h)
// and,
//   when a segment follows, its continuity w * (x_end (-) x_next) in tangent space (nx rows, after
//   the T * nch sensor rows, row k * nch + c for sample k and channel c). Parameter blocks, each
//   present only when the fit has it: z (np), m (fitted measurement terms), the segment's x_0
//   (nphys, on its StateManifold), the next segment's x_0 (nphys). Jacobians are row-major in the
//   ambient sizes Ceres asks for: the core's columns chained through dp/dz and, for states,
//   J_ambient = J_tangent P^+ (sysid/solve/state_manifold.h).
//   The columns of fitted control delays (in the m block) are central differences of whole
//   rollouts of the segment: its controls held again (sysid/data/sample_grid.h HoldControls) at
//   each delay +- kControlDelayStep steps, the residuals differenced; two rollouts per delay and
//   Jacobian evaluation. The hold is piecewise linear in the delay with a kink where a command
//   change crosses a step boundary, and the dynamics have kinks of their own (friction loss,
//   contacts): the step, 0.005 steps, lies past the on-grid tolerance (1e-3 steps) and is small
//   enough to straddle few kinks (measured on arm5 with friction loss, sysid/real_log_bench_test:
//   0.05 steps disagreed with Ceres' numeric differences by 8e-2, 0.005 steps agrees to 3e-10).
// - PriorCost: the Gaussian prior of one parameter, one residual on the z block.
//   A SegmentCost is a FoldableCost (sysid/solve/compressed_cost.h, "Folds ahead") where its
//   sequence has no fitted control delay (those columns are rollouts, and the controls shared
//   state): PrepareRows takes the cache's entry at the point when it is ready with Jacobians (under
//   the statistical stop's previous Jacobian: never), Rows computes the rows from it alone,
//   NoteRows notes its Jacobian warning.
// - PrefetchCallback: before each Ceres evaluation, every segment at the new point in batches
//   (EvaluationCache::Prefetch); after a Jacobian batch, the compressed blocks' folds ahead on the
//   simulator's workers (FoldAhead; FitOptions::advanced.fold_ahead).
// - ProgressCallback: one IterationInfo per iteration into FitResult::trace, the progress line,
//   FitOptions::on_iteration and FitOptions::interrupt.
//
// Failure: a segment whose simulation throws, warns or is not finite at the point evaluated
// returns false (Ceres rejects the trial point and shrinks the trust region) and is counted in
// FitDiagnostics. Threads: as the fit state, one thread (Ceres num_threads = 1), but
// SegmentCost::Rows, which reads the fit and writes only its outputs (the folds ahead's tasks).
#pragma once

#include <ceres/ceres.h>

#include <chrono>

#include "sysid/solve/compressed_cost.h"
#include "sysid/solve/fit_state.h"

namespace mjsysid {

// sets every Jacobian block Ceres asked of cost (jacobians[i] not null) to zero
void ZeroJacobians(const ceres::CostFunction& cost, double** jacobians);

class SegmentCost : public FoldableCost {
 public:
  // the finite-difference step of a fitted control delay's column, in simulation steps
  static constexpr double kControlDelayStep = 0.005;

  // parts are borrowed and must hold the prepared fit (PrepareFit); the segment's controls are
  // held at the fitted delays of the m block it is evaluated at (SolveContext::SyncControlDelays)
  SegmentCost(const FitParts& parts, int segment);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  // FoldableCost (see above)
  bool PrepareRows(double const* const* parameters) const override;
  bool Rows(double const* const* parameters, double* residuals, double** jacobians) const override;
  void NoteRows() const override;

 private:
  // the parameter blocks as Ceres passes them: values (nullptr: absent; x0 the sequence's given x0
  // when it is not a block) and index among the blocks (-1: absent)
  struct Blocks {
    const double *zv = nullptr, *mv = nullptr, *x0 = nullptr, *xn = nullptr;
    int zb = -1, mb = -1, xb = -1, nb = -1;
  };
  Blocks Unpack(double const* const* parameters) const;
  bool EvaluateOrThrow(double const* const* parameters, double* residuals,
                       double** jacobians) const;
  // the residuals and, with jacobians, every asked block's Jacobian (but the fitted control
  // delays' columns) from the segment's rollout tr and sensitivities s (read only with
  // jacobians); reads the fit, writes only its outputs (any thread)
  void FillRows(const Blocks& blocks, const Trajectory& tr, const Sensitivity* s, double* residuals,
                double** jacobians) const;
  // whether every residual is finite (else the point is rejected)
  bool Finite(const double* residuals) const;
  // the residuals of the segment from rollout tr (sensor rows, then continuity to xn when a
  // segment follows) at measurement terms mv, values only
  void Residuals(const Trajectory& tr, const double* mv, const double* xn, double* out) const;
  // the control delay columns of the m block's Jacobian jm (row-major, num_residuals x m size)
  void ControlDelayColumns(const double* zv, const double* mv, const double* x0, const double* xn,
                           double* jm) const;

  PreparedFit* fit_;
  const FitVariables* vars_;  // the blocks' sizes
  FitDiagnostics* diag_;
  SolveContext* solve_;
  int segment_;
  // PrepareRows: the cache's entry Rows reads, and the Jacobian warning NoteRows notes ("": none)
  mutable const EvaluationCache::Entry* ready_ = nullptr;
  mutable std::string ready_warning_;
};

class PriorCost : public ceres::CostFunction {
 public:
  // the prior of parameter g (FitParameter::has_prior); fit is borrowed
  PriorCost(const PreparedFit* fit, int g);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  const PreparedFit* fit_;
  int g_;
};

class PrefetchCallback : public ceres::EvaluationCallback {
 public:
  // parts are borrowed
  explicit PrefetchCallback(const FitParts& parts)
      : fit_(parts.fit), vars_(parts.vars), solve_(parts.solve) {}
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override;

 private:
  PreparedFit* fit_;
  const FitVariables* vars_;
  SolveContext* solve_;
};

class ProgressCallback : public ceres::IterationCallback {
 public:
  // result: where the trace and the interruption flag go; start: the fit's start (for seconds)
  ProgressCallback(const FitParts& parts, FitResult* result,
                   std::chrono::steady_clock::time_point start)
      : fit_(parts.fit),
        vars_(parts.vars),
        diag_(parts.diag),
        solve_(parts.solve),
        result_(result),
        start_(start) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override;

 private:
  const PreparedFit* fit_;
  const FitVariables* vars_;
  const FitDiagnostics* diag_;
  const SolveContext* solve_;
  FitResult* result_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mjsysid
