// A fit's inputs by content (issue 35, docs/bad-input.md "Issue 35: inputs changed since the
// fit"), through the real `sysid` binary: checkpoints and results record the SHA-256 of the
// experiment, every model file (and the files it includes) and every log (result.yaml key
// input_hashes); `fit --resume` refuses a checkpoint whose inputs changed, `report` refuses to
// re-simulate its motion clip from inputs changed since the fit; files written before the hashes
// existed are accepted with a warning. The log edited between a kill and a resume is in
// tests/tools/sysid_outputs_test.cc (ResumeRefusesALogEditedAfterTheKill).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::ReadFile;
using mjsysid::test::Shell;
using mjsysid::test::Sysid;
using mjsysid::test::WriteFile;

const std::string kModels = MJSYSID_MODELS_DIR;

class Hashes35Test : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = mjsysid::test::FreshTempDir("input_hashes_cli");
    // the pendulum as a model that includes a file (inc.xml includes parts.xml)
    WriteFile(dir_ + "/inc.xml",
              "<mujoco model=\"inc\">\n  <include file=\"parts.xml\"/>\n</mujoco>\n");
    fs::copy_file(kModels + "/pendulum.xml", dir_ + "/parts.xml");
    exp_ = dir_ + "/exp.yaml";
    WriteFile(exp_, Experiment(3000));
    ASSERT_EQ(Sysid("simulate " + exp_).code, 0);
    out_ = dir_ + "/res";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  static std::string Experiment(int steps) {
    return "name: pend\n"
           "model: inc.xml\n"
           "data: log.h5\n"
           "sensors:\n"
           "  - {name: angle, sigma: 0.001}\n"
           "  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.3,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "solver: {max_iterations: 50, verbose: false, threads: 1}\n"
           "simulate:\n"
           "  truth: {damping: 0.08}\n"
           "  sequences: 1\n"
           "  steps: " +
           std::to_string(steps) + "\n  noise: {angle: 0.001, rate: 0.01}\n";
  }

  // a fit into out_ killed (SIGKILL) once its first checkpoint is written: out_.partial holds it
  void KilledFit() {
    ASSERT_TRUE(mjsysid::test::FitKilledAtCheckpoint(exp_, out_))
        << "the fit ended before the kill";
    ASSERT_FALSE(fs::exists(out_ + "/result.yaml"));
  }

  // removes the input_hashes block of a result.yaml-like file (as files of older versions)
  static void DropHashes(const std::string& yaml) {
    std::string s = ReadFile(yaml);
    const size_t at = s.find("input_hashes:\n");
    ASSERT_NE(at, std::string::npos);
    size_t end = s.find('\n', at) + 1;
    while (s.compare(end, 4, "  - ") == 0) end = s.find('\n', end) + 1;
    s.erase(at, end - at);
    WriteFile(yaml, s);
  }

  std::string dir_, exp_, out_;
};

// A fit records the SHA-256 of the experiment, the model, the file the model includes and the log
// in result.yaml (input_hashes), each equal to coreutils' sha256sum of the file: exit 0.
TEST_F(Hashes35Test, AFitRecordsTheHashesOfItsInputs) {
  ASSERT_EQ(Sysid("fit " + exp_ + " --out " + out_ + " --quiet").code, 0);
  const std::string yaml = ReadFile(out_ + "/result.yaml");
  for (const auto& [role, file] : {std::pair<std::string, std::string>{"experiment", "exp.yaml"},
                                   {"model", "inc.xml"},
                                   {"model", "parts.xml"},
                                   {"log", "log.h5"}}) {
    SCOPED_TRACE(file);
    const std::string sum = Shell("sha256sum " + dir_ + "/" + file).output.substr(0, 64);
    ASSERT_EQ(sum.size(), 64u);
    EXPECT_NE(
        yaml.find("{role: " + role + ", path: " + dir_ + "/" + file + ", sha256: " + sum + "}"),
        std::string::npos)
        << yaml;
  }
}

