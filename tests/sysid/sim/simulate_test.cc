// simulated logs: round trip through HDF5, checks against the model, exact re-simulation from the
// stored controls and initial state, noise, seeds, several models, errors, and every shipped
// experiment file (parses, validates against its model(s), simulates)
#include "sysid/sim/simulate.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "mjsysid/version.h"
#include "sysid/data/sample_grid.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/problem.h"
#include "tests/temp_dir_test.h"

namespace mjsysid::sim {
namespace {

namespace fs = std::filesystem;

const std::string kModels = MJSYSID_MODELS_DIR;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

// a fresh directory per test, removed afterwards
class SimulateTest : public test::TempDirTest {
 protected:
  // an experiment parsed as if it were a file in the models folder (so `model: X.xml` works)
  static io::ExperimentConfig Parse(const std::string& yaml) {
    return io::ParseExperiment(yaml, kModels + "/test_experiment.yaml");
  }
};

const char* const kPendulum = R"(
model: pendulum.xml
parameters:
  - {name: damping, target: joint_damping, object: hinge, initial: 0.2, bounds: [0, 1]}
  - {name: bob_mass, target: body_mass, object: bob, initial: 0.8}
  - {name: friction, target: joint_frictionloss, object: hinge, initial: 0.02}
simulate:
  truth: {damping: 0.11, bob_mass: 1.3}
  sequences: 3
  steps: 400
  seed: 5
  excitation: {type: sines, amplitude: 3.0}
  initial_state: {qpos: [0.4], qvel: [-0.5]}
)";

// re-simulates a logged sequence from its first state and controls at the given parameters
Trajectory Resimulate(const mjModel& m, const std::vector<ParameterSpec>& params,
                      const Eigen::VectorXd& values, const io::Sequence& seq) {
  SimulatorOptions options;
  options.threads = 1;
  options.sensors = true;
  Simulator sim(m, params, options);
  sim.SetParameters(values);
  SequenceInput in;
  in.x0.qpos = seq.qpos.row(0).transpose();
  in.x0.qvel = seq.qvel.row(0).transpose();
  if (seq.act.size()) in.x0.act = seq.act.row(0).transpose();
  in.ctrl = seq.ctrl;
  return sim.Rollout(in);
}

// ---------------------------------------------------------------------------------------------
// one model, no noise

TEST_F(SimulateTest, LogRoundTripsValidatesAndReproducesExactly) {
  const io::ExperimentConfig cfg = Parse(kPendulum);
  const io::Log log = SimulateExperiment(cfg);
  const std::string path = (dir_ / "sim.h5").string();
  io::WriteLog(path, log);
  const io::Log back = io::ReadLog(path);
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  io::ValidateLogAgainstModel(back, *m, path);

  // layout and metadata
  ASSERT_EQ(back.sequences.size(), 3u);
  EXPECT_EQ(back.sensor_time, "pre");
  EXPECT_EQ(back.attributes.at("generator"),
            std::string("mjsysid ") + MJSYSID_VERSION + " simulate");
  EXPECT_EQ(back.attributes.at("mujoco_version"), MujocoVersion());
  EXPECT_EQ(back.attributes.at("model"), kModels + "/pendulum.xml");
  EXPECT_EQ(back.attributes.at("seed"), "5");
  EXPECT_EQ(std::stod(back.attributes.at("truth.damping")), 0.11);
  EXPECT_EQ(std::stod(back.attributes.at("truth.bob_mass")), 1.3);
  EXPECT_EQ(std::stod(back.attributes.at("truth.friction")), 0.01);  // the model's value
  EXPECT_EQ(back.attributes.at("truth_from_model"), "friction");
  EXPECT_EQ(back.attributes.at("initial_state.qpos"), "0.40000000000000002");
  EXPECT_NE(back.attributes.at("excitation").find("sines amplitude=3"), std::string::npos);

  // re-simulating the stored controls from the stored x_0 at the truth reproduces sensordata
  std::vector<ParameterSpec> params;
  for (const io::ParameterSpec* p : cfg.ParametersOf("test_experiment"))
    params.push_back(p->target);
  ASSERT_EQ(params.size(), 3u);
  EXPECT_EQ(params[0].kind, "joint_damping");
  EXPECT_EQ(params[0].label, "damping");
  Eigen::VectorXd truth(3);
  truth << 0.11, 1.3, 0.01;
  for (size_t s = 0; s < back.sequences.size(); ++s) {
    const io::Sequence& seq = back.sequences[s];
    EXPECT_EQ(seq.name, "seq" + std::to_string(s));
    ASSERT_EQ(seq.time.size(), 400);
    for (int k = 0; k < 400; ++k) ASSERT_EQ(seq.time[k], k * m->opt.timestep);
    EXPECT_EQ(seq.qpos(0, 0), 0.4);
    EXPECT_EQ(seq.qvel(0, 0), -0.5);
    EXPECT_EQ(seq.sensor_names, (std::vector<std::string>{"angle", "rate"}));
    EXPECT_EQ(seq.actuator_names, (std::vector<std::string>{"torque"}));
    EXPECT_EQ(seq.act.size(), 0);
    const Trajectory tr = Resimulate(*m, params, truth, seq);
    EXPECT_TRUE(tr.sensors == seq.sensordata) << "sequence " << s;
    EXPECT_TRUE(tr.states.topLeftCorner(400, 1) == seq.qpos) << "sequence " << s;
    EXPECT_TRUE(tr.states.block(0, 1, 400, 1) == seq.qvel) << "sequence " << s;
    // the logged sensors are y_k = h(x_k): the angle sensor is qpos itself
    EXPECT_TRUE(seq.sensordata.col(0) == seq.qpos.col(0));
  }
  // the sequences differ (seed + sequence index)
  EXPECT_GT((back.sequences[0].ctrl - back.sequences[1].ctrl).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_GT((back.sequences[1].ctrl - back.sequences[2].ctrl).cwiseAbs().maxCoeff(), 0.1);

  // and the model's own parameter values would not reproduce it
  Eigen::VectorXd model_values(3);
  model_values << 0.05, 1.0, 0.01;
  const Trajectory other = Resimulate(*m, params, model_values, back.sequences[0]);
  EXPECT_GT((other.sensors - back.sequences[0].sensordata).cwiseAbs().maxCoeff(), 1e-3);
}

TEST_F(SimulateTest, DefaultInitialStateIsTheReferenceState) {
  io::ExperimentConfig cfg = Parse(kPendulum);
  cfg.simulate.initial_state.qpos.clear();
  cfg.simulate.initial_state.qvel.clear();
  const io::Log log = SimulateExperiment(cfg);
  for (const io::Sequence& seq : log.sequences) {
    EXPECT_EQ(seq.qpos(0, 0), 0.0);
    EXPECT_EQ(seq.qvel(0, 0), 0.0);
  }
  EXPECT_EQ(log.attributes.count("initial_state.qpos"), 0u);
}

TEST_F(SimulateTest, ResultIsIndependentOfThreadsAndReproducibleFromTheSeed) {
  const io::ExperimentConfig cfg = Parse(kPendulum);
  SimulateSettings one;
  one.threads = 1;
  SimulateSettings three;
  three.threads = 3;
  const io::Log a = SimulateExperiment(cfg, one);
  const io::Log b = SimulateExperiment(cfg, three);
  ASSERT_EQ(a.sequences.size(), b.sequences.size());
  for (size_t s = 0; s < a.sequences.size(); ++s) {
    EXPECT_TRUE(a.sequences[s].sensordata == b.sequences[s].sensordata);
    EXPECT_TRUE(a.sequences[s].ctrl == b.sequences[s].ctrl);
  }
  io::ExperimentConfig other = cfg;
  other.simulate.seed = 6;
  const io::Log c = SimulateExperiment(other);
  EXPECT_FALSE(a.sequences[0].ctrl == c.sequences[0].ctrl);
  // seed 6's first sequence is seed 5's second: seeds are seed + sequence index
  EXPECT_TRUE(a.sequences[1].ctrl == c.sequences[0].ctrl);
}

// ---------------------------------------------------------------------------------------------
// logged as a robot logs (simulate.sample_rate, jitter, drop)

// the pendulum experiment at 150 Hz, stamps jittered by up to 1 ms, 2 % of the rows dropped: the
// instants are off the 2 ms grid, within the jitter of a 150 Hz clock, the drops counted; and a
// fit at the truth reads the noise-free log with zero residual (cost < 1e-20) while the model's
// values do not (cost > 1e-3)
TEST_F(SimulateTest, RobotLogIsOffGridAndExactAtTheTruth) {
  io::ExperimentConfig cfg =
      Parse(std::string(kPendulum) + "  sample_rate: 150\n  jitter: 0.001\n  drop: 0.02\n");
  const io::Log log = SimulateExperiment(cfg);
  const std::string path = (dir_ / "robot.h5").string();
  io::WriteLog(path, log);
  const io::Log back = io::ReadLog(path);
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  io::ValidateLogAgainstModel(back, *m, path);
  EXPECT_EQ(back.attributes.at("sample_rate"), "150");
  const double dt = m->opt.timestep, period = 1.0 / 150;
  // 400 steps: instants up to 0.798 s, 120 of them at 150 Hz, 2 dropped
  const int nominal = static_cast<int>(std::floor((399 * dt - 0.001) / period)) + 1;
  for (const io::Sequence& seq : back.sequences) {
    const Eigen::Index T = seq.time.size();
    EXPECT_EQ(T, nominal - static_cast<int>(std::round(0.02 * nominal))) << seq.name;
    EXPECT_EQ(seq.time[0], 0.0);
    EXPECT_LE(seq.time[T - 1], 399 * dt);
    int off_grid = 0;
    for (Eigen::Index k = 1; k < T; ++k) {
      // each instant within the jitter of a tick of the 150 Hz clock
      const double tick = std::round(seq.time[k] / period) * period;
      EXPECT_LE(std::abs(seq.time[k] - tick), 0.001 + 1e-12) << seq.name << " row " << k;
      EXPECT_GT(seq.time[k], seq.time[k - 1]);
      const double steps = seq.time[k] / dt;
      off_grid += std::abs(steps - std::round(steps)) > 0.01 ? 1 : 0;
      EXPECT_EQ(seq.ctrl.rows(), T);
      EXPECT_EQ(seq.qpos.rows(), T);
    }
    EXPECT_GT(off_grid, T / 2) << seq.name;
  }
  // the fit's view of the log: exact at the truth
  const auto cost_at = [&](double damping, double mass, double friction) {
    Problem problem;
    problem.AddModel("m", *m);
    problem.AddParameter(FitParameter("damping", cfg.parameters[0].target, damping));
    problem.AddParameter(FitParameter("bob_mass", cfg.parameters[1].target, mass));
    problem.AddParameter(FitParameter("friction", cfg.parameters[2].target, friction));
    for (const io::Sequence& seq : back.sequences) {
      InitialState x0;
      x0.qpos = seq.qpos.row(0).transpose();
      x0.qvel = seq.qvel.row(0).transpose();
      FitSequence fs(seq.name, "m", x0, seq.ctrl, seq.sensordata);
      fs.time = seq.time;
      problem.AddSequence(fs);
    }
    FitOptions o;
    o.max_iterations = 1;
    o.threads = 1;
    return problem.Fit(o).initial_cost;
  };
  EXPECT_LT(cost_at(0.11, 1.3, 0.01), 1e-20);
  EXPECT_GT(cost_at(0.05, 1.0, 0.01), 1e-3);
}

// jitter and drop need a sample rate; jitter stays below half a period, drop below one half
TEST_F(SimulateTest, RobotLogOptionsAreChecked) {
  const std::string base(kPendulum);
  EXPECT_THROW(Parse(base + "  jitter: 0.001\n"), io::ConfigError);
  EXPECT_THROW(Parse(base + "  drop: 0.1\n"), io::ConfigError);
  EXPECT_THROW(Parse(base + "  sample_rate: 0\n"), io::ConfigError);
  EXPECT_THROW(Parse(base + "  sample_rate: 100\n  jitter: 0.005\n"), io::ConfigError);
  EXPECT_THROW(Parse(base + "  sample_rate: 100\n  drop: 0.5\n"), io::ConfigError);
  EXPECT_NO_THROW(Parse(base + "  sample_rate: 100\n  jitter: 0.004\n  drop: 0.1\n"));
}

// ---------------------------------------------------------------------------------------------
// noise

TEST_F(SimulateTest, NoiseIsAddedToTheNamedSensorsWithTheirSigma) {
  io::ExperimentConfig clean = Parse(kPendulum);
  clean.simulate.steps = 3000;
  io::ExperimentConfig noisy = clean;
  noisy.simulate.noise = {{"rate", 0.05, {}}};
  const io::Log a = SimulateExperiment(clean);
  const io::Log b = SimulateExperiment(noisy);
  for (size_t s = 0; s < a.sequences.size(); ++s) {
    const RowMatrix diff = b.sequences[s].sensordata - a.sequences[s].sensordata;
    EXPECT_TRUE(diff.col(0).isZero(0)) << "angle has no noise";
    const double rms = std::sqrt(diff.col(1).squaredNorm() / 3000.0);
    EXPECT_NEAR(rms, 0.05, 0.004) << "sequence " << s;
    // states and controls stay the true ones
    EXPECT_TRUE(b.sequences[s].qpos == a.sequences[s].qpos);
    EXPECT_TRUE(b.sequences[s].ctrl == a.sequences[s].ctrl);
  }
  // each sequence has its own noise
  const RowMatrix n0 = b.sequences[0].sensordata - a.sequences[0].sensordata;
  const RowMatrix n1 = b.sequences[1].sensordata - a.sequences[1].sensordata;
  EXPECT_GT((n0 - n1).cwiseAbs().maxCoeff(), 0.01);
  EXPECT_EQ(b.attributes.at("noise.rate"), "0.050000000000000003");
}

// ---------------------------------------------------------------------------------------------
// several models

TEST_F(SimulateTest, SeveralModelsGetPrefixedSequencesAndPerModelParameters) {
  const io::ExperimentConfig cfg = Parse(R"(
models:
  - {name: light, path: pendulum.xml}
  - {name: heavy, path: pendulum.xml}
parameters:
  - {name: damping, target: joint_damping, object: hinge, initial: 0.2}
  - {name: payload, target: body_mass, object: bob, initial: 2.0, models: [heavy]}
simulate:
  truth: {damping: 0.1, payload: 3.0}
  sequences: 2
  steps: 100
)");
  const io::Log log = SimulateExperiment(cfg);
  ASSERT_EQ(log.sequences.size(), 4u);
  EXPECT_EQ(log.sequences[0].name, "light_seq0");
  EXPECT_EQ(log.sequences[1].name, "light_seq1");
  EXPECT_EQ(log.sequences[2].name, "heavy_seq0");
  EXPECT_EQ(log.sequences[3].name, "heavy_seq1");
  EXPECT_EQ(SimulatedSequenceName(cfg, "heavy", 1), "heavy_seq1");
  EXPECT_EQ(log.attributes.at("sequences.light"), "light_seq0,light_seq1");
  EXPECT_EQ(log.attributes.at("model.heavy"), kModels + "/pendulum.xml");
  EXPECT_EQ(std::stod(log.attributes.at("truth.damping")), 0.1);
  EXPECT_EQ(std::stod(log.attributes.at("truth.payload")), 3.0);
  // the same controls for both models, different motion (the payload)
  EXPECT_TRUE(log.sequences[0].ctrl == log.sequences[2].ctrl);
  EXPECT_GT((log.sequences[0].qpos - log.sequences[2].qpos).cwiseAbs().maxCoeff(), 1e-3);
  // the log is valid HDF5 with these names, and validates against the model
  const std::string path = (dir_ / "two.h5").string();
  io::WriteLog(path, log);
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  io::ValidateLogAgainstModel(io::ReadLog(path), *m, path);
}

TEST_F(SimulateTest, ModelValuesThatDifferBetweenModelsAreRecordedPerModel) {
  // a parameter without truth whose model value differs between the models: the pendulum's
  // damping 0.05 and an edited copy's 0.07
  std::ifstream in(kModels + "/pendulum.xml");
  std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "damping=\"0.05\"";
  ASSERT_NE(xml.find(from), std::string::npos);
  xml.replace(xml.find(from), from.size(), "damping=\"0.07\"");
  std::ofstream(dir_ / "pendulum_b.xml") << xml;
  const std::string yaml =
      "models:\n  - {name: a, path: " + kModels +
      "/pendulum.xml}\n  - {name: b, path: " + (dir_ / "pendulum_b.xml").string() +
      "}\nparameters:\n  - {name: damping, target: joint_damping, object: "
      "hinge, initial: 0.2}\nsimulate: {steps: 20, sequences: 1}\n";
  const io::Log log = SimulateExperiment(io::ParseExperiment(yaml, (dir_ / "x.yaml").string()));
  EXPECT_EQ(log.attributes.count("truth.damping"), 0u);
  EXPECT_EQ(std::stod(log.attributes.at("truth.a.damping")), 0.05);
  EXPECT_EQ(std::stod(log.attributes.at("truth.b.damping")), 0.07);
  EXPECT_EQ(log.attributes.at("truth_from_model"), "damping");
}

// A fitted control delay's truth (simulate.truth "controls.delay"): the log's ctrl are the
// commands (those of the experiment without `controls:`), the rollout got them held and delayed
// as the fit holds them (re-simulating the commands through BuildSampleGrid at 12 ms reproduces
// sensordata exactly, the undelayed commands do not), before: zero gives the first 6 steps 0;
// the attribute truth.controls.delay is the value simulated (the initial one without a truth).
TEST_F(SimulateTest, FittedDelaySimulatedAtItsTruthAndLoggedUndelayed) {
  const std::string body = R"(
model: pendulum.xml
parameters:
  - {name: damping, target: joint_damping, object: hinge, initial: 0.2, bounds: [0, 1]}
simulate:
  truth: {damping: 0.11, controls.delay: 0.012}
  sequences: 1
  steps: 300
  seed: 5
  excitation: {type: sines, amplitude: 3.0}
)";
  const std::string fitted = "controls: {delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}}\n";
  const std::string plain = R"(
model: pendulum.xml
parameters:
  - {name: damping, target: joint_damping, object: hinge, initial: 0.2, bounds: [0, 1]}
simulate: {truth: {damping: 0.11}, sequences: 1, steps: 300, seed: 5,
           excitation: {type: sines, amplitude: 3.0}}
)";
  const io::Log commands = SimulateExperiment(Parse(plain));
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  const double dt = m->opt.timestep;
  const std::vector<ParameterSpec> params = {Parse(plain).parameters[0].target};
  Eigen::VectorXd truth(1);
  truth << 0.11;
  for (const ControlBefore before : {ControlBefore::kHold, ControlBefore::kZero}) {
    SCOPED_TRACE(ControlBeforeName(before));
    const std::string controls =
        before == ControlBefore::kZero
            ? "controls: {before: zero, delay: {initial: 0.005, fit: true, bounds: [0, 0.05]}}\n"
            : fitted;
    const io::Log log = SimulateExperiment(Parse(body + controls));
    EXPECT_EQ(std::stod(log.attributes.at("truth.controls.delay")), 0.012);
    const io::Sequence& seq = log.sequences[0];
    EXPECT_EQ(seq.ctrl, commands.sequences[0].ctrl);  // the commands, undelayed
    const SampleGrid grid =
        BuildSampleGrid(seq.time, static_cast<int>(seq.time.size()), 0.0, seq.ctrl,
                        Eigen::VectorXd(), {}, {0.012}, dt, "", before);
    for (int n = 0; n < 6; ++n) {
      EXPECT_EQ(grid.ctrl(n, 0), before == ControlBefore::kZero ? 0.0 : seq.ctrl(0, 0)) << n;
    }
    EXPECT_EQ(grid.ctrl(6, 0), seq.ctrl(0, 0));
    io::Sequence held = seq;
    held.ctrl = grid.ctrl;
    EXPECT_EQ(Resimulate(*m, params, truth, held).sensors, seq.sensordata);
    EXPECT_GT((Resimulate(*m, params, truth, seq).sensors - seq.sensordata).norm(), 1e-3);
  }
  // without a truth the delay is simulated (and recorded) at its initial value
  io::ExperimentConfig initial = Parse(body + fitted);
  initial.simulate.truth.pop_back();
  EXPECT_EQ(std::stod(SimulateExperiment(initial).attributes.at("truth.controls.delay")), 0.005);
}

