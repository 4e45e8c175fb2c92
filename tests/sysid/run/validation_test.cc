// Held-out validation sequences (experiment `validation:`, sysid/run/validation.h): read and
// checked like fitted ones, never fitted, simulated at the start and at the estimate, with
// per-channel % fit (sysid/assess/metrics.h) in the result, its files and the report.
//
// Data: experiments/pendulum.yaml simulated (truth damping 0.08, frictionloss 0.03, bob_mass 1.2;
// start 0.2, 0.01, 0.8; three 2000-step sequences seq0..seq2 of multi-sine torque; noise angle
// 0.001 rad, rate 0.01 rad/s).
#include "sysid/run/validation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/assess/metrics.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"
#include "tools/report/report.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

std::string TempDir(const std::string& name) { return test::FreshTempDir("validation_" + name); }

// the pendulum experiment with its log simulated into dir
io::ExperimentConfig Pendulum(const std::string& dir) {
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  const std::string log = dir + "/log.h5";
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.verbose = false;
  return cfg;
}

io::SequenceRef Ref(const std::string& name) { return io::SequenceRef{"", name, {}}; }

const ChannelFit& Channel(const SequenceResult& s, const std::string& name) {
  for (const ChannelFit& f : s.channel_fits) {
    if (f.channel == name) return f;
  }
  ADD_FAILURE() << "no channel " << name << " in " << s.name;
  static const ChannelFit none;
  return none;
}

TEST(ValidationTest, FitOnOneSequenceValidateOnAnother) {
  const std::string dir = TempDir("one_other");
  io::ExperimentConfig cfg = Pendulum(dir);
  cfg.sequences = {Ref("seq0")};
  cfg.validation = {Ref("seq1")};

  // the held-out sequence is read and checked, not added to the problem
  const BuiltProblem built = BuildProblem(cfg);
  ASSERT_EQ(built.sequences.size(), 1u);
  EXPECT_EQ(built.sequences[0].name, "seq0");
  ASSERT_EQ(built.validation.size(), 1u);
  EXPECT_EQ(built.validation[0].name, "seq1");

  FitRunOptions opt;
  opt.out_dir = dir + "/out";
  opt.verbose = false;
  const FitRunOutcome out = RunFit(cfg, opt);
  ASSERT_EQ(out.exit_code, 0) << TerminationText(out.file.termination);
  ASSERT_EQ(out.file.sequences.size(), 1u);
  ASSERT_EQ(out.file.validation.size(), 1u);
  const SequenceResult& fit = out.file.sequences[0];
  const SequenceResult& val = out.file.validation[0];
  EXPECT_EQ(val.name, "seq1");
  EXPECT_EQ(val.model, "pendulum");
  ASSERT_EQ(val.measured.rows(), 2000);
  ASSERT_EQ(val.channel_fits.size(), 2u);

  // the measured columns are the log's own
  const io::Log log = io::ReadLog(cfg.data[0].path);
  for (const io::Sequence& s : log.sequences) {
    if (s.name != "seq1") continue;
    EXPECT_EQ((val.measured - s.sensordata).cwiseAbs().maxCoeff(), 0.0);
  }

  // at the estimate the held-out sequence is reproduced to its noise: angle noise 0.001 rad is
  // ~1e-2 of the swing, so % fit above 99 for the angle, above 95 for the rate (noise 0.01
  // rad/s); at the start (damping 2.5x, mass 0.67x the truth) clearly worse
  for (const char* ch : {"angle", "rate"}) {
    SCOPED_TRACE(ch);
    const ChannelFit& f = Channel(val, ch);
    std::printf("[ measured ] validation seq1 %-6s %% fit %.3f -> %.3f, NRMSE %.4g -> %.4g\n", ch,
                f.fit_initial, f.fit_final, f.nrmse_initial, f.nrmse_final);
    const ChannelFit& g = Channel(fit, ch);
    std::printf("[ measured ] fitted     seq0 %-6s %% fit %.3f -> %.3f\n", ch, g.fit_initial,
                g.fit_final);
    EXPECT_GT(f.fit_final, std::string(ch) == "angle" ? 99.0 : 95.0);
    EXPECT_LT(f.fit_initial, f.fit_final - 10.0);
    EXPECT_NEAR(f.fit_final, FitPercent(f.nrmse_final), 1e-12);
    // generalisation: the held-out fit is as good as the fitted one, up to the noise
    EXPECT_NEAR(f.fit_final, g.fit_final, 1.0);
  }

  // written and read back: the held-out signals and their metrics
  const io::FitResultFile back = io::ReadResult(opt.out_dir);
  ASSERT_EQ(back.validation.size(), 1u);
  EXPECT_EQ(back.validation[0].name, "seq1");
  EXPECT_EQ((back.validation[0].simulated_final - val.simulated_final).cwiseAbs().maxCoeff(), 0.0);
  ASSERT_EQ(back.validation[0].channel_fits.size(), 2u);
  EXPECT_EQ(back.validation[0].channel_fits[0].fit_final, val.channel_fits[0].fit_final);
  ASSERT_EQ(back.sequences.size(), 1u);
  EXPECT_EQ(back.sequences[0].channel_fits[1].fit_initial, fit.channel_fits[1].fit_initial);
  const std::string yaml = test::ReadFile(opt.out_dir + "/result.yaml");
  EXPECT_NE(yaml.find("role: validation"), std::string::npos) << yaml;

  // the report: the held-out plot and the metrics table, labelled
  EXPECT_GT(report::WriteReport(opt.out_dir, nullptr), 0);
  EXPECT_TRUE(fs::exists(opt.out_dir + "/val_seq1.png"));
  const std::string html = test::ReadFile(opt.out_dir + "/report.html");
  EXPECT_NE(html.find("Validation sequences (not fitted)"), std::string::npos);
  EXPECT_NE(html.find("<h2>Fit quality</h2>"), std::string::npos);
  fs::remove_all(dir);
}

