// A fitted control transport delay through the real command line (issue 14, docs/real-logs.md):
// a pendulum log whose commands come from a 50 Hz controller and reach the motor 13 ms late,
// fitted with `controls: {delay: {initial, fit: true, bounds}}` next to the hinge damping; and
// bad `controls` specs exiting 2 naming file, line and key; a hold per actuator applied; the
// warning when a delay reaches before the first logged command (`controls.before`); a delay's
// truth through `sysid simulate` and the fit's result.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "core/mujoco_env.h"
#include "sysid/data/sample_grid.h"
#include "sysid/io/log.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"
#include "tests/log_builder.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using test::Sysid;

// the number after "value: " following `key` in result.yaml text (NaN when absent)
double ValueAfter(const std::string& text, const std::string& key) {
  const size_t at = text.find(key);
  if (at == std::string::npos) return std::nan("");
  const size_t v = text.find("value: ", at);
  return v == std::string::npos ? std::nan("") : std::stod(text.substr(v + 7));
}

// the number after "truth: " in the entry of `key` in result.yaml text (NaN when absent)
double TruthAfter(const std::string& text, const std::string& key) {
  const size_t at = text.find(key);
  if (at == std::string::npos) return std::nan("");
  const size_t next = text.find("- name:", at + key.size());
  const size_t v = text.find("truth: ", at);
  return v == std::string::npos || v > next ? std::nan("") : std::stod(text.substr(v + 7));
}

