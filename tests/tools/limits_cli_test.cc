// Threads and memory bounded, through the real CLI (issue 35, item 4; docs/bad-input.md, "Issue
// 35: threads and memory"): one cap on threads for the command line and the experiment file
// (core/thread_pool.h kMaxThreads), and a fit refused before it simulates anything when its
// memory estimate (sysid/fit/memory_estimate.h) exceeds the limit (--memory-limit,
// solver.memory_limit_gb), with the estimate and the limit in the message.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::CliStreams;
using mjsysid::test::CountOf;
using mjsysid::test::SysidStreams;
using mjsysid::test::WriteFile;

class LimitsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = mjsysid::test::FreshTempDir("limits_cli");
    log_ = dir_ + "/pendulum.h5";
    WriteFile(dir_ + "/plain.yaml", Experiment(""));
    const CliStreams r = SysidStreams("simulate " + dir_ + "/plain.yaml --out " + log_);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // the pendulum fitting damping from 1 sequence of 300 steps; `solver` lines added to the
  // solver block (each "  key: value\n")
  static std::string Experiment(const std::string& solver) {
    return "name: limits\nmodel: " + std::string(MJSYSID_SOURCE_DIR) +
           "/models/pendulum.xml\ndata: " + log_ +
           "\nsensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "solver:\n  max_iterations: 20\n  verbose: true\n" +
           solver +
           "simulate:\n  truth: {damping: 0.08}\n  sequences: 1\n  steps: 300\n"
           "  noise: {angle: 0.001, rate: 0.01}\n";
  }

  static std::string dir_, log_;
};

std::string LimitsTest::dir_, LimitsTest::log_;

// `sysid fit --threads 1000000` (it started ~32,000 threads and printed nothing): exit 2, the
// cap named ("--threads: expected 0 (all cores) or a whole number from 1 to 256 ... got
// 1000000"), no output folder; the same for `simulate --threads 257` (one bound: it was 4096)
TEST_F(LimitsTest, HugeThreadsFlagIsRefused) {
  const std::string out = dir_ + "/res_threads";
  const CliStreams fit =
      SysidStreams("fit " + dir_ + "/plain.yaml --out " + out + " --threads 1000000");
  EXPECT_EQ(fit.code, 2) << fit.err;
  EXPECT_NE(fit.err.find("sysid fit: --threads: expected 0 (all cores) or a whole number from 1 "
                         "to 256"),
            std::string::npos)
      << fit.err;
  EXPECT_NE(fit.err.find("got 1000000"), std::string::npos) << fit.err;
  EXPECT_FALSE(fs::exists(out));
  const CliStreams sim =
      SysidStreams("simulate " + dir_ + "/plain.yaml --out " + dir_ + "/sim.h5 --threads 257");
  EXPECT_EQ(sim.code, 2) << sim.err;
  EXPECT_NE(sim.err.find("sysid simulate: --threads: expected 0 (all cores) or a whole number "
                         "from 1 to 256"),
            std::string::npos)
      << sim.err;
  EXPECT_FALSE(fs::exists(dir_ + "/sim.h5"));
  // not a number, negative: the same rule
  for (const std::string bad : {"-1", "many"}) {
    const CliStreams r =
        SysidStreams("fit " + dir_ + "/plain.yaml --out " + out + " --threads " + bad);
    EXPECT_EQ(r.code, 2) << bad << ": " << r.err;
    EXPECT_NE(r.err.find("from 1 to 256"), std::string::npos) << r.err;
  }
}

