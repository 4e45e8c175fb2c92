// One pass of a fit: the problem prepared once, solved once, and its estimate assessed, as a
// sequence of named stages (Ceres' Minimize): Solve runs stages 1-4, Assess stages 5-10.
// Problem::Fit (sysid/fit/policy.cc) runs a pass and, for auto multiple shooting, may run a second
// one in segments; it combines their records.
//
// The stages, in order, each a member function in its own file:
//   1. Start        (pass.cc)             the equation-error starts (`initial: auto`), PrepareFit,
//                                         the result's first fields and warnings
//   2. BuildCeres   (pass_build.cc)       the parameter blocks with bounds and manifolds, a
//   residual
//                                         block per segment (compressed), the priors
//   3. Configure    (pass_build.cc)       the solver's options, callbacks, the statistical stop
//   4. RunSolver    (pass_solve.cc)       the solve with the segment states held (auto's contact
//                                         segments), then the solve; stops early when auto's
//                                         single shooting meets a Jacobian warning (Stop)
//   5. RecordSolve  (pass_solve.cc)       costs, iterations, termination, the solve's warnings, the
//                                         estimate's values and bound flags
//   6. Uncertainty  (pass_uncertainty.cc) the Jacobian at the estimate and the covariance
//   7. CheckIntervals (pass_intervals.cc) the cost one standard error away against the Jacobian's
//                                         quadratic model; on a rugged cost its envelope at +-1
//                                         and +-2 standard errors
//   8. FinalSignals (pass_signals.cc)     bound and identifiability warnings, the simulated
//                                         signals at the start and the estimate (a fit in
//                                         segments: segment by segment and in one piece)
//   9. Residuals    (pass_residuals.cc)   the residuals' diagnostics per channel; intervals
//                                         widened by their correlation time when not white; the
//                                         derived inertials with the parameters' final covariance
//  10. Decide       (pass.cc)             the status (sysid/assess/fit_status.h), steps, ledger,
//                                         time
//
// Ownership: a pass borrows the fit state's parts (sysid/solve/fit_state.h) for its lifetime and
// owns the Ceres problem and what the solve needs around it; the solve context's borrowed pointers
// to the pass's ledger and compressed blocks are cleared when the pass ends. Not thread-safe: one
// pass at a time per Problem, on one thread (the simulators are parallel inside).
#pragma once

#include <ceres/ceres.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "sysid/fit/prepare.h"
#include "sysid/fit/segment_evaluator.h"
#include "sysid/solve/compressed_cost.h"
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/fit_ledger.h"
#include "sysid/solve/fit_state.h"
#include "sysid/solve/gn_convergence.h"
#include "sysid/solve/variable_manifold.h"

namespace mjsysid {

// stage 8's warning when a fit in segments has a continuity gap above 1e-3 at the estimate: this
// start, the gap and where, then the tail; the policy's one-piece check (sysid/fit/policy.cc)
// replaces the tail by kSegmentsJoinWithinNoiseTail when the estimate in one piece explains the
// data
inline constexpr char kSegmentsDoNotJoinWarning[] =
    "multiple shooting: segments do not join at the estimate";
inline constexpr char kSegmentsDoNotJoinTail[] =
    ": it describes no single trajectory; try shorter segments, a larger continuity_weight or a "
    "start closer to the data";
inline constexpr char kSegmentsJoinWithinNoiseTail[] =
    ", but the estimate simulated in one piece from each sequence's first state explains the data "
    "as well (the one-piece check passed): the gaps are within what the noise explains";

class FitPass {
 public:
  // why a pass ended before its result was assembled
  enum class Stop {
    kNone,             // the pass ran every stage
    kJacobianWarning,  // auto's single shooting met a Jacobian warning (refit in segments)
  };

  // parts: borrowed for the pass's lifetime
  FitPass(const FitParts& parts, const FitOptions& options);
  ~FitPass();
  FitPass(const FitPass&) = delete;
  FitPass& operator=(const FitPass&) = delete;

  // runs stages 1-4; kJacobianWarning when the solve stopped for one (the result then holds the
  // trace alone; Assess may still follow)
  Stop Solve();
  // runs stages 5-10 after Solve: the result is complete
  void Assess();
  // instead of Assess, for a pass whose estimate alone is wanted: the result's seconds, simulation
  // steps and ledger (its trace is the solve's)
  void FinishRecords();

