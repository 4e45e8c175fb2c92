// every shipped experiment end to end: simulate -> fit -> check recovery -> results -> report,
// so that none of experiments/ can rot; plus checkpoints, interruption and the identified MJCF
#include "sysid/run/fit_experiment.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/io/log.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"
#include "tools/report/report.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

// a fresh folder per test
std::string TempDir(const std::string& name) { return test::FreshTempDir("run_" + name); }

// the experiment with its log in dir, simulated
io::ExperimentConfig Simulated(const std::string& name, const std::string& dir) {
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/" + name + ".yaml");
  const std::string log = dir + "/log.h5";
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  return cfg;
}

// how each shipped experiment must recover its truth (from its noisy simulated data):
// "ci": converged, and every estimate within 4 reported standard errors of its truth (one noisy
// realisation: a 95% interval misses 1 truth in 20, so 17 parameters would often miss one; the
// calibration of the intervals is tested over 100 seeds in tests/sysid/problem_test.cc);
// a number: relative error bound (contact scenes: see tests/sysid/problem_test.cc);
// "closer": every parameter ends closer to the truth than it started (humanoid, 10 iterations)
struct Expectation {
  std::string rule;
  double tolerance = 0;
  int max_iterations = 0;  // 0: the experiment's own
};

const std::map<std::string, Expectation> kShipped = {
    {"spring_mass", {"ci"}},
    {"pendulum", {"ci"}},
    {"double_pendulum", {"ci"}},
    {"cartpole", {"ci"}},
    {"arm5", {"ci"}},
    {"arm7", {"ci"}},
    {"servo_arm7", {"ci"}},
    {"box_floor", {"relative", 0.03}},
    {"humanoid", {"closer", 0, 10}},
};

TEST(FitExperimentTest, EveryShippedExperimentRecoversItsTruth) {
  // every experiment file is covered here
  int files = 0;
  for (const auto& entry : fs::directory_iterator(kExperiments)) {
    if (entry.path().extension() != ".yaml") continue;
    ++files;
    EXPECT_TRUE(kShipped.count(entry.path().stem().string()))
        << entry.path() << " has no recovery expectation in this test";
  }
  EXPECT_EQ(files, static_cast<int>(kShipped.size()));

  for (const auto& [name, expect] : kShipped) {
    SCOPED_TRACE(name);
    const std::string dir = TempDir(name);
    io::ExperimentConfig cfg = Simulated(name, dir);
    if (expect.max_iterations) cfg.options.max_iterations = expect.max_iterations;
    cfg.options.verbose = false;
    FitRunOptions opt;
    opt.out_dir = dir + "/out";
    opt.verbose = false;
    const FitRunOutcome out = RunFit(cfg, opt);
    std::map<std::string, double> truth;
    for (const io::NamedValue& t : cfg.simulate.truth) truth[t.name] = t.value;
    std::printf("[ measured ] %-16s %-13s %2d iterations, %6.2f s, cost %.4g -> %.4g\n",
                name.c_str(), out.file.status.c_str(), out.file.iterations, out.file.seconds,
                out.file.initial_cost, out.file.final_cost);
    for (const ParameterEstimate& p : out.file.parameters) {
      ASSERT_TRUE(p.truth.has_value()) << p.name;
      const double t = *p.truth;
      std::printf(
          "[ measured ]   %-22s start %-10.4g estimate %-12.6g truth %-8.4g 95%% CI [%.6g, %.6g]\n",
          p.name.c_str(), p.initial, p.value, t, p.ci95_low, p.ci95_high);
      if (expect.rule == "ci") {
        EXPECT_EQ(out.exit_code, 0) << TerminationText(out.file.termination);
        EXPECT_GT(p.std_error, 0) << p.name;
        EXPECT_LE(std::abs(p.value - t), 4 * p.std_error) << p.name;
      } else if (expect.rule == "relative") {
        EXPECT_NEAR(p.value / t, 1.0, expect.tolerance) << p.name;
      } else {
        ASSERT_EQ(expect.rule, "closer");
        EXPECT_LT(std::abs(p.value - t), std::abs(p.initial - t)) << p.name;
      }
    }
    // derived quantities (body_inertial: mass, com, principal moments) with a truth: as the
    // parameters under "ci" (servo_arm7's payload mass, 1.1 kg)
    for (const DerivedQuantity& d : out.file.derived) {
      if (!d.truth) continue;
      std::printf(
          "[ measured ]   %-22s derived  estimate %-12.6g truth %-8.4g 95%% CI [%.6g, %.6g]\n",
          d.name.c_str(), d.value, *d.truth, d.ci95_low, d.ci95_high);
      if (expect.rule == "ci") {
        EXPECT_LE(std::abs(d.value - *d.truth), 4 * d.std_error) << d.name;
      }
    }
    if (name == "servo_arm7") {
      ASSERT_FALSE(out.file.derived.empty());
      EXPECT_EQ(out.file.derived[0].name, "link7.mass");
      ASSERT_TRUE(out.file.derived[0].truth.has_value());
      EXPECT_NEAR(*out.file.derived[0].truth, std::exp(2 * 0.0477), 1e-12);
    }
    EXPECT_LT(out.file.final_cost, out.file.initial_cost);

    // what a user loads afterwards: both files, the identified model, the report
    const io::FitResultFile back = io::ReadResult(opt.out_dir);
    EXPECT_EQ(back.parameters.size(), out.file.parameters.size());
    EXPECT_EQ(back.derived.size(), out.file.derived.size());
    EXPECT_EQ(back.status, out.file.status);
    for (const auto& [model, file] : back.identified_models) {
      EXPECT_TRUE(fs::exists(opt.out_dir + "/" + file)) << file;
    }
    EXPECT_EQ(back.identified_models.size(), cfg.models.size());
    std::string summary;
    EXPECT_GT(report::WriteReport(opt.out_dir, &summary), 0);
    EXPECT_TRUE(fs::exists(opt.out_dir + "/report.html"));
    fs::remove_all(dir);
  }
}

