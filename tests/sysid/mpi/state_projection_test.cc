// StateProjection (sysid/mpi/state_projection.h) on a real multiple-shooting fit without MPI: the
// pendulum (truth damping 0.08, bob mass 1.2; start 0.2 and 0.8), one sequence of 600 steps with
// noise 1e-3 on every sensor channel, segments of 100 steps (5 free states of 2 tangent columns).
// The reduced triangle's cost is exactly the sum of squares at the solved states, its gradient is
// the derivative of the projected cost min over the states (checked against central differences
// of the projected cost), and the committed states are the solution (solving again from them
// moves nothing).
#include "sysid/mpi/state_projection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/fit/segment_evaluator.h"
#include "sysid/problem.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

using test::Excitation;
using test::Measure;
using test::Spec;
using test::Truth;

const std::string kModels = MJSYSID_MODELS_DIR;

TEST(StateProjectionTest, ReducedBlockIsTheProjectedCost) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "hinge"), 0.08},
                                    {"mass", Spec("body_mass", "bob"), 1.2}};
  Problem problem;
  problem.AddModel("pendulum", *m);
  problem.AddParameter(FitParameter("damping", truth[0].spec, 0.2).Bounds(1e-4, 5).Log());
  problem.AddParameter(FitParameter("mass", truth[1].spec, 0.8).Bounds(0.05, 10).Log());
  InitialState x0;
  x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
  const RowMatrix u = Excitation(*m, 600, 1.5, 3);
  problem.AddSequence(FitSequence("seq0", "pendulum", x0, u, Measure(*m, truth, x0, u, 1e-3, 1)));
  FitOptions options;
  options.segment_steps = 100;
  options.threads = 1;
  SegmentEvaluator segments = PrepareOnly(&problem, options);
  ASSERT_EQ(segments.states().size(), 5u);
  ASSERT_EQ(segments.nm(), 0);
  mpi::StateProjection projection(segments);
  ASSERT_EQ(projection.StateColumns(0), 10);
  const int n = 2;

  Eigen::MatrixXd R;
  double sum = 0;
  ASSERT_TRUE(projection.Solve(0, true, &R, &sum));
  ASSERT_EQ(R.rows(), n + 1);
  // the block's cost is the sum of squares at the solved states (1e-12 relative)
  EXPECT_NEAR(R.col(n).squaredNorm(), sum, 1e-12 * sum);

  // the gradient of the projected cost f(z) = min_x |r(x, z)|^2: 2 J^T r of the block, against
  // central differences of f with step 1e-5 in z (log), each solved from the committed states:
  // within 1e-5 of the gradient's norm (measured 1e-6: the differences' truncation)
  const Eigen::VectorXd gradient = 2 * R.leftCols(n).transpose() * R.col(n);
  const std::vector<double> z0 = segments.z();
  for (int j = 0; j < n; ++j) {
    SCOPED_TRACE("z[" + std::to_string(j) + "]");
    const double h = 1e-5;
    double up = 0, down = 0;
    Eigen::MatrixXd unused;
    std::vector<double> z = z0;
    z[j] += h;
    segments.SetVariables(z.data());
    ASSERT_TRUE(projection.Solve(0, false, &unused, &up));
    z[j] = z0[j] - h;
    segments.SetVariables(z.data());
    ASSERT_TRUE(projection.Solve(0, false, &unused, &down));
    const double difference = (up - down) / (2 * h);
    EXPECT_NEAR(difference, gradient[j], 1e-5 * gradient.norm()) << "gradient " << gradient[j];
  }
  segments.SetVariables(z0.data());

  // solved: solving again from the committed states keeps them and the cost (1e-12; measured:
  // the same bits, the predicted decrease below the tolerance at once)
  std::vector<std::vector<double>> solved;
  for (size_t b = 0; b < segments.states().size(); ++b) {
    solved.emplace_back(segments.states()[b].begin(), segments.states()[b].end());
  }
  double again = 0;
  ASSERT_TRUE(projection.Solve(0, true, &R, &again));
  EXPECT_NEAR(again, sum, 1e-12 * sum);
  for (size_t b = 0; b < solved.size(); ++b) {
    for (size_t i = 0; i < solved[b].size(); ++i) {
      EXPECT_NEAR(segments.states()[b].data()[i], solved[b][i], 1e-12)
          << "block " << b << " entry " << i;
    }
  }
}

}  // namespace
}  // namespace mjsysid
