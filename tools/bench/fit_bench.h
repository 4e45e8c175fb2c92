// bench_fit's shared pieces (tools/bench/fit_bench.cc has the overview): a row of the table, a
// case, and the functions of its units: the measurements and the host probe
// (fit_bench_host.cc), the methods' fits (fit_bench_methods.cc), and the outputs
// (fit_bench_output.cc).
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/solve/fit_ledger.h"

namespace mjsysid {
namespace bench {

using Clock = std::chrono::steady_clock;

inline double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// one row of the table
struct Row {
  std::string case_name, method, status, note;
  int threads = 1, np = 0, sequences = 0;
  long long samples = 0;  // sum of T over the sequences
  double wall_s = NAN;
  int iterations = 0;
  long long steps = 0;  // simulation step calls (Simulator::StepCount; own count for the others)
  double initial_cost = NAN, final_cost = NAN;
  double max_rel_error = NAN, rms_rel_error = NAN;
  double t_step_us = NAN;    // nominal step time of the case
  double floor_ratio = NAN;  // (wall / iteration) / ((1 + np) * samples * t_step / threads)
  // ours: the point each iteration of the fit simulates (b.parameters' order), and t_step
  // averaged over them with the floor ratio it gives (the path floor)
  std::vector<Eigen::VectorXd> path;
  double path_t_step_us = NAN, path_floor_ratio = NAN;
  std::vector<std::pair<std::string, double>> estimates;
  // the load just before the row (MachineLoad): cores kept busy by other processes over one
  // second, the 1-minute load average, and whether the row ran idle (others <= 0.5 core per
  // thread of the row)
  double others_cores = NAN, load1 = NAN;
  bool idle = true;
  // the host's speed around the row (HostSlowness before and after it, the larger): 1 = as fast
  // as ever measured for the case; attempts: how often the row was measured (kMaxAttempts)
  double host_slowness = NAN;
  int attempts = 1;
  // ours: the fit's ledger (sysid/solve/fit_ledger.h) and the seconds of run::BuildProblem before
  // it (model loading, log reading, not part of wall_s)
  std::vector<LedgerRow> ledger;
  double build_s = NAN;
  // CPU seconds of the whole process (all threads) during the fit: less sensitive than wall time
  // to other processes on the machine (printed with --ledger)
  double cpu_s = NAN;
  // runs of the fit behind the row: wall_s is the fastest (--repeats; the estimates, iterations
  // and steps of every run are the same)
  int runs = 1;
};

// the case: experiment, truth, data
struct Case {
  std::string name;
  io::ExperimentConfig config;
  std::map<std::string, double> truth;
  double t_step = 0;  // seconds per nominal step (1 thread)
  // the problem as built for the step times, and the step time at each point measured so far,
  // relative to the nominal step's measured next to it (so that the host's speed cancels)
  std::shared_ptr<run::BuiltProblem> built;
  std::map<std::vector<double>, double> relative_t_step_at;
  long long samples = 0;
  int sequences = 0;
};

// ---------------------------------------------------------------------------------------------
// measurements and the host (fit_bench_host.cc)

// the process's CPU time (all threads), seconds
double ProcessCpuSeconds();
// the row's parameter errors against the case's truth
void Errors(const Case& c, Row* row);
// the row's floor ratios with the case's t_step as it stands (the fastest measured so far)
void Floor(Case* c, Row* row);
// loads the case and simulates its log when it is missing
Case LoadCase(const std::string& experiments_dir, const std::string& name);
// the case's nominal step time (the model file's values, >= 0.3 s and 3 passes)
void MeasureStep(Case* c);
// the step time at the fitted parameters' values over the nominal step time, measured once per
// point
double RelativeStepTimeAt(Case* c, const Eigen::VectorXd& values);
// before a row of `threads` threads: waits up to wait_s seconds for the machine to be idle for it
// and records the load in the row
void WaitForIdle(int threads, double wait_s, Row* row);
// the row's load note ("" when idle)
std::string LoadNote(const Row& r);
// the CPU's model name (/proc/cpuinfo)
std::string Machine();

// how a row is measured (bench_fit's --idle-wait, --repeats, --repeat-budget)
struct Repeats {
  double idle_wait = 30;
  int repeats = 5;
  double repeat_budget = 1.5;
};
// One row of fit(): the load checked (and waited for) and the host probed around the fastest of
// up to r.repeats runs; measured again while the host ran slow (up to kMaxAttempts in all).
Row MeasureRow(Case* c, int threads, const Repeats& r, const std::function<Row()>& fit);

// ---------------------------------------------------------------------------------------------
// the methods (fit_bench_methods.cc)

// ours and the whole-rollout oracle: the product's own fit with one Jacobian setting
// auto_start: every parameter `initial: auto` (the equation-error start,
// sysid/data/equation_error.h) reduce: the reduced model (FitOptions::reduce_model); subset: the
// subset start (FitOptions::subset_start)
Row FitOurs(const Case& c, const std::string& method, JacobianMode mode, bool central, int threads,
            int max_iterations, bool auto_start = false, bool reduce = true, bool subset = true);
// the hand-written baseline: Ceres numeric differentiation of whole rollouts
Row FitNumDiff(const Case& c, int max_iterations);
// a row of the peer, from the driver's JSON in dir
Row PeerRow(const Case& c, const std::string& dir, int threads, const std::string& method);

// ---------------------------------------------------------------------------------------------
// output (fit_bench_output.cc)

// Per case and thread count: our fastest row against the fastest peer row (Ceres numeric diff,
// mujoco.sysid in either parametrization) at the same number of threads, and our iterations
// against the peer's fewest (any row). speedup = peer wall / our wall (> 1: ours is faster).
struct Ratio {
  std::string case_name;
  bool own_start = false;  // ours from the experiment's own starts only (no `+auto` row)
  int threads = 1;
  const Row* ours = nullptr;
  const Row* peer = nullptr;
  int peer_fewest_iterations = 0;  // 0: no peer row finished
  double speedup = NAN;
};

std::string Num(double v, const char* fmt = "%.6g");
// the table's header line and one row of it, on stdout
void PrintHeader();
void PrintRow(const Row& r);
// own_start: our rows from the experiment's own starts only (not the equation-error start's)
std::vector<Ratio> Ratios(const std::vector<std::string>& cases, const std::vector<Row>& rows,
                          bool own_start);
std::string RatioLine(const Ratio& q, const char* sep);
void WriteCsv(const std::string& path, const std::vector<Row>& rows);
// the table as Markdown (BENCHMARKS.md is made from it)
void WriteMarkdown(const std::string& path, const std::vector<Row>& rows,
                   const std::vector<Ratio>& ratios);
// the rows with the machine, versions and command; non-finite numbers as null
void WriteJson(const std::string& path, const std::vector<Row>& rows,
               const std::vector<Ratio>& ratios, const std::string& command);
// error against time, one log-log panel per case; a point per method that finished
void WriteSvg(const std::string& path, const std::vector<std::string>& cases,
              const std::vector<Row>& rows);

}  // namespace bench
}  // namespace mjsysid
