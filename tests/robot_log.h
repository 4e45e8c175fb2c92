// A robot's log as a robot writes it, for fits of real-log style
// (tests/sysid/real_log_bench_test.cc, tests/sysid/assess/correlated_coverage_test.cc): a finer
// simulation (0.5 ms by default) of the true model plays the robot. Its controller updates at
// 50-100 Hz, each command held until the next and reaching the motors late (a transport delay); its
// sensors are logged at 100-250 Hz at jittered instants, with dropped rows, NaN cells, encoder
// quantization and noise. The cases (truth, start, excitation amplitude, encoder columns) are the
// shipped models': spring-mass (mass 1.5, damping 0.5, stiffness 6; start 1, 0.2, 3), pendulum
// (damping 0.08, bob mass 1.2; 0.2, 0.8), cart-pole (pole mass 0.25, cart damping 0.7; 0.15, 0.3),
// arm5 (armatures 0.5 .. 0.1; 0.05 each, multiple shooting).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/problem.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace test {

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// the model file with its timestep set to dt
inline ModelPtr WithTimestep(const std::string& file, double dt) {
  std::string xml = ReadText(std::string(MJSYSID_MODELS_DIR) + "/" + file);
  const size_t at = xml.find("timestep=\"");
  EXPECT_NE(at, std::string::npos);
  const size_t end = xml.find('"', at + 10);
  char value[32];
  std::snprintf(value, sizeof(value), "%.17g", dt);
  xml.replace(at + 10, end - at - 10, value);
  return LoadModelFromString(xml);
}

// how the robot logs
struct RobotSettings {
  double fine_dt = 0.0005;      // the robot's physics (s)
  double duration = 6.0;        // s
  double control_rate = 100;    // controller updates (Hz), each command held until the next
  double control_delay = 0.01;  // s from command to motor
  double sensor_rate = 100;     // Hz
  double jitter = 0.0003;       // sample instants: nominal + uniform(-jitter, jitter) (s)
  int dropped = 4;              // rows dropped
  int nan_cells = 6;            // cells logged as NaN
  double quantum = 0;           // encoder step of the position sensors (0: none)
  double sigma = 0;             // Gaussian noise on every sensor
  // the noise's correlation from one sample to the next (AR(1): e_k = phi e_{k-1} + sqrt(1 -
  // phi^2) sigma w_k; 0: white), as a filtered sensor logs it
  double noise_phi = 0;
  double model_dt = 0.002;  // on_grid: samples at every step of this
  bool on_grid = false;     // exact samples at every model step (the discretisation floor)
  int seed = 1;
};

struct RobotLog {
  Eigen::VectorXd time;  // sample instants (s)
  RowMatrix measured;    // T x nsensordata, NaN where not logged
  Eigen::VectorXd ctrl_time;
  RowMatrix ctrl;  // the controller's commands at ctrl_time
};

