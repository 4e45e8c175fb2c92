// Fitting model parameters to recorded sensor trajectories with Ceres.
//
// Ten lines for a C++ user:
//
//   mjsysid::Problem problem;
//   mjsysid::ModelPtr model = mjsysid::LoadModel("models/arm5.xml");
//   problem.AddModel("arm", *model);
//   problem.AddParameter(mjsysid::FitParameter("a1", {"joint_armature", "j1"}, 0.01)
//                            .Bounds(1e-4, 10).Log());
//   problem.AddSequence(mjsysid::FitSequence("run1", "arm", x0, ctrl, measured));
//   mjsysid::FitResult result = problem.Fit(mjsysid::FitOptions());
//   for (const auto& p : result.parameters)
//     std::printf("%s = %g +- %g\n", p.name.c_str(), p.value, p.std_error);
//
// Model. Residuals r_k = w * rho_hat(gain * y_sim(t_k - delay) + bias - y_meas_k) for every
// sample k and used sensor column (see FitSequence), with y_sim from the core's rollout under the
// time convention of core/simulator.h, w = 1/sigma (or a weight) per sensor, rho_hat the square
// root of a robust loss applied per scalar residual, plus Gaussian prior residuals
// (p - mean)/sigma, plus, in multiple shooting, continuity residuals
// continuity_weight * (x_end(segment i) (-) x_0(segment i+1)) in tangent space. Segments:
// FitOptions::segment_steps, by default auto (a growth probe at the initial values, then a refit
// in segments if the core flags single shooting's Jacobian as no longer local; the rule is in
// docs/numerics.md); later segments start from the data where it determines the state.
// Multiple shooting solves with Ceres' Schur complement (states eliminated first) and computes
// the parameters' covariance with the states eliminated (AnalyzeUncertaintyReduced).
//
// Variables. Physical parameters are optimised as z = p, log p or p / scale, with bounds mapped
// accordingly; measurement terms (delay in seconds, gain, bias) and fitted control delays
// (seconds, AddControlDelay; appended to the measurement terms' block) as themselves; initial
// states of sequences or segments as full physics vectors on a StateManifold (quaternion-correct).
//
// Jacobians come from the core (analytic to Ceres, no Ceres numeric differentiation), except a
// fitted control delay's column: a central difference of two whole rollouts with the controls
// held again (sysid/solve/cost_functions.h); residual-only evaluations run only the nominal
// rollout. An evaluation whose simulation warns or is not finite returns false, so the trust region
// shrinks instead of the fit failing.
//
// Errors: bad input (unknown names, shapes, NaN in data, a parameter that has no effect on the
// data, infeasible bounds, a sequence with nothing to fit, a fit with nothing to estimate, times
// that need more than 1e8 steps) throws std::invalid_argument or ParameterError before Ceres
// starts; the message names the sequence, the member and the sizes expected and found
// (docs/bad-input.md, "Issue 34").
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <atomic>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/types.h"

namespace ceres {
class Problem;
class EvaluationCallback;
}  // namespace ceres

namespace mjsysid {

class ResidualShards;    // below
struct FitParts;         // the fit state's parts (sysid/solve/fit_state.h)
class SegmentEvaluator;  // a shard's view of them (sysid/fit/segment_evaluator.h)

// result of Problem::CheckJacobians
struct JacobianCheck {
  double worst_relative_error = 0;  // over every residual block and variable
  std::vector<std::pair<std::string, double>> per_variable;  // parameters, measurement terms,
                                                             // then "x0 of <sequence>"
  std::string worst_where;  // the variable and block of the worst error
};

class Problem {
 public:
  Problem();
  ~Problem();
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;

  // copies m; name is what FitParameter::models and FitSequence::model refer to
  void AddModel(const std::string& name, const mjModel& m);
  void AddParameter(const FitParameter& parameter);
  void AddMeasurement(const FitMeasurement& measurement);
  void AddSequence(const FitSequence& sequence);
  // a fitted control transport delay (types.h FitControlDelay); its variable follows the
  // measurement terms in FitResult::parameters
  void AddControlDelay(const FitControlDelay& delay);

  // runs the fit; throws std::invalid_argument / ParameterError on bad input
  FitResult Fit(const FitOptions& options);

  // Checks the core's analytic Jacobians of every residual block at the initial point against
  // Ceres' numeric differentiation (ceres::GradientChecker, central differences of whole
  // rollouts). Returns the worst relative error per variable. Throws like Fit on bad input.
  JacobianCheck CheckJacobians(const FitOptions& options);

  // The parameters as added, in order. An `initial: auto` start (FitParameter::initial_auto,
  // initial NaN) is solved by Fit and CheckJacobians before anything is simulated: from then on
  // its entry holds the solved start value and initial_auto is false.
  const std::vector<FitParameter>& parameters() const;

  // Fit with the segment residuals evaluated by shards (borrowed; nullptr: here, as usual); see
  // ResidualShards.
  void DistributeResiduals(ResidualShards* shards);

 private:
  struct Impl;  // the state behind the API (sysid/problem.cc)
  // the fit state's parts, for the fit's internals (sysid/fit/prepare.h)
  friend FitParts PartsOf(Problem* problem);
  std::unique_ptr<Impl> impl_;
};

// Segment residuals evaluated elsewhere (sysid/mpi/: sharded across MPI ranks, each segment's
// block compressed to a thin-QR triangle). When set (Problem::DistributeResiduals), Fit adds no
// SegmentCost / StateCost blocks: it asks AddResidualBlocks for the blocks that replace them (on
// the z and m parameter blocks only: free states are eliminated by the shards), uses Callback() as
// the Ceres EvaluationCallback, and reports
// NumResiduals() (the rows of the uncompressed residual vector, for the residual variance and the
// chi-square) instead of the rows Ceres sees. The uncertainty then comes from the compressed
// Jacobian, whose normal matrix J^T J and cost equal the full one's.
class ResidualShards {
 public:
  virtual ~ResidualShards() = default;
  // called once by Fit after it prepared the fit, with its segments (borrowed for the fit);
  // blocks: z (np) if the fit has parameters, then m
  virtual void AddResidualBlocks(const SegmentEvaluator& segments, ceres::Problem* problem,
                                 const std::vector<double*>& blocks) = 0;
  virtual ceres::EvaluationCallback* Callback() = 0;
  virtual long long NumResiduals() const = 0;
  // the tangent columns of the states eliminated where the residuals are evaluated (multiple
  // shooting, estimated initial states: sysid/mpi/state_projection.h); the residual variance's
  // degrees of freedom subtract them, as the one-process fit's with the states in its Jacobian
  virtual int EliminatedColumns() const { return 0; }
  // called by Fit after the evaluation at the estimate: brings every sequence's eliminated states
  // into segments.states() (for the result's segment states, continuity gaps and final signals)
  virtual void CollectStates(SegmentEvaluator& /*segments*/) {}
  // the sequences whose start this process simulates, given each sequence's work (ShardStart,
  // sysid/fit/prepare.h; empty: all). Called by Fit's preparation; the caller of Fit then owns
  // the check that every parameter moves the data (AddResidualBlocks' place).
  virtual std::vector<bool> OwnedSequences(const std::vector<double>& /*work*/) const { return {}; }
};

}  // namespace mjsysid
