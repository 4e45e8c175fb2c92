#include "sysid/io/experiment.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "tests/temp_dir_test.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;

const std::string kModels = MJSYSID_MODELS_DIR;
constexpr double kInf = std::numeric_limits<double>::infinity();

// a fresh directory per test, removed afterwards
class ExperimentTest : public test::TempDirTest {
 protected:
  // writes text to dir_/relative and returns the full path
  std::string Write(const std::string& relative, const std::string& text) {
    const fs::path path = dir_ / relative;
    fs::create_directories(path.parent_path());
    std::ofstream(path) << text;
    return path.string();
  }

  // loads text written to dir_/exp.yaml and expects a ConfigError at line:column whose message
  // and hint contain the given parts
  void ExpectError(const std::string& text, int line, int column, const std::string& message,
                   const std::string& hint = {}) {
    const std::string path = Write("exp.yaml", text);
    try {
      LoadExperiment(path);
      ADD_FAILURE() << "expected a ConfigError containing '" << message << "'";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.file(), path) << e.what();
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_EQ(e.column(), column) << e.what();
      EXPECT_NE(e.message().find(message), std::string::npos) << e.what();
      EXPECT_NE(e.hint().find(hint), std::string::npos) << e.what();
      const std::string prefix =
          path + ":" + std::to_string(line) + ":" + std::to_string(column) + ": ";
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
    }
  }
};

// a small valid experiment for the pendulum model
const char kPendulum[] = R"(model: pendulum.xml
parameters:
  - {name: bob_mass, target: body_mass, object: bob, initial: 1.0}
)";

// -------------------------------------------------------------------------------------------
// well-formed files

TEST_F(ExperimentTest, FullExampleParsesEveryField) {
  const std::string path = Write("exp/pendulum.yaml", R"(# every key of the schema
version: 1
name: pendulum_damping
model: ../models/pendulum.xml
data:
  - logs/pendulum.h5
  - /abs/other.h5
sequences: [seq0, seq1]
sensor_time: post
sensors:
  - {name: angle, sigma: 0.01}
  - {name: rate, weight: 0.5}
parameters:
  - name: bob_mass
    target: body_mass
    object: bob
    initial: 2.0
    bounds: [0.1, 10.0]
    transform: log
    prior: {mean: 1.0, sigma: 0.5}
  - name: damping
    target: field
    field: dof_damping
    index: 0
    initial: 0.05
    bounds: [-.inf, .inf]
    transform: scale
    scale: 0.1
measurement:
  - sensor: angle
    delay: {initial: 0.01, fit: true, bounds: [0, 0.05]}
    gain: {initial: 1.0, fit: false}
    bias: {initial: 0.0, fit: true}
initial_state: {estimate: true}
multiple_shooting: {segment_steps: 50, continuity_weight: 2.5}
solver:
  max_iterations: 30
  function_tolerance: 1.0e-8
  gradient_tolerance: 1.0e-9
  parameter_tolerance: 1.0e-7
  jacobian: whole_rollout
  differences: central
  relative_step: 1.0e-5
  threads: 4
  loss: {type: huber, scale: 0.2}
  verbose: false
simulate:
  truth: {bob_mass: 1.0, damping: 0.07}
  sequences: 3
  steps: 500
  seed: 7
  excitation:
    type: chirp
    amplitude: 2.0
    f0: 0.2
    f1: 4.0
  noise: {angle: 0.01, rate: 0.0}
  initial_state: {qpos: [0.3], qvel: [0.0]}
output: results/pendulum
)");
  const ExperimentConfig c = LoadExperiment(path);
  const fs::path exp_dir = dir_ / "exp";

  EXPECT_EQ(c.version, 1);
  EXPECT_EQ(c.name, "pendulum_damping");
  EXPECT_EQ(c.source_file, path);
  EXPECT_EQ(c.base_dir, exp_dir.string());
  ASSERT_EQ(c.models.size(), 1u);
  EXPECT_FALSE(c.model_list);
  EXPECT_EQ(c.models[0].name, "pendulum");
  EXPECT_EQ(c.models[0].path, (dir_ / "models/pendulum.xml").string());
  EXPECT_EQ(c.models[0].marks.self.line, 4);
  EXPECT_EQ(c.models[0].marks.self.column, 8);
  ASSERT_EQ(c.data.size(), 2u);
  EXPECT_EQ(c.data[0].path, (exp_dir / "logs/pendulum.h5").string());
  EXPECT_EQ(c.data[1].path, "/abs/other.h5");
  EXPECT_EQ(c.data[0].mark.line, 6);
  EXPECT_EQ(c.data[0].mark.column, 5);
  ASSERT_EQ(c.sequences.size(), 2u);
  EXPECT_EQ(c.sequences[1].name, "seq1");
  EXPECT_EQ(c.sequences[1].model, "");
  EXPECT_EQ(c.sensor_time, SensorTime::kPost);

  ASSERT_EQ(c.sensors.size(), 2u);
  EXPECT_EQ(c.sensors[0].name, "angle");
  ASSERT_TRUE(c.sensors[0].sigma.has_value());
  EXPECT_DOUBLE_EQ(*c.sensors[0].sigma, 0.01);
  EXPECT_DOUBLE_EQ(c.sensors[0].ResidualWeight(), 100.0);
  EXPECT_FALSE(c.sensors[1].sigma.has_value());
  EXPECT_DOUBLE_EQ(c.sensors[1].weight, 0.5);
  EXPECT_DOUBLE_EQ(c.sensors[1].ResidualWeight(), 0.5);

  ASSERT_EQ(c.parameters.size(), 2u);
  const ParameterSpec& m = c.parameters[0];
  EXPECT_EQ(m.name, "bob_mass");
  EXPECT_EQ(m.target.kind, "body_mass");
  EXPECT_EQ(m.target.label, "bob_mass");
  EXPECT_EQ(m.target.object, "bob");
  EXPECT_EQ(m.target.index, 0);
  EXPECT_DOUBLE_EQ(m.initial, 2.0);
  EXPECT_DOUBLE_EQ(m.lower, 0.1);
  EXPECT_DOUBLE_EQ(m.upper, 10.0);
  EXPECT_EQ(m.transform, Transform::kLog);
  ASSERT_TRUE(m.has_prior);
  EXPECT_DOUBLE_EQ(m.prior_mean, 1.0);
  EXPECT_DOUBLE_EQ(m.prior_sigma, 0.5);
  EXPECT_TRUE(m.models.empty());
  EXPECT_EQ(m.marks.self.line, 14);
  EXPECT_EQ(m.marks.self.column, 5);
  EXPECT_EQ(m.marks.Of("object").line, 16);
  EXPECT_EQ(m.marks.Of("object").column, 13);
  const ParameterSpec& d = c.parameters[1];
  EXPECT_EQ(d.target.kind, "field");
  EXPECT_EQ(d.target.field, "dof_damping");
  EXPECT_EQ(d.target.object, "");
  EXPECT_EQ(d.lower, -kInf);
  EXPECT_EQ(d.upper, kInf);
  EXPECT_EQ(d.transform, Transform::kScale);
  EXPECT_DOUBLE_EQ(d.scale, 0.1);
  EXPECT_FALSE(d.has_prior);
  EXPECT_EQ(c.FindParameter("damping"), &c.parameters[1]);
  EXPECT_EQ(c.FindParameter("nope"), nullptr);

  ASSERT_EQ(c.measurement.size(), 1u);
  const MeasurementSpec& ms = c.measurement[0];
  EXPECT_EQ(ms.sensor, "angle");
  EXPECT_DOUBLE_EQ(ms.delay.initial, 0.01);
  EXPECT_TRUE(ms.delay.fit);
  EXPECT_DOUBLE_EQ(ms.delay.lower, 0.0);
  EXPECT_DOUBLE_EQ(ms.delay.upper, 0.05);
  EXPECT_DOUBLE_EQ(ms.gain.initial, 1.0);
  EXPECT_FALSE(ms.gain.fit);
  EXPECT_TRUE(ms.bias.fit);
  EXPECT_EQ(ms.bias.lower, -kInf);

  EXPECT_TRUE(c.options.estimate_initial_state);
  EXPECT_EQ(c.options.segment_steps, 50);
  EXPECT_DOUBLE_EQ(c.options.continuity_weight, 2.5);

  EXPECT_EQ(c.options.max_iterations, 30);
  EXPECT_DOUBLE_EQ(c.options.function_tolerance, 1e-8);
  EXPECT_DOUBLE_EQ(c.options.gradient_tolerance, 1e-9);
  EXPECT_DOUBLE_EQ(c.options.parameter_tolerance, 1e-7);
  EXPECT_EQ(c.options.jacobian.mode, JacobianMode::kWholeRollout);
  EXPECT_TRUE(c.options.jacobian.central);
  EXPECT_DOUBLE_EQ(c.options.jacobian.relative_step, 1e-5);
  EXPECT_EQ(c.options.threads, 4);
  EXPECT_EQ(c.options.loss, LossType::kHuber);
  EXPECT_DOUBLE_EQ(c.options.loss_scale, 0.2);
  EXPECT_FALSE(c.options.verbose);

  const SimulateOptions& s = c.simulate;
  ASSERT_EQ(s.truth.size(), 2u);
  EXPECT_EQ(s.truth[1].name, "damping");
  EXPECT_DOUBLE_EQ(s.truth[1].value, 0.07);
  EXPECT_EQ(s.sequences, 3);
  EXPECT_EQ(s.steps, 500);
  EXPECT_EQ(s.seed, 7u);
  ASSERT_EQ(s.excitation.size(), 1u);
  EXPECT_EQ(s.excitation[0].actuator, "");
  EXPECT_EQ(s.excitation[0].type, ExcitationType::kChirp);
  EXPECT_DOUBLE_EQ(s.excitation[0].amplitude, 2.0);
  EXPECT_DOUBLE_EQ(s.excitation[0].f0, 0.2);
  EXPECT_DOUBLE_EQ(s.excitation[0].f1, 4.0);
  ASSERT_EQ(s.noise.size(), 2u);
  EXPECT_EQ(s.noise[0].name, "angle");
  EXPECT_DOUBLE_EQ(s.noise[0].value, 0.01);
  EXPECT_EQ(s.initial_state.qpos, std::vector<double>{0.3});
  EXPECT_EQ(s.initial_state.qvel, std::vector<double>{0.0});
  EXPECT_EQ(c.output, (exp_dir / "results/pendulum").string());
}

