// ChooseLinearSolver (sysid/solve/multiple_shooting.h) on hand-made segment chains: which state
// blocks are eliminated, which solver, and the order of the groups the sparse Cholesky factorises.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <vector>

#include "sysid/solve/multiple_shooting.h"

namespace mjsysid {
namespace {

// one sequence of `segments` segments with a free state block of nx each after the first, and
// np parameters; returns the tangent size
int Chain(int segments, int nx, int np, PreparedFit* fit, FitVariables* vars) {
  vars->z.assign(static_cast<size_t>(np), 0.0);
  for (int s = 0; s < segments; ++s) {
    Segment seg;
    seg.k0 = 10 * s;
    seg.T = 10;
    if (s > 0) {
      seg.block = static_cast<int>(vars->states.size());
      vars->states.push_back(std::vector<double>(static_cast<size_t>(nx), 0.0));
    }
    seg.next = s + 1 < segments ? static_cast<int>(vars->states.size()) : -1;
    fit->segments.push_back(seg);
  }
  return np + (segments - 1) * nx;
}

// ChooseLinearSolver's options for such a chain
struct Choice {
  PreparedFit fit;
  FitVariables vars;
  ceres::Solver::Options so;
  Choice(int segments, int nx, int np) {
    const int tangent = Chain(segments, nx, np, &fit, &vars);
    ChooseLinearSolver(fit, vars, tangent, &so);
  }
};

// a humanoid-sized chain (issue 32: 2000 segments of 54 states, 22 parameters): every other block
// eliminated, the rest with z in a sparse Schur complement, and z factorised after the kept states.
// First, z (which every residual touches) filled the whole factor: CHOLMOD "problem too large"
// with the 1000 kept blocks, and did_not_move.
TEST(LinearSolverChoiceTest, TheParametersAreFactorisedAfterTheKeptStates) {
  Choice c(2000, 54, 22);
  const ceres::Solver::Options& so = c.so;
  FitVariables& vars = c.vars;
  EXPECT_EQ(so.linear_solver_type, ceres::SPARSE_SCHUR);
  ASSERT_TRUE(so.linear_solver_ordering);
  const ceres::ParameterBlockOrdering& order = *so.linear_solver_ordering;
  const int z_group = order.GroupId(vars.z.data());
  int eliminated = 0, kept = 0;
  for (size_t b = 0; b < vars.states.size(); ++b) {
    const int g = order.GroupId(vars.states[b].data());
    if (g == order.MinNonZeroGroup()) {
      ++eliminated;
    } else {
      ++kept;
      EXPECT_LT(g, z_group) << "state block " << b;
    }
  }
  EXPECT_EQ(eliminated, 1000);
  EXPECT_EQ(kept, 999);
  EXPECT_EQ(order.GroupSize(z_group), 1);
}

// a small chain: the reduced system (z and the kept states) of at most 200 dimensions is dense
TEST(LinearSolverChoiceTest, ASmallReducedSystemIsDense) {
  EXPECT_EQ(Choice(20, 4, 3).so.linear_solver_type, ceres::DENSE_SCHUR);  // 10 kept blocks of 4
}

// single shooting: dense QR
TEST(LinearSolverChoiceTest, SingleShootingIsDenseQr) {
  EXPECT_EQ(Choice(1, 4, 3).so.linear_solver_type, ceres::DENSE_QR);
}

}  // namespace
}  // namespace mjsysid