// The robot: the true model stepped at fine_dt under its controller's delayed, held commands
// (multi-sines of `amplitude`, from before the log starts so that a command is always in force),
// its sensors read at the (jittered) sample instants by linear interpolation between fine steps.
inline RobotLog MakeRobotLog(const std::string& file, const std::vector<Truth>& truth,
                             const InitialState& x0, double amplitude,
                             const std::vector<int>& positions, const RobotSettings& rs) {
  ModelPtr fine = WithTimestep(file, rs.fine_dt);
  const mjModel& m = *fine;
  std::mt19937_64 rng(rs.seed);
  RobotLog log;

  // controller: ticks from -0.2 s, multi-sine commands
  const double tick = 1.0 / rs.control_rate;
  const int J = static_cast<int>(std::ceil((rs.duration + 0.2) / tick)) + 1;
  log.ctrl_time.resize(J);
  log.ctrl.resize(J, m.nu);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI);
  std::vector<double> ph(3 * m.nu);
  for (double& p : ph) p = phase(rng);
  const double freqs[3] = {0.3, 0.9, 1.9};
  for (int j = 0; j < J; ++j) {
    const double t = -0.2 + j * tick;
    log.ctrl_time[j] = t;
    for (int i = 0; i < m.nu; ++i) {
      double v = 0;
      for (int f = 0; f < 3; ++f)
        v += std::sin(2 * M_PI * freqs[f] * (1 + 0.3 * i) * t + ph[3 * i + f]);
      log.ctrl(j, i) = amplitude * v / 3;
    }
  }

  // physics: fine step n at n fine_dt sees the last command with t_j + delay <= t_n
  const int N = static_cast<int>(std::round(rs.duration / rs.fine_dt)) + 2;
  RowMatrix u(N, m.nu);
  int j = 0;
  for (int n = 0; n < N; ++n) {
    const double t = n * rs.fine_dt;
    while (j + 1 < J && log.ctrl_time[j + 1] + rs.control_delay <= t + 1e-12) ++j;
    u.row(n) = log.ctrl.row(j);
  }
  const RowMatrix y =
      TrueSimulator(m, truth)->Rollout(SequenceInput{x0, u}).sensors;  // y_n at n fine_dt

  // sample instants
  std::vector<double> times;
  std::uniform_real_distribution<double> jitter(-rs.jitter, rs.jitter);
  const double period = rs.on_grid ? rs.model_dt : 1.0 / rs.sensor_rate;
  for (int k = 0;; ++k) {
    double t = k * period;
    if (k > 0 && !rs.on_grid) t += jitter(rng);
    if (t > rs.duration) break;
    times.push_back(t);
  }
  if (!rs.on_grid) {
    for (int d = 0; d < rs.dropped; ++d) {
      std::uniform_int_distribution<size_t> row(1, times.size() - 2);
      times.erase(times.begin() + static_cast<long>(row(rng)));
    }
  }
  const auto T = static_cast<Eigen::Index>(times.size());
  log.time = Eigen::Map<Eigen::VectorXd>(times.data(), T);
  log.measured.resize(T, m.nsensordata);
  std::normal_distribution<double> noise(0, 1);
  std::vector<double> colored(m.nsensordata, 0.0);
  for (double& e : colored) e = rs.sigma * noise(rng);
  for (Eigen::Index k = 0; k < T; ++k) {
    const double q = times[k] / rs.fine_dt;
    const int n = std::min(static_cast<int>(std::floor(q)), N - 2);
    const double a = q - n;
    for (int c = 0; c < m.nsensordata; ++c) {
      double v = (1 - a) * y(n, c) + a * y(n + 1, c);
      colored[c] = rs.noise_phi * colored[c] +
                   std::sqrt(1 - rs.noise_phi * rs.noise_phi) * rs.sigma * noise(rng);
      if (!rs.on_grid) v += rs.noise_phi > 0 ? colored[c] : rs.sigma * noise(rng);
      const bool position = std::find(positions.begin(), positions.end(), c) != positions.end();
      if (!rs.on_grid && position && rs.quantum > 0) v = rs.quantum * std::round(v / rs.quantum);
      log.measured(k, c) = v;
    }
  }
  if (!rs.on_grid) {
    std::uniform_int_distribution<Eigen::Index> row(1, T - 1);
    std::uniform_int_distribution<int> col(0, m.nsensordata - 1);
    for (int i = 0; i < rs.nan_cells; ++i)
      log.measured(row(rng), col(rng)) = std::numeric_limits<double>::quiet_NaN();
  }
  return log;
}

// one fit case: the model file, the truth, the start, the initial state and the excitation
struct Case {
  std::string file;
  std::vector<Truth> truth;
  std::vector<FitParameter> start;
  InitialState x0;
  double amplitude;
  std::vector<int> positions;  // sensordata columns quantized like encoders
  int segment_steps = 0;       // multiple shooting (simulation steps), 0: single
  RobotSettings robot;         // how the real-log bench's robot logs it
};