// ---------------------------------------------------------------------------------------------
// errors

TEST_F(SimulateTest, TruthThatIsNotAParameterIsAnErrorNamingIt) {
  // the parser rejects it with its position
  const std::string bad = R"(
model: pendulum.xml
parameters:
  - {name: damping, target: joint_damping, object: hinge, initial: 0.2}
simulate:
  truth: {damping: 0.1, dampnig: 0.3}
)";
  try {
    Parse(bad);
    FAIL() << "no error";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("dampnig"), std::string::npos) << e.what();
    EXPECT_EQ(e.line(), 6);
  }
  // and so does SimulateExperiment on a config built in code
  io::ExperimentConfig cfg = Parse(kPendulum);
  cfg.simulate.truth.push_back({"no_such_parameter", 1.0, {}});
  try {
    SimulateExperiment(cfg);
    FAIL() << "no error";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_parameter"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("is not a parameter"), std::string::npos) << e.what();
  }
  // a control delay's name is a truth only when that delay is fitted
  cfg = Parse(kPendulum);
  cfg.simulate.truth.push_back({"controls.delay", 0.012, {}});
  try {
    SimulateExperiment(cfg);
    FAIL() << "no error";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'controls.delay' is not a parameter nor a fitted control "
                                         "delay"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(SimulateTest, NamesTheModelLacksAreConfigErrors) {
  io::ExperimentConfig cfg = Parse(kPendulum);
  cfg.simulate.noise = {{"no_sensor", 0.1, {}}};
  EXPECT_THROW(SimulateExperiment(cfg), io::ConfigError);
  cfg = Parse(kPendulum);
  cfg.simulate.initial_state.qpos = {0.1, 0.2};
  EXPECT_THROW(SimulateExperiment(cfg), io::ConfigError);
  cfg = Parse(kPendulum);
  cfg.simulate.truth[0].value = std::nan("");
  EXPECT_THROW(SimulateExperiment(cfg), io::ConfigError);
}

TEST_F(SimulateTest, MissingModelIsAModelLoadError) {
  io::ExperimentConfig cfg = Parse(kPendulum);
  cfg.models[0].path = (dir_ / "missing.xml").string();
  EXPECT_THROW(SimulateExperiment(cfg), ModelLoadError);
}

TEST_F(SimulateTest, UnnamedSensorIsAnError) {
  std::ofstream(dir_ / "unnamed.xml") << R"(<mujoco>
  <worldbody><body><joint name="j" type="hinge"/><geom size="0.1" mass="1"/></body></worldbody>
  <sensor><jointpos joint="j"/></sensor>
</mujoco>)";
  const io::ExperimentConfig cfg = io::ParseExperiment(
      "model: unnamed.xml\n"
      "parameters: [{name: d, target: joint_damping, object: j, initial: 1}]\n"
      "simulate: {steps: 10}\n",
      (dir_ / "x.yaml").string());
  try {
    SimulateExperiment(cfg);
    FAIL() << "no error";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no name"), std::string::npos) << e.what();
  }
}

