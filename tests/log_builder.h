// The pendulum logs of the command-line tests (tests/tools/*_cli_test.cc): models/pendulum.xml
// (hinge `hinge`, motor `torque`, sensors `angle` and `rate`, 2 ms steps) simulated at a true
// hinge damping of 0.12 (the model says 0.05) under test::Excitation's multi-sine (amplitude 2,
// seed 4), sensors with noise 1e-3 (seed 5); and the experiment that fits the damping back.
#pragma once

#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/state.h"
#include "sysid/io/log.h"
#include "tests/test_util.h"

namespace mjsysid::test {

// models/pendulum.xml
inline std::string PendulumModelPath() { return std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml"; }

// the truth of every pendulum log: hinge damping 0.12 (the model says 0.05)
inline std::vector<Truth> PendulumTruth() {
  return {{"damping", Spec("joint_damping", "hinge"), 0.12}};
}

// the multi-sine torque, T x 1, one row a step, each value held for `hold` steps (a controller
// running at 1 / (hold * timestep)); hold 1: a new value at every step
inline RowMatrix PendulumTorque(const mjModel& m, int T, int hold = 1) {
  const RowMatrix smooth = Excitation(m, T, 2.0, 4);
  RowMatrix u(T, 1);
  for (int k = 0; k < T; ++k) u(k, 0) = smooth(k / hold * hold, 0);
  return u;
}

// the sensors (angle, rate), one row a step, from x0 under the step controls u at the truth, with
// noise 1e-3 (seed 5)
inline RowMatrix MeasurePendulum(const mjModel& m, const InitialState& x0, const RowMatrix& u) {
  return Measure(m, PendulumTruth(), x0, u, 1e-3, 5);
}

// the column of sensor `name` in a row of sensor values (its first component)
inline int SensorColumn(const mjModel& m, const char* name) {
  return m.sensor_adr[mj_name2id(&m, mjOBJ_SENSOR, name)];
}

// s's controls at their own times: rows 0, every, 2 every, ... of the step controls u (T x nu),
// at k * dt
inline void SetControlsEvery(const RowMatrix& u, double dt, int every, io::Sequence* s) {
  const int n = static_cast<int>(u.rows()) / every;
  s->ctrl_time.resize(n);
  s->ctrl.resize(n, u.cols());
  for (int j = 0; j < n; ++j) {
    s->ctrl_time[j] = (every * j) * dt;
    s->ctrl.row(j) = u.row(every * j);
  }
}

// an experiment (YAML text) fitting the hinge damping from 0.05 (bounds [0.001, 10], log
// transform) to the log `data`, with sigmas equal to the noise (1e-3 on angle and rate)
inline std::string PendulumDampingYaml(const std::string& data) {
  return "model: " + PendulumModelPath() + "\ndata: " + data +
         "\nsensors:\n"
         "  - {name: angle, sigma: 1.0e-3}\n"
         "  - {name: rate, sigma: 1.0e-3}\n"
         "parameters:\n"
         "  - {name: damping, target: joint_damping, object: hinge, "
         "initial: 0.05, bounds: [0.001, 10], transform: log}\n";
}

}  // namespace mjsysid::test