// --resume after the experiment file was edited: exit 2 naming the experiment and what to do;
// the checkpoint stays for a resume once the file is restored (exit 0).
TEST_F(Hashes35Test, ResumeRefusesAnEditedExperiment) {
  KilledFit();
  const std::string original = ReadFile(exp_);
  WriteFile(exp_, original + "# edited\n");
  const mjsysid::test::CliRun r = Sysid("fit --resume " + out_ + " --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(
      r.output.find("sysid fit: --resume " + out_ + ": the inputs changed since the checkpoint"),
      std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(exp_ + " (experiment) changed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("fit again without --resume, or restore the file"), std::string::npos);
  EXPECT_TRUE(fs::exists(out_ + ".partial/checkpoint.yaml"));
  WriteFile(exp_, original);
  const mjsysid::test::CliRun again = Sysid("fit --resume " + out_ + " --quiet");
  EXPECT_EQ(again.code, 0) << again.output;
}

// --resume after a file the model includes was edited: exit 2 naming that file (role model).
TEST_F(Hashes35Test, ResumeRefusesAnEditedIncludedModelFile) {
  KilledFit();
  std::string parts = ReadFile(dir_ + "/parts.xml");
  parts.replace(parts.find("damping=\"0.05\""), 14, "damping=\"0.20\"");
  WriteFile(dir_ + "/parts.xml", parts);
  const mjsysid::test::CliRun r = Sysid("fit --resume " + out_ + " --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find(dir_ + "/parts.xml (model) changed"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("inc.xml"), std::string::npos) << r.output;  // only the edited file
}

// --resume after the log was removed: exit 2 naming the log as gone.
TEST_F(Hashes35Test, ResumeRefusesALogThatIsGone) {
  KilledFit();
  fs::rename(dir_ + "/log.h5", dir_ + "/moved.h5");
  const mjsysid::test::CliRun r = Sysid("fit --resume " + out_ + " --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find(dir_ + "/log.h5 (log) is gone"), std::string::npos) << r.output;
}

// --resume from a checkpoint of an older version (no input_hashes): accepted (exit 0) with the
// warning that the inputs were not checked.
TEST_F(Hashes35Test, ResumeAcceptsAnOldCheckpointWithAWarning) {
  KilledFit();
  DropHashes(out_ + ".partial/checkpoint.yaml");
  const mjsysid::test::CliRun r = Sysid("fit --resume " + out_ + " --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("records no input hashes (written by an older mjsysid): the "
                          "experiment, models and logs were not checked against it"),
            std::string::npos)
      << r.output;
  EXPECT_NE(ReadFile(out_ + "/result.yaml").find("\ninput_hashes:"), std::string::npos);
}

// report after the model was edited: exit 2 naming the model and what to do (fit again, or
// --no-video), no report written; with --no-video (no re-simulation) exit 0.
TEST_F(Hashes35Test, ReportRefusesToReSimulateAnEditedModel) {
  WriteFile(exp_, Experiment(200));
  ASSERT_EQ(Sysid("simulate " + exp_ + " --force").code, 0);
  ASSERT_EQ(Sysid("fit " + exp_ + " --out " + out_ + " --quiet").code, 0);
  WriteFile(dir_ + "/inc.xml", ReadFile(dir_ + "/inc.xml") + "<!-- edited -->\n");
  const mjsysid::test::CliRun r = Sysid("report " + out_);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("sysid report: " + out_ + ": " + dir_ +
                          "/inc.xml (model) changed since the fit (run "),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("sysid report --no-video " + out_), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out_ + "/report.html"));
  const mjsysid::test::CliRun no_video = Sysid("report --no-video " + out_);
  EXPECT_EQ(no_video.code, 0) << no_video.output;
  EXPECT_TRUE(fs::exists(out_ + "/report.html"));
}

// report of a result of an older version (no input_hashes): accepted (exit 0) with a warning that
// the motion clip re-simulates the files unchecked.
TEST_F(Hashes35Test, ReportAcceptsAnOldResultWithAWarning) {
  WriteFile(exp_, Experiment(200));
  ASSERT_EQ(Sysid("simulate " + exp_ + " --force").code, 0);
  ASSERT_EQ(Sysid("fit " + exp_ + " --out " + out_ + " --quiet").code, 0);
  DropHashes(out_ + "/result.yaml");
  const mjsysid::test::CliRun r = Sysid("report " + out_);
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("sysid report: warning: " + out_ +
                          "/result.yaml records no input hashes (written by an older mjsysid)"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(fs::exists(out_ + "/report.html"));
}

}  // namespace
