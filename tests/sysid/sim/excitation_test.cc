// control signals and sensor noise of `sysid simulate`: amplitude and frequency content of each
// shape, PRBS switching times, seeding, clipping to ctrlrange, per-actuator excitation, noise
#include "sysid/sim/excitation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"

namespace mjsysid::sim {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

io::Excitation Sines(double amplitude, std::vector<double> frequencies) {
  io::Excitation e;
  e.type = io::ExcitationType::kSines;
  e.amplitude = amplitude;
  e.frequencies = std::move(frequencies);
  return e;
}

io::Excitation Chirp(double amplitude, double f0, double f1) {
  io::Excitation e;
  e.type = io::ExcitationType::kChirp;
  e.amplitude = amplitude;
  e.f0 = f0;
  e.f1 = f1;
  return e;
}

io::Excitation Prbs(double amplitude, double period) {
  io::Excitation e;
  e.type = io::ExcitationType::kPrbs;
  e.amplitude = amplitude;
  e.switch_period = period;
  return e;
}

// sign changes of u between samples first and last (exclusive)
int ZeroCrossings(const Eigen::VectorXd& u, int first = 0, int last = -1) {
  if (last < 0) last = static_cast<int>(u.size());
  int n = 0;
  for (int k = first + 1; k < last; ++k) {
    if ((u[k - 1] < 0) != (u[k] < 0)) ++n;
  }
  return n;
}

// amplitude of the component of u at frequency f (a single Fourier coefficient, exact for a
// whole number of periods over the horizon)
double ComponentAmplitude(const Eigen::VectorXd& u, double dt, double f) {
  std::complex<double> sum = 0;
  for (int k = 0; k < u.size(); ++k) {
    sum += u[k] * std::exp(std::complex<double>(0, -2.0 * M_PI * f * k * dt));
  }
  return 2.0 * std::abs(sum) / static_cast<double>(u.size());
}

// ---------------------------------------------------------------------------------------------
// sines

TEST(ExcitationTest, SinesPeakIsTheAmplitude) {
  const Eigen::VectorXd u = ExcitationSignal(Sines(2.5, {0.5, 1.3, 2.9}), 5000, 0.002, 7);
  ASSERT_EQ(u.size(), 5000);
  EXPECT_NEAR(u.cwiseAbs().maxCoeff(), 2.5, 1e-12);
  EXPECT_TRUE(u.allFinite());
}

TEST(ExcitationTest, SinesContainExactlyTheRequestedFrequencies) {
  // 10 s: every frequency below makes a whole number of periods, so the components are orthogonal
  const double dt = 0.001;
  const Eigen::VectorXd u = ExcitationSignal(Sines(1.0, {0.5, 1.3, 2.9}), 10000, dt, 3);
  const double a05 = ComponentAmplitude(u, dt, 0.5);
  const double a13 = ComponentAmplitude(u, dt, 1.3);
  const double a29 = ComponentAmplitude(u, dt, 2.9);
  // the three components have equal amplitudes (one unit sine each, then scaled together)
  EXPECT_GT(a05, 0.3);
  EXPECT_NEAR(a13, a05, 1e-9);
  EXPECT_NEAR(a29, a05, 1e-9);
  // and nothing at other frequencies
  for (double f : {0.2, 1.0, 2.0, 4.0, 7.5}) {
    EXPECT_LT(ComponentAmplitude(u, dt, f), 1e-9) << f << " Hz";
  }
}

TEST(ExcitationTest, SingleSineCrossesZeroTwicePerPeriod) {
  // 3 Hz for 4 s: 24 zero crossings (give or take the ends)
  const Eigen::VectorXd u = ExcitationSignal(Sines(1.0, {3.0}), 4000, 0.001, 11);
  EXPECT_NEAR(ZeroCrossings(u), 24, 1);
  EXPECT_NEAR(u.cwiseAbs().maxCoeff(), 1.0, 1e-12);
}

TEST(ExcitationTest, SeedsGiveReproducibleAndDifferentSignals) {
  const io::Excitation e = Sines(1.0, {0.5, 1.3, 2.9});
  const Eigen::VectorXd a = ExcitationSignal(e, 1000, 0.002, 42);
  const Eigen::VectorXd b = ExcitationSignal(e, 1000, 0.002, 42);
  const Eigen::VectorXd c = ExcitationSignal(e, 1000, 0.002, 43);
  EXPECT_EQ(a, b);
  EXPECT_GT((a - c).cwiseAbs().maxCoeff(), 0.1);
}

TEST(ExcitationTest, ZeroAmplitudeAndZeroTypeGiveZeros) {
  EXPECT_TRUE(ExcitationSignal(Sines(0.0, {1.0}), 100, 0.01, 1).isZero(0));
  io::Excitation zero;
  zero.type = io::ExcitationType::kZero;
  EXPECT_TRUE(ExcitationSignal(zero, 100, 0.01, 1).isZero(0));
  EXPECT_EQ(ExcitationSignal(Sines(1.0, {1.0}), 0, 0.01, 1).size(), 0);
}

// ---------------------------------------------------------------------------------------------
// chirp

TEST(ExcitationTest, ChirpSweepsLinearlyFromF0ToF1) {
  // 1 Hz -> 11 Hz over 10 s: f(t) = 1 + t
  const double dt = 0.0005;
  const int steps = 20000;
  const Eigen::VectorXd u = ExcitationSignal(Chirp(1.5, 1.0, 11.0), steps, dt, 5);
  EXPECT_LE(u.cwiseAbs().maxCoeff(), 1.5 + 1e-12);
  EXPECT_GT(u.cwiseAbs().maxCoeff(), 1.49);
  // crossings in each 1 s window: twice the mean frequency, f at the window's middle
  for (int w = 0; w < 10; ++w) {
    const int first = w * 2000;
    const double f_mid = 1.0 + (w + 0.5);
    EXPECT_NEAR(ZeroCrossings(u, first, first + 2000), 2.0 * f_mid, 1.5) << "window " << w;
  }
}

TEST(ExcitationTest, ChirpPhaseIsSeeded) {
  const Eigen::VectorXd a = ExcitationSignal(Chirp(1.0, 0.1, 5.0), 500, 0.002, 1);
  const Eigen::VectorXd b = ExcitationSignal(Chirp(1.0, 0.1, 5.0), 500, 0.002, 2);
  EXPECT_EQ(a, ExcitationSignal(Chirp(1.0, 0.1, 5.0), 500, 0.002, 1));
  EXPECT_GT((a - b).cwiseAbs().maxCoeff(), 0.01);
}

// ---------------------------------------------------------------------------------------------
// prbs

TEST(ExcitationTest, PrbsIsPlusMinusAmplitudeSwitchingOnlyAtMultiplesOfThePeriod) {
  // dt does not divide the period: switches fall on the first sample of each interval
  for (double dt : {0.002, 0.003, 0.01}) {
    const double period = 0.1;
    const int steps = 3000;
    const Eigen::VectorXd u = ExcitationSignal(Prbs(0.7, period), steps, dt, 9);
    int switches = 0;
    for (int k = 0; k < steps; ++k) {
      ASSERT_TRUE(u[k] == 0.7 || u[k] == -0.7) << "k " << k;
      if (k > 0 && u[k] != u[k - 1]) {
        ++switches;
        // sample k is the first one at or after a multiple of the period
        const double t = k * dt;
        const double multiple = std::floor(t / period + 1e-9) * period;
        EXPECT_LE(multiple, t + 1e-12) << "dt " << dt << " k " << k;
        EXPECT_GT(multiple, (k - 1) * dt + 1e-12) << "dt " << dt << " k " << k;
      }
    }
    // a fair coin per interval: about half of the boundaries switch
    const double intervals = steps * dt / period;
    EXPECT_GT(switches, 0.3 * intervals) << "dt " << dt;
    EXPECT_LT(switches, 0.7 * intervals) << "dt " << dt;
  }
}

TEST(ExcitationTest, PrbsIsReproducibleFromTheSeedAndIndependentOfTheTimeStep) {
  const Eigen::VectorXd a = ExcitationSignal(Prbs(1.0, 0.2), 2000, 0.002, 77);
  EXPECT_EQ(a, ExcitationSignal(Prbs(1.0, 0.2), 2000, 0.002, 77));
  EXPECT_NE(a, ExcitationSignal(Prbs(1.0, 0.2), 2000, 0.002, 78));
  // the same seed at half the time step: the same value at the same times (inside intervals)
  const Eigen::VectorXd fine = ExcitationSignal(Prbs(1.0, 0.2), 4000, 0.001, 77);
  for (int k = 0; k < 2000; k += 7) EXPECT_EQ(a[k], fine[2 * k]) << k;
}

// ---------------------------------------------------------------------------------------------
// controls of a model

TEST(ExcitationTest, ControlsAreClippedToTheCtrlrange) {
  // pendulum: torque in [-5, 5]
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  const RowMatrix u = GenerateControls(*m, {Sines(10.0, {0.5, 1.3})}, 2000, 1);
  ASSERT_EQ(u.rows(), 2000);
  ASSERT_EQ(u.cols(), 1);
  EXPECT_EQ(u.maxCoeff(), 5.0);
  EXPECT_EQ(u.minCoeff(), -5.0);
  // spring_mass: no ctrlrange, nothing clipped
  ModelPtr s = LoadModel(kModels + "/spring_mass.xml");
  const RowMatrix v = GenerateControls(*s, {Sines(10.0, {0.5, 1.3})}, 2000, 1);
  EXPECT_NEAR(v.cwiseAbs().maxCoeff(), 10.0, 1e-12);
}

TEST(ExcitationTest, ClipToCtrlRangeClipsLimitedActuatorsOnly) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  RowMatrix u(3, 1);
  u << -7, 2, 9;
  ClipToCtrlRange(*m, &u);
  EXPECT_EQ(u(0, 0), -5);
  EXPECT_EQ(u(1, 0), 2);
  EXPECT_EQ(u(2, 0), 5);
  RowMatrix wrong(3, 2);
  EXPECT_THROW(ClipToCtrlRange(*m, &wrong), std::invalid_argument);
}

