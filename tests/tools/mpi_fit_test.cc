// `mpirun -n N sysid fit` through the real launcher (OpenMPI, TCP forced, --oversubscribe): the
// sharded fit gives the estimates and iteration count of the fit on one rank with 1, 2 and 4 ranks
// and 1 or 2 threads, in single shooting, multiple shooting (fixed and auto) and with estimated
// initial states (their states eliminated per sequence on the owning rank; against the
// one-process joint fit within a small fraction of a standard error) and with --starts; bad input
// ends the run with exit 2 and the message; a stop signal to mpirun ends the fit after the
// iteration;
// a parameter without effect on the data is found across the ranks' shares of the start; a worker
// killed mid-fit ends the run naming the rank and host, its last checkpoint stays and
// `--resume` continues it to the uninterrupted estimate; `sysid simulate` shards its rollouts.
// Label `mpi` (docs/cluster.md).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"
#include "tests/temp_dir_test.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::Shell;

// mpirun with N ranks, the network path forced (TCP over loopback, no shared memory), as root,
// more ranks than cores; `marker` is exported to every rank (to find a rank's process)
std::string Mpirun(int ranks, const std::string& marker = "none") {
  return std::string(MJSYSID_MPIEXEC) +
         " --allow-run-as-root --oversubscribe --mca pml ob1 --mca btl tcp,self"
         " --mca btl_tcp_if_include lo -x MJSYSID_TEST_MARKER=" +
         marker + " -n " + std::to_string(ranks) + " ";
}

const std::string kSysid = MJSYSID_SYSID_BIN;

// got is want's fit: the same iterations, residual count and status, every estimate and standard
// error to 1e-12 relative (the ranks' tree gives the same bits)
void ExpectSameFit(const io::FitResultFile& got, const io::FitResultFile& want) {
  EXPECT_EQ(got.iterations, want.iterations);
  EXPECT_EQ(got.num_residuals, want.num_residuals);
  EXPECT_EQ(got.status, want.status);
  ASSERT_EQ(got.parameters.size(), want.parameters.size());
  for (size_t i = 0; i < want.parameters.size(); ++i) {
    SCOPED_TRACE(want.parameters[i].name);
    const double v = want.parameters[i].value, se = want.parameters[i].std_error;
    EXPECT_NEAR(got.parameters[i].value, v, 1e-12 * std::abs(v));
    EXPECT_NEAR(got.parameters[i].std_error, se, 1e-12 * se);
  }
}

// got: the fits of one process, 1 rank and 2 ranks (MpiFitTest::FitOneTwo). 2 ranks give the
// iterations and every estimate of 1 rank (1e-12 relative: the same tree of sums), and the one
// process agrees within `se_fraction` standard errors (another path to the same minimum)
void ExpectRanksAgree(const std::vector<io::FitResultFile>& got, double se_fraction) {
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[2].iterations, got[1].iterations);
  ASSERT_EQ(got[2].parameters.size(), got[1].parameters.size());
  ASSERT_EQ(got[0].parameters.size(), got[1].parameters.size());
  for (size_t i = 0; i < got[1].parameters.size(); ++i) {
    SCOPED_TRACE(got[1].parameters[i].name);
    const double v = got[1].parameters[i].value, se = got[1].parameters[i].std_error;
    EXPECT_NEAR(got[2].parameters[i].value, v, 1e-12 * std::abs(v));
    EXPECT_NEAR(got[0].parameters[i].value, v, se_fraction * se);
  }
}

// the pendulum of experiments/pendulum.yaml with 4 sequences of 1500 steps (truth damping 0.08,
// friction loss 0.03, bob mass 1.2; start 0.2, 0.01, 0.8; noise 1e-3 rad, 1e-2 rad/s, seed 1)
// extra: top-level keys; solver: more solver keys ("loss: {...}, "). The statistical stop
// (solver.gauss_newton_stop, sysid/solve/gn_convergence.h) is off: a sharded fit does not make it,
// and the fit of one process is compared with the sharded ones to 1e-6 standard errors
std::string Experiment(int steps, const std::string& extra = "", const std::string& solver = "") {
  return std::string("name: pendulum_mpi\nmodel: ") + MJSYSID_MODELS_DIR +
         "/pendulum.xml\n"
         "data: logs/pendulum.h5\nsensor_time: pre\n"
         "sensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.01}\n"
         "parameters:\n"
         "  - {name: damping, target: joint_damping, object: hinge, initial: 0.2, bounds: "
         "[1.0e-4, 5.0], transform: log}\n"
         "  - {name: frictionloss, target: joint_frictionloss, object: hinge, initial: 0.01, "
         "bounds: [1.0e-4, 2.0], transform: log}\n"
         "  - {name: bob_mass, target: body_mass, object: bob, initial: 0.8, bounds: [0.05, "
         "10.0], transform: log}\n"
         "solver: {" +
         solver +
         "max_iterations: 50, jacobian: auto, threads: 1, verbose: false, gauss_newton_stop: 0}\n" +
         extra +
         "simulate:\n  truth: {damping: 0.08, frictionloss: 0.03, bob_mass: 1.2}\n"
         "  sequences: 4\n  steps: " +
         std::to_string(steps) +
         "\n  seed: 1\n"
         "  excitation: {type: sines, amplitude: 2.0, frequencies: [0.3, 0.8, 1.7, 3.1]}\n"
         "  noise: {angle: 0.001, rate: 0.01}\n  initial_state: {qpos: [0.3], qvel: [0.0]}\n";
}

class MpiFitTest : public test::TempDirTest {
 protected:
  void Write(int steps, const std::string& extra = "", const std::string& solver = "") {
    exp_ = Path("exp.yaml");
    test::WriteFile(exp_, Experiment(steps, extra, solver));
    const CliRun sim = Shell(kSysid + " simulate " + exp_);
    ASSERT_EQ(sim.code, 0) << sim.output;
  }

  // `sysid fit` of exp_ into Path(out) under `launcher` ("" = one process, else Mpirun(N)) with
  // `flags`: it must exit 0; its result into *got. Call inside ASSERT_NO_FATAL_FAILURE.
  void Fit(const std::string& launcher, const std::string& out, const std::string& flags,
           io::FitResultFile* got) {
    const CliRun run = Shell(launcher + kSysid + " fit " + exp_ + " --out " + Path(out) + flags);
    ASSERT_EQ(run.code, 0) << run.output;
    *got = io::ReadResult(Path(out));
  }

  // the fit under mpirun with `ranks` ranks x `threads` threads is want's (ExpectSameFit), with the
  // same bits of `signal` (SequenceResult::simulated_initial or simulated_final) in every sequence
  void FitOnRanks(int ranks, int threads, const io::FitResultFile& want,
                  RowMatrix SequenceResult::*signal) {
    const std::string n = std::to_string(ranks), t = std::to_string(threads);
    SCOPED_TRACE(n + " ranks x " + t + " threads");
    io::FitResultFile got;
    ASSERT_NO_FATAL_FAILURE(Fit(Mpirun(ranks), "r" + n + "t" + t, " --quiet --threads " + t, &got));
    ExpectSameFit(got, want);
    ASSERT_EQ(got.sequences.size(), want.sequences.size());
    for (size_t q = 0; q < want.sequences.size(); ++q) {
      EXPECT_TRUE(got.sequences[q].*signal == want.sequences[q].*signal) << want.sequences[q].name;
    }
  }

  // the fit of one process, then under mpirun with 1 and 2 ranks (each with `flags`)
  void FitOneTwo(const std::string& name, const std::string& flags,
                 std::vector<io::FitResultFile>* got) {
    for (const std::string& launcher : {std::string(), Mpirun(1), Mpirun(2)}) {
      got->emplace_back();
      ASSERT_NO_FATAL_FAILURE(
          Fit(launcher, name + std::to_string(got->size() - 1), flags, &got->back()));
    }
  }

  // starts `sysid fit` of exp_ into Path(out) under `launcher` in the background (the shell execs
  // it: *pid is the launcher's; its output into Path(out + ".log")) and returns once its
  // checkpoint has reached `iterations` (waits at most 60 s). Call inside ASSERT_NO_FATAL_FAILURE.
  void StartFitUntil(const std::string& launcher, const std::string& out, int iterations,
                     pid_t* pid) {
    const std::string cp = Path(out + ".partial/checkpoint.yaml");
    const std::string reached = "\niterations: " + std::to_string(iterations) + "\n";
    *pid = fork();
    if (*pid == 0) {
      const std::string cmd = "exec " + launcher + kSysid + " fit " + exp_ + " --out " + Path(out) +
                              " --quiet --threads 1 >" + Path(out + ".log") + " 2>&1";
      execl("/bin/sh", "sh", "-c", cmd.c_str(), nullptr);
      _exit(127);
    }
    for (int i = 0; i < 600000 && test::ReadFile(cp).find(reached) == std::string::npos; ++i) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    ASSERT_NE(test::ReadFile(cp).find(reached), std::string::npos);
  }

  std::string exp_;
};

// truth: the fit under mpirun with 1 rank and 1 thread; 2 and 4 ranks and 1 or 2 threads must give
// every estimate to 1e-12 relative (measured: bitwise equal, the tree of sysid/mpi/shards.h), the
// same iterations, intervals and status, and the same initial signals of every sequence. The fit
// without MPI (one full Jacobian, Ceres' own QR) differs by rounding only: measured 9e-11 relative,
// here within 1e-6 standard errors.
TEST_F(MpiFitTest, SameEstimatesWithAnyRanksAndThreads) {
  Write(1500);
  io::FitResultFile want, here;
  ASSERT_NO_FATAL_FAILURE(Fit(Mpirun(1), "ref", " --quiet --threads 1", &want));
  ASSERT_GE(want.iterations, 3);
  ASSERT_NO_FATAL_FAILURE(Fit("", "plain", " --quiet", &here));
  ASSERT_EQ(here.parameters.size(), want.parameters.size());
  EXPECT_EQ(here.num_residuals, want.num_residuals);
  for (size_t i = 0; i < want.parameters.size(); ++i) {
    EXPECT_NEAR(here.parameters[i].value, want.parameters[i].value,
                1e-6 * want.parameters[i].std_error);
    EXPECT_NEAR(here.parameters[i].std_error, want.parameters[i].std_error,
                1e-6 * want.parameters[i].std_error);
  }
  // the start is sharded: rank 0 rolled out the other ranks' sequences at the initial values
  // for the result only; the same bits as the one rank that simulated all of them
  for (const auto& [ranks, threads] : {std::pair{1, 2}, {2, 1}, {2, 2}, {4, 1}}) {
    FitOnRanks(ranks, threads, want, &SequenceResult::simulated_initial);
  }
}

// a robust loss (Huber, scale 2) acts on each residual before the compression: 2 ranks give the
// bits of 1 rank (1e-12 relative), and the fit without MPI to rounding (measured 1.5e-11
// relative; here 1e-6 standard errors)
TEST_F(MpiFitTest, RobustLossIsSharded) {
  Write(600, "", "loss: {type: huber, scale: 2.0}, ");
  std::vector<io::FitResultFile> got;
  ASSERT_NO_FATAL_FAILURE(FitOneTwo("huber", " --quiet", &got));
  for (const io::FitResultFile& f : got) EXPECT_EQ(f.solver.at("loss"), "huber");
  ExpectRanksAgree(got, 1e-6);
}

// Multiple shooting (segments of 100 steps: 6 per sequence, 5 free states each) is sharded by
// whole sequences, each sequence's states solved and eliminated on its rank (variable projection,
// sysid/mpi/state_projection.h). Truth: the fit under mpirun with 1 rank; 2 ranks x 1 thread and
// 4 ranks x 2 threads give every estimate and standard error to 1e-12 relative (measured: the
// same bits), the same iterations and status and the same final signals of every sequence (which
// come from the states rank 0 collects). The one-process fit optimises states and parameters
// jointly (Ceres' Schur solver): another path to the same minimum, within 1e-3 standard errors
// (measured 2e-6) with the absolute continuity weight 1 used here. With the default weights
// relative to the sensors (about 100x stiffer on this log) both paths stop, converged, 0.03-0.04
// standard errors apart (measured at the merge), which this tolerance would not accept.
TEST_F(MpiFitTest, MultipleShootingIsShardedBySequence) {
  Write(600, "multiple_shooting: {segment_steps: 100, continuity_scale: absolute}\n");
  io::FitResultFile one, want;
  ASSERT_NO_FATAL_FAILURE(Fit("", "joint", " --quiet", &one));
  ASSERT_NO_FATAL_FAILURE(Fit(Mpirun(1), "ref", " --quiet --threads 1", &want));
  EXPECT_EQ(want.segment_steps_used, 100);
  EXPECT_EQ(want.status, "converged");
  EXPECT_EQ(want.num_residuals, one.num_residuals);
  ASSERT_EQ(want.parameters.size(), one.parameters.size());
  for (size_t i = 0; i < want.parameters.size(); ++i) {
    SCOPED_TRACE(want.parameters[i].name);
    EXPECT_NEAR(want.parameters[i].value, one.parameters[i].value,
                1e-3 * one.parameters[i].std_error);
    EXPECT_NEAR(want.parameters[i].std_error, one.parameters[i].std_error,
                1e-3 * one.parameters[i].std_error);
  }
  for (const auto& [ranks, threads] : {std::pair{2, 1}, {4, 2}}) {
    FitOnRanks(ranks, threads, want, &SequenceResult::simulated_final);
  }
}

// Estimated initial states (one free state per sequence) are eliminated the same way: 2 ranks give
// the bits of 1 rank (1e-12 relative), and the one-process joint fit agrees within 1e-3 standard
// errors (measured 1.4e-5)
TEST_F(MpiFitTest, EstimatedInitialStatesAreSharded) {
  Write(600, "initial_state: {estimate: true}\n");
  std::vector<io::FitResultFile> got;
  ASSERT_NO_FATAL_FAILURE(FitOneTwo("x0_", " --quiet --threads 1", &got));
  ExpectRanksAgree(got, 1e-3);
  for (size_t i = 0; i < got[0].parameters.size(); ++i) {
    const double se = got[1].parameters[i].std_error;
    EXPECT_NEAR(got[0].parameters[i].std_error, se, 1e-3 * se) << got[0].parameters[i].name;
  }
  for (size_t q = 0; q < got[0].sequences.size(); ++q) {
    EXPECT_TRUE(got[2].sequences[q].simulated_final == got[1].sequences[q].simulated_final);
  }
}

// `multiple_shooting: auto` under mpirun: every rank probes every sequence, so the segments are
// those of one process. The double pendulum released at (2.5, -2.0) rad (chaotic; 2 sequences of
// 2000 steps, chirp 0.5 N m, noise 1e-3 rad and 1e-2 rad/s; truth link masses 1.2 and 0.6 from 0.7
// and 1.1): one process chooses segments of 189 steps from the crossing in sequence 'seq1'
// (measured), which rank 1 owns under 2 ranks; 1 and 2 ranks choose the same length and reason,
// give the same estimates to 1e-12 relative, and agree with the one-process joint fit within 1e-3
// standard errors (measured: the same 8 printed digits)
TEST_F(MpiFitTest, AutoChoosesTheSameSegments) {
  const std::string models = MJSYSID_MODELS_DIR;
  exp_ = Path("dp.yaml");
  test::WriteFile(
      exp_, "name: dp_auto\nmodel: " + models +
                "/double_pendulum.xml\ndata: logs/dp.h5\n"
                "sensors:\n  - {name: q1, sigma: 0.001}\n  - {name: q2, sigma: 0.001}\n"
                "  - {name: v1, sigma: 0.01}\n  - {name: v2, sigma: 0.01}\n"
                "parameters:\n"
                "  - {name: link1_mass, target: body_mass_inertia, object: link1, initial: 0.7, "
                "bounds: [0.05, 10.0], transform: log}\n"
                "  - {name: link2_mass, target: body_mass_inertia, object: link2, initial: 1.1, "
                "bounds: [0.05, 10.0], transform: log}\n"
                "solver: {max_iterations: 50, jacobian: auto, threads: 1}\n"
                "multiple_shooting: {continuity_weight: 10}\n"
                "simulate:\n  truth: {link1_mass: 1.2, link2_mass: 0.6}\n  sequences: 2\n"
                "  steps: 2000\n  seed: 2\n"
                "  excitation: {type: chirp, amplitude: 0.5, f0: 0.2, f1: 3.0}\n"
                "  noise: {q1: 0.001, q2: 0.001, v1: 0.01, v2: 0.01}\n"
                "  initial_state: {qpos: [2.5, -2.0]}\n");
  const CliRun sim = Shell(kSysid + " simulate " + exp_);
  ASSERT_EQ(sim.code, 0) << sim.output;
  std::vector<io::FitResultFile> got;
  ASSERT_NO_FATAL_FAILURE(FitOneTwo("auto", " --quiet --threads 1", &got));
  EXPECT_GT(got[0].segment_steps_used, 0) << SegmentReasonText(got[0].segment_reason);
  EXPECT_LT(got[0].segment_steps_used, 2000) << SegmentReasonText(got[0].segment_reason);
  for (int i : {1, 2}) {
    EXPECT_EQ(got[i].segment_steps_used, got[0].segment_steps_used);
    EXPECT_EQ(SegmentReasonText(got[i].segment_reason), SegmentReasonText(got[0].segment_reason));
    EXPECT_EQ(got[i].status, "converged");
  }
  ExpectRanksAgree(got, 1e-3);
}

// `sysid simulate` under mpirun shards the rollouts (3 ranks, 4 sequences: shares of 1, 1 and 2)
// and rank 0 writes: every dataset equals the log of one process, bit for bit
TEST_F(MpiFitTest, SimulateIsShardedAndEqual) {
  Write(400);
  const CliRun sharded = Shell(Mpirun(3) + kSysid + " simulate " + exp_ + " --out " + Path("s.h5"));
  ASSERT_EQ(sharded.code, 0) << sharded.output;
  const io::Log want = io::ReadLog(Path("logs/pendulum.h5")), got = io::ReadLog(Path("s.h5"));
  ASSERT_EQ(got.sequences.size(), want.sequences.size());
  for (size_t i = 0; i < want.sequences.size(); ++i) {
    SCOPED_TRACE(want.sequences[i].name);
    EXPECT_EQ(got.sequences[i].name, want.sequences[i].name);
    EXPECT_TRUE(got.sequences[i].sensordata == want.sequences[i].sensordata);
    EXPECT_TRUE(got.sequences[i].qpos == want.sequences[i].qpos);
    EXPECT_TRUE(got.sequences[i].qvel == want.sequences[i].qvel);
    EXPECT_TRUE(got.sequences[i].ctrl == want.sequences[i].ctrl);
  }
  // one writer: the summary printed once
  EXPECT_EQ(sharded.output.find("wrote"), sharded.output.rfind("wrote")) << sharded.output;
}

