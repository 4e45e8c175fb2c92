// Logged states smoothed for differentiation (sysid/data/state_smoothing.h): the filter's
// derivatives on known signals, the width chosen from the noise, the logged velocity's lag, the
// refusals. The equation-error start it gives on noisy and encoder-only copies of shipped logs:
// tests/sysid/data/equation_error_test.cc.
#include "sysid/data/state_smoothing.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

// a slide joint driven by nothing (the filter only reads the log), 2 ms, Euler
constexpr char kSlide[] = R"(<mujoco><option timestep="0.002"/><worldbody><body>
  <joint name="x" type="slide" axis="1 0 0"/><geom type="sphere" size="0.1" mass="1"/>
</body></worldbody><actuator><motor joint="x"/></actuator></mujoco>)";

// x(t) = A sin(w t) at T jittered stamps (+-0.1 of the period, seed 2), positions with Gaussian
// noise sigma (and quantized to `quantum` when > 0), no qvel
FitSequence SineLog(int T, double sigma, double quantum, std::vector<double>* times) {
  const double A = 0.3, dt = 0.002;
  std::mt19937 rng(2);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> jitter(-0.1 * dt, 0.1 * dt);
  FitSequence s;
  s.time.resize(T);
  s.qpos.resize(T, 1);
  s.ctrl.setZero(T, 1);
  for (int k = 0; k < T; ++k) {
    s.time[k] = k * dt + (k ? jitter(rng) : 0.0);
    double x = A * std::sin(7.0 * s.time[k]) + sigma * normal(rng);
    if (quantum > 0) x = quantum * std::round(x / quantum);
    s.qpos(k, 0) = x;
  }
  times->assign(s.time.data(), s.time.data() + T);
  return s;
}

// the RMS error of the smoothed velocity (the integrator's convention: half a timestep behind)
// and acceleration against the sine's, over the samples 70 .. T - 70 (away from one-sided
// windows), relative to the amplitudes A w and A w^2
void SineErrors(const SmoothedStates& out, const std::vector<double>& t, double* ev, double* ea) {
  const double A = 0.3, w = 7.0, h = 0.002;
  double sv = 0, sa = 0;
  int n = 0;
  for (size_t k = 70; k + 70 < t.size(); ++k) {
    sv += std::pow(out.states.qvel(k, 0) - A * w * std::cos(w * (t[k] - h / 2)), 2);
    sa += std::pow(out.qacc(k, 0) + A * w * w * std::sin(w * t[k]), 2);
    ++n;
  }
  *ev = std::sqrt(sv / n) / (A * w);
  *ea = std::sqrt(sa / n) / (A * w * w);
}

// noise-free positions at jittered stamps: the narrowest window (h = 2) and derivatives within
// 1e-3 of the amplitudes (measured in [ measured ]); with Gaussian noise 1e-4 (1/3000 of the
// amplitude) a wider window and the acceleration within 3 % of its amplitude (raw second
// differences of that noise: ~20x the amplitude); quantized to 1e-4 (a 0.1 mm encoder) the same
TEST(StateSmoothingTest, EncoderSineDerivativesAndWidthFromTheNoise) {
  ModelPtr m = LoadModelFromString(kSlide);
  struct Case {
    const char* name;
    double sigma, quantum, tol_v, tol_a;
    bool wider;
  };
  for (const Case& c :
       {Case{"exact", 0, 0, 1e-3, 1e-3, false}, Case{"gaussian 1e-4", 1e-4, 0, 0.01, 0.03, true},
        Case{"quantized 1e-4", 0, 1e-4, 0.01, 0.03, true}}) {
    std::vector<double> t;
    const FitSequence s = SineLog(2000, c.sigma, c.quantum, &t);
    SmoothedStates out;
    std::string why;
    ASSERT_TRUE(SmoothLoggedStates(*m, s, &out, &why)) << why;
    EXPECT_TRUE(out.velocities_from_positions);
    double ev = 0, ea = 0;
    SineErrors(out, t, &ev, &ea);
    std::printf("[ measured ] %s: half-width %d, velocity error %.3g, acceleration error %.3g\n",
                c.name, out.half_width, ev, ea);
    EXPECT_LT(ev, c.tol_v) << c.name;
    EXPECT_LT(ea, c.tol_a) << c.name;
    if (c.wider) {
      EXPECT_GT(out.half_width, 2) << c.name;
    } else {
      EXPECT_EQ(out.half_width, 2) << c.name;
    }
  }
}

