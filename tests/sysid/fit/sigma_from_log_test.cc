// Sigma from the log (sysid/fit/sigma_from_log.h, `sigma: auto`): the estimate on logs with a
// known noise, the quantum floor, the options it gives, and the errors that name the sensor.
// The fits that use it (the status judging the model) are in tests/sysid/status_test.cc.
#include "sysid/fit/sigma_from_log.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

using test::Excitation;
using test::Measure;
using test::Spec;

// the pendulum (angle, rate) released at 0.3 rad under a 1.5 Nm multi-sine, T steps at the
// model's 2 ms, Gaussian noise `noise` on both sensors
PreparedFit PendulumLog(int T, double noise, int seed) {
  PreparedFit fit;
  FitModel mo;
  mo.name = "pendulum";
  mo.model = LoadModel(std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml");
  InitialState x0;
  x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
  const RowMatrix u = Excitation(*mo.model, T, 1.5, 3);
  const RowMatrix y =
      Measure(*mo.model, {{"damping", Spec("joint_damping", "hinge"), 0.2}}, x0, u, noise, seed);
  fit.sequences.push_back(FitSequence("seq0", "pendulum", x0, u, y));
  fit.models.push_back(std::move(mo));
  return fit;
}

FitOptions Auto(const std::vector<std::string>& sensors) {
  FitOptions o;
  o.sensors_sigma_from_log = sensors;
  return o;
}

std::string ErrorOf(const PreparedFit& fit, const FitOptions& o) {
  try {
    WithSigmasFromLog(fit, o, nullptr);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// white noise 0.01 over 2000 samples (a 6 s swing of ~1 rad and ~3 rad/s): each sensor's sigma
// within 10 % of 0.01 over 5 seeds (the median absolute second difference of 2000 samples has a
// relative spread of ~3 %; the swing's curvature adds (s'' dt^2)^2 / 6, below 1e-5 rad here), the
// weights 1 / sigma, both sensors then with a sigma
TEST(SigmaFromLogTest, WhiteNoiseIsEstimated) {
  for (int seed = 1; seed <= 5; ++seed) {
    const PreparedFit fit = PendulumLog(2000, 0.01, seed);
    std::map<std::string, double> sigmas;
    const FitOptions o = WithSigmasFromLog(fit, Auto({"angle", "rate"}), &sigmas);
    ASSERT_EQ(sigmas.size(), 2u);
    for (const char* s : {"angle", "rate"}) {
      std::printf("[ measured ] seed %d: sigma of %s %.5g (noise 0.01)\n", seed, s, sigmas[s]);
      EXPECT_NEAR(sigmas[s], 0.01, 0.001) << s;
      EXPECT_DOUBLE_EQ(o.sensor_weights.at(s), 1 / sigmas[s]);
    }
    EXPECT_EQ(o.sensors_with_sigma, (std::vector<std::string>{"angle", "rate"}));
    EXPECT_TRUE(o.sensors_sigma_from_log.empty());
  }
}

// an encoder's quantum q = 2 pi / 4096 on a noise-free angle: its rounding noise q / sqrt(12)
// (4.4e-4) within 30 %
TEST(SigmaFromLogTest, QuantizedColumnGetsTheQuantumFloor) {
  PreparedFit fit = PendulumLog(2000, 0.0, 1);
  const double q = 2 * M_PI / 4096;
  RowMatrix& y = fit.sequences[0].measured;
  for (Eigen::Index k = 0; k < y.rows(); ++k) y(k, 0) = q * std::round(y(k, 0) / q);
  std::map<std::string, double> sigmas;
  WithSigmasFromLog(fit, Auto({"angle"}), &sigmas);
  std::printf("[ measured ] quantized angle: sigma %.4g (q / sqrt(12) = %.4g)\n", sigmas["angle"],
              q / std::sqrt(12.0));
  EXPECT_GE(sigmas["angle"], q / std::sqrt(12.0) * (1 - 1e-12));
  EXPECT_LE(sigmas["angle"], 1.3 * q / std::sqrt(12.0));
}

// a noise-free log: the estimate is the signal's curvature only (tiny but > 0), never 0
TEST(SigmaFromLogTest, NoiseFreeLogGivesASmallPositiveSigma) {
  const PreparedFit fit = PendulumLog(2000, 0.0, 1);
  std::map<std::string, double> sigmas;
  WithSigmasFromLog(fit, Auto({"angle", "rate"}), &sigmas);
  for (const auto& [s, sigma] : sigmas) {
    std::printf("[ measured ] noise-free %s: sigma %.3g\n", s.c_str(), sigma);
    EXPECT_GT(sigma, 0);
    EXPECT_LT(sigma, 1e-4);
  }
}

// what cannot be estimated is an error naming the sensor and the way out
TEST(SigmaFromLogTest, ErrorsNameTheSensor) {
  const PreparedFit fit = PendulumLog(2000, 0.01, 1);
  // a sigma and auto for one sensor
  FitOptions both = Auto({"angle"});
  both.sensor_weights["angle"] = 100;
  both.sensors_with_sigma = {"angle"};
  EXPECT_NE(ErrorOf(fit, both).find("sensor 'angle' (sigma: auto): it has a weight or sigma"),
            std::string::npos)
      << ErrorOf(fit, both);
  // no model has it
  EXPECT_NE(ErrorOf(fit, Auto({"angel"})).find("no fitted sequence fits this sensor"),
            std::string::npos);
  // a column of zeros
  PreparedFit zeros = PendulumLog(2000, 0.01, 1);
  zeros.sequences[0].measured.col(1).setZero();
  EXPECT_NE(ErrorOf(zeros, Auto({"rate"})).find("reads 0 throughout"), std::string::npos)
      << ErrorOf(zeros, Auto({"rate"}));
  // too few consecutive samples: every other one NaN
  PreparedFit gappy = PendulumLog(2000, 0.01, 1);
  for (Eigen::Index k = 0; k < gappy.sequences[0].measured.rows(); k += 2) {
    gappy.sequences[0].measured(k, 0) = std::nan("");
  }
  EXPECT_NE(ErrorOf(gappy, Auto({"angle"})).find("too short or too gappy"), std::string::npos)
      << ErrorOf(gappy, Auto({"angle"}));
  // a sequence that fits other sensors only does not count
  PreparedFit other = PendulumLog(2000, 0.01, 1);
  other.sequences[0].sensors = {"rate"};
  EXPECT_NE(ErrorOf(other, Auto({"angle"})).find("no fitted sequence fits this sensor"),
            std::string::npos);
}

}  // namespace
}  // namespace mjsysid