// --starts 3 under mpirun: every start a whole sharded fit, one after another (the workers build
// each start's Problem from the values rank 0 broadcasts). Truth: the report of one process (the
// same spread starts, seed 0); 1 and 2 ranks give every start's estimate, cost and iterations to
// 1e-12 relative and the same best start; one process agrees within 1e-6 standard errors
// (measured: the same printed digits)
TEST_F(MpiFitTest, StartsRunOneAfterAnother) {
  Write(600);
  std::vector<io::FitResultFile> got;
  for (const std::string& launcher : {std::string(), Mpirun(1), Mpirun(2)}) {
    const std::string out = Path("starts" + std::to_string(got.size()));
    const CliRun run = Shell(launcher + kSysid + " fit " + exp_ + " --out " + out +
                             " --quiet --threads 1 --starts 3");
    ASSERT_EQ(run.code, 0) << run.output;
    EXPECT_NE(run.output.find("3 starts (3 converged"), std::string::npos) << run.output;
    got.push_back(io::ReadResult(out));
    ASSERT_EQ(got.back().starts.size(), 3u);
  }
  for (int i : {1, 2}) EXPECT_EQ(got[i].best_start, got[0].best_start);
  for (size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE("start " + std::to_string(k));
    const StartResult &a = got[1].starts[k], &b = got[2].starts[k];
    EXPECT_EQ(b.iterations, a.iterations);
    EXPECT_NEAR(b.final_cost, a.final_cost, 1e-12 * a.final_cost);
    ASSERT_EQ(b.estimate.size(), a.estimate.size());
    for (Eigen::Index j = 0; j < a.estimate.size(); ++j) {
      EXPECT_NEAR(b.estimate[j], a.estimate[j], 1e-12 * std::abs(a.estimate[j]));
    }
  }
  for (size_t i = 0; i < got[0].parameters.size(); ++i) {
    SCOPED_TRACE(got[0].parameters[i].name);
    const double se = got[1].parameters[i].std_error;
    EXPECT_NEAR(got[0].parameters[i].value, got[1].parameters[i].value, 1e-6 * se);
  }
}

// bad input ends the run on every rank with exit 2 and one message; no result folder is written
TEST_F(MpiFitTest, BadInputEndsEveryRank) {
  Write(300);
  // a log only rank 1 cannot read (its node lacks the file: rank 1 reads the experiment from a
  // folder without logs/, by mpirun's MPMD form "-n 1 A : -n 1 B"): found before the fit, rank 0
  // reports it naming rank 1 and its host, exit 2
  test::WriteFile(exp_, Experiment(300));
  ASSERT_EQ(Shell(kSysid + " simulate " + exp_).code, 0);
  fs::create_directories(Path("node1"));
  test::WriteFile(Path("node1/exp.yaml"), Experiment(300));
  const std::string mpmd = std::string(MJSYSID_MPIEXEC) +
                           " --allow-run-as-root --oversubscribe --mca pml ob1 --mca btl tcp,self"
                           " --mca btl_tcp_if_include lo -n 1 " +
                           kSysid + " fit " + exp_ + " --out " + Path("one") + " --quiet : -n 1 " +
                           kSysid + " fit " + Path("node1/exp.yaml") + " --out " + Path("one") +
                           " --quiet";
  const CliRun one = Shell(mpmd);
  EXPECT_EQ(one.code, 2) << one.output;
  char host[256] = {0};
  gethostname(host, sizeof(host) - 1);
  EXPECT_NE(one.output.find(std::string("rank 1 on host ") + host), std::string::npos)
      << one.output;
  EXPECT_NE(one.output.find("node1/logs/pendulum.h5"), std::string::npos) << one.output;
  EXPECT_FALSE(fs::exists(Path("one")));
  // a log no rank can read: the message once (rank 0 reports), exit 2
  fs::remove(Path("logs/pendulum.h5"));
  const CliRun bad =
      Shell(Mpirun(2) + kSysid + " fit " + exp_ + " --out " + Path("bad") + " --quiet");
  EXPECT_EQ(bad.code, 2) << bad.output;
  EXPECT_NE(bad.output.find("pendulum.h5"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(Path("bad")));
}

// Each rank simulates only its own sequences at the start; the ranks combine what they saw before
// the fit. A parameter without effect on any sequence (the bob's sliding friction: the pendulum
// touches nothing, so its Jacobian column is exactly zero): 1 and 2 ranks alike end with exit 2,
// the message printed once (rank 0), no result folder
TEST_F(MpiFitTest, NoEffectIsFoundAcrossRanks) {
  Write(300);
  std::string text = Experiment(300);
  const std::string key = "parameters:\n";
  text.insert(text.find(key) + key.size(),
              "  - {name: bob_friction, target: geom_friction, object: bob, index: 0, initial: "
              "1.0, bounds: [0.1, 2.0]}\n");
  test::WriteFile(exp_, text);
  for (int ranks : {1, 2}) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks");
    const std::string out = Path("none" + std::to_string(ranks));
    const CliRun run =
        Shell(Mpirun(ranks) + kSysid + " fit " + exp_ + " --out " + out + " --quiet");
    EXPECT_EQ(run.code, 2) << run.output;
    const std::string message = "parameter 'bob_friction' has no effect";
    EXPECT_NE(run.output.find(message), std::string::npos) << run.output;
    EXPECT_EQ(run.output.find(message), run.output.rfind(message)) << run.output;
    EXPECT_FALSE(fs::exists(out));
  }
  // a parameter that moves only rank 1's sequences: the motor's gear, with rank 0's two sequences
  // undriven (simulated with amplitude 0: the gear's column is exactly zero there). Rank 0 alone
  // would call it without effect; the ranks' logical or says it moves the data, so the 2-rank fit
  // is not refused (exit 2 is bad input; measured: exit 4, the status jacobian_unreliable of this
  // stick-slip fit, gear 1.11 +- 0.46 for truth 1) and gives the gear an interval
  std::string still = Experiment(300);
  still.replace(still.find("amplitude: 2.0"), 14, "amplitude: 0.0");
  still.replace(still.find("logs/pendulum.h5"), 16, "logs/still.h5");
  test::WriteFile(Path("still.yaml"), still);
  const CliRun sim = Shell(kSysid + " simulate " + Path("still.yaml"));
  ASSERT_EQ(sim.code, 0) << sim.output;
  io::Log log = io::ReadLog(Path("logs/pendulum.h5"));
  const io::Log undriven = io::ReadLog(Path("logs/still.h5"));
  ASSERT_EQ(log.sequences.size(), 4u);
  for (int q : {0, 1}) log.sequences[q] = undriven.sequences[q];
  ASSERT_EQ(log.sequences[0].ctrl.norm(), 0.0);
  io::WriteLog(Path("logs/pendulum.h5"), log);
  text = Experiment(300);
  text.insert(text.find(key) + key.size(),
              "  - {name: gear, target: actuator_gear, object: torque, initial: 1.3, bounds: "
              "[0.5, 2.0]}\n");
  test::WriteFile(exp_, text);
  const CliRun run = Shell(Mpirun(2) + kSysid + " fit " + exp_ + " --out " + Path("gear") +
                           " --quiet --threads 1");
  EXPECT_NE(run.code, 2) << run.output;
  EXPECT_EQ(run.output.find("has no effect"), std::string::npos) << run.output;
  const io::FitResultFile got = io::ReadResult(Path("gear"));
  ASSERT_EQ(got.parameters.size(), 4u);
  EXPECT_EQ(got.parameters[0].name, "gear");
  EXPECT_GT(got.parameters[0].std_error, 0.0) << "the gear has an interval";
  EXPECT_TRUE(std::isfinite(got.parameters[0].std_error));
}

