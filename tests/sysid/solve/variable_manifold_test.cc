#include "sysid/solve/variable_manifold.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/fit_test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

// a relative variable grows by p (1 + delta), shrinks by p exp(delta); the others move by delta;
// Minus inverts Plus; the Jacobians are the identity
TEST(VariableManifoldTest, PlusMinusAndJacobians) {
  const VariableManifold M({true, false});
  EXPECT_EQ(M.AmbientSize(), 2);
  EXPECT_EQ(M.TangentSize(), 2);
  EXPECT_TRUE(M.any_relative());
  EXPECT_FALSE(VariableManifold({false, false}).any_relative());
  const double z[2] = {std::log(0.002), 0.5};
  for (double delta : {-30.0, -2.0, -0.3, 0.0, 0.4, 25.0}) {
    const double d[2] = {delta, delta};
    double y[2], back[2];
    ASSERT_TRUE(M.Plus(z, d, y));
    const double ratio = delta > 0 ? 1 + delta : std::exp(delta);
    EXPECT_NEAR(std::exp(y[0]), 0.002 * ratio, 1e-15 + 1e-12 * 0.002 * ratio) << delta;
    EXPECT_GT(std::exp(y[0]), 0.0);
    EXPECT_DOUBLE_EQ(y[1], 0.5 + delta);
    ASSERT_TRUE(M.Minus(y, z, back));
    EXPECT_NEAR(back[0], delta, 1e-9 * (1 + std::abs(delta))) << delta;
    EXPECT_NEAR(back[1], delta, 1e-12 * (1 + std::abs(delta))) << delta;
  }
  double J[4];
  ASSERT_TRUE(M.PlusJacobian(z, J));
  EXPECT_EQ(std::vector<double>(J, J + 4), (std::vector<double>{1, 0, 0, 1}));
  ASSERT_TRUE(M.MinusJacobian(z, J));
  EXPECT_EQ(std::vector<double>(J, J + 4), (std::vector<double>{1, 0, 0, 1}));
  // the slope of Plus at delta = 0 is 1 from both sides (central difference, h 1e-6)
  const double h = 1e-6, up[2] = {h, 0}, down[2] = {-h, 0};
  double yu[2], yd[2];
  ASSERT_TRUE(M.Plus(z, up, yu));
  ASSERT_TRUE(M.Plus(z, down, yd));
  EXPECT_NEAR((yu[0] - yd[0]) / (2 * h), 1.0, 1e-6);
}

TEST(VariableManifoldTest, RelativeStepOnlyForLogVariablesOfLinearKinds) {
  FitParameter damping("d", ParameterSpec{"joint_damping", "hinge", "", 0, ""}, 0.1);
  FitParameter friction("f", ParameterSpec{"geom_friction", "box", "", 0, ""}, 0.5);
  EXPECT_FALSE(RelativeStep(damping));
  damping.Log();
  friction.Log();
  EXPECT_TRUE(RelativeStep(damping));
  EXPECT_FALSE(RelativeStep(friction));
  EXPECT_TRUE(EntersInverseDynamicsLinearly(ParameterKind::kBodyMass));
  EXPECT_FALSE(EntersInverseDynamicsLinearly(ParameterKind::kBodyCom));
}

// experiments/pendulum.yaml simulated as shipped (truth damping 0.08, frictionloss 0.03,
// bob_mass 1.2; noise 0.001 rad and 0.01 rad/s, the sigmas; start 0.2, 0.01, 0.8), fitted as
// shipped (every parameter log p) and in physical units (transform none): both converge to the
// same minimum (1e-6 relative, far inside the standard errors) and the log fit takes no more
// LM iterations than the physical one (before the relative step: 18 against 5), the truth
// within 4 standard errors
TEST(VariableManifoldTest, PendulumInLogSpaceNeedsNoMoreIterationsThanPhysical) {
  InstallMujocoHandlers();
  const fs::path dir =
      fs::temp_directory_path() / ("variable_manifold_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  io::ExperimentConfig cfg =
      io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml");
  const std::string log = (dir / "log.h5").string();
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  auto fit = [&](bool physical) {
    io::ExperimentConfig c = cfg;
    if (physical) {
      for (io::ParameterSpec& p : c.parameters) p.transform = Transform::kNone;
    }
    run::BuiltProblem b = run::BuildProblem(c, 1);
    FitOptions o = b.options;
    o.verbose = false;
    // Ceres' tolerances alone: the LM paths to the same minimum (1e-6 relative) are compared, not
    // where the statistical stop (sysid/solve/gn_convergence.h) ends them (measured with it: log 5,
    // physical 4 iterations)
    o.gauss_newton_stop = 0;
    return b.problem->Fit(o);
  };
  const FitResult log_fit = fit(false), physical_fit = fit(true);
  ASSERT_TRUE(log_fit.converged);
  ASSERT_TRUE(physical_fit.converged);
  std::printf("iterations: log %d, physical %d\n", log_fit.iterations, physical_fit.iterations);
  EXPECT_LE(log_fit.iterations, physical_fit.iterations);
  for (const auto& [name, truth] : std::vector<std::pair<std::string, double>>{
           {"damping", 0.08}, {"frictionloss", 0.03}, {"bob_mass", 1.2}}) {
    const ParameterEstimate& a = test::Estimate(log_fit, name);
    const ParameterEstimate& b = test::Estimate(physical_fit, name);
    EXPECT_NEAR(a.value, b.value, 1e-6 * std::abs(b.value)) << name;
    EXPECT_NEAR(a.value, truth, 4 * a.std_error) << name;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid
