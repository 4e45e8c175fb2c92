#include "sysid/io/result.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sysid/assess/metrics.h"
#include "tests/file_util.h"
#include "tests/temp_dir_test.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// helpers

// a fresh directory per test (test::TempDirTest)
class ResultTest : public test::TempDirTest {
 protected:
  // names of the files in the test directory
  std::vector<std::string> Files() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) out.push_back(e.path().filename());
    std::sort(out.begin(), out.end());
    return out;
  }

  // writes both files
  void WriteBoth(const FitResultFile& r) const {
    WriteResultYaml(Path("result.yaml"), r);
    WriteResultH5(Path("result.h5"), r);
  }

  // the message of the ResultError that ReadResult throws
  std::string ReadError() const {
    try {
      ReadResult(Dir());
    } catch (const ResultError& e) {
      return e.what();
    }
    ADD_FAILURE() << "ReadResult did not throw";
    return "";
  }
};

using test::ReadFile;
using test::WriteFile;

// replaces the one occurrence of `from` in the file
void ReplaceInFile(const std::string& path, const std::string& from, const std::string& to) {
  std::string text = ReadFile(path);
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from << " not in\n" << text;
  ASSERT_EQ(text.find(from, at + 1), std::string::npos) << from << " twice in\n" << text;
  WriteFile(path, text.replace(at, from.size(), to));
}

// deterministic, varied values
RowMatrix Matrix(Eigen::Index rows, Eigen::Index cols, int seed) {
  RowMatrix m(rows, cols);
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < cols; ++c) {
      m(r, c) = std::sin(1.3 * seed + 0.7 * static_cast<double>(r) + 2.9 * static_cast<double>(c)) *
                std::pow(10.0, static_cast<double>((r + c) % 7) - 3.0);
    }
  }
  return m;
}

SequenceResult Sequence(const std::string& name, std::vector<std::string> sensors,
                        std::vector<int> dims, Eigen::Index samples, int seed) {
  SequenceResult s;
  s.name = name;
  s.model = "pendulum";
  s.sensor_names = std::move(sensors);
  s.sensor_dims = std::move(dims);
  Eigen::Index cols = 0;
  for (int d : s.sensor_dims) cols += d;
  s.time.resize(samples);
  for (Eigen::Index k = 0; k < samples; ++k) s.time[k] = 0.002 * static_cast<double>(k);
  s.measured = Matrix(samples, cols, seed);
  s.simulated_initial = Matrix(samples, cols, seed + 1);
  s.simulated_final = Matrix(samples, cols, seed + 2);
  return s;
}

// the statistical stop's record, fired before the last Jacobian (its numbers need rounding)
FitTermination GaussNewtonTermination() {
  FitTermination t;
  t.kind = FitTermination::Kind::kGaussNewtonStop;
  t.solver_message = "User callback returned SOLVER_TERMINATE_SUCCESSFULLY.";
  t.fraction = 0.03;
  t.largest = 0.0134;
  t.iteration = 5;
  t.jacobian_iteration = 4;
  t.step_std_errors = 0.265;
  return t;
}

// the interval check skipped along two smooth simulator parameters
IntervalCheckRecord SkippedIntervalCheck() {
  IntervalCheckRecord r;
  r.kind = IntervalCheckRecord::Kind::kSkippedSmooth;
  r.evaluations = 2;
  r.skipped = 2;
  r.parameters = 3;
  r.wide_fraction = 0.1;
  return r;
}

// every field set, with awkward values: infinities, values that need 17 digits, odd text
FitResultFile FullResult() {
  FitResultFile r;
  r.name = "pendulum";
  r.experiment = "/work/experiments/pendulum.yaml";
  r.status = "converged";
  r.intervals_valid = true;
  r.termination.kind = FitTermination::Kind::kSolverConvergence;
  r.termination.solver_message = "function tolerance reached: |dcost|/cost = 3e-11 < 1e-10";
  r.created = "2024-05-01T12:00:00Z";
  r.mjsysid_version = "0.1.0";
  r.mujoco_version = "4.0.0";
  r.diagnostics.jacobian_mode = "analytic";
  r.iterations = 7;
  r.num_residuals = 8000;
  r.initial_cost = 1.0 / 3.0;
  r.final_cost = 0.1 + 0.2;
  r.uncertainty.residual_variance = 1e-300;
  r.seconds = 12.5;
  r.solver = {{"max_iterations", "100"},
              {"function_tolerance", "1e-10"},
              {"linear_solver", "dense_qr"},
              {"note", "a: b # c"}};

  // identified, at a bound, unidentifiable
  ParameterEstimate damping;
  damping.name = "damping";
  damping.value = 0.0800000000000001;
  damping.initial = 0.1;
  damping.std_error = 1.234e-4;
  damping.ci95_low = damping.value - 1.96 * damping.std_error;
  damping.ci95_high = damping.value + 1.96 * damping.std_error;
  damping.truth = 0.08;
  ParameterEstimate friction;
  friction.name = "frictionloss";
  friction.value = 0;
  friction.initial = 0.05;
  friction.std_error = 2e-3;
  friction.ci95_low = -3.92e-3;
  friction.ci95_high = 3.92e-3;
  friction.at_lower = true;
  ParameterEstimate mass;
  mass.name = "bob_mass";
  mass.value = 1.7;
  mass.initial = 1.0;
  mass.std_error = kInf;
  mass.ci95_low = -kInf;
  mass.ci95_high = kInf;
  mass.at_upper = true;
  mass.identifiable = false;
  mass.truth = 1.2;
  r.parameters = {damping, friction, mass};
  r.uncertainty.unidentifiable = {"bob_mass - 0.3 damping (singular value 1e-14)"};
  r.warnings = {"sequence seq1: MuJoCo warning at t = 1.5 s", "two\nlines: 'quoted' \"too\""};
  r.identified_models = {{"pendulum", "pendulum_identified.xml"}};

  // three iterations
  for (int i = 0; i < 3; ++i) {
    IterationInfo e;
    e.iteration = i;
    e.cost = 1.0 / (1 + i * i * 7.0);
    e.step_norm = 0.1 * i;
    e.gradient_norm = std::exp(-i);
    e.seconds = 0.25 * (i + 1);
    e.successful = i != 1;
    e.parameters = Eigen::Vector3d(0.1 - 0.01 * i, 0.05 / (i + 1), 1.0 + 0.3 * i);
    r.trace.push_back(e);
  }
  r.uncertainty.covariance = Matrix(3, 3, 7);
  r.uncertainty.covariance(2, 2) = kInf;
  r.jacobian = Matrix(11, 3, 9);
  r.sequences = {Sequence("seq0", {"angle", "accel"}, {1, 3}, 25, 1),
                 Sequence("pendulum_seq1", {"rate"}, {1}, 4, 5),
                 Sequence("a", {"angle"}, {1}, 1, 11)};
  // held-out sequences (under /validation in result.h5)
  r.validation = {Sequence("val0", {"angle", "accel"}, {1, 3}, 7, 21)};
  // the metrics as the runner fills them (the reader recomputes them from the signals)
  for (std::vector<SequenceResult>* list : {&r.sequences, &r.validation}) {
    for (SequenceResult& s : *list) s.channel_fits = ChannelFits(s);
  }
  return r;
}