// the pid of the process of `rank` started with marker (its environment: OMPI_COMM_WORLD_RANK)
int FindRank(const std::string& marker, int rank) {
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream env(e.path() / "environ");
    std::stringstream ss;
    ss << env.rdbuf();
    const std::string s = ss.str();
    if (s.find("MJSYSID_TEST_MARKER=" + marker + '\0') != std::string::npos &&
        s.find("OMPI_COMM_WORLD_RANK=" + std::to_string(rank) + '\0') != std::string::npos) {
      return std::stoi(name);
    }
  }
  return -1;
}

// rank 1 of 2 killed (SIGKILL) after the checkpoint of iteration 2: the run ends with an error
// naming rank 1 and the host, the checkpoint stays, and `--resume` (2 ranks again) ends at the
// uninterrupted estimate to 1e-3 standard errors (as tests/tools/sysid_outputs_test.cc: Ceres'
// trust region restarts at the checkpoint)
TEST_F(MpiFitTest, KilledRankEndsTheRunAndResumeContinues) {
  Write(3000);
  io::FitResultFile want;
  ASSERT_NO_FATAL_FAILURE(Fit(Mpirun(2), "full", " --quiet --threads 1", &want));
  ASSERT_GE(want.iterations, 4);
  const std::string out = Path("part"), cp = out + ".partial/checkpoint.yaml";
  const std::string marker = "kill" + std::to_string(getpid());
  pid_t pid = -1;
  ASSERT_NO_FATAL_FAILURE(StartFitUntil(Mpirun(2, marker), "part", 2, &pid));
  const int worker = FindRank(marker, 1);
  ASSERT_GT(worker, 0);
  ASSERT_EQ(kill(worker, SIGKILL), 0);
  int status = 0;
  waitpid(pid, &status, 0);
  const std::string said = test::ReadFile(out + ".log");
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 0) << said;
  char host[256] = {0};
  gethostname(host, sizeof(host) - 1);
  EXPECT_NE(said.find("rank 1"), std::string::npos) << said;
  EXPECT_NE(said.find(host), std::string::npos) << said;
  EXPECT_FALSE(fs::exists(out + "/result.yaml"));
  ASSERT_TRUE(fs::exists(cp));
  const CliRun resumed =
      Shell(Mpirun(2) + kSysid + " fit --resume " + out + " --quiet --threads 1");
  ASSERT_EQ(resumed.code, 0) << resumed.output;
  const io::FitResultFile got = io::ReadResult(out);
  EXPECT_EQ(got.status, "converged");
  EXPECT_GE(got.iterations, 2);
  for (size_t i = 0; i < want.parameters.size(); ++i) {
    SCOPED_TRACE(want.parameters[i].name);
    EXPECT_NEAR(got.parameters[i].value, want.parameters[i].value,
                1e-3 * want.parameters[i].std_error);
  }
}