TEST_F(SimulateTest, DivergingSimulationIsASimulationError) {
  // an absurd spring stiffness: the acceleration overflows and MuJoCo warns (bad qacc)
  const io::ExperimentConfig cfg = Parse(R"(
model: spring_mass.xml
parameters:
  - {name: k, target: joint_stiffness, object: slide, initial: 4.0}
simulate:
  truth: {k: 1.0e+30}
  steps: 100
  initial_state: {qpos: [1.0]}
)");
  EXPECT_THROW(SimulateExperiment(cfg), SimulationError);
}

// ---------------------------------------------------------------------------------------------
// the shipped experiments

std::vector<std::string> ExperimentFiles() {
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(kExperiments)) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST_F(SimulateTest, EveryShippedExperimentParsesValidatesAndSimulates) {
  const std::vector<std::string> files = ExperimentFiles();
  EXPECT_GE(files.size(), 6u) << "experiments/ lost its files";
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    const io::ExperimentConfig cfg = io::LoadExperiment(file);
    io::CheckModelFilesExist(cfg);
    for (const io::ModelSpec& spec : cfg.models) {
      ModelPtr m = LoadModel(spec.path);
      io::ValidateExperimentAgainstModel(cfg, *m, spec.name);
      EXPECT_FALSE(cfg.ParametersOf(spec.name).empty());
    }

    // conventions of the shipped files: a log under experiments/logs, truth for every
    // parameter away from its initial value and inside its bounds, the sensors' sigma equal to
    // the simulated noise
    ASSERT_EQ(cfg.data.size(), 1u);
    EXPECT_EQ(fs::path(cfg.data[0].path).parent_path(), fs::path(kExperiments) / "logs");
    for (const io::ParameterSpec& p : cfg.parameters) {
      auto t = std::find_if(cfg.simulate.truth.begin(), cfg.simulate.truth.end(),
                            [&](const io::NamedValue& v) { return v.name == p.name; });
      ASSERT_NE(t, cfg.simulate.truth.end()) << p.name << " has no truth";
      EXPECT_GT(std::abs(t->value - p.initial), 0.05 * std::abs(t->value)) << p.name;
      EXPECT_GE(t->value, p.lower) << p.name;
      EXPECT_LE(t->value, p.upper) << p.name;
    }
    for (const io::SensorSpec& s : cfg.sensors) {
      auto n = std::find_if(cfg.simulate.noise.begin(), cfg.simulate.noise.end(),
                            [&](const io::NamedValue& v) { return v.name == s.name; });
      ASSERT_NE(n, cfg.simulate.noise.end()) << s.name << " has no noise";
      ASSERT_TRUE(s.sigma.has_value()) << s.name;
      EXPECT_EQ(*s.sigma, n->value) << s.name;
    }
    EXPECT_GE(cfg.simulate.sequences, 2);
    EXPECT_GE(cfg.simulate.steps, 300);
    EXPECT_LE(cfg.simulate.steps, 3000);

    // a short simulation, checked against the model(s)
    io::ExperimentConfig short_cfg = cfg;
    short_cfg.simulate.steps = 50;
    const io::Log log = SimulateExperiment(short_cfg);
    EXPECT_EQ(log.sequences.size(), cfg.models.size() * cfg.simulate.sequences);
    for (const io::ModelSpec& spec : cfg.models) {
      ModelPtr m = LoadModel(spec.path);
      io::Log mine;
      for (const io::Sequence& seq : log.sequences) {
        if (cfg.models.size() == 1 || seq.name.rfind(spec.name + "_", 0) == 0) {
          mine.sequences.push_back(seq);
        }
      }
      io::ValidateLogAgainstModel(mine, *m, file);
    }
  }
}