// FullResult with a multi-start block: three starts, one failed (cost .inf), the best the second
// (not in FullResult: its keys repeat final_cost, which the edit-the-text tests expect once)
FitResultFile MultiStartResult() {
  FitResultFile r = FullResult();
  for (int k = 0; k < 3; ++k) {
    StartResult st;
    st.start = Eigen::Vector3d(0.1 * (k + 1), 1.0 / 3.0, 1.0 + k);
    if (k != 2) st.estimate = Eigen::Vector3d(0.1 + 1e-17 * k, 0.0501, 1.2 + 0.1 * k);
    st.initial_cost = k == 2 ? kInf : 10.0 / (k + 1);
    st.final_cost = k == 2 ? kInf : 0.1 + 0.2 * k;
    st.status = k == 0 ? FitStatus::kModelMismatch : FitStatus::kConverged;
    st.iterations = 7 * k;
    if (k == 2) st.error = "simulation failed: 'bad qacc' at t = 0.5 s";
    r.starts.push_back(st);
  }
  r.best_start = 1;
  r.start_spread = {
      {"damping", 0.1, 0.1, 0}, {"friction", 0.0501, 0.0501, 0}, {"bob_mass", 1.2, 1.3, 0.1 / 1.3}};
  return r;
}

// doubles compared bit for bit (infinities included)
void ExpectSame(const Eigen::Ref<const Eigen::MatrixXd>& a,
                const Eigen::Ref<const Eigen::MatrixXd>& b, const std::string& what) {
  ASSERT_EQ(a.rows(), b.rows()) << what;
  ASSERT_EQ(a.cols(), b.cols()) << what;
  for (Eigen::Index r = 0; r < a.rows(); ++r) {
    for (Eigen::Index c = 0; c < a.cols(); ++c) {
      EXPECT_EQ(a(r, c), b(r, c)) << what << " (" << r << ", " << c << ")";
    }
  }
}