// multiple_shooting: auto (scalar), {segment_steps: auto|0|N}; anything else names the value
TEST_F(ExperimentTest, MultipleShootingAutoForms) {
  const std::string base = kPendulum;
  EXPECT_EQ(
      LoadExperiment(Write("a.yaml", base + "multiple_shooting: auto\n")).options.segment_steps,
      -1);
  const ExperimentConfig c = LoadExperiment(
      Write("b.yaml", base + "multiple_shooting: {segment_steps: auto, continuity_weight: 3}\n"));
  EXPECT_EQ(c.options.segment_steps, -1);
  EXPECT_DOUBLE_EQ(c.options.continuity_weight, 3.0);
  EXPECT_EQ(LoadExperiment(Write("c.yaml", base + "multiple_shooting: {segment_steps: 0}\n"))
                .options.segment_steps,
            0);
  ExpectError(base + "multiple_shooting: sometimes\n", 4, 20, "expected 'auto' or a map",
              "segment_steps: auto|0|N");
}

// solver.global: auto (default) | off, solver.global_budget > 0 (default 3 local fits); other
// values name the key, its line and the forms
TEST_F(ExperimentTest, GlobalStageKeys) {
  const std::string base = kPendulum;
  const ExperimentConfig d = LoadExperiment(Write("d.yaml", base));
  EXPECT_TRUE(d.options.global_stage);
  EXPECT_DOUBLE_EQ(d.options.global_budget, 3.0);
  const ExperimentConfig c =
      LoadExperiment(Write("c.yaml", base + "solver: {global: off, global_budget: 1.5}\n"));
  EXPECT_FALSE(c.options.global_stage);
  EXPECT_DOUBLE_EQ(c.options.global_budget, 1.5);
  EXPECT_TRUE(
      LoadExperiment(Write("a.yaml", base + "solver: {global: auto}\n")).options.global_stage);
  ExpectError(base + "solver: {global: sometimes}\n", 4, 18,
              "solver.global: 'sometimes' is not one of", "allowed values: auto, off");
  ExpectError(base + "solver: {global_budget: 0}\n", 4, 25, "solver.global_budget");
}

// multiple_shooting: continuity_scale relative (default) | absolute, jumping_sensors omit (default)
// | fit; other values name the key, its line and the forms
TEST_F(ExperimentTest, MultipleShootingContinuityScaleAndJumpingSensors) {
  const std::string base = kPendulum;
  const ExperimentConfig d = LoadExperiment(Write("d.yaml", base));
  EXPECT_TRUE(d.options.continuity_relative);
  EXPECT_FALSE(d.options.fit_jumping_sensors);
  const ExperimentConfig c = LoadExperiment(Write(
      "e.yaml", base + "multiple_shooting: {continuity_scale: absolute, jumping_sensors: fit}\n"));
  EXPECT_FALSE(c.options.continuity_relative);
  EXPECT_TRUE(c.options.fit_jumping_sensors);
  ExpectError(base + "multiple_shooting: {continuity_scale: sensors}\n", 4, 39,
              "expected 'relative' or 'absolute'", "continuity_scale: relative|absolute");
  ExpectError(base + "multiple_shooting: {jumping_sensors: drop}\n", 4, 38,
              "expected 'omit' or 'fit'", "jumping_sensors: omit|fit");
}

// sensors[].sigma: auto (the noise estimated from the log, sysid/fit/sigma_from_log.h): no stated
// sigma, the sensor marked; another word or a quoted value names the key and the forms
TEST_F(ExperimentTest, SensorSigmaAuto) {
  const std::string head = "model: pendulum.xml\nsensors:\n";
  const std::string tail =
      "parameters:\n  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  const ExperimentConfig c = LoadExperiment(Write(
      "auto.yaml", head + "  - {name: angle, sigma: auto}\n  - {name: rate, sigma: 0.1}\n" + tail));
  ASSERT_EQ(c.sensors.size(), 2u);
  EXPECT_TRUE(c.sensors[0].sigma_from_log);
  EXPECT_FALSE(c.sensors[0].sigma.has_value());
  EXPECT_FALSE(c.sensors[1].sigma_from_log);
  ExpectError(head + "  - {name: angle, sigma: atuo}\n" + tail, 3, 26,
              "sensors[0].sigma: expected a number > 0 or auto, got the string 'atuo'",
              "or auto (estimated from the log)");
  ExpectError(head + "  - {name: angle, sigma: auto, weight: 2}\n" + tail, 3, 32,
              "give either 'sigma' or 'weight', not both");
}