TEST_F(SimulateTest, ShippedBoxSlidesWithoutTipping) {
  // the box_floor excitation must beat static friction at the truth, or friction is not
  // identifiable: the box moves by more than 10 cm in every sequence and stays flat on the floor
  const io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/box_floor.yaml");
  const io::Log log = SimulateExperiment(cfg);
  for (const io::Sequence& seq : log.sequences) {
    SCOPED_TRACE(seq.name);
    const Eigen::VectorXd x = seq.qpos.col(0);
    EXPECT_GT(x.maxCoeff() - x.minCoeff(), 0.1);
    // sliding back and forth: the velocity changes sign many times
    int reversals = 0;
    for (int k = 1; k < seq.qvel.rows(); ++k) {
      if ((seq.qvel(k - 1, 0) > 0.01 && seq.qvel(k, 0) <= 0.01) ||
          (seq.qvel(k - 1, 0) < -0.01 && seq.qvel(k, 0) >= -0.01)) {
        ++reversals;
      }
    }
    EXPECT_GE(reversals, 4);
    const Eigen::VectorXd z = seq.qpos.col(2);
    EXPECT_NEAR(z.maxCoeff(), 0.1, 0.005);
    EXPECT_NEAR(z.minCoeff(), 0.1, 0.005);
    // the quaternion stays near identity (tilt below 2 degrees)
    EXPECT_GT(seq.qpos.col(3).minCoeff(), std::cos(M_PI / 180.0));
  }
}

}  // namespace
}  // namespace mjsysid::sim
