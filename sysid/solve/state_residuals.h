// Logged states as fitted data: the residuals of a sequence's logged qpos, qvel and act
// (FitSequence, chosen by FitOptions::states), next to its sensor residuals, so that a model
// without sensors can be fitted unchanged.
//
// Model. For sample k of a segment (at its position on the simulation grid,
// sysid/data/sample_grid.h) and one fitted state channel (a joint's position or velocity, an
// actuator's activation) with weight w = 1/sigma:
//   x   = x_i (+) a (x_{i+1} (-) x_i)       the simulated physics vector at the sample: the rollout
//                                           state of step i = floor(position), interpolated in
//                                           tangent space (a = 0 on the grid: x_i itself)
//   e   = w * (x (-) x_meas)                per coordinate; a ball or free joint orientation as the
//                                           3-vector mju_subQuat(q, q_meas) = log(q_meas^-1 q), rad
//   r   = rho_hat(e)                        the fit's robust loss per row
//   (sysid/solve/residual_model.h)
// Jacobian: de/dx_tangent is w I for scalar coordinates and w Jr^-1(e / w) for an orientation
// (the inverse right Jacobian of SO(3): x is perturbed in its body frame, as mj_integratePos
// does), times the rows of the core's DxDp ((T+1) nx x ncol, tangent space) interpolated with the
// same a (exact on the grid and for scalars; first order in one step's rotation off the grid for
// orientations). Chained to the optimiser's variables like the sensor rows (cost_functions.h).
//
// Masking: a channel's sample with any NaN among its logged values is left out (no row). Logged
// quaternions are normalised before the fit (a log's rounding leaves them slightly off unit).
//
// Failure: BuildStateChannels and CheckLoggedStates throw std::invalid_argument for bad input
// (unknown joint or actuator, sigma not > 0, a missing or wrongly shaped log, Inf, a channel with
// no measured sample). StateCost rejects a trial point like SegmentCost.
#pragma once

#include <ceres/ceres.h>
#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/types.h"

namespace mjsysid {

// the fit state's parts (sysid/solve/fit_state.h)
struct PreparedFit;
struct FitVariables;
struct FitDiagnostics;
struct SolveContext;
struct FitParts;

// one fitted state of a model: a joint's position or velocity or an actuator's activation
struct StateChannel {
  std::string name;   // "qpos:<joint>", "qvel:<joint>", "act:<actuator>"
  int part = 0;       // the logged matrix: 0 qpos, 1 qvel, 2 act (FitSequence)
  int column = 0;     // its first column there
  int phys = 0;       // its first entry in the physics vector [qpos, qvel, act]
  int tangent = 0;    // its first tangent row (nx layout, core/state.h)
  int scalars = 1;    // leading scalar coordinates (free joint qpos 3, ball 0, hinge/slide 1)
  bool quat = false;  // a trailing orientation quaternion (4 logged values, 3 rows)
  double weight = 1;  // 1/sigma
  int width() const { return scalars + (quat ? 4 : 0); }  // logged values
  int rows() const { return scalars + (quat ? 3 : 0); }   // residual rows
};

// The channels FitStates selects in model m, in the order qpos, qvel, act and model order within
// each part (names given: their order). Throws std::invalid_argument (prefixed by `where`) for an
// unknown joint or actuator (with a "did you mean"), an actuator without activation, a part naming
// nothing, a sigma count that is neither 1 nor the names' count, or a sigma that is not > 0.
std::vector<StateChannel> BuildStateChannels(const mjModel& m, const FitStates& states,
                                             const std::string& where);

// Checks the logged states of sequence sq (T samples) for the channels: each part used must be
// T x nq (nv, na); no Inf; every channel must have a measured sample. Normalises logged
// quaternions. Returns per channel the samples not measured (NaN). Throws std::invalid_argument
// naming the sequence (`where`), the part and the channel.
std::vector<int> CheckLoggedStates(const mjModel& m, const std::vector<StateChannel>& channels,
                                   int T, const std::string& where, FitSequence* sq);

// residual rows of the channels over the measured samples [first, first + count) of sq
int StateRows(const std::vector<StateChannel>& channels, const FitSequence& sq, int first,
              int count);

// The simulated physics vector at `position` (steps from the first row of states, a rollout's
// (T+1) x nphys rows): row i = floor(position), moved a = position - i of the way to row i + 1 in
// tangent space. scratch: nx doubles. x: nphys.
void StateAtPosition(const mjModel& m, const RowMatrix& states, double position, double* scratch,
                     double* x);

// The weighted difference e = w (x (-) logged) of one channel (rows() values) between the
// simulated physics vector x and the channel's logged values (width()), and, when de is not null,
// de/dx in tangent space: a rows() x rows() row-major block. Returns false when a logged value is
// NaN (not measured).
bool StateDifference(const StateChannel& ch, const double* x, const double* logged, double* e,
                     double* de);

// the logged values of channel ch at sample k of sq (width() consecutive doubles)
const double* LoggedState(const StateChannel& ch, const FitSequence& sq, int k);

// SequenceResult's state columns of sequence sq: names, widths and the logged values (T x
// sum(width)); the simulated and residual matrices sized (T x sum(width), T x sum(rows)), NaN.
void InitStateResult(const std::vector<StateChannel>& channels, const FitSequence& sq,
                     SequenceResult* sr);

// Rows [first, first + count) of the simulated states (physics columns of the channels) and,
// when residual is not null, of the weighted differences (NaN where not measured), read from a
// rollout's states (rows from step k0) at the samples' positions on the grid, as StateCost does.
void StatesAtSamples(const mjModel& m, const std::vector<StateChannel>& channels,
                     const FitSequence& sq, const RowMatrix& states,
                     const std::vector<double>& position, int k0, int first, int count,
                     RowMatrix* simulated, RowMatrix* residual);

// The residuals of one segment's fitted states (rows as StateRows, sample by sample, channel by
// channel). Parameter blocks, each present only when the fit has it: z (np), the segment's x_0
// (nphys, on its StateManifold). Jacobians as SegmentCost's (sysid/solve/cost_functions.h).
class StateCost : public ceres::CostFunction {
 public:
  // parts are borrowed and must hold the prepared fit (PrepareFit)
  StateCost(const FitParts& parts, int segment);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  bool EvaluateOrThrow(double const* const* parameters, double* residuals,
                       double** jacobians) const;

  const PreparedFit* fit_;
  const FitVariables* vars_;  // the blocks' sizes
  FitDiagnostics* diag_;
  SolveContext* solve_;
  int segment_;
};

}  // namespace mjsysid