// multiple_shooting: hold_states_first true (default) | false, event_window 0 (default, off) | k
// in 0..1000; other values name the key, its line and the forms
TEST_F(ExperimentTest, MultipleShootingHeldStatesAndEventWindow) {
  const std::string base = kPendulum;
  const ExperimentConfig d = LoadExperiment(Write("d.yaml", base));
  EXPECT_TRUE(d.options.hold_states_first);
  EXPECT_EQ(d.options.event_window, 0);
  const ExperimentConfig c = LoadExperiment(
      Write("e.yaml", base + "multiple_shooting: {hold_states_first: false, event_window: 3}\n"));
  EXPECT_FALSE(c.options.hold_states_first);
  EXPECT_EQ(c.options.event_window, 3);
  EXPECT_EQ(c.options.segment_steps, -1);  // still auto
  ExpectError(base + "multiple_shooting: {hold_states_first: maybe}\n", 4, 40,
              "expected true or false", "hold_states_first: true|false");
  ExpectError(base + "multiple_shooting: {event_window: -1}\n", 4, 35, "must be in 0..1000");
}

TEST_F(ExperimentTest, MinimalFileGetsTheDefaults) {
  const ExperimentConfig c = LoadExperiment(Write("swing.yaml", kPendulum));
  EXPECT_EQ(c.name, "swing");
  EXPECT_EQ(c.models[0].path, (dir_ / "pendulum.xml").string());
  EXPECT_TRUE(c.data.empty());
  EXPECT_TRUE(c.sequences.empty());
  EXPECT_EQ(c.sensor_time, SensorTime::kPre);
  EXPECT_TRUE(c.sensors.empty());
  const ParameterSpec& p = c.parameters.at(0);
  EXPECT_EQ(p.target.index, 0);
  EXPECT_EQ(p.lower, -kInf);
  EXPECT_EQ(p.upper, kInf);
  EXPECT_EQ(p.transform, Transform::kNone);
  EXPECT_DOUBLE_EQ(p.scale, 1.0);
  EXPECT_TRUE(c.measurement.empty());
  EXPECT_FALSE(c.options.estimate_initial_state);
  EXPECT_EQ(c.options.segment_steps, -1);  // auto (multiple_shooting absent)
  EXPECT_DOUBLE_EQ(c.options.continuity_weight, 1.0);
  EXPECT_EQ(c.options.max_iterations, 100);
  EXPECT_DOUBLE_EQ(c.options.function_tolerance, 1e-10);
  EXPECT_DOUBLE_EQ(c.options.gradient_tolerance, 1e-10);
  EXPECT_DOUBLE_EQ(c.options.parameter_tolerance, 1e-10);
  EXPECT_EQ(c.options.jacobian.mode, JacobianMode::kAuto);
  EXPECT_FALSE(c.options.jacobian.central);
  EXPECT_DOUBLE_EQ(c.options.jacobian.relative_step, 1e-6);
  EXPECT_EQ(c.options.threads, 0);
  EXPECT_EQ(c.options.loss, LossType::kNone);
  EXPECT_DOUBLE_EQ(c.options.loss_scale, 1.0);
  EXPECT_TRUE(c.options.verbose);
  EXPECT_EQ(c.simulate.marks.self.line, 0);
  EXPECT_EQ(c.simulate.sequences, 2);
  EXPECT_EQ(c.simulate.steps, 2000);
  EXPECT_EQ(c.simulate.seed, 42u);
  ASSERT_EQ(c.simulate.excitation.size(), 1u);
  EXPECT_EQ(c.simulate.excitation[0].type, ExcitationType::kSines);
  EXPECT_EQ(c.simulate.excitation[0].frequencies, (std::vector<double>{0.5, 1.3, 2.9}));
  EXPECT_EQ(c.output, (dir_ / "results/swing").string());
}

TEST_F(ExperimentTest, SeveralModelsSequencesAndPerModelParameters) {
  const ExperimentConfig c = LoadExperiment(Write("sub/arm.yaml", R"(models:
  - {name: nominal, path: ../models/arm5.xml}
  - {name: payload, path: /opt/arm5_payload.xml}
sequences: [payload/seq0, seq1]
sensors: [angle, rate]
parameters:
  - {name: load, target: body_mass, object: hand, initial: 0.5, models: [payload]}
  - {name: damp, target: joint_damping, object: j1, initial: 0.1}
simulate:
  excitation:
    - {actuator: m1, type: prbs, switch_period: 0.05}
    - {actuator: m2, type: zero}
)"));
  EXPECT_TRUE(c.model_list);
  ASSERT_EQ(c.models.size(), 2u);
  EXPECT_EQ(c.models[0].path, (dir_ / "models/arm5.xml").string());
  EXPECT_EQ(c.models[1].path, "/opt/arm5_payload.xml");
  EXPECT_EQ(c.FindModel("payload"), &c.models[1]);
  ASSERT_EQ(c.sequences.size(), 2u);
  EXPECT_EQ(c.sequences[0].model, "payload");
  EXPECT_EQ(c.sequences[0].name, "seq0");
  EXPECT_EQ(c.sequences[1].model, "");
  ASSERT_EQ(c.sensors.size(), 2u);
  EXPECT_DOUBLE_EQ(c.sensors[1].ResidualWeight(), 1.0);
  EXPECT_FALSE(c.parameters[0].AppliesTo("nominal"));
  EXPECT_TRUE(c.parameters[0].AppliesTo("payload"));
  EXPECT_TRUE(c.parameters[1].AppliesTo("nominal"));
  ASSERT_EQ(c.simulate.excitation.size(), 2u);
  EXPECT_EQ(c.simulate.excitation[0].actuator, "m1");
  EXPECT_EQ(c.simulate.excitation[0].type, ExcitationType::kPrbs);
  EXPECT_DOUBLE_EQ(c.simulate.excitation[0].switch_period, 0.05);
  EXPECT_EQ(c.simulate.excitation[1].type, ExcitationType::kZero);
}

TEST_F(ExperimentTest, RelativePathsResolveAgainstTheYamlDirectory) {
  // parse from another working directory: the yaml's folder decides, not the cwd
  const std::string path = Write("a/b/exp.yaml", R"(model: ./m/../pendulum.xml
data: ../logs/run.h5
output: out
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)");
  struct ChangeDirectory {
    explicit ChangeDirectory(const fs::path& to) : from(fs::current_path()) {
      fs::current_path(to);
    }
    ~ChangeDirectory() { fs::current_path(from); }
    fs::path from;
  };
  ExperimentConfig c;
  {
    const ChangeDirectory cd(dir_ / "a");
    c = LoadExperiment("b/exp.yaml");
  }
  EXPECT_EQ(c.models[0].path, (dir_ / "a/b/pendulum.xml").string());
  ASSERT_EQ(c.data.size(), 1u);
  EXPECT_EQ(c.data[0].path, (dir_ / "a/logs/run.h5").string());
  EXPECT_EQ(c.output, (dir_ / "a/b/out").string());
  EXPECT_EQ(c.source_file, path);
}

TEST_F(ExperimentTest, ParseExperimentUsesThePathForMessagesAndPaths) {
  const ExperimentConfig c = ParseExperiment(kPendulum, "/some/where/run.yaml");
  EXPECT_EQ(c.name, "run");
  EXPECT_EQ(c.models[0].path, "/some/where/pendulum.xml");
  EXPECT_EQ(c.parameters[0].marks.self.file, "/some/where/run.yaml");
  try {
    ParseExperiment("model: x.xml\nparameters: 3\n", "/some/where/run.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(),
                 "/some/where/run.yaml:2:13: parameters: expected a list, got the number 3");
  }
}

TEST_F(ExperimentTest, ParseExperimentWithoutAPath) {
  const ExperimentConfig c = ParseExperiment(kPendulum, "");
  EXPECT_EQ(c.name, "experiment");
  EXPECT_EQ(c.models[0].path, (fs::current_path() / "pendulum.xml").string());
  try {
    ParseExperiment("model: [a\n", "");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "<experiment>");
    EXPECT_EQ(e.line(), 2);
  }
}