void ExpectSame(const FitResultFile& a, const FitResultFile& b) {
  // summary
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.experiment, b.experiment);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.intervals_valid, b.intervals_valid);
  EXPECT_EQ(TerminationText(a.termination), TerminationText(b.termination));
  EXPECT_EQ(a.termination.kind, b.termination.kind);
  EXPECT_EQ(a.created, b.created);
  EXPECT_EQ(a.mjsysid_version, b.mjsysid_version);
  EXPECT_EQ(a.mujoco_version, b.mujoco_version);
  EXPECT_EQ(a.diagnostics.jacobian_mode, b.diagnostics.jacobian_mode);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.num_residuals, b.num_residuals);
  EXPECT_EQ(a.initial_cost, b.initial_cost);
  EXPECT_EQ(a.final_cost, b.final_cost);
  EXPECT_EQ(a.uncertainty.residual_variance, b.uncertainty.residual_variance);
  EXPECT_EQ(a.seconds, b.seconds);
  EXPECT_EQ(a.solver, b.solver);
  EXPECT_EQ(a.uncertainty.unidentifiable, b.uncertainty.unidentifiable);
  EXPECT_EQ(a.warnings, b.warnings);
  EXPECT_EQ(a.identified_models, b.identified_models);

  // parameters
  ASSERT_EQ(a.parameters.size(), b.parameters.size());
  for (size_t i = 0; i < a.parameters.size(); ++i) {
    const ParameterEstimate& p = a.parameters[i];
    const ParameterEstimate& q = b.parameters[i];
    EXPECT_EQ(p.name, q.name);
    EXPECT_EQ(p.value, q.value) << p.name;
    EXPECT_EQ(p.initial, q.initial) << p.name;
    EXPECT_EQ(p.std_error, q.std_error) << p.name;
    EXPECT_EQ(p.ci95_low, q.ci95_low) << p.name;
    EXPECT_EQ(p.ci95_high, q.ci95_high) << p.name;
    EXPECT_EQ(p.at_lower, q.at_lower) << p.name;
    EXPECT_EQ(p.at_upper, q.at_upper) << p.name;
    EXPECT_EQ(p.identifiable, q.identifiable) << p.name;
    EXPECT_EQ(p.truth, q.truth) << p.name;
  }

  // trace
  ASSERT_EQ(a.trace.size(), b.trace.size());
  for (size_t i = 0; i < a.trace.size(); ++i) {
    EXPECT_EQ(a.trace[i].iteration, b.trace[i].iteration);
    EXPECT_EQ(a.trace[i].cost, b.trace[i].cost);
    EXPECT_EQ(a.trace[i].step_norm, b.trace[i].step_norm);
    EXPECT_EQ(a.trace[i].gradient_norm, b.trace[i].gradient_norm);
    EXPECT_EQ(a.trace[i].seconds, b.trace[i].seconds);
    EXPECT_EQ(a.trace[i].successful, b.trace[i].successful);
    EXPECT_EQ(a.trace[i].parameters, b.trace[i].parameters);
  }

  // multi-start
  ASSERT_EQ(a.starts.size(), b.starts.size());
  EXPECT_EQ(a.best_start, b.best_start);
  for (size_t k = 0; k < a.starts.size(); ++k) {
    const StartResult& s = a.starts[k];
    const StartResult& t = b.starts[k];
    EXPECT_EQ(s.start, t.start) << k;
    EXPECT_EQ(s.estimate, t.estimate) << k;
    EXPECT_EQ(s.initial_cost, t.initial_cost) << k;
    EXPECT_EQ(s.final_cost, t.final_cost) << k;
    EXPECT_EQ(s.status, t.status) << k;
    EXPECT_EQ(s.iterations, t.iterations) << k;
    EXPECT_EQ(s.error, t.error) << k;
  }
  ASSERT_EQ(a.start_spread.size(), b.start_spread.size());
  for (size_t j = 0; j < a.start_spread.size(); ++j) {
    EXPECT_EQ(a.start_spread[j].name, b.start_spread[j].name);
    EXPECT_EQ(a.start_spread[j].min, b.start_spread[j].min);
    EXPECT_EQ(a.start_spread[j].max, b.start_spread[j].max);
    EXPECT_EQ(a.start_spread[j].relative, b.start_spread[j].relative);
  }

  // arrays
  ExpectSame(a.uncertainty.covariance, b.uncertainty.covariance, "covariance");
  ExpectSame(a.jacobian, b.jacobian, "jacobian");
  ASSERT_EQ(a.sequences.size(), b.sequences.size());
  ASSERT_EQ(a.validation.size(), b.validation.size());
  std::vector<std::pair<const SequenceResult*, const SequenceResult*>> pairs;
  for (size_t i = 0; i < a.sequences.size(); ++i)
    pairs.push_back({&a.sequences[i], &b.sequences[i]});
  for (size_t i = 0; i < a.validation.size(); ++i) {
    pairs.push_back({&a.validation[i], &b.validation[i]});
  }
  for (const auto& [sa, sb] : pairs) {
    const SequenceResult& s = *sa;
    const SequenceResult& t = *sb;
    // the per-channel metrics (NaN for a constant column compares as NaN)
    ASSERT_EQ(s.channel_fits.size(), t.channel_fits.size()) << s.name;
    for (size_t c = 0; c < s.channel_fits.size(); ++c) {
      const ChannelFit& f = s.channel_fits[c];
      const ChannelFit& g = t.channel_fits[c];
      EXPECT_EQ(f.channel, g.channel);
      for (const auto& [x, y] : {std::pair{f.fit_initial, g.fit_initial},
                                 {f.fit_final, g.fit_final},
                                 {f.nrmse_initial, g.nrmse_initial},
                                 {f.nrmse_final, g.nrmse_final}}) {
        EXPECT_TRUE(x == y || (std::isnan(x) && std::isnan(y))) << s.name << " " << f.channel;
      }
    }
    EXPECT_EQ(s.name, t.name);
    EXPECT_EQ(s.model, t.model);
    EXPECT_EQ(s.sensor_names, t.sensor_names);
    EXPECT_EQ(s.sensor_dims, t.sensor_dims);
    ExpectSame(s.time, t.time, s.name + " time");
    ExpectSame(s.measured, t.measured, s.name + " measured");
    ExpectSame(s.simulated_initial, t.simulated_initial, s.name + " simulated_initial");
    ExpectSame(s.simulated_final, t.simulated_final, s.name + " simulated_final");
  }
}

// ---------------------------------------------------------------------------------------------
// round trips

TEST_F(ResultTest, RoundTripKeepsEveryFieldExactly) {
  const FitResultFile r = FullResult();
  WriteBoth(r);
  EXPECT_EQ(Files(), (std::vector<std::string>{"result.h5", "result.yaml"}));
  ExpectSame(ReadResult(Dir()), r);
}

TEST_F(ResultTest, RoundTripKeepsTheStartsOfAMultiStartFit) {
  const FitResultFile r = MultiStartResult();
  WriteBoth(r);
  ExpectSame(ReadResult(Dir()), r);
}

// the event windows of a contact fit (sysid/data/event_windows.h): written only when cells were
// left out, read back as written
TEST_F(ResultTest, EventWindowsRoundTripAndAreAbsentWhenNone) {
  FitResultFile r = FullResult();
  WriteBoth(r);
  EXPECT_EQ(ReadResult(Dir()).event_windows.masked, 0);
  EXPECT_EQ(test::ReadFile(Dir() + "/result.yaml").find("event_windows"), std::string::npos);
  r.event_windows = {2, 76, 771, {"torso_gyro", "leg_vel"}};
  WriteBoth(r);
  const FitResultFile back = ReadResult(Dir());
  EXPECT_EQ(back.event_windows.window, 2);
  EXPECT_EQ(back.event_windows.events, 76);
  EXPECT_EQ(back.event_windows.masked, 771);
  EXPECT_EQ(back.event_windows.sensors, (std::vector<std::string>{"torso_gyro", "leg_vel"}));
}

