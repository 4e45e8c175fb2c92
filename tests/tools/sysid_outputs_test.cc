// Results are never lost or mixed (issue 13, docs/bad-input.md), through the real `sysid` binary:
// outputs never overwrite inputs; a result folder is one run (swapped in whole, run ids checked by
// `report`, a lock against a second fit); SIGTERM/SIGINT/SIGHUP write a complete interrupted
// result and a second signal leaves the previous one; a full disk names the file and the reason
// and keeps the previous result; a kill loop at random moments of simulate, fit and report.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::ReadFile;
using mjsysid::test::Snapshot;
using mjsysid::test::WriteFile;
namespace io = mjsysid::io;

const std::string kModels = MJSYSID_MODELS_DIR;
const std::string kSysid = MJSYSID_SYSID_BIN;

// how a process ended
struct Ended {
  int code = -1;    // exit code; -1 when killed by a signal
  int signal = 0;   // the signal that ended it
  std::string out;  // stdout
  std::string err;  // stderr
};

// a `sysid` process running in the background, its stdout and stderr in files
class Process {
 public:
  Process(const std::string& args, const std::string& dir, const std::string& shell_prefix = "") {
    static int count = 0;
    out_ = dir + "/proc" + std::to_string(++count);
    const std::string cmd =
        shell_prefix + "exec " + kSysid + " " + args + " >" + out_ + ".out 2>" + out_ + ".err";
    pid_ = fork();
    if (pid_ == 0) {
      execl("/bin/bash", "bash", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  pid_t pid() const { return pid_; }
  void Signal(int s) const { kill(pid_, s); }
  Ended Wait() {
    int status = 0;
    waitpid(pid_, &status, 0);
    Ended e;
    if (WIFEXITED(status)) e.code = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) e.signal = WTERMSIG(status);
    e.out = ReadFile(out_ + ".out");
    e.err = ReadFile(out_ + ".err");
    return e;
  }

 private:
  pid_t pid_ = -1;
  std::string out_;
};

class SysidOutputsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // one folder per process: ctest runs each case as its own process, in parallel
    dir_ = mjsysid::test::FreshTempDir("outputs");
    exp_ = dir_ + "/exp.yaml";
    WriteFile(exp_, Experiment(200, 20));
    ASSERT_EQ(Run("simulate " + exp_).code, 0);
    log_ = dir_ + "/log.h5";
    ASSERT_TRUE(fs::exists(log_));
  }
  void TearDown() override {
    umount2((dir_ + "/small").c_str(), MNT_DETACH);  // FullDiskKeepsThePreviousResult's, if any
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // the pendulum experiment with `steps` samples per sequence and at most `iterations`
  static std::string Experiment(int steps, int iterations, const std::string& extra_solver = "") {
    return "name: pend\nmodel: " + kModels +
           "/pendulum.xml\n"
           "data: log.h5\n"
           "sensors:\n"
           "  - {name: angle, sigma: 0.001}\n"
           "  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.3,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "  - {name: bob_mass, target: body_mass, object: bob, initial: 0.7,\n"
           "     bounds: [0.1, 10.0]}\n"
           "solver: {max_iterations: " +
           std::to_string(iterations) + ", verbose: false, threads: 1" + extra_solver +
           "}\n"
           "simulate:\n"
           "  truth: {damping: 0.08, bob_mass: 1.2}\n"
           "  sequences: 2\n"
           "  steps: " +
           std::to_string(steps) +
           "\n"
           "  noise: {angle: 0.001, rate: 0.01}\n";
  }

  // runs `sysid ARGS` to the end
  Ended Run(const std::string& args) { return Process(args, dir_).Wait(); }

  // `sysid ARGS` must exit 2 saying each of `pieces`
  void ExpectRefused(const std::string& args, const std::vector<std::string>& pieces) {
    SCOPED_TRACE("sysid " + args);
    const Ended e = Run(args);
    EXPECT_EQ(e.code, 2) << e.err;
    for (const std::string& p : pieces) EXPECT_NE(e.err.find(p), std::string::npos) << e.err;
  }

  // waits up to 60 s for a file to exist
  static bool WaitFor(const std::string& path) {
    for (int i = 0; i < 60000; ++i) {
      if (fs::exists(path)) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }

  std::string dir_, exp_, log_;
};

// ---------------------------------------------------------------------------------------------
// outputs never overwrite inputs

TEST_F(SysidOutputsTest, OutputsNeverOverwriteInputs) {
  const std::string model = kModels + "/pendulum.xml";
  const std::string model_bytes = ReadFile(model);
  const std::string exp_bytes = ReadFile(exp_);
  ExpectRefused("simulate " + exp_ + " --out " + exp_, {"--out " + exp_, "is an input"});
  ExpectRefused("simulate " + exp_ + " --out " + kModels + "/../models/pendulum.xml",
                {"is an input", "pendulum.xml"});
  const std::string csv = dir_ + "/a.csv";
  const std::string csv_bytes = "time,torque,angle,rate\n0,0,0,0\n0.002,0,0,0\n";
  WriteFile(csv, csv_bytes);
  ExpectRefused("import " + model + " " + csv + " --out " + csv, {"is an input", csv});
  ExpectRefused("import " + model + " " + csv + " --out " + model, {"is an input"});
  // through a symlink too
  fs::create_symlink(csv, dir_ + "/link.h5");
  ExpectRefused("import " + model + " " + csv + " --out " + dir_ + "/link.h5", {"is an input"});
  // a fit into a folder that holds its experiment, model or log
  ExpectRefused("fit " + exp_ + " --out " + dir_ + " --quiet", {"holds", "an input of this run"});
  ExpectRefused("fit " + exp_ + " --out " + kModels + " --quiet", {"holds", "pendulum.xml"});
  EXPECT_EQ(ReadFile(model), model_bytes);
  EXPECT_EQ(ReadFile(exp_), exp_bytes);
  EXPECT_EQ(ReadFile(csv), csv_bytes);
  EXPECT_TRUE(fs::exists(log_));
}

TEST_F(SysidOutputsTest, ForeignFilesNeedForce) {
  const std::string model = kModels + "/pendulum.xml";
  const std::string csv = dir_ + "/a.csv";
  WriteFile(csv, "time,torque,angle,rate\n0,0,0,0\n0.002,0,0,0\n");
  const std::string foreign = dir_ + "/notes.h5";
  WriteFile(foreign, "my notes\n");
  ExpectRefused("import " + model + " " + csv + " --out " + foreign, {foreign, "--force"});
  ExpectRefused("simulate " + exp_ + " --out " + foreign, {foreign, "not an mjsysid log"});
  EXPECT_EQ(ReadFile(foreign), "my notes\n");
  EXPECT_EQ(Run("import " + model + " " + csv + " --out " + foreign + " --force").code, 0);
  EXPECT_NO_THROW(io::ReadLog(foreign));
  // a log that import wrote: simulate replaces it only with --force (docs/bad-input.md, "Issue 35:
  // outputs that would lose data"); import replaces any mjsysid log (its --out is explicit)
  ExpectRefused("simulate " + exp_ + " --out " + foreign, {foreign, "written by sysid import"});
  EXPECT_EQ(Run("simulate " + exp_ + " --out " + foreign + " --force").code, 0);
  EXPECT_EQ(Run("import " + model + " " + csv + " --out " + foreign).code, 0);

  // a folder that is not a result folder
  const std::string folder = dir_ + "/mine";
  fs::create_directories(folder);
  WriteFile(folder + "/thesis.tex", "keep\n");
  ExpectRefused("fit " + exp_ + " --out " + folder + " --quiet",
                {folder, "not an mjsysid result folder", "--force"});
  EXPECT_EQ(ReadFile(folder + "/thesis.tex"), "keep\n");
  const Ended forced = Run("fit " + exp_ + " --out " + folder + " --quiet --force");
  EXPECT_EQ(forced.code, 0) << forced.err;
  EXPECT_FALSE(fs::exists(folder + "/thesis.tex"));
  EXPECT_NO_THROW(io::ReadResult(folder));
}

// ---------------------------------------------------------------------------------------------
// a result folder is one run

TEST_F(SysidOutputsTest, ANewFitReplacesTheWholeFolder) {
  const std::string out = dir_ + "/res";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + out + " --quiet").code, 0);
  ASSERT_EQ(Run("report " + out).code, 0);
  const std::string first = io::ReadResult(out).run_id;
  EXPECT_FALSE(first.empty());
  WriteFile(out + "/other_identified.xml", "<mujoco/>\n");
  for (const std::string f : {"report.html", "cost.png", "parameters.png"}) {
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;
  }
  const Ended again = Run("fit " + exp_ + " --out " + out + " --quiet");
  ASSERT_EQ(again.code, 0) << again.err;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(out)) names.push_back(e.path().filename());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names,
            (std::vector<std::string>{"pendulum_identified.xml", "result.h5", "result.yaml"}));
  const io::FitResultFile second = io::ReadResult(out);
  EXPECT_NE(second.run_id, first);
  EXPECT_NE(ReadFile(out + "/pendulum_identified.xml").find(second.run_id), std::string::npos);
  EXPECT_NE(ReadFile(out + "/result.yaml").find("run_id: " + second.run_id), std::string::npos);
  // nothing left beside it
  EXPECT_FALSE(fs::exists(out + ".partial"));
  EXPECT_FALSE(fs::exists(out + ".lock"));
}

TEST_F(SysidOutputsTest, ReportRefusesFoldersThatMixRuns) {
  const std::string a = dir_ + "/a", b = dir_ + "/b";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + a + " --quiet").code, 0);
  ASSERT_EQ(Run("fit " + exp_ + " --out " + b + " --quiet").code, 0);
  for (const std::string file : {"result.h5", "pendulum_identified.xml"}) {
    SCOPED_TRACE(file);
    const std::string mixed = dir_ + "/mixed_" + file;
    fs::copy(a, mixed);
    fs::copy_file(b + "/" + file, mixed + "/" + file, fs::copy_options::overwrite_existing);
    ExpectRefused("report " + mixed, {mixed, "different fits", file == "result.h5" ? "run" : file});
    EXPECT_FALSE(fs::exists(mixed + "/report.html"));
  }
}

TEST_F(SysidOutputsTest, ALockStopsASecondFitAndNamesTheFirst) {
  WriteFile(exp_, Experiment(200, 200,
                             ", function_tolerance: 0, gradient_tolerance: 0, "
                             "parameter_tolerance: 0"));
  const std::string out = dir_ + "/res";
  Process first("fit " + exp_ + " --out " + out + " --quiet", dir_);
  ASSERT_TRUE(WaitFor(out + ".partial/checkpoint.yaml"));
  first.Signal(SIGSTOP);  // holds the lock while the second one tries
  const std::string pid = "pid " + std::to_string(first.pid());
  ExpectRefused("fit " + exp_ + " --out " + out + " --quiet", {out, "in use", "sysid fit", pid});
  ExpectRefused("report " + out, {out, "in use", pid});
  first.Signal(SIGCONT);
  const Ended e = first.Wait();
  EXPECT_EQ(e.signal, 0);
  EXPECT_NO_THROW(io::ReadResult(out));
  // concurrent fits into one folder: each finishes or is refused; one run's result remains
  std::vector<Process> fits;
  for (int i = 0; i < 4; ++i) fits.emplace_back("fit " + exp_ + " --out " + out + " --quiet", dir_);
  int done = 0;
  for (Process& p : fits) {
    const Ended r = p.Wait();
    EXPECT_TRUE(r.code == 1 || r.code == 0 ||
                (r.code == 2 && r.err.find("in use") != std::string::npos))
        << r.err;
    done += r.code != 2;
  }
  EXPECT_GE(done, 1);
  EXPECT_NO_THROW(io::ReadResult(out));
}

// ---------------------------------------------------------------------------------------------
// signals

TEST_F(SysidOutputsTest, StopSignalsWriteACompleteInterruptedResult) {
  WriteFile(exp_, Experiment(200, 200,
                             ", function_tolerance: 0, gradient_tolerance: 0, "
                             "parameter_tolerance: 0"));
  const std::string out = dir_ + "/res";
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    SCOPED_TRACE(strsignal(sig));
    Process fit("fit " + exp_ + " --out " + out + " --quiet", dir_);
    ASSERT_TRUE(WaitFor(out + ".partial/checkpoint.yaml"));
    fit.Signal(sig);
    const Ended e = fit.Wait();
    EXPECT_EQ(e.signal, 0);
    EXPECT_EQ(e.code, 1) << e.err;
    EXPECT_NE(e.err.find("interrupted"), std::string::npos) << e.err;
    const io::FitResultFile r = io::ReadResult(out);
    EXPECT_EQ(r.status, "interrupted");
    const std::string termination = TerminationText(r.termination);
    EXPECT_EQ(termination.find("Ceres"), std::string::npos) << termination;
    EXPECT_NE(termination.find("stop signal"), std::string::npos) << termination;
    EXPECT_EQ(r.termination.kind, mjsysid::FitTermination::Kind::kInterrupted) << termination;
    EXPECT_LT(r.iterations, 200);
    // no uncertainty step after a signal: no intervals, and the result says so
    for (const mjsysid::ParameterEstimate& p : r.parameters) {
      EXPECT_TRUE(std::isnan(p.std_error) && std::isnan(p.ci95_low)) << p.name;
    }
    EXPECT_NE(std::find(r.warnings.begin(), r.warnings.end(),
                        "interrupted: no uncertainty step, the estimate has no intervals"),
              r.warnings.end());
    EXPECT_EQ(Run("report " + out).code, 0);
  }
}