TEST_F(ExperimentTest, OnlyMeasurementParametersMayBeFitted) {
  const ExperimentConfig c = LoadExperiment(Write("exp.yaml", R"(model: pendulum.xml
measurement:
  - {sensor: angle, delay: {initial: 0.01, fit: true}}
)"));
  EXPECT_TRUE(c.parameters.empty());
  EXPECT_TRUE(c.measurement.at(0).delay.fit);
  EXPECT_DOUBLE_EQ(c.measurement.at(0).delay.lower, 0.0);
}

TEST(ParameterKindNamesTest, ListsEveryKindInEnumOrder) {
  const std::vector<std::string> expected = {"body_mass",
                                             "body_mass_inertia",
                                             "body_inertia",
                                             "body_com",
                                             "joint_damping",
                                             "joint_frictionloss",
                                             "joint_armature",
                                             "joint_stiffness",
                                             "geom_friction",
                                             "actuator_gain",
                                             "actuator_bias",
                                             "actuator_gear",
                                             "tendon_damping",
                                             "tendon_stiffness",
                                             "tendon_frictionloss",
                                             "tendon_lengthspring",
                                             "geom_solref",
                                             "geom_solimp",
                                             "pair_solref",
                                             "pair_solimp",
                                             "pair_friction",
                                             "actuator_kp",
                                             "actuator_kv",
                                             "actuator_ki",
                                             "body_inertial",
                                             "actuator_delay",
                                             "sensor_delay",
                                             "dcmotor_motorconst",
                                             "dcmotor_resistance",
                                             "dcmotor_inductance",
                                             "dcmotor_cogging",
                                             "dcmotor_lugre",
                                             "field"};
  EXPECT_EQ(ParameterKindNames(), expected);
  EXPECT_EQ(ParameterKindName(ParameterKind::kJointArmature), "joint_armature");
  EXPECT_EQ(ParameterKindName(ParameterKind::kField), "field");
}

TEST(ConfigErrorTest, FormatsPositionMessageAndHint) {
  const ConfigError with_hint(Mark{"a.yaml", 3, 7}, "bad thing", "do this");
  EXPECT_STREQ(with_hint.what(), "a.yaml:3:7: bad thing (hint: do this)");
  EXPECT_EQ(with_hint.file(), "a.yaml");
  EXPECT_EQ(with_hint.line(), 3);
  EXPECT_EQ(with_hint.column(), 7);
  const ConfigError no_hint(Mark{"a.yaml", 1, 1}, "bad");
  EXPECT_STREQ(no_hint.what(), "a.yaml:1:1: bad");
  const ConfigError no_position(Mark{"a.yaml", 0, 0}, "gone");
  EXPECT_STREQ(no_position.what(), "a.yaml: gone");
}

// -------------------------------------------------------------------------------------------
// errors: each at its file:line:column with its hint

// `controls`: the hold rule and transport delay of the logged commands (docs/real-logs.md)
TEST_F(ExperimentTest, ControlsHoldAndDelay) {
  const std::string base =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  const ExperimentConfig def = LoadExperiment(Write("exp.yaml", base));
  EXPECT_EQ(def.control_hold, ControlHold::kZeroOrder);
  EXPECT_EQ(def.control_delay, 0.0);
  const ExperimentConfig c =
      LoadExperiment(Write("exp.yaml", base + "controls: {hold: linear, delay: 0.015}\n"));
  EXPECT_EQ(c.control_hold, ControlHold::kLinear);
  EXPECT_EQ(c.control_delay, 0.015);
  ExpectError(base + "controls: {hold: foh}\n", 4, 18, "foh", "zoh");
  ExpectError(base + "controls: {delay: -0.01}\n", 4, 19, "-0.01");
}

// `controls` per actuator and fitted: the shared delay as {initial, fit, bounds} (fit: false is
// the plain given delay), actuator-keyed holds and delays (numbers or terms); a fitted delay alone
// is something to fit
TEST_F(ExperimentTest, ControlsPerActuatorAndFittedDelay) {
  const std::string base =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  const ExperimentConfig shared = LoadExperiment(Write(
      "exp.yaml", base + "controls: {delay: {initial: 0.01, fit: true, bounds: [0, 0.05]}}\n"));
  ASSERT_EQ(shared.control_delays.size(), 1u);
  EXPECT_EQ(shared.control_delays[0].actuator, "");
  EXPECT_TRUE(shared.control_delays[0].term.fit);
  EXPECT_EQ(shared.control_delays[0].term.initial, 0.01);
  EXPECT_EQ(shared.control_delays[0].term.lower, 0.0);
  EXPECT_EQ(shared.control_delays[0].term.upper, 0.05);
  const ExperimentConfig given =
      LoadExperiment(Write("exp.yaml", base + "controls: {delay: {initial: 0.02}}\n"));
  EXPECT_TRUE(given.control_delays.empty());
  EXPECT_EQ(given.control_delay, 0.02);
  const ExperimentConfig per = LoadExperiment(
      Write("exp.yaml", base + "controls:\n"
                               "  hold: {torque: linear}\n"
                               "  delay: {torque: {initial: 0.01, fit: true}, other: 0.003}\n"));
  ASSERT_EQ(per.control_holds.size(), 1u);
  EXPECT_EQ(per.control_holds[0].first, "torque");
  EXPECT_EQ(per.control_holds[0].second, ControlHold::kLinear);
  EXPECT_EQ(per.control_hold, ControlHold::kZeroOrder);
  EXPECT_EQ(per.control_hold_marks[0].line, 5);
  ASSERT_EQ(per.control_delays.size(), 2u);
  EXPECT_EQ(per.control_delays[0].actuator, "torque");
  EXPECT_TRUE(per.control_delays[0].term.fit);
  EXPECT_EQ(per.control_delays[1].actuator, "other");
  EXPECT_FALSE(per.control_delays[1].term.fit);
  EXPECT_EQ(per.control_delays[1].term.initial, 0.003);
  EXPECT_EQ(per.control_delays[1].mark.line, 6);
  // only the delay fitted
  const ExperimentConfig alone = LoadExperiment(
      Write("exp.yaml", "model: pendulum.xml\ncontrols: {delay: {initial: 0.01, fit: true}}\n"));
  EXPECT_TRUE(alone.parameters.empty());
  ExpectError(base + "controls: {delay: {initial: 0.01, fit: true, bounds: [-1, 1]}}\n", 4, 54,
              "cannot be negative", "seconds");
  ExpectError(base + "controls: {delay: {torque: {initial: -0.01, fit: true}}}\n", 4, 38,
              "outside bounds", "seconds");
  ExpectError(base + "controls: {hold: {torque: foh}}\n", 4, 27, "foh", "zoh");
  ExpectError(base + "controls: {delay: {torque: 1, torque: 2}}\n", 4, 31, "given twice", "");
}

// `controls.before`: hold (default) or zero before the first logged command; anything else is an
// error at the value naming the key and the allowed values
TEST_F(ExperimentTest, ControlsBefore) {
  const std::string base =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  EXPECT_EQ(LoadExperiment(Write("exp.yaml", base)).control_before, ControlBefore::kHold);
  EXPECT_EQ(LoadExperiment(Write("exp.yaml", base + "controls: {before: zero}\n")).control_before,
            ControlBefore::kZero);
  EXPECT_EQ(LoadExperiment(Write("exp.yaml", base + "controls: {before: hold, delay: 0.01}\n"))
                .control_before,
            ControlBefore::kHold);
  ExpectError(base + "controls: {before: bogus}\n", 4, 20, "controls.before: 'bogus'",
              "allowed values: hold, zero");
}

// simulate.truth names parameters and fitted control delays ("controls.delay", or
// "controls.delay.<actuator>"); a given delay has no truth to state
TEST_F(ExperimentTest, TruthOfAFittedControlDelay) {
  const std::string base =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  const ExperimentConfig shared = LoadExperiment(
      Write("exp.yaml", base + "controls: {delay: {initial: 0.005, fit: true}}\n"
                               "simulate: {truth: {m: 2, controls.delay: 0.012}}\n"));
  ASSERT_EQ(shared.simulate.truth.size(), 2u);
  EXPECT_EQ(shared.simulate.truth[1].name, "controls.delay");
  EXPECT_EQ(shared.simulate.truth[1].value, 0.012);
  ASSERT_NE(shared.FindFittedControlDelay("controls.delay"), nullptr);
  EXPECT_EQ(shared.FindFittedControlDelay("controls.delay.torque"), nullptr);
  const ExperimentConfig own = LoadExperiment(
      Write("exp.yaml", base + "controls: {delay: {torque: {initial: 0.005, fit: true}}}\n"
                               "simulate: {truth: {controls.delay.torque: 0.012}}\n"));
  EXPECT_EQ(own.simulate.truth[0].name, "controls.delay.torque");
  ExpectError(base + "controls: {delay: 0.01}\nsimulate: {truth: {controls.delay: 0.012}}\n", 5, 20,
              "'controls.delay' is not a parameter nor a fitted control delay");
}

// a sequence entry may fit a window of the sequence: {name, start, end} in seconds
TEST_F(ExperimentTest, SequenceWindows) {
  const std::string base =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1}\n";
  const ExperimentConfig c = LoadExperiment(
      Write("exp.yaml", base + "sequences: [{name: seq0, start: 0.5, end: 2.0}, seq1]\n"));
  ASSERT_EQ(c.sequences.size(), 2u);
  EXPECT_EQ(c.sequences[0].name, "seq0");
  EXPECT_EQ(c.sequences[0].start, 0.5);
  EXPECT_EQ(c.sequences[0].end, 2.0);
  EXPECT_EQ(c.sequences[1].name, "seq1");
  EXPECT_FALSE(std::isfinite(c.sequences[1].start));
  ExpectError(base + "sequences: [{name: seq0, start: 2.0, end: 1.0}]\n", 4, 13,
              "the window's start must be before its end");
  ExpectError(base + "sequences: [{start: 2.0}]\n", 4, 13, "missing required key 'name'");
}

