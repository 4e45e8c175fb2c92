// The residual blocks of single and multiple shooting handed to Ceres as their thin-QR triangles
// (sysid/solve/compressed_cost.h, FitOptions::advanced.compress_blocks) against the same blocks row
// by row.
//
// Unit: a linear cost with known rows (m = 2500 > kChunkRows, so the fold takes three chunks)
// gives, compressed, the cost 0.5 |r|^2, the gradient J^T r and the Gauss-Newton matrix J^T J of
// its rows to 1e-12 relative, with and without Jacobians, and asks Ceres for n + 1 rows.
// Fits: shipped experiments (the `simulate` block's truth, noise and seed, fewer sequences and
// steps so that both fits take a few seconds; single shooting; robust losses; estimated initial
// states, whose blocks sit on the state manifold) fitted both ways reach the same
// iterations and residual rows, and costs, estimates and standard errors that differ by rounding
// alone: the Levenberg-Marquardt steps depend on the rows only through J^T J, J^T r and the cost.
// Rounding is amplified by the finite-difference Jacobians (a parameter moved by one ulp moves
// the differences by ~eps / h relative): the row-by-row fit itself, started 2 ulp (4e-16
// relative) away, ends up to 1.3e-9 relative away in the estimates and 1.0e-7 in the standard
// errors on these cases; the compressed fit's differences were at most 3.1e-9 and 3.6e-7
// (cart_damping on the cartpole; measured at the commit of this test). Tolerances: costs 1e-10,
// estimates 1e-8, standard errors 1e-6 relative (3x the largest difference measured).
// Multiple shooting (segments given, or auto's), whose blocks keep their state blocks (z, m,
// x_0, x_next) and whose uncertainty step eliminates the state columns from the compressed rows
// (sysid/assess/uncertainty.h AnalyzeUncertaintyReduced): the same iterations, residual rows, dof
// and rank, and the residual variance over the real rows. Measured (start moved by 2 ulp,
// row-by-row fit against itself | compressed against row by row; estimates, standard errors,
// cost): arm5 (1 x 1000, segments of 200) 0, 0, 0 (the log transform absorbs the move) | 2.8e-12,
// 9.4e-10, 4.4e-16; double pendulum (segments of 100) 3.4e-12, 1.0e-9, 8.9e-15 | 3.2e-12,
// 7.5e-10, 2.3e-15: the single-shooting tolerances. The hopper under auto's contact segments
// (10 steps, states held first, sysid/solve/multiple_shooting.h) is more sensitive: 3.6e-8, 5.0e-8,
// 2.6e-10 | 3.6e-8, 7.9e-8, 3.1e-10; tolerances 1e-9 (cost and residual variance), 2e-7, 1e-6.
// The humanoid (contacts, quaternion states) is not a case: its row-by-row fit moves by 3.6e-3 in
// the estimates after 3 iterations from a start 4e-16 away (compressed: 2.7e-5).
#include "sysid/solve/compressed_cost.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/experiment_log.h"
#include "tests/file_util.h"

namespace mjsysid {
namespace {

// r = J x - b over two parameter blocks (sizes 2 and 1), J and b fixed random rows
class LinearCost : public ceres::CostFunction {
 public:
  LinearCost(const RowMatrix& J, const Eigen::VectorXd& b) : J_(J), b_(b) {
    set_num_residuals(static_cast<int>(J.rows()));
    mutable_parameter_block_sizes()->push_back(2);
    mutable_parameter_block_sizes()->push_back(1);
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const Eigen::Vector3d x(p[0][0], p[0][1], p[1][0]);
    Eigen::Map<Eigen::VectorXd>(residuals, J_.rows()) = J_ * x - b_;
    if (jacobians) {
      for (Eigen::Index i = 0; i < J_.rows(); ++i) {
        if (jacobians[0]) jacobians[0][2 * i] = J_(i, 0), jacobians[0][2 * i + 1] = J_(i, 1);
        if (jacobians[1]) jacobians[1][i] = J_(i, 2);
      }
    }
    return true;
  }

