#include "core/solver_stats.h"

#include <algorithm>

namespace mjsysid {
namespace {

const char* SolverName(int solver) {
  switch (solver) {
    case mjSOL_PGS:
      return "PGS";
    case mjSOL_CG:
      return "CG";
    case mjSOL_NEWTON:
      return "Newton";
  }
  return "unknown";
}

}  // namespace

void CountSolve(const mjModel& m, const mjData& d, SolverStats* stats) {
  // the rows per solver state against the step before's
  int states[6] = {0, 0, 0, 0, 0, 0};
  for (int i = 0; m.opt.solver != mjSOL_PGS && i < d.nefc; ++i) {
    const int s = d.efc_state[i];
    const bool friction =
        d.efc_type[i] == mjCNSTR_FRICTION_DOF || d.efc_type[i] == mjCNSTR_FRICTION_TENDON;
    if (friction) {
      ++states[s == mjCNSTRSTATE_QUADRATIC ? 4 : 5];
    } else {
      ++states[s == mjCNSTRSTATE_SATISFIED   ? 0
               : s == mjCNSTRSTATE_QUADRATIC ? 1
               : s == mjCNSTRSTATE_CONE      ? 3
                                             : 2];
    }
  }
  if (stats->last_nefc >= 0) {
    if (d.nefc != stats->last_nefc || !std::equal(states, states + 4, stats->last_states)) {
      ++stats->row_changes;
    } else if (!std::equal(states + 4, states + 6, stats->last_states + 4)) {
      ++stats->friction_changes;
    }
  }
  stats->last_nefc = d.nefc;
  std::copy(states, states + 6, stats->last_states);
  if (d.nefc == 0) return;
  ++stats->solved;
  // islands with a count: at least slot 0 (monolithic), at most mjNISLAND
  const int slots = std::max(1, std::min(d.nisland, static_cast<int>(mjNISLAND)));
  for (int i = 0; i < slots; ++i) {
    if (d.solver_niter[i] >= m.opt.iterations) {
      ++stats->capped;
      return;
    }
  }
}

std::vector<std::string> SolverWarnings(const mjModel& m, const SolverStats& nominal,
                                        const SolverStats& perturbed) {
  std::vector<std::string> out;
  // no step ran the constraint solver: its kind and convergence do not matter
  if (nominal.solved + perturbed.solved == 0) return out;
  const std::string iterations = std::to_string(m.opt.iterations);
  if (m.opt.solver != mjSOL_NEWTON) {
    out.push_back(std::string("constraint solver is ") + SolverName(m.opt.solver) +
                  ", not Newton: it converges less tightly within opt.iterations = " + iterations +
                  ", and finite differences carry its residual error; prefer <option "
                  "solver=\"Newton\"/> for fitting");
  }
  // with tolerance 0 (fixed_solver_iterations) every solve runs to the cap by design
  if (m.opt.tolerance > 0 && nominal.capped + perturbed.capped > 0) {
    out.push_back("constraint solver stopped at its iteration cap (opt.iterations = " + iterations +
                  ") in " + std::to_string(nominal.capped) + " of " +
                  std::to_string(nominal.solved) + " nominal and " +
                  std::to_string(perturbed.capped) + " of " + std::to_string(perturbed.solved) +
                  " perturbed steps with constraints: unconverged solves put solver error into "
                  "the finite differences; raise <option iterations> or use the Newton solver");
  }
  return out;
}

}  // namespace mjsysid