// the residual diagnostics per channel and what the intervals came from (sysid/assess/
// residual_diagnostics.h): written when the fit made them, read back as written (NaN included:
// a channel without sigma); a file without them reads as white residuals
TEST_F(ResultTest, ResidualDiagnosticsRoundTripAndAreAbsentWhenNone) {
  FitResultFile r = FullResult();
  WriteBoth(r);
  EXPECT_TRUE(ReadResult(Dir()).residuals.empty());
  EXPECT_EQ(ReadResult(Dir()).interval_inflation, 1.0);
  EXPECT_EQ(test::ReadFile(Dir() + "/result.yaml").find("\nresiduals:"), std::string::npos);
  ResidualDiagnostics angle;
  angle.channel = "angle";
  angle.samples = 1496;
  angle.mean = -2.5e-5;
  angle.rms = 9.1e-4;
  angle.sigma = 4.5e-4;
  angle.ratio = 2.02;
  angle.bias_units = 0.21;
  angle.lag1 = 0.74;
  angle.tau = 29.0;
  angle.portmanteau_p = 0;
  angle.white = false;
  angle.sigma_from_log = true;
  ResidualDiagnostics rate = angle;
  rate.sigma_from_log = false;
  rate.channel = "rate[1]";
  rate.sigma = rate.ratio = std::numeric_limits<double>::quiet_NaN();
  rate.white = true;
  r.residuals = {angle, rate};
  r.parameters[0].timestep_bias = -3.5e-4;
  r.timestep_check = "the same fit at half the timestep (0.001 s, 3 iterations, converged)";
  r.subset_start = "ran on the first 500 of 4000 samples (1/8 of each sequence) in 0.05 s";
  r.interval_inflation = 29.0;
  r.intervals_from =
      "correlated residuals: s^2 (J^T J)^-1 x 29, the correlation time (samples) of 'angle'";
  WriteBoth(r);
  const FitResultFile back = ReadResult(Dir());
  ASSERT_EQ(back.residuals.size(), 2u);
  EXPECT_EQ(back.residuals[0].channel, "angle");
  EXPECT_EQ(back.residuals[0].samples, 1496);
  EXPECT_EQ(back.residuals[0].mean, -2.5e-5);
  EXPECT_EQ(back.residuals[0].rms, 9.1e-4);
  EXPECT_EQ(back.residuals[0].ratio, 2.02);
  EXPECT_EQ(back.residuals[0].bias_units, 0.21);
  EXPECT_EQ(back.residuals[0].lag1, 0.74);
  EXPECT_EQ(back.residuals[0].tau, 29.0);
  EXPECT_EQ(back.residuals[0].portmanteau_p, 0.0);
  EXPECT_FALSE(back.residuals[0].white);
  EXPECT_TRUE(back.residuals[0].sigma_from_log);
  EXPECT_FALSE(back.residuals[1].sigma_from_log);
  EXPECT_EQ(back.residuals[1].channel, "rate[1]");
  EXPECT_TRUE(std::isnan(back.residuals[1].sigma));
  EXPECT_TRUE(std::isnan(back.residuals[1].ratio));
  EXPECT_TRUE(back.residuals[1].white);
  EXPECT_EQ(back.interval_inflation, 29.0);
  EXPECT_EQ(back.intervals_from, r.intervals_from);
  EXPECT_EQ(back.timestep_check, r.timestep_check);
  EXPECT_EQ(back.subset_start, r.subset_start);
  EXPECT_EQ(back.parameters[0].timestep_bias, -3.5e-4);
  EXPECT_FALSE(back.parameters[1].timestep_bias.has_value());
}

// a fit in segments: the estimate in one piece (result.h5 simulated_one_piece) round trips, the
// % fit read back is the one piece's with the segments' beside it (result.yaml fit_segments); a
// fit in one piece writes neither
TEST_F(ResultTest, OnePieceSimulationRoundTripsWithItsFit) {
  FitResultFile r = FullResult();
  WriteBoth(r);
  EXPECT_EQ(test::ReadFile(Dir() + "/result.yaml").find("fit_segments"), std::string::npos);
  SequenceResult& s = r.sequences[0];
  s.simulated_one_piece = Matrix(s.measured.rows(), s.measured.cols(), 77);
  s.channel_fits = ChannelFits(s);
  WriteBoth(r);
  EXPECT_NE(test::ReadFile(Dir() + "/result.yaml").find("fit_segments"), std::string::npos);
  const FitResultFile back = ReadResult(Dir());
  const SequenceResult& t = back.sequences[0];
  ExpectSame(s.simulated_one_piece, t.simulated_one_piece, "simulated_one_piece");
  ASSERT_EQ(t.channel_fits.size(), s.channel_fits.size());
  for (size_t i = 0; i < t.channel_fits.size(); ++i) {
    const ChannelFit& f = t.channel_fits[i];
    EXPECT_EQ(f.nrmse_final, Nrmse(s.measured.col(i), s.simulated_one_piece.col(i)));
    EXPECT_EQ(f.nrmse_segments, Nrmse(s.measured.col(i), s.simulated_final.col(i)));
  }
  EXPECT_EQ(back.sequences[1].simulated_one_piece.rows(), 0);
  // a one-piece matrix of another shape is refused, naming it
  s.simulated_one_piece = Matrix(s.measured.rows(), s.measured.cols() + 1, 78);
  EXPECT_THROW(WriteBoth(r), std::exception);
}

// where the covariance's Jacobian was taken (the statistical stop before the last Jacobian,
// sysid/solve/gn_convergence.h): written only when it was the previous iterate's, read back as
// written
TEST_F(ResultTest, CovarianceJacobianRoundTripsAndIsAbsentWhenTheEstimates) {
  FitResultFile r = FullResult();
  WriteBoth(r);
  EXPECT_EQ(ReadResult(Dir()).diagnostics.covariance_jacobian_iteration, -1);
  EXPECT_TRUE(std::isnan(ReadResult(Dir()).diagnostics.last_step_std_errors));
  EXPECT_EQ(test::ReadFile(Dir() + "/result.yaml").find("covariance_jacobian"), std::string::npos);
  r.diagnostics.covariance_jacobian_iteration = 4;
  r.diagnostics.last_step_std_errors = 0.265;
  WriteBoth(r);
  const FitResultFile back = ReadResult(Dir());
  EXPECT_EQ(back.diagnostics.covariance_jacobian_iteration, 4);
  EXPECT_EQ(back.diagnostics.last_step_std_errors, 0.265);
}