// the identified MJCF compiles to the fitted values (every parameter kind the pendulum has)
TEST(FitExperimentTest, IdentifiedModelReproducesTheEstimates) {
  const std::string dir = TempDir("identified");
  io::ExperimentConfig cfg = Simulated("pendulum", dir);
  cfg.options.max_iterations = 3;
  FitRunOptions opt;
  opt.out_dir = dir + "/out";  // a folder of its own: a fit replaces its output folder
  opt.verbose = false;
  const FitRunOutcome out = RunFit(cfg, opt);
  ModelPtr m = LoadModel(dir + "/out/pendulum_identified.xml");
  std::vector<ParameterSpec> specs;
  for (const io::ParameterSpec& p : cfg.parameters) {
    specs.push_back(p.target);
  }
  ParameterSet params(*m, specs);
  std::vector<double> values(specs.size());
  params.Read(*m, values.data());
  for (size_t i = 0; i < specs.size(); ++i) {
    EXPECT_EQ(values[i], out.file.parameters[i].value) << specs[i].label;
  }
  for (const std::string& w : out.file.warnings) {
    EXPECT_EQ(w.find("identified model"), std::string::npos) << w;
  }
  fs::remove_all(dir);
}

// Every shipped experiment's identified model reproduces its fit: fitted for 2 iterations on one
// short log (the values need not be converged), each <model>_identified.xml is reloaded and
// simulated over every sequence's controls from the same initial state; states and sensors agree
// with the original model with the estimates written in (the fit's own simulator) to 1e-9.
TEST(FitExperimentTest, EveryIdentifiedModelReproducesItsFit) {
  for (const auto& entry : kShipped) {
    const std::string& name = entry.first;
    SCOPED_TRACE(name);
    const std::string dir = TempDir("reproduce_" + name);
    io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/" + name + ".yaml");
    cfg.simulate.sequences = 1;
    cfg.simulate.steps = 300;
    const std::string log = dir + "/log.h5";
    cfg.data = {io::DataFile{log, {}}};
    io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
    cfg.options.max_iterations = 2;
    cfg.options.verbose = false;
    FitRunOptions opt;
    opt.out_dir = dir + "/out";
    opt.verbose = false;
    const FitRunOutcome out = RunFit(cfg, opt);
    for (const std::string& w : out.file.warnings) {
      EXPECT_EQ(w.find("identified model"), std::string::npos) << w;
    }
    const BuiltProblem built = BuildProblem(cfg);
    int compared = 0;
    for (const io::ModelSpec& ms : cfg.models) {
      ASSERT_EQ(out.file.identified_models.count(ms.name), 1u) << ms.name;
      ModelPtr identified = LoadModel(opt.out_dir + "/" + out.file.identified_models.at(ms.name));
      ModelPtr original = LoadModel(ms.path);
      // the fitted model: the original with this model's estimates written in
      std::vector<ParameterSpec> specs;
      std::vector<double> values;
      for (const io::ParameterSpec* p : cfg.ParametersOf(ms.name)) {
        for (const ParameterEstimate& e : out.file.parameters) {
          if (e.name != p->name) continue;
          specs.push_back(p->target);
          values.push_back(e.value);
        }
      }
      Simulator fitted(*original, specs);
      fitted.SetParameters(Eigen::Map<const Eigen::VectorXd>(values.data(), values.size()));
      Simulator reloaded(*identified, {});
      Simulator unfitted(*original, {});
      for (const FitSequence& s : built.sequences) {
        if (s.model != ms.name) continue;
        const SequenceInput in{s.x0, s.ctrl};
        const Trajectory a = fitted.Rollout(in);
        const Trajectory b = reloaded.Rollout(in);
        ASSERT_EQ(a.states.rows(), b.states.rows());
        ASSERT_EQ(a.sensors.cols(), b.sensors.cols());
        const double state_diff = (a.states - b.states).cwiseAbs().maxCoeff();
        const double sensor_diff = (a.sensors - b.sensors).cwiseAbs().maxCoeff();
        std::printf("[ measured ] %-16s %-14s %s: %d steps, max |state| diff %.3g, |sensor| %.3g\n",
                    name.c_str(), ms.name.c_str(), s.name.c_str(), a.T, state_diff, sensor_diff);
        EXPECT_LE(state_diff, 1e-9) << s.name;
        EXPECT_LE(sensor_diff, 1e-9) << s.name;
        // the estimates matter: the original model alone simulates differently
        const Trajectory c = unfitted.Rollout(in);
        EXPECT_GT((a.states - c.states).cwiseAbs().maxCoeff(), 1e-6) << s.name;
        ++compared;
      }
    }
    EXPECT_GT(compared, 0);
    fs::remove_all(dir);
  }
}