TEST_F(SysidOutputsTest, ASecondSignalExitsAtOnceAndKeepsThePreviousResult) {
  const std::string out = dir_ + "/res";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + out + " --quiet").code, 0);
  const auto before = Snapshot(out);
  WriteFile(exp_, Experiment(200, 200,
                             ", function_tolerance: 0, gradient_tolerance: 0, "
                             "parameter_tolerance: 0"));
  Process fit("fit " + exp_ + " --out " + out + " --quiet", dir_);
  ASSERT_TRUE(WaitFor(out + ".partial/checkpoint.yaml"));
  fit.Signal(SIGSTOP);
  fit.Signal(SIGTERM);
  fit.Signal(SIGCONT);
  std::this_thread::sleep_for(std::chrono::milliseconds(1));
  fit.Signal(SIGTERM);
  const Ended e = fit.Wait();
  // the second TERM ends it at once, or the first one's interrupted result was already written
  if (e.signal == SIGTERM) {
    EXPECT_EQ(Snapshot(out), before);
  } else {
    EXPECT_EQ(e.code, 1);
    EXPECT_EQ(io::ReadResult(out).status, "interrupted");
  }
  EXPECT_NO_THROW(io::ReadResult(out));
}

// ---------------------------------------------------------------------------------------------
// resume

// a fit killed (SIGKILL) after iteration 1 or 3, or stopped by SIGTERM, and resumed with
// `sysid fit --resume DIR` ends at the uninterrupted fit's estimate. Not bit-identical: Ceres'
// trust-region radius and Jacobian scaling restart at the checkpoint (sysid/run/resume.h);
// measured on this case, the estimates differ by < 1e-4 standard errors (up to 3e-7 relative),
// the tolerance here is 1e-3 standard errors.
TEST_F(SysidOutputsTest, ResumedFitsMatchUninterruptedOnes) {
  WriteFile(exp_, Experiment(2000, 50));
  ASSERT_EQ(Run("simulate " + exp_).code, 0);
  const std::string full = dir_ + "/full";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + full + " --quiet").code, 0);
  const io::FitResultFile want = io::ReadResult(full);
  ASSERT_GE(want.iterations, 5);
  ExpectRefused("fit --resume " + full, {"nothing to resume", full});
  for (int stop_after : {1, 3, -1}) {
    SCOPED_TRACE("stopped after iteration " + std::to_string(stop_after));
    const std::string out = dir_ + "/part" + std::to_string(stop_after);
    Process fit("fit " + exp_ + " --out " + out + " --quiet", dir_);
    const std::string cp = out + ".partial/checkpoint.yaml";
    const std::string mark = "\niterations: " + std::to_string(std::max(stop_after, 1)) + "\n";
    for (int i = 0; i < 60000 && ReadFile(cp).find(mark) == std::string::npos; ++i) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    fit.Signal(stop_after > 0 ? SIGKILL : SIGTERM);
    const Ended stopped = fit.Wait();
    if (stop_after > 0) {
      ASSERT_EQ(stopped.signal, SIGKILL);
      EXPECT_FALSE(fs::exists(out + "/result.yaml"));
    } else {
      ASSERT_EQ(stopped.code, 1) << stopped.err;
      ASSERT_EQ(io::ReadResult(out).status, "interrupted");
    }
    const Ended resumed = Run("fit --resume " + out + " --quiet");
    ASSERT_EQ(resumed.code, 0) << resumed.err;
    EXPECT_NE(resumed.err.find("resumed from the checkpoint"), std::string::npos) << resumed.err;
    const io::FitResultFile got = io::ReadResult(out);
    EXPECT_EQ(got.status, "converged");
    EXPECT_EQ(got.initial_cost, want.initial_cost);
    EXPECT_GT(got.iterations, std::max(stop_after, 1));
    EXPECT_GE(got.trace.size(), static_cast<size_t>(got.iterations) / 2);
    ASSERT_EQ(got.parameters.size(), want.parameters.size());
    for (size_t i = 0; i < want.parameters.size(); ++i) {
      SCOPED_TRACE(want.parameters[i].name);
      EXPECT_EQ(got.parameters[i].initial, want.parameters[i].initial);
      EXPECT_NEAR(got.parameters[i].value, want.parameters[i].value,
                  1e-3 * want.parameters[i].std_error);
    }
    EXPECT_FALSE(fs::exists(out + ".partial"));
  }
}