// every field of the table in sysid/io/result_fields.h, the optional ones set to values other
// than their defaults: written, read back and written again, result.yaml is the same text (a field
// the reader missed would come back as its default) and result.h5 holds the same root attributes
TEST_F(ResultTest, EveryFieldOfTheTableIsReadBackAsWritten) {
  FitResultFile r = MultiStartResult();
  r.run_id = "20261122T180501Z-12345-9f3a";
  r.intervals_valid = false;  // not the default of a converged result without the key
  r.segment_steps_used = 25;
  r.termination = GaussNewtonTermination();
  r.segment_reason.choice = "auto: growth beyond linear after 25 steps";
  r.segment_reason.weights = "continuity weights 1 x S / state spread";
  r.segment_reason.held_iterations = 3;
  r.segment_reason.held_initial_cost = 1.0 / 3.0;
  r.segment_reason.held_final_cost = 0.125;
  r.interval_check = SkippedIntervalCheck();
  r.diagnostics.covariance_jacobian_iteration = 3;
  r.diagnostics.last_step_std_errors = 0.125;
  r.event_windows = {2, 76, 771, {"torso_gyro", "leg_vel"}};
  DerivedQuantity mass;
  mass.name = "payload.mass";
  mass.unit = "kg";
  mass.value = 1.0 / 3.0;
  mass.std_error = kInf;
  mass.ci95_low = -kInf;
  mass.ci95_high = kInf;
  mass.derived_from = "payload log-Cholesky variables, delta method";
  mass.truth = 0.3;
  DerivedQuantity com = mass;
  com.name = "payload.com[0]";
  com.unit = "m";
  com.truth.reset();
  r.derived = {mass, com};
  r.diagnostics.reduction.recorded = true;
  r.diagnostics.reduction.used = true;
  r.diagnostics.reduction.collision_pairs = 12;
  r.diagnostics.reduction.collision_pairs_off = 5;
  r.diagnostics.reduction.geoms_off = 3;
  r.diagnostics.reduction.disabled = {"island", "contact"};
  r.diagnostics.reduction.guard_trips = 1;
  r.input_hashes = {{"experiment", "/abs/exp.yaml", std::string(64, 'a')},
                    {"log", "/abs/log.h5", std::string(64, 'b')}};
  WriteBoth(r);
  const std::string first = ReadFile(Path("result.yaml"));

  // (the files only: the identified models are not written here)
  const FitResultFile back = ReadResultFiles(Path("result.yaml"), Path("result.h5"));
  ExpectSame(back, r);
  EXPECT_EQ(back.run_id, r.run_id);
  EXPECT_FALSE(back.intervals_valid);
  EXPECT_EQ(back.derived.size(), 2u);
  EXPECT_TRUE(back.diagnostics.reduction.recorded);
  ASSERT_EQ(back.input_hashes.size(), 2u);
  EXPECT_EQ(back.input_hashes[1].role, "log");
  EXPECT_EQ(back.input_hashes[1].path, "/abs/log.h5");
  EXPECT_EQ(back.input_hashes[1].sha256, std::string(64, 'b'));
  WriteBoth(back);
  EXPECT_EQ(ReadFile(Path("result.yaml")), first);
  const FitResultFile again = ReadResultFiles(Path("result.yaml"), Path("result.h5"));
  EXPECT_EQ(again.run_id, r.run_id);
  EXPECT_FALSE(again.intervals_valid);
}

// the records of the result (termination, interval check, segments) are written as the text their
// functions render, each kind's name on the line after its text, and read back as that text and
// kind
TEST_F(ResultTest, RecordsAreWrittenAsTheirTextWithTheirKinds) {
  FitResultFile r = FullResult();
  r.termination = GaussNewtonTermination();
  r.interval_check = SkippedIntervalCheck();
  r.segment_reason.choice = "single shooting: sensitivity bounded";
  r.segment_reason.weights = "continuity weight 1 (absolute)";
  WriteBoth(r);
  const std::string text = ReadFile(Path("result.yaml"));
  const YAML::Node root = YAML::Load(text);
  EXPECT_EQ(root["termination"].as<std::string>(),
            "converged: predicted Gauss-Newton step below 3 % of every standard error (largest "
            "1.3 %, iteration 5); with the Jacobian of iteration 4, 0.27 standard errors from the "
            "estimate (the standard errors too; the estimate's own not simulated)");
  EXPECT_EQ(root["termination_kind"].as<std::string>(), "gauss_newton_stop");
  EXPECT_EQ(root["interval_check"].as<std::string>(), IntervalCheckText(r.interval_check));
  EXPECT_EQ(root["interval_check_kind"].as<std::string>(), "skipped_smooth");
  EXPECT_EQ(root["segment_reason"].as<std::string>(),
            "single shooting: sensitivity bounded; continuity weight 1 (absolute)");
  // each kind right after its text
  const auto after = [&text](const std::string& key, const std::string& next) {
    const size_t at = text.find("\n" + key + ": ");
    const size_t line_end = text.find('\n', at + 1);
    return at != std::string::npos && text.compare(line_end + 1, next.size() + 1, next + ":") == 0;
  };
  EXPECT_TRUE(after("termination", "termination_kind")) << text;
  EXPECT_TRUE(after("interval_check", "interval_check_kind")) << text;

  const FitResultFile back = ReadResult(Dir());
  EXPECT_EQ(back.termination.kind, FitTermination::Kind::kGaussNewtonStop);
  EXPECT_EQ(TerminationText(back.termination), TerminationText(r.termination));
  EXPECT_EQ(back.interval_check.kind, IntervalCheckRecord::Kind::kSkippedSmooth);
  EXPECT_EQ(IntervalCheckText(back.interval_check), IntervalCheckText(r.interval_check));
  EXPECT_EQ(back.segment_reason.choice, SegmentReasonText(r.segment_reason));
  EXPECT_EQ(SegmentReasonText(back.segment_reason), SegmentReasonText(r.segment_reason));

  // a checkpoint's and an interruption's termination, a smooth check that ran, a rugged one
  const std::pair<FitTermination::Kind, const char*> terminations[] = {
      {FitTermination::Kind::kCheckpoint, "checkpoint after iteration 5"},
      {FitTermination::Kind::kInterrupted, "interrupted (a stop signal) after iteration 5"}};
  for (const auto& [kind, line] : terminations) {
    r.termination.kind = kind;
    WriteBoth(r);
    const FitResultFile read = ReadResult(Dir());
    EXPECT_EQ(read.termination.kind, kind);
    EXPECT_EQ(TerminationText(read.termination), line);
  }
  r.interval_check.kind = IntervalCheckRecord::Kind::kRanRugged;
  r.interval_check.rugged = "contacts in 12 of 600 steps";
  WriteBoth(r);
  EXPECT_EQ(ReadResult(Dir()).interval_check.kind, IntervalCheckRecord::Kind::kRanRugged);
  EXPECT_EQ(IntervalCheckText(ReadResult(Dir()).interval_check),
            "ran: 2 cost evaluations (contacts in 12 of 600 steps)");
}