TEST_F(ExperimentTest, UnknownTopLevelKeySuggestsTheClosest) {
  ExpectError(R"(model: pendulum.xml
solvr: {max_iterations: 3}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              2, 1, "unknown key 'solvr' in the experiment", "did you mean 'solver'?");
  // the hint lists the valid keys of that map
  ExpectError("model: a.xml\nsolvr: 1\n", 2, 1, "unknown key",
              "valid keys of the experiment: version, name, model, models, data");
}

TEST_F(ExperimentTest, UnknownNestedKeySuggestsTheClosest) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - name: m
    target: body_mass
    object: bob
    initial: 1
    bouds: [0, 2]
)",
              7, 5, "unknown key 'bouds' in parameters[0]", "did you mean 'bounds'?");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  loss: {type: huber, scael: 2}
)",
              5, 23, "unknown key 'scael' in solver.loss", "did you mean 'scale'? valid keys");
  // nothing close: the hint still lists the keys
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver: {zzzzzzzzzzzz: 1}
)",
              4, 10, "unknown key 'zzzzzzzzzzzz' in solver",
              "valid keys of solver: max_iterations, function_tolerance");
}

TEST_F(ExperimentTest, WrongTypesNameTheKeyAndTheExpectedType) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: heavy}
)",
              3, 56, "parameters[0].initial: expected a number, got the string 'heavy'");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  max_iterations: "100"
)",
              5, 19, "solver.max_iterations: expected an integer, got the quoted string \"100\"",
              "remove the quotes");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  max_iterations: 2.5
)",
              5, 19, "solver.max_iterations: expected an integer, got the number 2.5");
  ExpectError(R"(model: pendulum.xml
parameters:
  name: m
  target: body_mass
)",
              3, 3, "parameters: expected a list, got a map");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver: [1, 2]
)",
              4, 9, "solver: expected a map, got a list", "valid keys: max_iterations");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  verbose: yes please
)",
              5, 12, "solver.verbose: expected true or false");
  // an empty value points at its key
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  threads:
  verbose: true
)",
              5, 3, "solver.threads: expected an integer, got an empty value");
}

TEST_F(ExperimentTest, OutOfRangeNumbers) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: .inf}
)",
              3, 56, "parameters[0].initial: must be a finite number");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver: {max_iterations: 0}
)",
              4, 26, "solver.max_iterations: must be >= 1, got 0");
  ExpectError(R"(model: pendulum.xml
sensors:
  - {name: angle, sigma: -0.1}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              3, 26, "sensors[0].sigma: must be > 0");
}

TEST_F(ExperimentTest, MissingRequiredKeysNameTheParentAndTheKey) {
  ExpectError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              1, 1, "missing required key 'model' (or 'models')", "models:");
  ExpectError(R"(model: pendulum.xml
parameters:
  - name: m
    target: body_mass
    object: bob
)",
              3, 5, "missing required key 'initial' in parameters[0]");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, initial: 1}
)",
              3, 5, "missing required key 'object' in parameters[0]", "body");
  ExpectError(R"(models:
  - {name: a, path: a.xml}
  - {path: b.xml}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              3, 5, "missing required key 'name' in models[1]");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, prior: {mean: 1}}
)",
              3, 66, "missing required key 'sigma' in parameters[0].prior");
  ExpectError("model: pendulum.xml\n", 1, 1, "no parameters to identify", "measurement");
}