// a logged velocity that is the backward difference of the positions (a drive's, or a
// simulator's semi-implicit Euler) lags them by half a sample: the fitted lag is 1 ms within
// 5 %, and the smoothed qvel matches the one from the positions alone within 1e-3 of A w
TEST(StateSmoothingTest, LoggedVelocityLagIsFitted) {
  ModelPtr m = LoadModelFromString(kSlide);
  std::vector<double> t;
  FitSequence s = SineLog(2000, 0, 0, &t);
  s.time.resize(0);  // on the timestep's grid, so the backward difference lags by exactly dt / 2
  for (int k = 0; k < 2000; ++k) s.qpos(k, 0) = 0.3 * std::sin(7.0 * k * 0.002);
  s.qvel.resize(2000, 1);
  s.qvel(0, 0) = 0.3 * 7.0;
  for (int k = 1; k < 2000; ++k) s.qvel(k, 0) = (s.qpos(k, 0) - s.qpos(k - 1, 0)) / 0.002;
  SmoothedStates with, without;
  std::string why;
  ASSERT_TRUE(SmoothLoggedStates(*m, s, &with, &why)) << why;
  FitSequence encoders = s;
  encoders.qvel.resize(0, 1);
  ASSERT_TRUE(SmoothLoggedStates(*m, encoders, &without, &why)) << why;
  std::printf("[ measured ] lag %.6g s\n", with.qvel_lag);
  EXPECT_NEAR(with.qvel_lag, 0.001, 5e-5);
  for (int k = 10; k < 1990; ++k) {
    EXPECT_NEAR(with.states.qvel(k, 0), without.states.qvel(k, 0), 1e-3 * 0.3 * 7.0) << k;
  }
}

// a few NaN cells: a window with fewer than five finite samples widens, so every sample is
// filtered from its finite neighbours, NaN cells included (the exact sine: h = 2);
// what is missing is said: no qpos, no qvel with a ball joint, no act for a model with activations
TEST(StateSmoothingTest, GapsLeftOutAndRefusalsSaid) {
  ModelPtr m = LoadModelFromString(kSlide);
  std::vector<double> t;
  FitSequence s = SineLog(500, 0, 0, &t);
  s.qpos(100, 0) = s.qpos(101, 0) = s.qpos(300, 0) = std::nan("");
  SmoothedStates out;
  std::string why;
  ASSERT_TRUE(SmoothLoggedStates(*m, s, &out, &why)) << why;
  ASSERT_EQ(out.half_width, 2);
  for (int k = 2; k < 498; ++k) {
    EXPECT_TRUE(std::isfinite(out.qacc(k, 0)) && std::isfinite(out.states.qvel(k, 0))) << k;
  }
  EXPECT_NEAR(out.states.qpos(300, 0), 0.3 * std::sin(7.0 * t[300]), 1e-6);

  FitSequence none;
  EXPECT_FALSE(SmoothLoggedStates(*m, none, &out, &why));
  EXPECT_EQ(why, "the log has no qpos");
  ModelPtr ball = LoadModelFromString(R"(<mujoco><worldbody><body><joint type="ball"/>
    <geom type="sphere" size="0.1"/></body></worldbody></mujoco>)");
  FitSequence q;
  q.qpos.setZero(100, 4);
  q.qpos.col(0).setOnes();
  EXPECT_FALSE(SmoothLoggedStates(*ball, q, &out, &why));
  EXPECT_EQ(why, "the log has no qvel and the model has ball or free joints");
  ModelPtr act = LoadModelFromString(R"(<mujoco><worldbody><body><joint name="j"/>
    <geom type="sphere" size="0.1"/></body></worldbody>
    <actuator><general joint="j" dyntype="filter" dynprm="0.1"/></actuator></mujoco>)");
  FitSequence a = SineLog(100, 0, 0, &t);
  EXPECT_FALSE(SmoothLoggedStates(*act, a, &out, &why));
  EXPECT_EQ(why, "the log has no act");
}

}  // namespace
}  // namespace mjsysid