  // the result (complete after Assess)
  FitResult& result() { return result_; }
  const FitPlan& plan() const { return plan_; }
  // the first Jacobian warning of the solve (Stop::kJacobianWarning)
  const std::string& first_jacobian_warning() const;
  // seconds since the pass began
  double Seconds() const;
  // the solve's final cost (after Solve; with max_iterations 0: the cost at the start)
  double SolvedCost() const { return summary_.final_cost; }
  // ... and its initial cost (the cost at the start)
  double SolvedInitialCost() const { return summary_.initial_cost; }
  // the physical parameters' values now (after Solve: the solve's end point)
  std::vector<double> Estimate() const;
  // the later segments' states start from the data (logged states or joint sensors), not from a
  // rollout (after Solve)
  bool StatesFromData() const;

 private:
  void Start();
  void BuildCeres();
  void Configure();
  bool RunSolver();  // false: stopped for a Jacobian warning
  void RecordSolve();
  void Uncertainty();
  void CheckIntervals();
  void FinalSignals();
  void Residuals();
  void Decide();

  // stage 8's parts
  void SequenceSignals(size_t q, double* worst_gap, std::string* worst_gap_where);
  // rows [first, first + count) of *out (T x nsensordata): sequence q's sensors in rollout tr
  // (from step k0) at those samples, the measurement terms applied to the fitted columns
  void SimulatedAtSamples(size_t q, const Trajectory& tr, int k0, int first, int count,
                          RowMatrix* out) const;
  // multiple shooting: sequence q at the estimate simulated in one piece from x0 (its first
  // segment's state, physics vector) into sr->simulated_one_piece and state_simulated_one_piece
  // (NaN and a warning when that rollout fails)
  void OnePieceSignals(size_t q, const Eigen::VectorXd& x0, SequenceResult* sr);
  // stage 9's
  void DerivedQuantities();
  // the cost with variable v of FitResult::parameters moved by delta (physical units): false
  // outside its bounds or when the residuals cannot be evaluated
  bool CostAt(int v, double delta, double* cost);
  bool OnBound(int v, double value, bool lower) const;
  // the variables' standard errors, 95 % intervals and covariance scaled by widen (stage 7)
  void WidenIntervals(const Eigen::VectorXd& widen);

  const FitParts parts_;
  PreparedFit& fit_;
  FitVariables& vars_;
  FitDiagnostics& diag_;
  SolveContext& solve_;
  const FitOptions& options_;
  const std::chrono::steady_clock::time_point start_;
  FitLedger ledger_;
  FitResult result_;
  FitPlan plan_;
  int np_ = 0;  // physical parameters
  int nm_ = 0;  // measurement terms and control delays (the m block)

  // the Ceres problem and what it borrows (declared before it: destroyed after it)
  std::unique_ptr<PrefetchCallback> prefetch_;
  std::unique_ptr<VariableManifold> variable_manifold_;
  CompressedBlocks compressed_;
  bool compress_ = false;
  std::unique_ptr<ceres::Problem> problem_;
  std::vector<double*> blocks_;  // every parameter block, in the order added
  ceres::Solver::Options solver_;
  UncertaintyOptions uncertainty_;
  std::unique_ptr<ProgressCallback> progress_;
  std::unique_ptr<GaussNewtonStop> gn_stop_;
  bool gn_valid_ = false;  // the statistical stop's test is valid for this fit

  // the solve (stage 4)
  ceres::Solver::Summary summary_;
  int held_accepted_ = 0;           // accepted steps of the solve with the states held
  double held_initial_cost_ = -1;   // its initial cost (-1: it did not run)
  bool previous_jacobian_ = false;  // the stop fired before the estimate's Jacobian

  // the estimate (stages 6-7)
  ceres::Problem::EvaluateOptions evaluate_;
  bool evaluated_ = false;  // the residuals and Jacobian at the estimate were evaluated
  bool multiple_ = false;   // segments joined by continuity rows (here, not sharded)
  Eigen::MatrixXd r_aug_;   // the triangle [R q; 0 rho] of [J_p r] (physical units)
  bool cost_not_local_ = false;
  bool jacobian_warned_at_estimate_ = false;
  // the cost along every variable confirmed the intervals' model (stage 7: the interval check
  // matched it, or the envelope held, on a cost checked as rugged)
  bool intervals_confirmed_ = false;
};

}  // namespace mjsysid