TEST(ValidationTest, WithoutSequencesEveryOtherSequenceIsFitted) {
  const std::string dir = TempDir("others");
  io::ExperimentConfig cfg = Pendulum(dir);
  cfg.validation = {Ref("seq2")};
  const BuiltProblem built = BuildProblem(cfg);
  ASSERT_EQ(built.sequences.size(), 2u);
  EXPECT_EQ(built.sequences[0].name, "seq0");
  EXPECT_EQ(built.sequences[1].name, "seq1");
  ASSERT_EQ(built.validation.size(), 1u);
  EXPECT_EQ(built.validation[0].name, "seq2");
  fs::remove_all(dir);
}

TEST(ValidationTest, HeldOutAtTheTruthMatchesItsNoiseFreeSimulation) {
  // SimulateHeldOut alone: at estimates equal to the truth the simulation is the noise-free log
  // up to the noise, so the residual RMS is the noise sigma (0.001 rad) within 10 %
  const std::string dir = TempDir("truth");
  io::ExperimentConfig cfg = Pendulum(dir);
  cfg.validation = {Ref("seq1")};
  const BuiltProblem built = BuildProblem(cfg);
  std::vector<ParameterEstimate> at_truth;
  for (const io::NamedValue& t : cfg.simulate.truth) {
    ParameterEstimate e;
    e.name = t.name;
    e.value = t.value;
    e.initial = cfg.FindParameter(t.name)->initial;
    at_truth.push_back(e);
  }
  std::vector<std::string> warnings;
  const SequenceResult s = SimulateHeldOut(*built.models[0], built.parameters, built.measurements,
                                           at_truth, built.validation[0], 1, &warnings);
  EXPECT_TRUE(warnings.empty());
  ASSERT_EQ(s.sensor_names.size(), 2u);
  EXPECT_EQ(s.sensor_names[0], "angle");
  const double rms = std::sqrt((s.simulated_final.col(0) - s.measured.col(0)).squaredNorm() /
                               static_cast<double>(s.measured.rows()));
  EXPECT_NEAR(rms, 0.001, 1e-4);
  fs::remove_all(dir);
}