// inputs changed between kill and resume (issue 35): a fit killed (SIGKILL) after iteration 1,
// its log then rewritten (simulated again from another truth), and `sysid fit --resume DIR`:
// exit 2 naming the log and what to do, the checkpoint kept; the original log restored, the
// resume runs (exit 0).
TEST_F(SysidOutputsTest, ResumeRefusesALogEditedAfterTheKill) {
  WriteFile(exp_, Experiment(2000, 50));
  ASSERT_EQ(Run("simulate " + exp_).code, 0);
  const std::string out = dir_ + "/part";
  Process fit("fit " + exp_ + " --out " + out + " --quiet", dir_);
  const std::string cp = out + ".partial/checkpoint.yaml";
  for (int i = 0; i < 60000 && ReadFile(cp).find("\niterations: 1\n") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  fit.Signal(SIGKILL);
  ASSERT_EQ(fit.Wait().signal, SIGKILL);
  const std::string original = ReadFile(log_);
  // the same experiment with another truth writes log.h5 again
  std::string other = Experiment(2000, 50);
  other.replace(other.find("damping: 0.08"), 13, "damping: 0.09");
  WriteFile(dir_ + "/other.yaml", other);
  ASSERT_EQ(Run("simulate " + dir_ + "/other.yaml --force").code, 0);  // another experiment's
  ASSERT_NE(ReadFile(log_), original);
  ExpectRefused("fit --resume " + out + " --quiet",
                {"sysid fit: --resume " + out + ": the inputs changed since the checkpoint of run ",
                 log_ + " (log) changed", "fit again without --resume, or restore the file"});
  EXPECT_TRUE(fs::exists(cp));
  WriteFile(log_, original);
  const Ended resumed = Run("fit --resume " + out + " --quiet");
  EXPECT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_EQ(io::ReadResult(out).status, "converged");
}

// ---------------------------------------------------------------------------------------------
// write failures

// the new result does not fit: the estimates are printed, the error names the file and the
// system's reason, the previous result stays
void ExpectWriteFailureKeepsPrevious(const Ended& e, const std::string& out,
                                     const std::map<std::string, std::string>& before,
                                     const std::string& reason) {
  EXPECT_EQ(e.signal, 0);
  EXPECT_EQ(e.code, 1) << e.err;
  EXPECT_NE(e.err.find(reason), std::string::npos) << e.err;
  EXPECT_NE(e.err.find(out + ".partial/"), std::string::npos) << e.err;
  EXPECT_EQ(e.err.find("HDF5"), std::string::npos) << e.err;
  EXPECT_NE(e.out.find("damping"), std::string::npos) << e.out;
  EXPECT_NE(e.out.find("estimate"), std::string::npos) << e.out;
  EXPECT_EQ(Snapshot(out), before);
}

TEST_F(SysidOutputsTest, FileSizeLimitKeepsThePreviousResult) {
  const std::string out = dir_ + "/res";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + out + " --quiet").code, 0);
  const auto before = Snapshot(out);
  ASSERT_GT(fs::file_size(out + "/result.h5"), 16u * 1024);
  // bash's ulimit -f counts KiB; SIGXFSZ ignored: write() fails with EFBIG
  const Ended e =
      Process("fit " + exp_ + " --out " + out + " --quiet", dir_, "ulimit -f 16; trap '' XFSZ; ")
          .Wait();
  ExpectWriteFailureKeepsPrevious(e, out, before, "File too large");
}