 private:
  RowMatrix J_;
  Eigen::VectorXd b_;
};

TEST(CompressedCostTest, KeepsCostGradientAndGaussNewtonMatrix) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const int m = 2500;
  RowMatrix J(m, 3);
  Eigen::VectorXd b(m);
  for (int i = 0; i < m; ++i) {
    for (int c = 0; c < 3; ++c) J(i, c) = normal(rng);
    b[i] = 10 * normal(rng);
  }
  CompressedBlocks blocks;
  ceres::CostFunction* inner = new LinearCost(J, b);
  std::unique_ptr<ceres::CostFunction> cost(Compress(inner, &blocks));
  ASSERT_NE(cost.get(), inner);
  EXPECT_EQ(cost->num_residuals(), 4);
  EXPECT_EQ(blocks.hidden_rows, m - 4);
  EXPECT_EQ(RealRows(*cost), m);

  const double x0[2] = {0.3, -1.2}, x1[1] = {2.5};
  const double* params[2] = {x0, x1};
  const Eigen::VectorXd r = J * Eigen::Vector3d(0.3, -1.2, 2.5) - b;
  // residuals only: the norm
  Eigen::VectorXd rc(4);
  ASSERT_TRUE(cost->Evaluate(params, rc.data(), nullptr));
  EXPECT_NEAR(rc.squaredNorm(), r.squaredNorm(), 1e-12 * r.squaredNorm());
  // with Jacobians: cost, J^T r, J^T J
  RowMatrix j0(4, 2), j1(4, 1);
  double* jac[2] = {j0.data(), j1.data()};
  ASSERT_TRUE(cost->Evaluate(params, rc.data(), jac));
  RowMatrix Jc(4, 3);
  Jc << j0, j1;
  EXPECT_NEAR(rc.squaredNorm(), r.squaredNorm(), 1e-12 * r.squaredNorm());
  const Eigen::Vector3d g = J.transpose() * r, gc = Jc.transpose() * rc;
  EXPECT_LT((g - gc).norm(), 1e-12 * g.norm()) << g.transpose() << " vs " << gc.transpose();
  const Eigen::Matrix3d H = J.transpose() * J, Hc = Jc.transpose() * Jc;
  EXPECT_LT((H - Hc).norm(), 1e-12 * H.norm());
  EXPECT_EQ(Jc.row(3).norm(), 0.0);  // [R; 0]