inline Case SpringMass() {
  Case c;
  c.file = "spring_mass.xml";
  c.truth = {{"mass", Spec("body_mass", "mass"), 1.5},
             {"damping", Spec("joint_damping", "slide"), 0.5},
             {"stiffness", Spec("joint_stiffness", "slide"), 6.0}};
  c.start = {
      FitParameter("mass", Spec("body_mass", "mass"), 1.0).Bounds(0.01, 100).Log(),
      FitParameter("damping", Spec("joint_damping", "slide"), 0.2).Bounds(1e-4, 100).Log(),
      FitParameter("stiffness", Spec("joint_stiffness", "slide"), 3.0).Bounds(1e-3, 1000).Log()};
  c.amplitude = 2.0;
  c.positions = {0};
  c.robot.quantum = 1e-4;  // m
  c.robot.sigma = 1e-4;
  return c;
}

inline Case Pendulum() {
  Case c;
  c.file = "pendulum.xml";
  c.truth = {{"damping", Spec("joint_damping", "hinge"), 0.08},
             {"bob_mass", Spec("body_mass", "bob"), 1.2}};
  c.start = {FitParameter("damping", Spec("joint_damping", "hinge"), 0.2).Bounds(1e-4, 5).Log(),
             FitParameter("bob_mass", Spec("body_mass", "bob"), 0.8).Bounds(0.05, 10).Log()};
  c.x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
  c.x0.qvel = Eigen::VectorXd::Zero(1);
  c.amplitude = 2.0;
  c.positions = {0};
  c.robot.sensor_rate = 250;
  c.robot.control_rate = 50;
  c.robot.control_delay = 0.015;
  c.robot.jitter = 0.0008;
  c.robot.quantum = 2 * M_PI / 4096;  // a 12-bit encoder
  c.robot.sigma = 1e-4;
  return c;
}

inline Case CartPole() {
  Case c;
  c.file = "cartpole.xml";
  c.truth = {{"pole_mass", Spec("body_mass", "pole"), 0.25},
             {"cart_damping", Spec("joint_damping", "slider"), 0.7}};
  c.start = {
      FitParameter("pole_mass", Spec("body_mass", "pole"), 0.15).Bounds(0.01, 5).Log(),
      FitParameter("cart_damping", Spec("joint_damping", "slider"), 0.3).Bounds(1e-3, 10).Log()};
  c.x0.qpos = Eigen::Vector2d(0.0, M_PI);
  c.x0.qvel = Eigen::Vector2d::Zero();
  c.amplitude = 4.0;
  c.positions = {0, 1};
  c.robot.sensor_rate = 200;
  c.robot.control_rate = 50;
  c.robot.control_delay = 0.02;
  c.robot.jitter = 0.001;
  c.robot.quantum = 1e-4;  // m and rad
  c.robot.sigma = 1e-4;
  c.robot.duration = 5;
  return c;
}

inline Case Arm5() {
  Case c;
  c.file = "arm5.xml";
  const double truth[5] = {0.5, 0.4, 0.3, 0.2, 0.1};
  for (int j = 0; j < 5; ++j) {
    const std::string joint = "j" + std::to_string(j + 1);
    c.truth.push_back({joint + "_armature", Spec("joint_armature", joint), truth[j]});
    c.start.push_back(FitParameter(joint + "_armature", Spec("joint_armature", joint), 0.05)
                          .Bounds(1e-4, 5)
                          .Log());
  }
  c.amplitude = 3.0;
  c.positions = {0, 1, 2, 3, 4};
  c.segment_steps = 250;  // multiple shooting, 0.5 s segments
  c.robot.sensor_rate = 100;
  c.robot.control_rate = 100;
  c.robot.control_delay = 0.005;
  c.robot.jitter = 0.0005;
  c.robot.quantum = 2 * M_PI / 16384;  // 14-bit encoders
  c.robot.sigma = 1e-4;
  c.robot.duration = 3;
  return c;
}

}  // namespace test
}  // namespace mjsysid