// several models: a held-out sequence belongs to its model by the one rule (the log's record of
// `sysid simulate`, or a `model/seq` entry), like a fitted one
TEST(ValidationTest, HeldOutSequencesOfSeveralModelsKeepTheirModel) {
  const std::string dir = TempDir("models");
  io::ExperimentConfig cfg = io::ParseExperiment(R"(
models:
  - {name: cart, path: ../models/cart.xml}
  - {name: cart_payload, path: ../models/cart_payload.xml}
sensors: [x, xdot]
parameters:
  - {name: mass, target: body_mass, object: cart, initial: 1.2, bounds: [0.1, 10], transform: log}
validation: [cart_payload_seq1, cart/cart_seq0]
simulate:
  truth: {mass: 2.0}
  sequences: 2
  steps: 200
)",
                                                 kExperiments + "/cart_pair.yaml");
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(cfg.data[0].path, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  const BuiltProblem built = BuildProblem(cfg);
  ASSERT_EQ(built.validation.size(), 2u);
  ASSERT_EQ(built.sequences.size(), 2u);
  for (const FitSequence& s : built.validation) {
    EXPECT_EQ(s.name.rfind(s.model + "_seq", 0), 0u) << s.name << " held out with " << s.model;
  }
  for (const FitSequence& s : built.sequences) {
    EXPECT_TRUE(s.name == "cart_seq1" || s.name == "cart_payload_seq0") << s.name;
  }
  fs::remove_all(dir);
}

// a held-out sequence takes the fitted control delays by the fit's rule: an actuator's own over the
// shared one, at the estimate (its initial value without one); other actuators keep theirs
TEST(ValidationTest, FittedControlDelaysReachHeldOutSequencesByTheFitsRule) {
  ModelPtr m = LoadModel(std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml");  // actuator torque
  FitSequence sq("held", "m", InitialState{}, RowMatrix::Zero(3, 1), RowMatrix::Zero(3, 2));
  ApplyFittedControlDelays(*m, {}, {}, &sq);
  EXPECT_TRUE(sq.ctrl_delay.empty()) << "no fitted delay: the sequence's own stay";
  ParameterEstimate shared, own;
  shared.name = "controls.delay";
  shared.value = 0.012;
  own.name = "controls.delay.torque";
  own.value = 0.007;
  ApplyFittedControlDelays(*m, {{"", 0.01, 0, 0.05}}, {shared}, &sq);
  EXPECT_EQ(sq.ctrl_delay, std::vector<double>{0.012});
  ApplyFittedControlDelays(*m, {{"", 0.01, 0, 0.05}, {"torque", 0.02, 0, 0.05}}, {shared, own},
                           &sq);
  EXPECT_EQ(sq.ctrl_delay, std::vector<double>{0.007});
  ApplyFittedControlDelays(*m, {{"torque", 0.02, 0, 0.05}}, {}, &sq);
  EXPECT_EQ(sq.ctrl_delay, std::vector<double>{0.02}) << "no estimate: the initial value";
  ApplyFittedControlDelays(*m, {{"other", 0.02, 0, 0.05}}, {}, &sq);
  EXPECT_EQ(sq.ctrl_delay, std::vector<double>{0.02}) << "another actuator's: unchanged";
}

TEST(ValidationTest, BadValidationEntriesAreNamedErrors) {
  const std::string dir = TempDir("bad");
  io::ExperimentConfig cfg = Pendulum(dir);
  // a held-out sequence the data does not have: a ConfigError naming it
  cfg.validation = {Ref("seq9")};
  try {
    BuildProblem(cfg);
    ADD_FAILURE() << "no error";
  } catch (const io::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("seq9"), std::string::npos) << e.what();
  }
  // every sequence held out: nothing left to fit
  cfg.validation = {Ref("seq0"), Ref("seq1"), Ref("seq2")};
  EXPECT_THROW(BuildProblem(cfg), io::ConfigError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid::run