// an interruption stops after the current iteration and leaves complete results of that iterate;
// every successful iteration left a readable checkpoint before
TEST(FitExperimentTest, InterruptKeepsTheLastGoodIterate) {
  const std::string dir = TempDir("interrupt");
  io::ExperimentConfig cfg = Simulated("pendulum", dir);
  std::atomic<bool> stop{true};  // set before the first iteration: stops after iteration 0
  FitRunOptions opt;
  opt.out_dir = dir + "/out";  // a folder of its own: a fit replaces its output folder
  opt.verbose = false;
  opt.interrupt = &stop;
  const FitRunOutcome out = RunFit(cfg, opt);
  EXPECT_EQ(out.file.status, "interrupted");
  EXPECT_EQ(out.exit_code, 1);
  EXPECT_TRUE(out.file.interrupted);
  const io::FitResultFile back = io::ReadResult(opt.out_dir);
  EXPECT_EQ(back.status, "interrupted");
  ASSERT_EQ(back.parameters.size(), cfg.parameters.size());
  // the iterate written is the fit's (initial values: stopped before any step)
  for (size_t i = 0; i < cfg.parameters.size(); ++i) {
    EXPECT_NEAR(back.parameters[i].value, cfg.parameters[i].initial,
                1e-12 * std::abs(cfg.parameters[i].initial));
  }
  fs::remove_all(dir);
}

