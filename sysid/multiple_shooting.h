// Multiple shooting, the parts of a fit that Problem (sysid/problem.cc) delegates: how long the
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
#include "sysid/problem_impl.h"

namespace mjsysid {

// the segment length chosen and why (FitResult::segment_steps_used / segment_reason)
struct HorizonChoice {
  int steps = 0;  // per segment; 0 = single shooting
  std::string reason;
  double rate = 0;    // lambda of the probe (largest ln(E_k) / k), per step
  double growth = 0;  // the probe's largest growth beyond linear E (1 when bounded)
};

// FitOptions::segment_steps >= 0: as set. Auto (-1): a probe per sequence at the current
// parameters (one more rollout each, from x0 with the velocities raised by a tiny step; initial:
// the nominal rollouts): exponential growth beyond linear past x100 gives segments, else single
// shooting. I's simulators must hold the initial parameter values.
HorizonChoice ChooseHorizon(Problem::Impl& I, const std::vector<Trajectory>& initial,
                            const FitOptions& options);

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
// the rollout. Returns where it came from (for the reason).
std::string SegmentStart(const Problem::Impl& I, int q, int k0, const Trajectory& rollout,
                         std::vector<double>* x);

// Ceres' linear solver for I's variables (tangent: their total tangent size): single shooting
// dense QR (sparse normal Cholesky past 200); multiple shooting DENSE_SCHUR / SPARSE_SCHUR with
// every other state block of each sequence eliminated first (so->linear_solver_ordering); a
// sharded fit (Impl::shards: the states eliminated by the shards) as single shooting
void ChooseLinearSolver(Problem::Impl& I, int tangent, ceres::Solver::Options* so);

// Ceres' CRS Jacobian -> A (rows x nvar, dense: the first nvar columns) and B (rows x the rest,
// sparse: the state columns in tangent space)
void SplitJacobian(const ceres::CRSMatrix& crs, int nvar, RowMatrix* A,
                   Eigen::SparseMatrix<double>* B);

}  // namespace mjsysid