  // a block with no more rows than its triangle stays as it is
  ceres::CostFunction* small = new LinearCost(J.topRows(4), b.head(4));
  std::unique_ptr<ceres::CostFunction> same(Compress(small, &blocks));
  EXPECT_EQ(same.get(), small);
  EXPECT_EQ(blocks.hidden_rows, m - 4);
}

struct Case {
  std::string experiment;  // under experiments/
  int sequences, steps;
  const char* loss;  // "" as shipped, else solver.loss's type (scale 2)
  bool x0 = false;   // the initial states estimated too (their blocks on the state manifold)
  // 0: single shooting; > 0: multiple shooting in segments of this many steps; -1: auto
  int segment_steps = 0;
  // relative tolerances on the final cost (and the residual variance), estimates, standard errors
  double cost_tol = 1e-10, value_tol = 1e-8, se_tol = 1e-6;
};

class CompressedFitTest : public ::testing::TestWithParam<Case> {};

FitResult FitOnce(const io::ExperimentConfig& cfg, bool compress, const Case& c) {
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  FitOptions options = built.options;
  options.estimate_initial_state = c.x0;
  options.verbose = false;
  options.threads = 1;
  options.segment_steps = c.segment_steps;
  options.advanced.compress_blocks = compress;
  return built.problem->Fit(options);
}

// |a - b| <= tol |b|
::testing::AssertionResult Near(double a, double b, double tol) {
  if (std::abs(a - b) <= tol * std::abs(b)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << a << " vs " << b << ": relative " << (a - b) / b << " > " << tol;
}

TEST_P(CompressedFitTest, SameFitAsRowByRow) {
  const Case& c = GetParam();
  io::ExperimentConfig cfg =
      test::ShippedExperimentWithLog(c.experiment, c.sequences, c.steps, "compressed_fit");
  if (*c.loss) {
    cfg.options.loss = std::string(c.loss) == "huber" ? LossType::kHuber : LossType::kCauchy;
    cfg.options.loss_scale = 2.0;
  }

  const FitResult rows = FitOnce(cfg, false, c);
  const FitResult compressed = FitOnce(cfg, true, c);
  std::printf("%s: %d iterations, cost %.10g, %d residual rows, segments of %d steps\n",
              c.experiment.c_str(), compressed.iterations, compressed.final_cost,
              compressed.num_residuals, compressed.segment_steps_used);
  EXPECT_TRUE(rows.converged);
  EXPECT_EQ(rows.converged, compressed.converged);
  EXPECT_EQ(rows.iterations, compressed.iterations);
  EXPECT_EQ(rows.num_residuals, compressed.num_residuals);
  if (c.segment_steps >= 0) {
    EXPECT_EQ(rows.segment_steps_used, c.segment_steps);
  } else {
    EXPECT_GT(rows.segment_steps_used, 0);  // auto chose segments
  }
  EXPECT_EQ(compressed.segment_steps_used, rows.segment_steps_used);
  EXPECT_TRUE(Near(compressed.initial_cost, rows.initial_cost, 1e-10));
  EXPECT_TRUE(Near(compressed.final_cost, rows.final_cost, c.cost_tol));
  // the residual variance over the real rows (multiple shooting: the rows left after the
  // elimination of the state columns, sysid/assess/uncertainty.h AnalyzeUncertaintyReduced)
  EXPECT_EQ(rows.uncertainty.dof, compressed.uncertainty.dof);
  EXPECT_EQ(rows.uncertainty.rank, compressed.uncertainty.rank);
  EXPECT_TRUE(Near(compressed.uncertainty.residual_variance, rows.uncertainty.residual_variance,
                   c.cost_tol));
  ASSERT_EQ(rows.parameters.size(), compressed.parameters.size());
  for (size_t i = 0; i < rows.parameters.size(); ++i) {
    const ParameterEstimate &a = compressed.parameters[i], &b = rows.parameters[i];
    EXPECT_TRUE(Near(a.value, b.value, c.value_tol)) << b.name;
    EXPECT_TRUE(Near(a.std_error, b.std_error, c.se_tol)) << b.name;
  }
  EXPECT_EQ(rows.outcome, compressed.outcome);
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

INSTANTIATE_TEST_SUITE_P(
    Shipped, CompressedFitTest,
    ::testing::Values(Case{"pendulum.yaml", 2, 1000, ""}, Case{"pendulum.yaml", 2, 1000, "huber"},
                      Case{"cartpole.yaml", 1, 1000, ""},
                      Case{"spring_mass.yaml", 1, 1000, "cauchy"},
                      Case{"double_pendulum.yaml", 1, 1000, ""},
                      Case{"double_pendulum.yaml", 1, 1000, "", true},
                      Case{"arm5.yaml", 1, 1000, "", false, 200},
                      Case{"double_pendulum.yaml", 1, 1000, "", false, 100},
                      Case{"robust/hopper.yaml", 1, 400, "", false, -1, 1e-9, 2e-7, 1e-6}),
    [](const ::testing::TestParamInfo<Case>& p) {
      std::string name = p.param.experiment.substr(0, p.param.experiment.find('.'));
      if (name.find('/') != std::string::npos) {
        name = name.substr(name.find('/') + 1);
      }
      return name + (*p.param.loss ? std::string("_") + p.param.loss : "") +
             (p.param.x0 ? "_x0" : "") +
             (p.param.segment_steps > 0   ? "_ms" + std::to_string(p.param.segment_steps)
              : p.param.segment_steps < 0 ? "_auto"
                                          : "");
    });

}  // namespace
}  // namespace mjsysid