// Two models whose names are prefixes of each other: each sequence is fitted with the model the
// log records for it (sequences.<model>, written by simulate), never by a name prefix (which
// fitted the cart_payload sequences with `cart` and returned mass 3.82, gear 4.78).
// Truth: cart mass 2, gear 3 (shared); start 40 % off; noise sigma 1e-3 on x, 1e-2 on xdot;
// tolerance: within 4 standard errors and 1 % of the truth.
TEST(FitExperimentTest, ModelsWhoseNamesArePrefixesGetTheirOwnSequences) {
  const std::string dir = TempDir("cart_pair");
  io::ExperimentConfig cfg = io::ParseExperiment(R"(
models:
  - {name: cart, path: ../models/cart.xml}
  - {name: cart_payload, path: ../models/cart_payload.xml}
sensors:
  - {name: x, sigma: 0.001}
  - {name: xdot, sigma: 0.01}
parameters:
  - {name: mass, target: body_mass, object: cart, initial: 1.2, bounds: [0.1, 10], transform: log}
  - {name: gear, target: actuator_gear, object: drive, initial: 1.8, bounds: [0.1, 10],
     transform: log}
solver: {verbose: false}
simulate:
  truth: {mass: 2.0, gear: 3.0}
  sequences: 2
  steps: 1000
  seed: 5
  excitation: {type: prbs, amplitude: 5.0, switch_period: 0.2}
  noise: {x: 0.001, xdot: 0.01}
)",
                                                 kExperiments + "/cart_pair.yaml");
  const std::string log = dir + "/log.h5";
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  const BuiltProblem built = BuildProblem(cfg);
  ASSERT_EQ(built.sequences.size(), 4u);
  for (const FitSequence& s : built.sequences) {
    EXPECT_EQ(s.name.rfind(s.model + "_seq", 0), 0u) << s.name << " fitted with " << s.model;
  }
  FitRunOptions opt;
  opt.out_dir = dir + "/out";  // a folder of its own: a fit replaces its output folder
  opt.verbose = false;
  const FitRunOutcome out = RunFit(cfg, opt);
  ASSERT_TRUE(out.file.converged) << TerminationText(out.file.termination);
  const std::map<std::string, double> truth = {{"mass", 2.0}, {"gear", 3.0}};
  for (const ParameterEstimate& e : out.file.parameters) {
    SCOPED_TRACE(e.name);
    EXPECT_LT(std::abs(e.value - truth.at(e.name)), 4 * e.std_error);
    EXPECT_LT(std::abs(e.value - truth.at(e.name)), 0.01 * truth.at(e.name));
  }
  fs::remove_all(dir);
}

TEST(FitExperimentTest, BadInputsAreNamedErrors) {
  const std::string dir = TempDir("bad");
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  cfg.data = {io::DataFile{dir + "/missing.h5", {}}};
  EXPECT_THROW(BuildProblem(cfg), io::ConfigError);
  // a log of another model
  io::ExperimentConfig other = io::LoadExperiment(kExperiments + "/cartpole.yaml");
  other.data = {io::DataFile{dir + "/cartpole.h5", {}}};
  io::WriteLog(dir + "/cartpole.h5", sim::SimulateExperiment(other, sim::SimulateSettings{}));
  cfg.data = other.data;
  EXPECT_THROW(BuildProblem(cfg), io::LogError);
  // sigma: auto on a sensor that reads 0 throughout: refused before any fit, at the sensor's
  // sigma in the experiment (exit 2 for the command line), naming the sensor
  io::ExperimentConfig zero = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  zero.data = {io::DataFile{dir + "/zero.h5", {}}};
  io::Log log = sim::SimulateExperiment(zero, sim::SimulateSettings{});
  for (io::Sequence& s : log.sequences) s.sensordata.col(1).setZero();
  io::WriteLog(dir + "/zero.h5", log);
  for (io::SensorSpec& ss : zero.sensors) {
    ss.sigma.reset();
    ss.sigma_from_log = true;
  }
  try {
    BuildProblem(zero);
    ADD_FAILURE() << "sigma: auto on a column of zeros was accepted";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sensor 'rate' (sigma: auto): it reads 0 throughout"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid::run