// a result.yaml written before the kinds (no termination_kind, no interval_check_kind): the text
// is read as it is with the kind unknown, and written again without the kind keys, the same file
TEST_F(ResultTest, FilesWithoutKindsKeepTheirTextAndAnUnknownKind) {
  FitResultFile r = FullResult();
  r.interval_check = SkippedIntervalCheck();
  WriteBoth(r);
  ReplaceInFile(Path("result.yaml"), "termination_kind: solver_convergence\n", "");
  ReplaceInFile(Path("result.yaml"), "interval_check_kind: skipped_smooth\n", "");
  const std::string old = ReadFile(Path("result.yaml"));
  const FitResultFile back = ReadResult(Dir());
  EXPECT_EQ(back.termination.kind, FitTermination::Kind::kUnknown);
  EXPECT_EQ(TerminationText(back.termination), TerminationText(r.termination));
  EXPECT_EQ(back.interval_check.kind, IntervalCheckRecord::Kind::kUnknown);
  EXPECT_EQ(IntervalCheckText(back.interval_check), IntervalCheckText(r.interval_check));
  WriteBoth(back);
  EXPECT_EQ(ReadFile(Path("result.yaml")), old);
  // without an interval check: no key, nothing recorded
  r.interval_check = IntervalCheckRecord();
  WriteBoth(r);
  EXPECT_EQ(ReadFile(Path("result.yaml")).find("interval_check"), std::string::npos);
  EXPECT_EQ(ReadResult(Dir()).interval_check.kind, IntervalCheckRecord::Kind::kNotRun);
}

// a kind this build does not know is named with its key and position
TEST_F(ResultTest, UnknownKindIsNamed) {
  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "termination_kind: solver_convergence\n",
                "termination_kind: tired\n");
  const std::string message = ReadError();
  EXPECT_NE(message.find("key 'termination_kind': unknown 'tired'"), std::string::npos) << message;
}

TEST_F(ResultTest, FitMetricsAreWrittenPerSequenceAndChannel) {
  // result.yaml lists the metrics of the fitted and the held-out sequences, each channel by name,
  // with the values the runner computed (read back with yaml-cpp, at full precision)
  const FitResultFile r = FullResult();
  WriteBoth(r);
  const YAML::Node root = YAML::LoadFile(Dir() + "/result.yaml");
  const YAML::Node m = root["fit_metrics"];
  ASSERT_TRUE(m.IsSequence());
  ASSERT_EQ(m.size(), 4u);  // seq0, pendulum_seq1, a, val0
  EXPECT_EQ(m[0]["sequence"].as<std::string>(), "seq0");
  EXPECT_EQ(m[0]["role"].as<std::string>(), "fit");
  EXPECT_EQ(m[3]["sequence"].as<std::string>(), "val0");
  EXPECT_EQ(m[3]["role"].as<std::string>(), "validation");
  ASSERT_EQ(m[3]["channels"].size(), 4u);
  EXPECT_EQ(m[3]["channels"][1]["channel"].as<std::string>(), "accel[0]");
  EXPECT_EQ(m[3]["channels"][1]["fit_final"].as<double>(),
            r.validation[0].channel_fits[1].fit_final);
  EXPECT_EQ(m[3]["channels"][1]["nrmse_initial"].as<double>(),
            r.validation[0].channel_fits[1].nrmse_initial);
  // a one-sample sequence has a constant measured column: no fit (.nan)
  EXPECT_EQ(m[2]["channels"][0]["fit_final"].as<std::string>(), ".nan");
}

TEST_F(ResultTest, RoundTripOfAnEmptyishResultAndOddText) {
  // no trace, no covariance or jacobian, no sequences, no lists; text YAML could misread
  FitResultFile r;
  r.name = "null";
  r.experiment = "";
  r.status = "yes";
  r.termination.kind = FitTermination::Kind::kSolverFailure;
  r.termination.solver_message = "- not a list";
  r.created = "~";
  r.mjsysid_version = "1.0";
  r.mujoco_version = "#x";
  r.diagnostics.jacobian_mode = " padded ";
  r.solver = {{"true", "false"}, {"k", ""}, {"ü", "[1, 2]"}};
  ParameterEstimate p;
  p.name = "0.5";
  p.value = -0.0;
  p.std_error = 5e-324;
  p.ci95_low = -1.7976931348623157e308;
  p.ci95_high = 1.7976931348623157e308;
  r.parameters = {p};
  WriteBoth(r);
  ExpectSame(ReadResult(Dir()), r);
  EXPECT_TRUE(std::signbit(ReadResult(Dir()).parameters[0].value));
}