TEST_F(ExperimentTest, EnumsListTheAllowedValues) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mas, object: bob, initial: 1}
)",
              3, 23, "parameters[0].target: 'body_mas' is not one of body_mass",
              "did you mean 'body_mass'? allowed values: body_mass, body_mass_inertia");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
solver:
  jacobian: matrx
)",
              5, 13, "solver.jacobian: 'matrx' is not one of",
              "did you mean 'matrix'? allowed values: auto, directional, matrix, whole_rollout");
  ExpectError(R"(model: pendulum.xml
sensor_time: during
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              2, 14, "sensor_time: 'during' is not one of pre, post", "allowed values: pre, post");
}

TEST_F(ExperimentTest, DuplicatesAreErrors) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
  - {name: m, target: joint_damping, object: hinge, initial: 1}
)",
              4, 12, "duplicate parameter name 'm'", "first defined at line 3");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
model: other.xml
)",
              4, 1, "duplicate key 'model' in the experiment", "first given at line 1");
  ExpectError(R"(model: pendulum.xml
sensors: [angle, rate, angle]
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              2, 24, "duplicate sensor 'angle'");
}

TEST_F(ExperimentTest, BoundsMustContainInitial) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - name: m
    target: body_mass
    object: bob
    initial: 20
    bounds: [0.1, 10]
)",
              6, 14, "parameters[0].initial: 20 is outside bounds [0.1, 10]",
              "bounds are given at line 7");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, bounds: [2, 1]}
)",
              3, 67, "parameters[0].bounds: lower bound 2 must be < upper bound 1");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, bounds: [0, 1, 2]}
)",
              3, 67, "expected [lower, upper], got a list of 3 values");
  ExpectError(R"(model: pendulum.xml
measurement:
  - sensor: angle
    delay: {initial: -0.01, fit: true}
)",
              4, 22, "measurement[0].delay.initial: -0.01 is outside bounds [0, .inf]");
}

TEST_F(ExperimentTest, TransformRules) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, bounds: [0, 2], transform: log}
)",
              3, 86, "parameters[0].transform: log needs a lower bound > 0, got 0");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: c, target: body_com, object: bob, index: 2, initial: -0.5, transform: log}
)",
              3, 82, "log needs initial > 0, got -0.5");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, transform: scale, scale: 0}
)",
              3, 84, "parameters[0].scale: must be > 0");
}

TEST_F(ExperimentTest, ObjectFieldAndIndexRules) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: d, target: field, object: hinge, field: dof_damping, initial: 1}
)",
              3, 30, "parameters[0].object: not used by target 'field'");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: d, target: joint_damping, object: hinge, field: dof_damping, initial: 1}
)",
              3, 53, "parameters[0].field: only used by target 'field'");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: i, target: body_inertia, object: bob, index: 3, initial: 1}
)",
              3, 57,
              "index 3 is out of range for body_inertia of body 'bob' (0..2: principal moments");
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: g, target: actuator_gain, object: torque, index: -1, initial: 1}
)",
              3, 61, "parameters[0].index: must be >= 0, got -1");
}

TEST_F(ExperimentTest, ReferencesToUndeclaredNames) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: bob_mass, target: body_mass, object: bob, initial: 1}
simulate:
  truth: {bob_mas: 1.0}
)",
              5, 11, "simulate.truth: 'bob_mas' is not a parameter",
              "did you mean 'bob_mass'? valid parameters: bob_mass");
  ExpectError(R"(models:
  - {name: nominal, path: a.xml}
  - {name: payload, path: b.xml}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1, models: [paylod]}
)",
              5, 68, "parameters[0].models[0]: unknown model 'paylod'",
              "did you mean 'payload'? valid models: nominal, payload");
  ExpectError(R"(models:
  - {name: nominal, path: a.xml}
  - {name: payload, path: b.xml}
sequences: [heavy/seq0]
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              4, 13, "sequences[0]: unknown model 'heavy'", "valid models: nominal, payload");
  ExpectError(R"(model: pendulum.xml
sensors: [angle]
measurement:
  - {sensor: rate, bias: {fit: true}}
)",
              4, 14, "measurement[0].sensor: sensor 'rate' is not in 'sensors'",
              "valid sensors: angle");
  ExpectError(R"(model: pendulum.xml
sensors:
  - {name: angle, sigma: 0.1, weight: 10}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              3, 31, "give either 'sigma' or 'weight', not both");
  ExpectError(R"(model: pendulum.xml
models:
  - {name: a, path: a.xml}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              2, 1, "both 'model' and 'models' are given");
}

TEST_F(ExperimentTest, YamlSyntaxErrorsHaveAPosition) {
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1
solver: {}
)",
              4, 7, "YAML syntax error: end of map flow not found", "indentation");
  ExpectError("model: a.xml\nsolver:\n  threads: 1\n verbose: true\n", 4, 2,
              "YAML syntax error: end of map not found");
  ExpectError("model: pendulum.xml\n\tparameters: []\n", 2, 1, "YAML syntax error");
}

TEST_F(ExperimentTest, MissingFileNamesTheFile) {
  const std::string path = (dir_ / "nope" / "missing.yaml").string();
  try {
    LoadExperiment(path);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 0);
    EXPECT_NE(std::string(e.what()).find("experiment file not found: " + path), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(LoadExperiment(dir_.string()), ConfigError);  // a directory
  ExpectError("", 1, 1, "the experiment file is empty");
}

TEST_F(ExperimentTest, CheckModelFilesExistPointsAtTheModel) {
  const std::string present = Write("models/pendulum.xml", "<mujoco/>");
  EXPECT_NO_THROW(
      CheckModelFilesExist(LoadExperiment(Write("e/ok.yaml", R"(model: ../models/pendulum.xml
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)"))));
  const ExperimentConfig c = LoadExperiment(Write("e/bad.yaml", R"(models:
  - {name: a, path: ../models/pendulum.xml}
  - {name: b, path: ../models/missing.xml}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)"));
  try {
    CheckModelFilesExist(c);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 21);
    EXPECT_NE(e.message().find((dir_ / "models/missing.xml").string()), std::string::npos)
        << e.what();
  }
}

// -------------------------------------------------------------------------------------------
// checks against a real model (pendulum: body bob, joint hinge, actuator torque, sensors angle
// and rate)

class ModelValidationTest : public ExperimentTest {
 protected:
  void SetUp() override {
    ExperimentTest::SetUp();
    model_ = LoadModel(kModels + "/pendulum.xml");
  }

  // parses text (the model line is prepended) and validates it against the pendulum; expects a
  // ConfigError at line:column (counted in text, i.e. after the model line)
  void ExpectModelError(const std::string& text, int line, int column, const std::string& message,
                        const std::string& hint = {}) {
    const std::string path = Write("exp.yaml", "model: " + kModels + "/pendulum.xml\n" + text);
    const ExperimentConfig c = LoadExperiment(path);
    try {
      ValidateExperimentAgainstModel(c, *model_, "pendulum");
      ADD_FAILURE() << "expected a ConfigError containing '" << message << "'";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.file(), path) << e.what();
      EXPECT_EQ(e.line(), line + 1) << e.what();
      EXPECT_EQ(e.column(), column) << e.what();
      EXPECT_NE(e.message().find(message), std::string::npos) << e.what();
      EXPECT_NE(e.hint().find(hint), std::string::npos) << e.what();
    }
  }

  ModelPtr model_;
};

TEST_F(ModelValidationTest, AValidExperimentPasses) {
  const ExperimentConfig c = LoadExperiment(Write("exp.yaml", "model: " + kModels + R"(/pendulum.xml
sensors: [angle, {name: rate, sigma: 0.1}]
parameters:
  - {name: m, target: body_mass_inertia, object: bob, initial: 1}
  - {name: c, target: body_com, object: bob, index: 2, initial: 0}
  - {name: d, target: joint_damping, object: hinge, initial: 0.05}
  - {name: f, target: joint_frictionloss, object: hinge, initial: 0.01}
  - {name: g, target: geom_friction, object: rod, index: 1, initial: 0.005}
  - {name: k, target: actuator_gain, object: torque, index: 0, initial: 1}
  - {name: r, target: actuator_gear, object: torque, index: 0, initial: 1}
  - {name: a, target: field, field: dof_armature, index: 0, initial: 0.0}
measurement:
  - {sensor: rate, gain: {fit: true}}
simulate:
  noise: {angle: 0.01}
  excitation: [{actuator: torque, type: sines}]
  initial_state: {qpos: [0.3], qvel: [0.0]}
)"));
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(c, *model_, "pendulum"));
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(c, *model_, ""));
}

TEST_F(ModelValidationTest, UnknownSensor) {
  ExpectModelError(R"(sensors:
  - {name: angle}
  - {name: angel_rate, weight: 2}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
                   3, 12, "no sensor named 'angel_rate'", "valid sensor names: angle, rate");
  ExpectModelError(R"(sensors: [angl]
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
                   1, 11, "no sensor named 'angl'", "did you mean 'angle'?");
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
simulate:
  noise: {angle: 0.1, speed: 0.2}
)",
                   4, 23, "no sensor named 'speed'", "valid sensor names: angle, rate");
  ExpectModelError(R"(measurement:
  - {sensor: ang, delay: {fit: true}}
)",
                   2, 14, "no sensor named 'ang'", "did you mean 'angle'?");
}