TEST_F(SysidOutputsTest, FullDiskKeepsThePreviousResult) {
  const std::string mnt = dir_ + "/small";
  fs::create_directories(mnt);
  if (mount("tmpfs", mnt.c_str(), "tmpfs", 0, "size=1m") != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs here (" << std::strerror(errno)
                 << "): FileSizeLimitKeepsThePreviousResult covers a failing write";
  }
  const std::string out = mnt + "/res";
  ASSERT_EQ(Run("fit " + exp_ + " --out " + out + " --quiet").code, 0);
  const auto before = Snapshot(out);
  // fill the disk but 12 KiB: the checkpoint fits, result.h5 does not
  const fs::space_info space = fs::space(mnt);
  WriteFile(mnt + "/filler", std::string(space.available - 12 * 1024, 'x'));
  const Ended e = Run("fit " + exp_ + " --out " + out + " --quiet");
  ExpectWriteFailureKeepsPrevious(e, out, before, "No space left on device");
}

// ---------------------------------------------------------------------------------------------
// kill loop

// 60 runs of simulate, fit and report, each sent SIGTERM, SIGKILL, SIGINT or two SIGTERMs at a
// random moment of its run; after each, the result folder is one complete run (ReadResult checks
// the run ids), the previous one or a new one, and the log is the previous one or a valid new one
TEST_F(SysidOutputsTest, KillLoopNeverLosesOrMixesResults) {
  WriteFile(exp_, Experiment(1000, 15));
  ASSERT_EQ(Run("simulate " + exp_).code, 0);
  const std::string out = dir_ + "/res";
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(Run("fit " + exp_ + " --out " + out + " --quiet").code, 0);
  const double fit_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::string run = io::ReadResult(out).run_id;
  std::string log_bytes = ReadFile(log_);
  std::mt19937 random(12345);
  int kills = 0, killed_midway = 0, interrupted = 0;
  const char* commands[] = {"simulate", "fit", "fit", "report"};
  const int signals[] = {SIGTERM, SIGKILL, SIGINT, 0 /* two SIGTERMs */};
  for (int i = 0; i < 60; ++i) {
    const std::string what = commands[random() % 4];
    const int sig = signals[random() % 4];
    SCOPED_TRACE(what + " kill " + std::to_string(i) + " signal " + std::to_string(sig));
    const std::string args = what == "simulate" ? "simulate " + exp_
                             : what == "fit"    ? "fit " + exp_ + " --out " + out + " --quiet"
                                                : "report " + out;
    Process p(args, dir_);
    const double delay = std::uniform_real_distribution<double>(0, 1.2 * fit_s)(random);
    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
    p.Signal(sig ? sig : SIGTERM);
    if (!sig) p.Signal(SIGTERM);
    const Ended e = p.Wait();
    ++kills;
    killed_midway += e.signal != 0;
    interrupted += e.code == 1;
    // the result folder: one complete run, the previous one or a new one
    io::FitResultFile r;
    ASSERT_NO_THROW(r = io::ReadResult(out)) << e.err;
    if (r.run_id != run) {
      EXPECT_EQ(what, "fit");
      run = r.run_id;
    }
    // the log: the previous bytes or a valid new log
    const std::string now = ReadFile(log_);
    if (now != log_bytes) {
      EXPECT_EQ(what, "simulate");
      EXPECT_NO_THROW(io::ReadLog(log_));
      log_bytes = now;
    }
    // a report that finished belongs to the folder's run
    if (what == "report" && e.code == 0) {
      EXPECT_NO_THROW(io::ReadResult(out));
    }
  }
  std::printf(
      "[ measured ] %d kills: %d ended by the signal, %d interrupted fits (exit 1), "
      "one fit %.2f s\n",
      kills, killed_midway, interrupted, fit_s);
  EXPECT_GE(kills, 50);
  // the signals landed during the runs, not after them (measured: 22 to 48 of 60)
  EXPECT_GE(killed_midway + interrupted, 15);
}

}  // namespace