class ControlDelayCliTest : public ::testing::Test {
 protected:
  // truth: hinge damping 0.12 (the model says 0.05), from the reference state; a multi-sine
  // commanded at 50 Hz (every 10th step of 2 ms), held, reaching the motor 13 ms (6.5 steps)
  // late: the steps' controls are the fit's own zero-order hold (sysid/data/sample_grid.h) of the
  // commands at that delay; 1500 steps, sensors at every step, noise 1e-3 (seed 5)
  void SetUp() override {
    dir_ = test::FreshTempDir("ctrl_delay");
    ModelPtr m = LoadModel(test::PendulumModelPath());
    const double dt = m->opt.timestep;
    const int T = 1500;
    io::Sequence s;
    s.name = "run1";
    s.actuator_names = {"torque"};
    test::SetControlsEvery(test::PendulumTorque(*m, T), dt, 10, &s);
    s.time.resize(T);
    for (int k = 0; k < T; ++k) s.time[k] = k * dt;
    const SampleGrid grid =
        BuildSampleGrid(s.time, T, 0.0, s.ctrl, s.ctrl_time, {}, {0.013}, dt, "");
    const RowMatrix y = test::MeasurePendulum(*m, InitialState(), grid.ctrl.topRows(T));
    s.sensor_names = {"angle", "rate"};
    s.sensor_dims = {1, 1};
    s.sensordata = y;
    io::Log log;
    log.sequences.push_back(s);
    log_ = dir_ + "/robot.h5";
    io::WriteLog(log_, log);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // fits the hinge damping from 0.05 with sigmas equal to the noise, and the `controls` block
  std::string Experiment(const std::string& controls) {
    const std::string path = dir_ + "/fit.yaml";
    test::WriteFile(path, test::PendulumDampingYaml(log_) + "controls:\n" + controls);
    return path;
  }

  std::string dir_, log_;
};

// truth 13 ms, start 5 ms, bounds [0, 50 ms]: exit 0, converged, the delay within one model step
// (2 ms) of its truth and the damping within 1 %, both in result.yaml and the CLI summary
TEST_F(ControlDelayCliTest, FitsTheSharedDelay) {
  const std::string exp = Experiment("  delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}\n");
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out");
  ASSERT_EQ(fit.code, 0) << fit.output;
  EXPECT_NE(fit.output.find("controls.delay"), std::string::npos) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const double delay = ValueAfter(result, "name: controls.delay");
  const double damping = ValueAfter(result, "name: damping");
  std::printf("[ measured ] controls.delay %.6g s (truth 0.013), damping %.6g (truth 0.12)\n",
              delay, damping);
  EXPECT_NEAR(delay, 0.013, 0.002);
  EXPECT_NEAR(damping, 0.12, 0.0012);
  EXPECT_NE(result.find("status: converged"), std::string::npos) << result;
}

// per actuator, the pendulum's one actuator named: the same estimate under its own name
TEST_F(ControlDelayCliTest, FitsAnActuatorsOwnDelay) {
  const std::string exp = Experiment(
      "  hold: {torque: zoh}\n"
      "  delay: {torque: {initial: 0.005, fit: true, bounds: [0, 0.05]}}\n");
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  ASSERT_EQ(fit.code, 0) << fit.output;
  const double delay =
      ValueAfter(test::ReadFile(dir_ + "/out/result.yaml"), "name: controls.delay.torque");
  EXPECT_NEAR(delay, 0.013, 0.002);
}

// the hold per actuator reaches the fit: with the delay given (13 ms), `hold: {torque: zoh}`
// recovers the damping within 0.5 % (exit 0), `hold: {torque: linear}` (the 50 Hz commands
// interpolated instead of held) does not, and its residuals exceed the noise (model_mismatch)
TEST_F(ControlDelayCliTest, HoldPerActuatorIsApplied) {
  double estimate[2];
  for (int linear = 0; linear < 2; ++linear) {
    const std::string exp =
        Experiment(std::string("  hold: {torque: ") + (linear ? "linear" : "zoh") +
                   "}\n  delay: {torque: 0.013}\n");
    const test::CliRun fit =
        Sysid("fit " + exp + " --out " + dir_ + "/out" + std::to_string(linear) + " --quiet");
    // linear: the residuals far above the noise (sigmas given): model_mismatch, exit 3
    ASSERT_EQ(fit.code, linear ? 3 : 0) << fit.output;
    estimate[linear] = ValueAfter(
        test::ReadFile(dir_ + "/out" + std::to_string(linear) + "/result.yaml"), "name: damping");
  }
  std::printf("[ measured ] damping: zoh %.6g, linear %.6g (truth 0.12)\n", estimate[0],
              estimate[1]);
  EXPECT_NEAR(estimate[0], 0.12, 0.0006);
  EXPECT_GT(std::abs(estimate[1] - 0.12), 0.0012);
}

// `sysid check` lists the fitted control delays with the parameters: the shared one, one per
// actuator; a given (not fitted) delay is not a fitted value and is not listed
TEST_F(ControlDelayCliTest, CheckListsFittedDelaysWithTheParameters) {
  const std::string prefix = "  parameters damping (joint_damping hinge)";
  const struct {
    std::string controls, line;
  } cases[] = {
      {"  delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}\n",
       prefix + ", controls.delay (control delay of every actuator)\n"},
      {"  delay: {torque: {initial: 0.005, fit: true, bounds: [0, 0.05]}}\n",
       prefix + ", controls.delay.torque (control delay torque)\n"},
      {"  delay: {torque: 0.013}\n", prefix + "\n"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.controls);
    const test::CliRun check = Sysid("check --no-jacobians " + Experiment(c.controls));
    EXPECT_EQ(check.code, 0) << check.output;
    EXPECT_NE(check.output.find(c.line), std::string::npos) << check.output;
  }
}

// bad specs: exit 2 naming the file, the line and the key
TEST_F(ControlDelayCliTest, BadSpecsExitTwoNamingFileLineAndKey) {
  struct Bad {
    std::string controls;
    std::string line;  // fit.yaml:<line>
    std::string message;
  };
  const Bad bad[] = {
      {"  delay: {initial: 0.01, fit: true, bounds: [-0.01, 0.05]}\n",
       "fit.yaml:9:", "controls.delay.bounds: a delay cannot be negative"},
      {"  delay: {motor: {initial: 0.01, fit: true}}\n",
       "fit.yaml:9:", "controls.delay.motor: no actuator named 'motor'"},
      {"  hold: {motor: linear}\n",
       "fit.yaml:9:", "controls.hold.motor: no actuator named 'motor'"},
      {"  delay: {initial: 0.07, fit: true, bounds: [0, 0.05]}\n",
       "fit.yaml:9:", "controls.delay.initial: 0.07 is outside bounds"},
      {"  delay: {torque: -0.01}\n", "fit.yaml:9:", "controls.delay.torque"},
      {"  before: bogus\n", "fit.yaml:9:", "controls.before: 'bogus' is not one of hold, zero"},
  };
  for (const Bad& b : bad) {
    SCOPED_TRACE(b.controls);
    for (const std::string& command : {"check --no-jacobians " + Experiment(b.controls),
                                       "fit " + Experiment(b.controls) + " --out " + dir_ + "/x"}) {
      const test::CliRun run = Sysid(command);
      EXPECT_EQ(run.code, 2) << run.output;
      EXPECT_NE(run.output.find(b.line), std::string::npos) << run.output;
      EXPECT_NE(run.output.find(b.message), std::string::npos) << run.output;
    }
  }
}

// The commands start with the first sample: a delay (given 13 ms: 6.5 steps) reaches before the
// first one, and the fit warns (CLI and result.yaml) how many steps use commands nobody logged,
// with the rule used (hold, or zero); a fitted delay up to its upper bound. A window from 0.1 s
// has logged commands from before it (at their own times, ctrl_time): no warning.
TEST_F(ControlDelayCliTest, WarnsWhenADelayReachesBeforeTheFirstCommand) {
  const std::string given =
      "sequence 'run1': the control delay 13 ms reaches before the first logged command (at "
      "0.000 s, first sample at 0.000 s): the first 7 steps use commands nobody logged "
      "(controls.before: hold holds the first one; log the commands from before the first "
      "sample, or start the fit later)";
  const struct {
    std::string controls, warning;
  } cases[] = {
      {"  delay: 0.013\n", given},
      {"  before: zero\n  delay: 0.013\n",
       "the first 7 steps use commands nobody logged (controls.before: zero gives them 0;"},
      {"  delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}\n",
       "the control delay controls.delay (fitted, up to its upper bound 50 ms) reaches before the "
       "first logged command (at 0.000 s, first sample at 0.000 s): up to the first 25 steps use "
       "commands nobody logged"},
  };
  int i = 0;
  for (const auto& c : cases) {
    SCOPED_TRACE(c.controls);
    const std::string out = dir_ + "/out" + std::to_string(i++);
    const test::CliRun fit = Sysid("fit " + Experiment(c.controls) + " --out " + out);
    EXPECT_NE(fit.output.find(c.warning), std::string::npos) << fit.output;
    EXPECT_NE(test::ReadFile(out + "/result.yaml").find("reaches before the first logged command"),
              std::string::npos);
  }
  std::printf("[ measured ] %s\n", given.c_str());
  const std::string window = dir_ + "/window.yaml";
  test::WriteFile(window, test::PendulumDampingYaml(log_) +
                              "sequences: [{name: run1, start: 0.1}]\ncontrols:\n  delay: 0.013\n");
  const test::CliRun fit = Sysid("fit " + window + " --out " + dir_ + "/outw");
  EXPECT_EQ(fit.code, 0) << fit.output;
  EXPECT_EQ(fit.output.find("before the first logged command"), std::string::npos) << fit.output;
  EXPECT_EQ(test::ReadFile(dir_ + "/outw/result.yaml").find("before the first logged command"),
            std::string::npos);
}

// A delay's truth: `sysid simulate` with `truth: {controls.delay: 0.012}` and the shared delay
// fitted (initial 5 ms, bounds [0, 50 ms]) logs truth.controls.delay 0.012 and the commands
// undelayed; the noise-free log fitted from 5 ms recovers 12 ms within one model step (2 ms) and
// the result's controls.delay row shows the truth 0.012
TEST_F(ControlDelayCliTest, SimulatedDelayTruthIsRecoveredAndShown) {
  const std::string exp = dir_ + "/sim.yaml";
  test::WriteFile(exp, test::PendulumDampingYaml(dir_ + "/sim.h5") +
                           "controls: {delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}}\n"
                           "simulate:\n"
                           "  truth: {damping: 0.12, controls.delay: 0.012}\n"
                           "  sequences: 1\n  steps: 1500\n  seed: 5\n"
                           "  excitation: {type: sines, amplitude: 3.0}\n");
  const test::CliRun sim = Sysid("simulate " + exp);
  ASSERT_EQ(sim.code, 0) << sim.output;
  EXPECT_NE(sim.output.find("truth       controls.delay = 0.012\n"), std::string::npos)
      << sim.output;
  const io::Log log = io::ReadLog(dir_ + "/sim.h5");
  EXPECT_EQ(std::stod(log.attributes.at("truth.controls.delay")), 0.012);
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out");
  ASSERT_EQ(fit.code, 0) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const double delay = ValueAfter(result, "name: controls.delay");
  const double damping = ValueAfter(result, "name: damping");
  std::printf("[ measured ] controls.delay %.6g s (truth 0.012), damping %.6g (truth 0.12)\n",
              delay, damping);
  EXPECT_NEAR(delay, 0.012, 0.002);
  EXPECT_EQ(TruthAfter(result, "name: controls.delay"), 0.012);
  EXPECT_EQ(TruthAfter(result, "name: damping"), 0.12);
  // the CLI summary's truth column
  EXPECT_NE(fit.output.find("0.012"), std::string::npos) << fit.output;
}

}  // namespace
}  // namespace mjsysid