TEST(ExcitationTest, OneEntryForAllGivesEachActuatorItsOwnSignal) {
  ModelPtr m = LoadModel(kModels + "/arm5.xml");
  const RowMatrix u = GenerateControls(*m, {Sines(1.0, {0.5, 1.3, 2.9})}, 500, 4);
  ASSERT_EQ(u.cols(), 5);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(u.col(i).cwiseAbs().maxCoeff(), 1.0, 1e-12);
    for (int j = 0; j < i; ++j) EXPECT_GT((u.col(i) - u.col(j)).cwiseAbs().maxCoeff(), 0.05);
  }
  // a different sequence seed changes every column
  const RowMatrix w = GenerateControls(*m, {Sines(1.0, {0.5, 1.3, 2.9})}, 500, 5);
  for (int i = 0; i < 5; ++i) EXPECT_GT((u.col(i) - w.col(i)).cwiseAbs().maxCoeff(), 0.05);
}

TEST(ExcitationTest, PerActuatorEntriesAndUnlistedActuatorsGetZero) {
  ModelPtr m = LoadModel(kModels + "/arm5.xml");
  io::Excitation a = Chirp(2.0, 0.1, 4.0);
  a.actuator = "m1";
  io::Excitation b = Prbs(1.0, 0.2);
  b.actuator = "m3";
  const RowMatrix u = GenerateControls(*m, {a, b}, 1000, 8);
  EXPECT_GT(u.col(0).cwiseAbs().maxCoeff(), 1.9);
  EXPECT_TRUE(u.col(1).isZero(0));
  EXPECT_EQ(u.col(2).cwiseAbs().minCoeff(), 1.0);
  EXPECT_TRUE(u.col(3).isZero(0));
  EXPECT_TRUE(u.col(4).isZero(0));
  // an actuator's signal does not depend on the other entries
  const RowMatrix only_a = GenerateControls(*m, {a}, 1000, 8);
  EXPECT_EQ(RowMatrix(u.col(0)), RowMatrix(only_a.col(0)));
  // unknown actuators are errors naming them
  io::Excitation bad = Sines(1.0, {1.0});
  bad.actuator = "m9";
  try {
    GenerateControls(*m, {bad}, 10, 1);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("m9"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// sensor noise

TEST(ExcitationTest, SensorNoiseHasTheRequestedSigmaOnTheNamedSensorsOnly) {
  // arm5: q1..q5 then v1..v5, one column each
  ModelPtr m = LoadModel(kModels + "/arm5.xml");
  const int rows = 20000;
  RowMatrix y = RowMatrix::Constant(rows, 10, 0.25);
  AddSensorNoise(*m, {{"q2", 0.01, {}}, {"v4", 0.3, {}}, {"v5", 0.0, {}}}, 12, &y);
  const Eigen::VectorXd q2 = y.col(1).array() - 0.25;
  const Eigen::VectorXd v4 = y.col(8).array() - 0.25;
  auto stddev = [](const Eigen::VectorXd& x) {
    return std::sqrt((x.array() - x.mean()).square().sum() / static_cast<double>(x.size() - 1));
  };
  EXPECT_NEAR(stddev(q2), 0.01, 0.0003);
  EXPECT_NEAR(stddev(v4), 0.3, 0.009);
  EXPECT_NEAR(q2.mean(), 0.0, 4 * 0.01 / std::sqrt(rows));
  EXPECT_NEAR(v4.mean(), 0.0, 4 * 0.3 / std::sqrt(rows));
  for (int c : {0, 2, 3, 4, 5, 6, 7, 9}) EXPECT_TRUE((y.col(c).array() == 0.25).all()) << c;

  // reproducible from the seed; another seed differs
  RowMatrix y2 = RowMatrix::Constant(rows, 10, 0.25);
  AddSensorNoise(*m, {{"q2", 0.01, {}}, {"v4", 0.3, {}}}, 12, &y2);
  EXPECT_EQ(y, y2);
  RowMatrix y3 = RowMatrix::Constant(rows, 10, 0.25);
  AddSensorNoise(*m, {{"q2", 0.01, {}}}, 13, &y3);
  EXPECT_NE(RowMatrix(y.col(1)), RowMatrix(y3.col(1)));
}

TEST(ExcitationTest, SensorNoiseCoversEveryColumnOfAVectorSensor) {
  ModelPtr m = LoadModel(kModels + "/box_floor.xml");
  const int ns = static_cast<int>(m->nsensordata);
  RowMatrix y = RowMatrix::Zero(5000, ns);
  AddSensorNoise(*m, {{"box_vel", 0.1, {}}}, 1, &y);
  const int id = mj_name2id(m.get(), mjOBJ_SENSOR, "box_vel");
  const int adr = m->sensor_adr[id];
  for (int c = 0; c < ns; ++c) {
    const double rms = std::sqrt(y.col(c).squaredNorm() / 5000.0);
    if (c >= adr && c < adr + 3) {
      EXPECT_NEAR(rms, 0.1, 0.006) << c;
    } else {
      EXPECT_EQ(rms, 0.0) << c;
    }
  }
  EXPECT_THROW(AddSensorNoise(*m, {{"nope", 0.1, {}}}, 1, &y), std::invalid_argument);
}

TEST(ExcitationTest, SeedStreamsDiffer) {
  EXPECT_NE(SeedFor(42, 0), SeedFor(42, 1));
  EXPECT_NE(SeedFor(42, 0), SeedFor(43, 0));
  EXPECT_NE(SeedFor(0, 0), 0u);
  EXPECT_EQ(SeedFor(42, 3), SeedFor(42, 3));
}

TEST(ExcitationTest, DescriptionNamesTypesAndSettings) {
  io::Excitation a = Chirp(2.0, 0.1, 4.0);
  a.actuator = "m1";
  io::Excitation z;
  z.type = io::ExcitationType::kZero;
  z.actuator = "m2";
  EXPECT_EQ(DescribeExcitation({a, z}), "m1: chirp amplitude=2 f0=0.1 f1=4; m2: zero");
  EXPECT_EQ(DescribeExcitation({Sines(1.0, {0.5, 1.3})}),
            "all: sines amplitude=1 frequencies=[0.5, 1.3]");
  EXPECT_EQ(DescribeExcitation({Prbs(3.0, 0.25)}), "all: prbs amplitude=3 switch_period=0.25");
}

}  // namespace
}  // namespace mjsysid::sim
