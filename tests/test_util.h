// Helpers shared by tests that build synthetic data (core, sysid and stress tests): parameter
// specs, multi-sine controls, and noisy sensor measurements from the true parameter values.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/state.h"

namespace mjsysid::test {

// two hinges in a chain driven by one motor on hinge1, no sensor (fitted from logged states)
inline constexpr char kChainXml[] = R"(
<mujoco model="chain">
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <body name="link1" pos="0 0 2">
      <joint name="hinge1" type="hinge" axis="0 1 0" damping="0.2"/>
      <geom name="link1" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="1.0"/>
      <body name="link2" pos="0 0 -0.5">
        <joint name="hinge2" type="hinge" axis="0 1 0" damping="0.1"/>
        <geom name="link2" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="0.8"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="torque1" joint="hinge1" gear="1"/>
  </actuator>
</mujoco>)";

inline ParameterSpec Spec(const std::string& kind, const std::string& object, int index = 0) {
  ParameterSpec s;
  s.kind = kind;
  s.object = object;
  s.index = index;
  return s;
}

// multi-sine controls, different per actuator and per seed: offset + amplitude * mean of three
// sines at 0.4, 1.1, 2.3 Hz (scaled per actuator) with random phases
inline RowMatrix Excitation(const mjModel& m, int T, double amplitude, int seed,
                            double offset = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phase(0, 2 * M_PI);
  RowMatrix u(T, m.nu);
  const double freqs[3] = {0.4, 1.1, 2.3};
  for (int i = 0; i < m.nu; ++i) {
    double ph[3];
    for (double& p : ph) p = phase(rng);
    for (int k = 0; k < T; ++k) {
      double v = 0;
      for (int f = 0; f < 3; ++f) {
        v += std::sin(2 * M_PI * freqs[f] * (1 + 0.2 * i) * k * m.opt.timestep + ph[f]) / 3;
      }
      u(k, i) = offset + amplitude * v;
    }
  }
  return u;
}

struct Truth {
  std::string name;
  ParameterSpec spec;
  double value;
};

// a simulator of m with `truth`'s parameters at their true values (the model's own with none)
inline std::unique_ptr<Simulator> TrueSimulator(const mjModel& m, const std::vector<Truth>& truth) {
  std::vector<ParameterSpec> specs;
  Eigen::VectorXd values(truth.size());
  for (size_t i = 0; i < truth.size(); ++i) {
    specs.push_back(truth[i].spec);
    values[i] = truth[i].value;
  }
  auto sim = std::make_unique<Simulator>(m, specs);
  if (!truth.empty()) sim->SetParameters(values);
  return sim;
}

// rollouts and Jacobians (options jo) of simulators a and b on sequence in, compared bit for bit:
// for two simulators that must compute the same numbers by different paths (reduced model,
// encoder copies)
inline void ExpectSameSimulation(Simulator& a, Simulator& b, const SequenceInput& in,
                                 const JacobianOptions& jo) {
  std::vector<Trajectory> ta, tb;
  std::vector<Sensitivity> sa, sb;
  a.RolloutAndJacobians({in}, jo, &ta, &sa);
  b.RolloutAndJacobians({in}, jo, &tb, &sb);
  EXPECT_TRUE(ta[0].states == tb[0].states);
  EXPECT_TRUE(ta[0].sensors == tb[0].sensors);
  EXPECT_EQ(ta[0].ncon, tb[0].ncon);
  EXPECT_TRUE(sa[0].DyDp == sb[0].DyDp);
  EXPECT_TRUE(sa[0].DxDp == sb[0].DxDp);
  EXPECT_EQ(sa[0].kinks, sb[0].kinks);
  EXPECT_GT(sa[0].DxDp.norm(), 0.0);
}

// sensors of m with the true parameter values, plus Gaussian noise sigma (all channels)
inline RowMatrix Measure(const mjModel& m, const std::vector<Truth>& truth, const InitialState& x0,
                         const RowMatrix& ctrl, double sigma, int seed) {
  const std::unique_ptr<Simulator> sim = TrueSimulator(m, truth);
  RowMatrix y = sim->Rollout(SequenceInput{x0, ctrl}).sensors;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, sigma);
  if (sigma > 0) {
    for (Eigen::Index i = 0; i < y.size(); ++i) y.data()[i] += noise(rng);
  }
  return y;
}

// the MJCF template with every "{key}" replaced by values.at(key) (keys in values only)
inline std::string FillTemplate(std::string xml, const std::map<std::string, std::string>& values) {
  for (const auto& [key, value] : values) {
    const std::string token = "{" + key + "}";
    for (size_t pos = xml.find(token); pos != std::string::npos; pos = xml.find(token)) {
      xml.replace(pos, token.size(), value);
    }
  }
  return xml;
}

// `steps` steps of a model with four actuators (the writer tests' scene) from its reference state
// under sines of angular rate w per step (slower or faster per actuator): the physics vectors
// x_1..x_steps, each followed by the sensor values after its step when with_sensors; expects no
// simulation warning
inline std::vector<double> SineRollout(const mjModel& m, int steps, double w,
                                       bool with_sensors = false) {
  DataPtr d = MakeData(m);
  const StateDims dims(m);
  const int row = dims.nphys + (with_sensors ? dims.ns : 0);
  std::vector<double> out(static_cast<size_t>(steps) * row);
  for (int k = 0; k < steps; ++k) {
    d->ctrl[0] = 2.0 * std::sin(w * k);
    d->ctrl[1] = 1.5 * std::sin(0.75 * w * k + 1);
    d->ctrl[2] = 8.0 + 4.0 * std::sin(0.5 * w * k);
    d->ctrl[3] = 0.2 * std::sin(1.5 * w * k);
    mj_step(&m, d.get());
    double* x = out.data() + static_cast<size_t>(k) * row;
    GetPhysics(m, *d, x);
    if (with_sensors) std::copy(d->sensordata, d->sensordata + dims.ns, x + dims.nphys);
  }
  EXPECT_EQ(SimulationWarnings(*d), "");
  return out;
}

inline double MaxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

}  // namespace mjsysid::test
