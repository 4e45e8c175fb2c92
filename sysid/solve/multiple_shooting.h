// Multiple shooting, the parts of a fit that a fit pass (sysid/fit/pass.h) delegates: how long the
// segments are (FitOptions::segment_steps, auto by default), where their initial states start,
// which Ceres linear solver runs, and the split of the Jacobian for the uncertainty with the
// segment states eliminated. The rules and their measurements are in docs/numerics.md
// ("Automatic multiple shooting", "Multiple shooting: linear solver and uncertainty").
#pragma once

#include <ceres/ceres.h>

#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "sysid/solve/fit_state.h"

namespace mjsysid {

// the segment length chosen and why (FitResult::segment_steps_used / segment_reason)
struct HorizonChoice {
  int steps = 0;  // per segment; 0 = single shooting
  std::string reason;
  double rate = 0;        // lambda of the probe (largest ln(E_k) / k), per step
  double growth = 0;      // the probe's largest growth beyond linear E (1 when bounded)
  bool contacts = false;  // the segments are kContactSegmentSteps because of contact changes
};

// FitOptions::segment_steps >= 0: as set. Auto (-1): a probe per sequence at the current
// parameters (one more rollout each, from x0 with the velocities raised by a tiny step; initial:
// the nominal rollouts): exponential growth beyond linear past x100 gives segments, else single
// shooting. fit's simulators must hold the initial parameter values.
HorizonChoice ChooseHorizon(const PreparedFit& fit, const std::vector<Trajectory>& initial,
                            const FitOptions& options);

// Auto on contacts: when no exponential growth decides, but the rollouts at the initial values
// change their contact count (Trajectory::ncon) at events and the segments can start on the data
// (SegmentStart: logged qpos/qvel or joint sensors), segments of kContactSegmentSteps; with
// exponential growth too, the shorter of the two, and the contact segments on a tie (the outside
// hopper's impacts gave growth segments of 10 steps too, which kept its jumping accelerometer in
// the fit at a weighted residual variance of 3.0; as contact segments it converges within 1.9 %).
// Measured on the robust suite (docs/stress.md, "Why the contact cases still do not recover"): over
// whole sequences the cost of every channel of the finger, hopper, walker and crate is rugged
// (total variation 2-57 times its fall along the line from the start to the truth); restarted from
// the logged states every 20 steps it falls nearly monotonically (1.0-1.5, crate 1.3-2.2). 10 steps
// rather than 20: the finger's worst error 1.3 % against 25 %, the walker's 3.8 % against 10.7 %,
// the hopper's 10.8 % against 11.6 % (docs/stress.md, "Contact segments under auto"). Only while
// the contact count changes at no more than kContactEventRate of the steps (events: the finger's
// flicks 0.7 %, the hopper's and walker's touch-downs 5.0 % and 5.7 %): a box sliding on MuJoCo's
// soft contact chatters (box_floor 21.5 %, the robust crate 19.9 %), each 20-step segment still
// holds ~4 changes, and there contact segments did not help (crate 40 % either way) or hurt
// (box_floor: single shooting 0.6 % in 2.6 s, 20-step segments 18 % and not_converged after 423 s
// under load): single shooting stays.
constexpr int kContactSegmentSteps = 10;
constexpr double kContactEventRate = 0.1;

// Auto's contact segments (HorizonChoice::contacts) and FitOptions::fit_jumping_sensors false:
// the fitted touch, accelerometer, force and torque sensors (JumpingSensorType,
// sysid/data/contact_channels.h) are left out of the fit (their channels removed from fit.channels,
// fit.missing and fit.fitted: not fitted, not in the chi-square test, not in the result's
// sequences), unless that would leave a sequence without a fitted sensor. Returns one warning per
// sensor left out. Measured (docs/stress.md): the finger's fingertip touch sensor alone turned a
// 1.0 % fit into 68 %; the hopper's foot touch and torso accelerometer ended with weighted
// residual variances of 2.3e3 and 415 against 3-95 for its other sensors.
std::vector<std::string> OmitJumpingSensors(PreparedFit& fit);

// Auto after single shooting's Jacobian warned (a core Sensitivity warning "... from step k* ..."):
// the segment length min(k*/2, ln 2 / rate), at least 10, and the reason; 0 when the warning
// names no step.
int SegmentStepsAfterWarning(const std::string& warning, double rate, std::string* reason);
// the step k* a core Sensitivity warning names ("... from step k* ...": the last one), or -1
int WarningStep(const std::string& warning);

// Auto, third stage: a single-shooting fit (auto chose it) whose optimiser did not converge, on a
// system whose probe grew beyond linear by more than kRefitGrowth (growth: HorizonChoice::growth;
// stable and dissipative systems read 1-2.4), is refitted in multiple shooting with ln(2) / rate
// steps per segment (at least 10). Returns that length and the reason, or 0 (no refit) when the
// growth is below kRefitGrowth or the segments would not be shorter than half of the shortest
// sequence (shortest_steps).
constexpr double kRefitGrowth = 10;
int SegmentStepsAfterFailure(double growth, double rate, int shortest_steps, std::string* reason);

// x (nphys) = the initial state of sequence q's segment at sample k0 > 0: logged states
// (FitSequence::states), else jointpos/jointvel sensors, else rollout.states.row(k0); act from
// the rollout. Returns where it came from (for the reason): kStartFromRollout when not the data.
constexpr char kStartFromRollout[] = "the rollout";
std::string SegmentStart(const PreparedFit& fit, int q, int k0, const Trajectory& rollout,
                         std::vector<double>* x);

// The continuity weights (FitOptions::continuity_weight, continuity_relative), per model and
// tangent coordinate (nx = 2 nv + na): relative (the default), a gap of a fraction f of a state
// coordinate's spread costs as much as a sensor residual of the same fraction f of its sensor's
// spread:
//   w_i = continuity_weight * S / s_i,  S = median over fitted sensor columns of weight * spread,
// s_i the standard deviation of tangent coordinate i (from the sequence's first state) over the
// samples (logged qpos/qvel where present, else the rollout at the initial values), floored at
// 1e-3 of the largest spread of its part (positions, velocities, activations) so that a
// coordinate that does not move is not pinned. Absolute (continuity_relative false), no sensor
// columns or no spread: w_i = continuity_weight. With 1 % sensor noise S is ~100, so a joint
// angle swinging over 1 rad gets w ~ 100 (measured best on the finger and hopper, docs/stress.md;
// the absolute 1 left gaps of 7.6 and 54). *summary: one line for FitResult::segment_reason.
std::vector<std::vector<double>> ContinuityWeights(const PreparedFit& fit,
                                                   const std::vector<Trajectory>& initial,
                                                   const FitOptions& options, std::string* summary);

// Ceres' linear solver for the variables (tangent: their total tangent size): single shooting
// dense QR (sparse normal Cholesky past 200); multiple shooting DENSE_SCHUR / SPARSE_SCHUR with
// every other state block of each sequence eliminated first (so->linear_solver_ordering); a
// sharded fit (PreparedFit::shards: the states eliminated by the shards) as single shooting
void ChooseLinearSolver(const PreparedFit& fit, FitVariables& vars, int tangent,
                        ceres::Solver::Options* so);

// Auto's contact segments, first stage: the solve with every segment state held where it started
// (on the logged states: SegmentStart), so that the parameters alone fit each segment's prediction
// from the data (the cost that falls nearly monotonically from the start to the truth,
// docs/stress.md); the states are released after it, for the solve that follows. `so`: the main
// solve's options (its iteration cap and tolerances); the held solve uses dense QR on the
// parameters. Returns the held solve's summary; *problem is left with every state variable.
ceres::Solver::Summary SolveWithStatesHeld(FitVariables& vars, ceres::Problem* problem,
                                           ceres::Solver::Options so);

// Ceres' CRS Jacobian -> A (rows x nvar, dense: the first nvar columns) and B (rows x the rest,
// sparse: the state columns in tangent space)
void SplitJacobian(const ceres::CRSMatrix& crs, int nvar, RowMatrix* A,
                   Eigen::SparseMatrix<double>* B);

}  // namespace mjsysid