// solver.threads: 100000 in the experiment: exit 2 from fit, check and simulate with
// file:line:column ("threads.yaml:13:12: solver.threads: expected 0 (all cores) or a whole number
// from 1 to 256 ..., got 100000"); 256 itself is accepted (check exits 0)
TEST_F(LimitsTest, HugeSolverThreadsIsRefused) {
  const std::string exp = dir_ + "/threads.yaml";
  WriteFile(exp, Experiment("  threads: 100000\n"));
  for (const std::string sub : {"fit", "check", "simulate"}) {
    SCOPED_TRACE(sub);
    const std::string out = sub == "check" ? "" : " --out " + dir_ + "/res_" + sub;
    const CliStreams r = SysidStreams(sub + " " + exp + out + (sub == "simulate" ? ".h5" : ""));
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("threads.yaml:13:12: solver.threads: expected 0 (all cores) or a whole "
                         "number from 1 to 256"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("got 100000"), std::string::npos) << r.err;
    EXPECT_EQ(CountOf(r.err, "threads.yaml"), 1) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ + "/res_fit"));
  WriteFile(exp, Experiment("  threads: 256\n"));
  const CliStreams ok = SysidStreams("check " + exp);
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// A fit whose estimate exceeds --memory-limit 0.001 (1 MB; a fit holds more than the process's
// own ~48 MB): exit 2 before anything is simulated or written, the message with the estimate,
// the limit and how to reduce the fit or raise the limit ("the fit needs an estimated 0.1.. GB
// (300 samples, ...), more than the limit of 0.001 GB (--memory-limit); fit fewer or shorter
// sequences ..."); no progress line (nothing simulated), no output folder. The same fit with
// --memory-limit 100 runs (exit 0) and prints its estimate under --verbose.
TEST_F(LimitsTest, FitOverTheMemoryLimitIsRefusedBeforeItSimulates) {
  const std::string out = dir_ + "/res_memory";
  const CliStreams r =
      SysidStreams("fit " + dir_ + "/plain.yaml --out " + out + " --memory-limit 0.001");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("plain.yaml: the fit needs an estimated "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("(300 samples, "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("more than the limit of 0.001 GB (--memory-limit)"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("fit fewer or shorter sequences"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("raise the limit with `sysid fit --memory-limit GB` or "
                       "solver.memory_limit_gb"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("iter"), std::string::npos) << r.err;  // the progress table never began
  EXPECT_EQ(r.out, "");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out + ".partial"));

  const CliStreams ok =
      SysidStreams("fit " + dir_ + "/plain.yaml --out " + out + " --memory-limit 100 --verbose");
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_NE(ok.err.find("memory: estimated "), std::string::npos) << ok.err;
  EXPECT_NE(ok.err.find("limit 100 GB"), std::string::npos) << ok.err;
  EXPECT_TRUE(fs::exists(out + "/result.yaml"));
}

// solver.memory_limit_gb: 0.001 in the experiment: the same refusal naming it as the limit's
// source ("(solver.memory_limit_gb)", the file named once); --memory-limit 100 overrides it (exit
// 0); a limit <= 0 or not a number is bad input with file:line:column / the option named
TEST_F(LimitsTest, MemoryLimitFromTheExperimentAndItsOverride) {
  const std::string exp = dir_ + "/memlimit.yaml";
  WriteFile(exp, Experiment("  memory_limit_gb: 0.001\n"));
  const CliStreams r = SysidStreams("fit " + exp + " --out " + dir_ + "/res_ml");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("more than the limit of 0.001 GB (solver.memory_limit_gb)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(CountOf(r.err, "memlimit.yaml"), 1) << r.err;  // the file named once
  EXPECT_FALSE(fs::exists(dir_ + "/res_ml"));
  const CliStreams ok =
      SysidStreams("fit " + exp + " --out " + dir_ + "/res_ml --memory-limit 100 --quiet");
  EXPECT_EQ(ok.code, 0) << ok.err;

  WriteFile(exp, Experiment("  memory_limit_gb: 0\n"));
  const CliStreams zero = SysidStreams("fit " + exp + " --out " + dir_ + "/res_ml0");
  EXPECT_EQ(zero.code, 2) << zero.err;
  EXPECT_NE(zero.err.find("memlimit.yaml:13:20: solver.memory_limit_gb:"), std::string::npos)
      << zero.err;
  for (const std::string bad : {"0", "-2", "lots"}) {
    const CliStreams flag = SysidStreams("fit " + dir_ + "/plain.yaml --out " + dir_ +
                                         "/res_ml1 --memory-limit " + bad);
    EXPECT_EQ(flag.code, 2) << bad << ": " << flag.err;
    EXPECT_NE(flag.err.find("--memory-limit: expected a finite number > 0, got '" + bad + "'"),
              std::string::npos)
        << flag.err;
    EXPECT_LT(flag.err.size(), 200u) << flag.err;  // not CLI11's 309-digit range
  }
  EXPECT_FALSE(fs::exists(dir_ + "/res_ml0"));
  EXPECT_FALSE(fs::exists(dir_ + "/res_ml1"));
}

// an allocation that fails although the estimate was under the limit (the machine is short of
// memory; one thread: here a 300,000-step pendulum log, 14 MB, fitted with --memory-limit 100 under
// a `ulimit -v` 60 MB above what the binary needs to start, measured on this machine with `sysid
// --version` in 5 MB steps): exit 5 with one line "out of memory (std::bad_alloc) during
// ..." (while reading the log or during the fit, wherever the limit is met), never a bare
// std::bad_alloc, never the log reader's "corrupt file?" (its own cap is not the limit that
// failed); no output folder
TEST_F(LimitsTest, AnAllocationThatFailsAnywayIsOutOfMemoryExit5) {
  const std::string exp = dir_ + "/big.yaml";
  std::string text = Experiment("");
  const std::string steps = "steps: 300\n";
  text.replace(text.find(steps), steps.size(), "steps: 300000\n");
  text.replace(text.find("data: " + log_), 6 + log_.size(), "data: " + dir_ + "/big.h5");
  WriteFile(exp, text);
  ASSERT_EQ(SysidStreams("simulate " + exp + " --out " + dir_ + "/big.h5").code, 0);
  long floor_kb = 0;
  for (long kb = 150000; kb <= 2000000 && floor_kb == 0; kb += 5000) {
    const std::string ulimit = "ulimit -v " + std::to_string(kb) + "; ";
    if (SysidStreams("--version", 30, ulimit).code == 0) floor_kb = kb;
  }
  ASSERT_GT(floor_kb, 0) << "sysid --version never started under ulimit -v";
  const std::string ulimit = "ulimit -v " + std::to_string(floor_kb + 60000) + "; ";
  const std::string out = dir_ + "/res_oom";
  const CliStreams r = SysidStreams(
      "fit " + exp + " --out " + out + " --memory-limit 100 --quiet --threads 1", 300, ulimit);
  std::printf("[ measured ] start floor %ld kB; fit under %ld kB: exit %d: %s", floor_kb,
              floor_kb + 60000, r.code, r.err.c_str());
  EXPECT_EQ(r.code, 5) << r.err;
  EXPECT_NE(r.err.find("sysid fit: out of memory (std::bad_alloc) during "), std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("corrupt file?"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  // 40 MB above the start floor (measured here: the limit is met while the log is read): exit 5,
  // not the log reader's "corrupt file?", whose own cap is above the process's limit
  const CliStreams read =
      SysidStreams("fit " + exp + " --out " + out + " --memory-limit 100 --quiet --threads 1", 300,
                   "ulimit -v " + std::to_string(floor_kb + 40000) + "; ");
  std::printf("[ measured ] fit under %ld kB: exit %d: %s", floor_kb + 40000, read.code,
              read.err.c_str());
  EXPECT_EQ(read.code, 5) << read.err;
  EXPECT_EQ(read.err.find("corrupt file?"), std::string::npos) << read.err;
  EXPECT_FALSE(fs::exists(out));
  // with 8 threads the limit may stop a thread's stack first: exit 5 too, one line, either
  // "out of memory" or "could not start a thread (Resource temporarily unavailable)"
  const CliStreams t = SysidStreams(
      "fit " + exp + " --out " + out + " --memory-limit 100 --quiet --threads 8", 300, ulimit);
  std::printf("[ measured ] with 8 threads: exit %d: %s", t.code, t.err.c_str());
  EXPECT_EQ(t.code, 5) << t.err;
  EXPECT_TRUE(t.err.find("sysid fit: out of memory (std::bad_alloc) during ") == 0 ||
              t.err.find("sysid fit: could not start a thread (") == 0)
      << t.err;
  EXPECT_EQ(CountOf(t.err, "\n"), 1) << t.err;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