TEST_F(ModelValidationTest, UnknownObjects) {
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bobb, initial: 1}
)",
                   2, 42, "no body named 'bobb'",
                   "did you mean 'bob'? valid body names: world, pole, bob");
  ExpectModelError(R"(parameters:
  - {name: d, target: joint_damping, object: hindge, initial: 1}
)",
                   2, 46, "no joint named 'hindge'", "did you mean 'hinge'?");
  ExpectModelError(R"(parameters:
  - {name: g, target: geom_friction, object: bob_geom, initial: 1}
)",
                   2, 46, "no geom named 'bob_geom'", "valid geom names: rod, bob");
  ExpectModelError(R"(parameters:
  - {name: k, target: actuator_bias, object: motor, initial: 1}
)",
                   2, 46, "no actuator named 'motor'", "valid actuator names: torque");
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: world, initial: 1}
)",
                   2, 42, "the world body");
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
simulate:
  excitation: [{actuator: torq}]
)",
                   4, 27, "no actuator named 'torq'", "did you mean 'torque'?");
}

TEST_F(ModelValidationTest, IndicesOutsideTheObject) {
  // a joint kind takes index 0 only (one MJCF attribute per joint): rejected without a model
  ExpectError(R"(model: pendulum.xml
parameters:
  - {name: d, target: joint_damping, object: hinge, index: 1, initial: 1}
)",
              3, 60,
              "index 1 is out of range for joint_damping of joint 'hinge' (0 only: one MJCF "
              "attribute per joint, applied to every dof)");
  // dof_damping has nv = 1 elements
  ExpectModelError(R"(parameters:
  - {name: d, target: field, field: dof_damping, index: 1, initial: 1}
)",
                   2, 57, "index 1 is out of range for field 'dof_damping' (0 only: flat index");
  ExpectModelError(R"(parameters:
  - {name: d, target: field, field: dof_dampin, initial: 1}
)",
                   2, 37, "field: mjModel has no array named 'dof_dampin'",
                   "did you mean 'dof_damping'?");
  // int arrays are not parameters
  ExpectModelError(R"(parameters:
  - {name: d, target: field, field: jnt_type, initial: 1}
)",
                   2, 37, "field: mjModel array 'jnt_type' holds int, not a floating-point");
}

// a joint kind takes index 0 for every joint type: a ball joint's damping index 1 is rejected with
// core's message (the text Parameter::Resolve gives), at the index's YAML position
TEST_F(ExperimentTest, BallJointDampingIndexIsCoresError) {
  const std::string path = Write("exp.yaml", "model: " + kModels + R"(/ball_pendulum.xml
parameters:
  - name: d
    target: joint_damping
    object: ball
    index: 1
    initial: 0.05
)");
  ::mjsysid::ParameterSpec spec;
  spec.kind = "joint_damping";
  spec.object = "ball";
  spec.index = 1;
  const ModelPtr m = LoadModel(kModels + "/ball_pendulum.xml");
  ASSERT_EQ(m->jnt_type[mj_name2id(m.get(), mjOBJ_JOINT, "ball")], mjJNT_BALL);
  std::string core_message;
  try {
    Parameter::Resolve(*m, spec);
  } catch (const ParameterError& e) {
    core_message = e.message();
  }
  EXPECT_EQ(core_message,
            "index 1 is out of range for joint_damping of joint 'ball' (0 only: one MJCF "
            "attribute per joint, applied to every dof)");
  try {
    LoadExperiment(path);
    ADD_FAILURE() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 6) << e.what();
    EXPECT_EQ(e.column(), 12) << e.what();
    EXPECT_EQ(e.message(), core_message);
  }
  // index 0 is the joint's one damping: accepted, with and without the model
  std::ofstream(path, std::ios::trunc) << "model: " + kModels + R"(/ball_pendulum.xml
parameters:
  - {name: d, target: joint_damping, object: ball, index: 0, initial: 0.05}
)";
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(LoadExperiment(path), *m, ""));
}

TEST_F(ModelValidationTest, InitialStateSizes) {
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
simulate:
  initial_state: {qpos: [0.1, 0.2]}
)",
                   4, 25, "simulate.initial_state.qpos has 2 values", "default");
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
simulate:
  initial_state:
    qpos: []
    qvel: [0, 1]
)",
                   6, 11, "simulate.initial_state.qvel has 2 values, model 'pendulum'",
                   "leave it out");
}

// the two complete examples of docs/experiment-schema.md parse and fit the shipped models
TEST_F(ModelValidationTest, DocumentedExamplesAreValid) {
  std::ifstream in(kModels + "/../docs/experiment-schema.md");
  ASSERT_TRUE(in.good());
  std::vector<std::string> examples;
  std::string line, block;
  bool in_block = false, after_example = false;
  while (std::getline(in, line)) {
    if (line.rfind("## Example", 0) == 0) after_example = true;
    if (after_example && line == "```yaml") {
      in_block = true;
      block.clear();
    } else if (in_block && line == "```") {
      in_block = false;
      examples.push_back(block);
    } else if (in_block) {
      block += line + "\n";
    }
  }
  ASSERT_EQ(examples.size(), 2u);

  const ExperimentConfig pendulum = LoadExperiment(Write("exp/pendulum.yaml", examples[0]));
  EXPECT_EQ(pendulum.parameters.size(), 3u);
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(pendulum, *model_, "pendulum"));

  const ExperimentConfig arm = LoadExperiment(Write("exp/arm.yaml", examples[1]));
  EXPECT_EQ(arm.models.size(), 2u);
  EXPECT_EQ(arm.sequences.size(), 3u);
  EXPECT_EQ(arm.simulate.excitation.size(), 3u);
  const ModelPtr arm5 = LoadModel(kModels + "/arm5.xml");
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(arm, *arm5, "nominal"));
  // the payload body exists only in the payload model
  EXPECT_THROW(ValidateExperimentAgainstModel(arm, *arm5, "payload"), ConfigError);
}