TEST_F(ResultTest, TraceWithoutParameterValuesRoundTrips) {
  FitResultFile r = FullResult();
  for (IterationInfo& e : r.trace) e.parameters.resize(0);
  WriteBoth(r);
  ExpectSame(ReadResult(Dir()), r);
}

TEST_F(ResultTest, YamlIsReadableWithYamlInfinitiesAndShortNumbers) {
  WriteResultYaml(Path("result.yaml"), FullResult());
  const std::string text = ReadFile(Path("result.yaml"));
  EXPECT_NE(text.find("format: mjsysid-result\n"), std::string::npos) << text;
  EXPECT_NE(text.find("format_version: 1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("std: .inf\n"), std::string::npos) << text;
  EXPECT_NE(text.find("ci95: [-.inf, .inf]"), std::string::npos) << text;
  EXPECT_NE(text.find("flags: [at_upper_bound, unidentifiable]"), std::string::npos) << text;
  EXPECT_NE(text.find("initial: 0.1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("truth: 1.2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("final_cost: 0.30000000000000004\n"), std::string::npos) << text;
}

// ---------------------------------------------------------------------------------------------
// atomic writes

TEST_F(ResultTest, FailingWritesLeaveThePreviousFilesAndNoTemporary) {
  const FitResultFile good = FullResult();
  WriteBoth(good);
  const std::string yaml_before = ReadFile(Path("result.yaml"));
  const std::string h5_before = ReadFile(Path("result.h5"));

  // h5: the last sequence is malformed, found after the others were written
  FitResultFile bad = good;
  bad.name = "changed";
  bad.sequences.back().simulated_final.resize(0, 0);
  try {
    WriteResultH5(Path("result.h5"), bad);
    FAIL() << "no error";
  } catch (const ResultError& e) {
    EXPECT_NE(std::string(e.what()).find("result.h5: /sequences/a/simulated_final: has shape"),
              std::string::npos)
        << e.what();
  }

  // yaml: two parameters with one name
  bad.parameters[1].name = bad.parameters[0].name;
  EXPECT_THROW(WriteResultYaml(Path("result.yaml"), bad), ResultError);
  EXPECT_THROW(WriteResultH5(Path("result.h5"), bad), ResultError);

  EXPECT_EQ(ReadFile(Path("result.yaml")), yaml_before);
  EXPECT_EQ(ReadFile(Path("result.h5")), h5_before);
  EXPECT_EQ(Files(), (std::vector<std::string>{"result.h5", "result.yaml"}));
  ExpectSame(ReadResult(Dir()), good);
}

TEST_F(ResultTest, FailedRenameRemovesTheTemporary) {
  // the target is a non-empty directory: everything is written, then the rename fails
  fs::create_directories(Path("result.yaml/x"));
  fs::create_directories(Path("result.h5/x"));
  EXPECT_THROW(WriteResultYaml(Path("result.yaml"), FullResult()), ResultError);
  EXPECT_THROW(WriteResultH5(Path("result.h5"), FullResult()), ResultError);
  EXPECT_EQ(Files(), (std::vector<std::string>{"result.h5", "result.yaml"}));
  EXPECT_TRUE(fs::is_directory(Path("result.yaml/x")));
}

TEST_F(ResultTest, WriterRejectsInconsistentSizesNamingTheDataset) {
  FitResultFile r = FullResult();
  r.uncertainty.covariance.resize(2, 2);
  try {
    WriteResultH5(Path("result.h5"), r);
    FAIL() << "no error";
  } catch (const ResultError& e) {
    EXPECT_NE(
        std::string(e.what()).find("result.h5: /covariance: has shape (2, 2), expected (3, 3)"),
        std::string::npos)
        << e.what();
  }
  r = FullResult();
  r.trace[1].parameters.conservativeResize(r.trace[1].parameters.size() - 1);
  EXPECT_THROW(WriteResultH5(Path("result.h5"), r), ResultError);
  r = FullResult();
  r.sequences[0].sensor_dims = {1, 2};
  EXPECT_THROW(WriteResultH5(Path("result.h5"), r), ResultError);
  EXPECT_TRUE(Files().empty());
}

// ---------------------------------------------------------------------------------------------
// errors on reading

TEST_F(ResultTest, MissingFilesAreNamed) {
  std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.yaml") + ": no such file"), std::string::npos) << msg;
  WriteResultYaml(Path("result.yaml"), FullResult());
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": no such file"), std::string::npos) << msg;
}

TEST_F(ResultTest, MissingYamlKeyIsNamed) {
  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "final_cost: 0.30000000000000004\n", "");
  const std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.yaml")), std::string::npos) << msg;
  EXPECT_NE(msg.find("key 'final_cost': is missing"), std::string::npos) << msg;
}

TEST_F(ResultTest, WrongYamlTypesAreNamedWithTheirPosition) {
  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "iterations: 7\n", "iterations: seven\n");
  std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.yaml") + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find("key 'iterations': expected an integer, found 'seven'"), std::string::npos)
      << msg;

  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "std: .inf\n", "std: [1, 2]\n");
  msg = ReadError();
  EXPECT_NE(msg.find("key 'parameters[2].std': expected a number, found a list"), std::string::npos)
      << msg;

  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "[at_upper_bound, unidentifiable]",
                "[at_upper_bound, unidentifyable]");
  msg = ReadError();
  EXPECT_NE(msg.find("key 'parameters[2].flags': unknown flag 'unidentifyable'"), std::string::npos)
      << msg;

  WriteFile(Path("result.yaml"), "format: [unclosed\n");
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.yaml") + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find("invalid YAML"), std::string::npos) << msg;
}

TEST_F(ResultTest, FilesOfDifferentFitsAreRejected) {
  WriteBoth(FullResult());
  FitResultFile other = FullResult();
  other.parameters.pop_back();
  other.uncertainty.covariance.resize(0, 0);
  other.jacobian.resize(0, 0);
  for (IterationInfo& e : other.trace) e.parameters.conservativeResize(e.parameters.size() - 1);
  WriteResultYaml(Path("result.yaml"), other);
  const std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": /parameters attribute 'names': the parameters differ"),
            std::string::npos)
      << msg;
}

