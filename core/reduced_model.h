// The reduced model of a fit (issue 15, item 2): what a fit's private model copy can switch off
// because it can never change a simulated number of the fitted data.
//
// Two reductions, each exact (the reduced model steps bit for bit like the full one; tested):
// - island discovery (mjDSBL_ISLAND) on a model with at most one kinematic tree and sleeping off:
//   every constraint then lies in the one island, and the solver's island path and its whole-model
//   path compute the same numbers. Static: true for every state, no guard needed.
// - collision: geom pairs that can collide (contype/conaffinity, not in the same weld body, not
//   parent and child unless mjDSBL_FILTERPARENT) but whose bounding spheres stay farther apart
//   than their margin plus kReductionClearance (metres) at every sample of every nominal rollout.
//   A geom all of whose pairs stay that far is switched off (contype = conaffinity = 0); when every
//   pair stays that far (and the model has no explicit <pair>), collision as a whole is switched
//   off (mjDSBL_CONTACT). MuJoCo's own bounding-sphere test skips a pair whose spheres are farther
//   apart than rbound1 + rbound2 + margin (a plane: the sphere's height above it), so the switched
//   off pairs produce no contact as long as that holds.
// The guard (ReductionGuardClear) checks, after every step of a reduced rollout, the pairs switched
// off at the poses the step computed (geom_xpos), with half the clearance: a pair that came nearer
// makes the Simulator drop the reduction and simulate the call again with the full model
// (core/simulator.h, SetReduction). Finite-difference perturbations move geoms by at most
// kSensitivityGrowthLimit (1e-2 state units) before the Jacobians warn, which half the clearance
// covers.
//
// Sensors are not part of the reduction: the residuals index sensordata at the model's addresses.
// A model whose sensors are all joint encoders skips MuJoCo's sensor stage in every step of the
// Simulator instead, reduced or not (core/state_sensors.h).
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <utility>
#include <vector>

#include "core/state.h"

namespace mjsysid {

// metres of bounding-sphere gap beyond the margin that a pair must keep at every nominal sample to
// be switched off; the guard trips at half of it
constexpr double kReductionClearance = 0.02;

struct ModelReduction {
  int disable = 0;                           // mjDSBL_* bits added to opt.disableflags
  std::vector<int> geoms_off;                // geoms switched off (contype = conaffinity = 0)
  std::vector<int> contype, conaffinity;     // their values in the full model (restored by Revert)
  std::vector<std::pair<int, int>> watched;  // geom pairs switched off (g1 < g2): the guard's
  int candidate_pairs = 0;  // geom pairs that can collide (contype/conaffinity and body filters)
  int pairs_off = 0;        // of those, switched off (watched.size())
  bool Empty() const { return disable == 0 && geoms_off.empty(); }
  // e.g. "collision_pairs_off: 3 of 4, geoms_off: 2, disabled: [island, contact]"
  std::string Summary() const;
};

// names of the mjDSBL_* bits in disable, e.g. {"contact", "island"}
std::vector<std::string> DisabledNames(int disable);

// Analyses model m (the full model) over nominal rollouts: states[i] is a (T_i+1) x nphys matrix of
// physics vectors [qpos, qvel, act] (core/state.h), inputs[i] the inputs held during rollout i
// (Trajectory::inputs, length StateDims::ninput; may be empty when ninput is 0). Runs
// mj_kinematics once per sample on a private mjData. Throws MujocoError on a MuJoCo error.
ModelReduction AnalyzeReduction(const mjModel& m, const StateDims& dims,
                                const std::vector<const RowMatrix*>& states,
                                const std::vector<const Eigen::VectorXd*>& inputs);

// switches r off in m (a copy of the model r was analysed on, any parameter values)
void ApplyReduction(const ModelReduction& r, mjModel* m);
// undoes ApplyReduction on m
void RevertReduction(const ModelReduction& r, mjModel* m);

// true when every watched pair of r stays farther apart than its margin plus half of
// kReductionClearance at the geom poses in d (geom_xpos, geom_xmat: after mj_kinematics or a step
// of m). No allocation.
bool ReductionGuardClear(const ModelReduction& r, const mjModel& m, const mjData& d);

}  // namespace mjsysid