TEST_F(ModelValidationTest, ParametersOfOtherModelsAreSkipped) {
  const ExperimentConfig c = LoadExperiment(Write("exp.yaml", R"(models:
  - {name: nominal, path: a.xml}
  - {name: payload, path: b.xml}
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
  - {name: load, target: body_mass, object: payload_body, initial: 1, models: [payload]}
)"));
  EXPECT_NO_THROW(ValidateExperimentAgainstModel(c, *model_, "nominal"));
  EXPECT_THROW(ValidateExperimentAgainstModel(c, *model_, "payload"), ConfigError);
  try {
    ValidateExperimentAgainstModel(c, *model_, "heavy");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(e.hint().find("valid models: nominal, payload"), std::string::npos) << e.what();
  }
}

// `validation:`: held-out sequences spelled like `sequences:` entries, never also fitted
TEST_F(ExperimentTest, ValidationSequences) {
  const ExperimentConfig c = LoadExperiment(Write("val.yaml", R"(models:
  - {name: nominal, path: a.xml}
  - {name: payload, path: b.xml}
sequences: [payload/seq0, seq1]
validation: [payload/seq2, seq3]
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)"));
  ASSERT_EQ(c.validation.size(), 2u);
  EXPECT_EQ(c.validation[0].model, "payload");
  EXPECT_EQ(c.validation[0].name, "seq2");
  EXPECT_EQ(c.validation[1].model, "");
  EXPECT_EQ(c.validation[1].name, "seq3");
  EXPECT_EQ(c.validation[1].mark.line, 5);
  EXPECT_TRUE(LoadExperiment(Write("none.yaml", kPendulum)).validation.empty());

  // a sequence both fitted and held out, a duplicate, an unknown model
  ExpectError(std::string(kPendulum) + "sequences: [seq0, seq1]\nvalidation: [seq2, seq1]\n", 5, 20,
              "validation: sequence 'seq1' is also fitted (`sequences:` at line 4)",
              "remove it from one of the lists");
  ExpectError(std::string(kPendulum) + "validation: [seq2, seq2]\n", 4, 20,
              "duplicate sequence 'seq2'");
  ExpectError(R"(models:
  - {name: nominal, path: a.xml}
  - {name: payload, path: b.xml}
validation: [heavy/seq0]
parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
)",
              4, 14, "validation[0]: unknown model 'heavy'", "valid models: nominal, payload");
}

}  // namespace
}  // namespace mjsysid::io

namespace mjsysid::io {
namespace {

// the `states` key (logged states fitted as data): parsed into FitOptions::states, sigma shared
// or per name
TEST_F(ExperimentTest, StatesKeyParses) {
  const ExperimentConfig c = LoadExperiment(Write("exp.yaml", std::string(kPendulum) + R"(states:
  qpos: {sigma: 1.0e-3}
  qvel: {sigma: [0.01, 0.02], joints: [a, b]}
)"));
  const FitStates& st = c.options.states;
  EXPECT_TRUE(st.qpos.fit);
  EXPECT_TRUE(st.qpos.names.empty());
  EXPECT_EQ(st.qpos.sigma, std::vector<double>{1e-3});
  EXPECT_TRUE(st.qvel.fit);
  EXPECT_EQ(st.qvel.names, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(st.qvel.sigma, (std::vector<double>{0.01, 0.02}));
  EXPECT_FALSE(st.act.fit);
  EXPECT_EQ(c.states_marks.Of("qvel.joints[1]").line, 6);
}

// its errors, at the element, naming what was expected
TEST_F(ExperimentTest, StatesKeyErrors) {
  const std::string p = kPendulum;
  ExpectError(p + "states:\n  qpos: {joints: [a]}\n", 5, 9, "missing required key 'sigma'");
  ExpectError(p + "states:\n  qpos: {sigma: -1}\n", 5, 17, "must be > 0");
  ExpectError(p + "states:\n  qpos: {sigma: [1, 2]}\n", 5, 17, "has 2 values for 0 joints",
              "one sigma per entry");
  ExpectError(p + "states:\n  qpos: {sigma: 1, joints: [a, a]}\n", 5, 32, "given twice");
  ExpectError(p + "states:\n  qpos: {sigma: 1, joints: []}\n", 5, 28, "is empty");
  ExpectError(p + "states:\n  qpoz: {sigma: 1}\n", 5, 3, "qpoz", "qpos");
  ExpectError(p + "states:\n  act: {sigma: 1, joints: [a]}\n", 5, 19, "joints", "actuators");
}

// against the model: an unknown joint with a hint, an actuator without activation
TEST_F(ModelValidationTest, StatesNamesExistInTheModel) {
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
states:
  qpos: {sigma: 1, joints: [hinge, hinj]}
)",
                   4, 36, "no joint named 'hinj'", "did you mean 'hinge'");
  ExpectModelError(R"(parameters:
  - {name: m, target: body_mass, object: bob, initial: 1}
states:
  act: {sigma: 1}
)",
                   4, 8, "has no actuator with an activation");
}

}  // namespace
}  // namespace mjsysid::io

namespace mjsysid::io {
namespace {

class ExcitationFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("excitation_file_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& text) {
    const std::string path = (dir_ / "exp.yaml").string();
    std::ofstream(path) << text;
    return path;
  }
  fs::path dir_;
};

// `excitation: {type: file, path}`: the path resolved against the YAML file's folder; a file
// without a path, a path on another type, and a file in the per-actuator list are errors at
// their line and column
TEST_F(ExcitationFileTest, AFileExcitationNamesItsCsvAndStandsAlone) {
  const std::string head =
      "model: pendulum.xml\nparameters:\n"
      "  - {name: m, target: body_mass, object: bob, initial: 1.0}\nsimulate:\n";
  const ExperimentConfig c =
      LoadExperiment(Write(head + "  excitation: {type: file, path: designs/controls.csv}\n"));
  ASSERT_EQ(c.simulate.excitation.size(), 1u);
  EXPECT_EQ(c.simulate.excitation[0].type, ExcitationType::kFile);
  EXPECT_EQ(c.simulate.excitation[0].path, (dir_ / "designs/controls.csv").string());
  const auto expect_error = [&](const std::string& text, int line, int column,
                                const std::string& message) {
    try {
      LoadExperiment(Write(head + text));
      ADD_FAILURE() << "no error for " << text;
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_EQ(e.column(), column) << e.what();
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  expect_error("  excitation: {type: file}\n", 5, 15, "missing required key 'path'");
  expect_error("  excitation: {type: sines, path: a.csv}\n", 5, 35,
               "only a `file` excitation reads a path");
  expect_error("  excitation:\n    - {actuator: torque, type: file, path: a.csv}\n", 6, 32,
               "a `file` excitation gives every actuator's control");
}

}  // namespace
}  // namespace mjsysid::io