// opens result.h5 for editing
hid_t OpenForEdit(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  EXPECT_GE(f, 0);
  return f;
}

// the root attribute intervals_valid of result.h5 (-1 when it has none)
int H5IntervalsValid(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(f, 0);
  int value = -1;
  if (H5Aexists(f, "intervals_valid") > 0) {
    const hid_t a = H5Aopen(f, "intervals_valid", H5P_DEFAULT);
    EXPECT_GE(H5Aread(a, H5T_NATIVE_INT, &value), 0);
    H5Aclose(a);
  }
  H5Fclose(f);
  return value;
}

// replaces the root attribute intervals_valid of result.h5 by `value` (none: removes it)
void SetH5IntervalsValid(const std::string& path, std::optional<int> value) {
  const hid_t f = OpenForEdit(path);
  ASSERT_GE(H5Adelete(f, "intervals_valid"), 0);
  if (value) {
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a =
        H5Acreate2(f, "intervals_valid", H5T_STD_I32LE, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    EXPECT_GE(H5Awrite(a, H5T_NATIVE_INT, &*value), 0);
    H5Aclose(a);
    H5Sclose(space);
  }
  H5Fclose(f);
}

TEST_F(ResultTest, IntervalsValidIsStoredInTheH5FileToo) {
  // both values round-trip, and result.h5 holds them itself (not only result.yaml)
  for (const bool valid : {true, false}) {
    FitResultFile r = FullResult();
    r.intervals_valid = valid;
    WriteBoth(r);
    EXPECT_EQ(H5IntervalsValid(Path("result.h5")), valid ? 1 : 0);
    EXPECT_EQ(ReadResult(Dir()).intervals_valid, valid);
  }

  // a result.h5 of an older version (no attribute) reads as result.yaml says
  WriteBoth(FullResult());
  SetH5IntervalsValid(Path("result.h5"), std::nullopt);
  EXPECT_TRUE(ReadResult(Dir()).intervals_valid);

  // disagreeing with result.yaml, or not 0/1: named
  WriteBoth(FullResult());
  SetH5IntervalsValid(Path("result.h5"), 0);
  std::string msg = ReadError();
  EXPECT_NE(
      msg.find(Path("result.h5") + ": / attribute 'intervals_valid': is 0 but result.yaml's " +
               "intervals_valid is true"),
      std::string::npos)
      << msg;
  WriteBoth(FullResult());
  SetH5IntervalsValid(Path("result.h5"), 2);
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": / attribute 'intervals_valid': expected one value, 0 " +
                     "or 1"),
            std::string::npos)
      << msg;
}

TEST_F(ResultTest, MissingH5DatasetIsNamed) {
  WriteBoth(FullResult());
  const hid_t f = OpenForEdit(Path("result.h5"));
  ASSERT_GE(H5Ldelete(f, "/parameters/std", H5P_DEFAULT), 0);
  H5Fclose(f);
  const std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": /parameters/std: required dataset is missing"),
            std::string::npos)
      << msg;
}

TEST_F(ResultTest, WrongH5TypesAndShapesAreNamed) {
  // text instead of numbers
  WriteBoth(FullResult());
  hid_t f = OpenForEdit(Path("result.h5"));
  ASSERT_GE(H5Ldelete(f, "/trace/cost", H5P_DEFAULT), 0);
  {
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, 8);
    const hsize_t n = 3;
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t d =
        H5Dcreate2(f, "/trace/cost", type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    H5Dclose(d);
    H5Sclose(space);
    H5Tclose(type);
  }
  H5Fclose(f);
  std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": /trace/cost: must hold numbers"), std::string::npos)
      << msg;

  // a vector instead of a matrix
  WriteBoth(FullResult());
  f = OpenForEdit(Path("result.h5"));
  ASSERT_GE(H5Ldelete(f, "/covariance", H5P_DEFAULT), 0);
  {
    const hsize_t n = 9;
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t d =
        H5Dcreate2(f, "/covariance", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    H5Dclose(d);
    H5Sclose(space);
  }
  H5Fclose(f);
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": /covariance: has rank 1 (shape (9)), expected rank 2"),
            std::string::npos)
      << msg;

  // an attribute of the wrong type
  WriteBoth(FullResult());
  f = OpenForEdit(Path("result.h5"));
  ASSERT_GE(H5Adelete_by_name(f, "/sequences/seq0", "sensor_dims", H5P_DEFAULT), 0);
  {
    const hid_t g = H5Gopen2(f, "/sequences/seq0", H5P_DEFAULT);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a = H5Acreate2(g, "sensor_dims", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    H5Aclose(a);
    H5Sclose(space);
    H5Gclose(g);
  }
  H5Fclose(f);
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") +
                     ": /sequences/seq0 attribute 'sensor_dims': is not an integer attribute"),
            std::string::npos)
      << msg;
}

TEST_F(ResultTest, TruncatedH5IsNamed) {
  WriteBoth(FullResult());
  fs::resize_file(Path("result.h5"), fs::file_size(Path("result.h5")) / 2);
  const std::string msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": "), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
}

TEST_F(ResultTest, NotAResultIsNamed) {
  WriteBoth(FullResult());
  ReplaceInFile(Path("result.yaml"), "format: mjsysid-result\n", "format: mjsysid-log\n");
  std::string msg = ReadError();
  EXPECT_NE(msg.find("key 'format': is 'mjsysid-log', expected 'mjsysid-result'"),
            std::string::npos)
      << msg;
  WriteBoth(FullResult());
  WriteFile(Path("result.h5"), "not hdf5");
  msg = ReadError();
  EXPECT_NE(msg.find(Path("result.h5") + ": is not an HDF5 file"), std::string::npos) << msg;
}

}  // namespace
}  // namespace mjsysid::io