// SIGTERM to mpirun (as Ctrl-C or a scheduler's stop; mpirun forwards it to every rank) after
// the checkpoint of iteration 1: the workers note it and keep serving, the ranks stop after the
// current iteration, rank 0 writes the result of the last good iterate once (status
// interrupted, no intervals) and the run ends with exit 1, the documented interrupted code,
// before the uninterrupted fit's iteration count (truth: the same fit without the signal).
// mpirun passes the signal on through its kill sequence (OpenMPI 4.1: SIGCONT, a wait of
// odls_base_sigkill_timeout seconds, SIGTERM, the same wait, SIGKILL; default 1 s), so the ranks
// see the signal T s after mpirun and have T s to end the iteration. With the default 1 s a
// loaded machine killed the ranks inside an iteration of this log (no result written); the test
// sets T to about two iterations of the uninterrupted fit (at least 2 s), so the signal arrives
// mid-fit and the iteration can end (docs/cluster.md).
TEST_F(MpiFitTest, StopSignalEndsAfterTheIteration) {
  Write(60000);
  io::FitResultFile want;
  ASSERT_NO_FATAL_FAILURE(Fit(Mpirun(2), "full", " --quiet --threads 1", &want));
  ASSERT_GE(want.iterations, 6);
  const int wait_s = std::max(2, static_cast<int>(std::ceil(2 * want.seconds / want.iterations)));
  const std::string mpirun =
      Mpirun(2) + "--mca odls_base_sigkill_timeout " + std::to_string(wait_s) + " ";
  const std::string out = Path("stopped");
  pid_t pid = -1;
  ASSERT_NO_FATAL_FAILURE(StartFitUntil(mpirun, "stopped", 1, &pid));
  ASSERT_EQ(kill(pid, SIGTERM), 0);
  int status = 0;
  waitpid(pid, &status, 0);
  const std::string said = test::ReadFile(out + ".log");
  ASSERT_TRUE(WIFEXITED(status)) << said;
  EXPECT_EQ(WEXITSTATUS(status), 1) << said;
  EXPECT_NE(said.find("results of the last good iterate written"), std::string::npos) << said;
  const io::FitResultFile got = io::ReadResult(out);
  EXPECT_EQ(got.status, "interrupted");
  EXPECT_GE(got.iterations, 1);
  EXPECT_LT(got.iterations, want.iterations);
  for (const auto& p : got.parameters) EXPECT_TRUE(std::isfinite(p.value)) << p.name;
}

}  // namespace
}  // namespace mjsysid
