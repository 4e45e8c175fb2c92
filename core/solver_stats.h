// Convergence of MuJoCo's constraint solver over a set of steps, and the Jacobian warnings it
// gives (docs/numerics.md, "Solver tolerance and iteration cap").
//
// Contract:
// - A step counts as solved when it ran the constraint solver (mjData::nefc > 0), and as capped
//   when the solver stopped at opt.iterations in any island: MuJoCo keeps the iteration count per
//   island in mjData::solver_niter (the first mjNISLAND islands), or in slot 0 for a monolithic
//   solve. MuJoCo adds noslip iterations to that count: with noslip on, capped is an upper bound.
// - SolverWarnings names a solver that is not Newton and the capped counts, in the words of
//   Sensitivity::warnings; nothing when no step ran the solver.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

namespace mjsysid {

// Constraint-solver convergence over a set of steps.
struct SolverStats {
  int solved = 0;  // steps that ran the constraint solver (nefc > 0)
  int capped = 0;  // of those, steps where it stopped at opt.iterations (in any island)
  // Over the steps of one rollout in order (a Trajectory's; summed by +=): the steps after the
  // first whose constraint rows differ from the step before's. row_changes: another number of
  // rows (a contact, limit or other constraint that came or went), or as many rows other than
  // friction loss in other solver states (mjData::efc_state counted per state: active or
  // satisfied, a contact's friction sticking or slipping); friction_changes: the friction-loss
  // rows (dof and tendon) between sticking (quadratic) and slipping (linear), a force continuous
  // in the velocity (a kink). Both 0: the constraint forces followed one smooth branch
  // (sysid/assess/interval_check.h). PGS keeps no row states: only the number of rows is compared.
  int row_changes = 0;
  int friction_changes = 0;
  int last_nefc = -1;                       // the step before's rows (-1: no step counted yet)
  int last_states[6] = {0, 0, 0, 0, 0, 0};  // its rows per state (satisfied, quadratic, linear,
                                            // cone; friction loss quadratic, linear)

  SolverStats& operator+=(const SolverStats& other) {
    solved += other.solved;
    capped += other.capped;
    row_changes += other.row_changes;
    friction_changes += other.friction_changes;
    return *this;
  }
};

// counts the constraint solve of the step just taken in d with model m
void CountSolve(const mjModel& m, const mjData& d, SolverStats* stats);

// warnings about the solver of m for Jacobians whose nominal and perturbed steps gave these counts
std::vector<std::string> SolverWarnings(const mjModel& m, const SolverStats& nominal,
                                        const SolverStats& perturbed);

}  // namespace mjsysid
