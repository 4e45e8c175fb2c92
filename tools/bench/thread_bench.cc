// bench_threads: the 2-thread wall-clock speed-up of the product's fit, measured against the
// noise of a shared machine (issue 15, item 4; BENCHMARKS.md "Threads").
//
//   bench_threads --cases pendulum,cartpole --repeats 15 [--threads 1,2] [--fold-ahead false]
//
// Every repeat fits each case once per thread count, the thread counts in alternating order
// (1, 2 then 2, 1, ...), so that a slow spell of the machine falls on both. Each fit is the
// experiment's own (run::BuildProblem, the product's FitOptions, progress off). Per case and
// thread count it prints the minimum and the median wall time of the fit (FitResult::seconds),
// the ratios of the 1-thread to the n-thread minimum and median, the median of the ratios of the
// repeats' adjacent pairs ("x pair": fit i at 1 thread over fit i at n threads, run one right
// after the other, so that a machine whose speed drifts between repeats moves both), and per
// fit (median) the time
// outside the simulators' batches (serial: residuals, Ceres, setup; FitLedger's batch seconds),
// the ratio of the base's time inside them to this one's (median wall - median serial, "batch x":
// to compare with the task model's bound, BENCHMARKS.md "Threads"),
// the number of batches, their hand-off (wake: publication to the last worker's start; wait: the
// fit thread's wait for the workers after its own last task, core/thread_pool.h) and the process
// CPU time, and the fit thread's CPU time outside the batches over its whole CPU time ("serial
// cpu": at 1 thread the serial share of the fit's work, independent of other processes' load, so
// that 1 / (serial + (1 - serial) / model) bounds the speed-up with the task model's ratio
// model = the base's steps over the critical steps at 2 workers: "model x", "bound x"). The
// load average (/proc/loadavg) is printed before and after. Final costs must be the
// same at every thread count bit for bit: a difference is printed as an error (exit 1).
//
// The experiments' data files must exist (`sysid simulate experiments/<case>.yaml` writes one; so
// does bench_fit on its first run).
//
//   bench_threads --handoff 2000
//
// measures the pool's hand-off alone instead: batches of 2 tasks of 50 us of busy work on a
// 2-thread pool, the fit thread busy for a serial gap of 20, 200 or 2000 us between batches, the
// pool's bounded spin on (ThreadPool::kSpinSeconds) and off (MJSYSID_POOL_SPIN_US=0); per batch
// the wall time over the 50 us a batch would take with a free second core, and the wake-up.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/thread_pool.h"
#include "sysid/io/experiment.h"
#include "sysid/problem.h"
#include "sysid/run/fit_experiment.h"

namespace mjsysid {
namespace {

double ProcessCpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

std::string LoadAverage() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  f >> a >> b >> c;
  return a + " " + b + " " + c;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// one fit's measurements
struct Sample {
  double wall = 0, serial = 0, wake = 0, wait = 0, cpu = 0, batches = 0;
  // the fit thread's CPU time outside the batches over its whole CPU time (load-independent; at 1
  // thread the serial share of the fit's work)
  double serial_cpu_share = 0;
  double steps = 0, critical_steps = 0;  // the ledger's steps and critical steps at 2 workers
  double final_cost = 0;
  int iterations = 0;
};

Sample FitOnce(const io::ExperimentConfig& config, int threads, bool fold_ahead) {
  run::BuiltProblem b = run::BuildProblem(config, threads);
  FitOptions o = b.options;
  o.threads = threads;
  o.advanced.fold_ahead = fold_ahead;
  o.verbose = false;
  o.on_iteration = nullptr;
  const double cpu0 = ProcessCpuSeconds(), thread0 = ThreadCpuSeconds();
  const FitResult r = b.problem->Fit(o);
  Sample s;
  s.cpu = ProcessCpuSeconds() - cpu0;
  const double thread_cpu = ThreadCpuSeconds() - thread0;
  double serial_cpu = thread_cpu;
  s.wall = r.seconds;
  s.serial = r.seconds;
  for (const LedgerRow& row : r.diagnostics.ledger) {
    s.serial -= row.batch_seconds;
    s.wake += row.wake_seconds;
    s.wait += row.wait_seconds;
    s.batches += static_cast<double>(row.batches);
    serial_cpu -= row.batch_cpu_seconds;
    s.steps += static_cast<double>(row.steps);
    s.critical_steps += static_cast<double>(row.critical_steps);
  }
  s.serial_cpu_share = thread_cpu > 0 ? serial_cpu / thread_cpu : 0;
  s.final_cost = r.final_cost;
  s.iterations = r.iterations;
  return s;
}

using Clock = std::chrono::steady_clock;

// busy for `seconds` (no sleep: a core's worth of work)
void BusyFor(double seconds) {
  const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(seconds));
  while (Clock::now() < end) {
  }
}

// the hand-off microbenchmark (see the top of the file)
void HandOff(int batches) {
  std::printf("load average before: %s\n", LoadAverage().c_str());
  std::printf("%-10s %8s %10s %14s %12s %8s\n", "spin [us]", "gap [us]", "batches", "overhead [us]",
              "wake [us]", "slept");
  constexpr double kTask = 50e-6;
  for (double gap : {20e-6, 200e-6, 2000e-6}) {
    for (const char* spin : {"0", ""}) {
      // "": the pool's own bound; the variable is read when a pool is built
      if (*spin) {
        setenv("MJSYSID_POOL_SPIN_US", spin, 1);
      } else {
        unsetenv("MJSYSID_POOL_SPIN_US");
      }
      ThreadPool pool(2);
      pool.ParallelFor(2, [](int, int) {});  // the worker started
      pool.ResetLoad();
      for (int b = 0; b < batches; ++b) {
        BusyFor(gap);
        pool.ParallelFor(2, [&](int, int) { BusyFor(kTask); });
      }
      const PoolTime& t = pool.time();
      std::printf("%-10s %8.0f %10lld %14.1f %12.1f %8lld\n",
                  *spin ? spin : std::to_string(ThreadPool::kSpinSeconds * 1e6).c_str(), gap * 1e6,
                  t.batches, (t.seconds / t.batches - kTask) * 1e6,
                  t.wake_seconds / t.batches * 1e6, t.sleeps);
    }
  }
  unsetenv("MJSYSID_POOL_SPIN_US");
  std::printf("load average after: %s\n", LoadAverage().c_str());
}

int Main(int argc, char** argv) {
  CLI::App app("bench_threads: 1- against n-thread wall time of the fit, alternating repeats");
  std::vector<std::string> cases = {"spring_mass", "pendulum", "cartpole", "double_pendulum"};
  std::vector<int> threads = {1, 2};
  std::string experiments = MJSYSID_EXPERIMENTS_DIR;
  int repeats = 11;
  app.add_option("--cases", cases, "comma-separated experiment names")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--threads", threads, "comma-separated thread counts, the first the base")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--repeats", repeats, "fits per case and thread count")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--experiments", experiments, "folder of the experiment files")
      ->capture_default_str();
  bool fold_ahead = true;
  app.add_option(
         "--fold-ahead", fold_ahead,
         "FitOptions::advanced.fold_ahead (false: each compressed block folded when Ceres asks)")
      ->capture_default_str();
  int handoff = 0;
  app.add_option("--handoff", handoff,
                 "instead of fits: the pool's hand-off in this many batches per setting");
  CLI11_PARSE(app, argc, argv);
  if (handoff > 0) {
    HandOff(handoff);
    return 0;
  }

  std::printf("load average before: %s\n", LoadAverage().c_str());
  // samples[case][thread index]
  std::map<std::string, std::vector<std::vector<Sample>>> samples;
  std::map<std::string, io::ExperimentConfig> configs;
  for (const std::string& name : cases) {
    configs[name] = io::LoadExperiment(experiments + "/" + name + ".yaml");
    samples[name].resize(threads.size());
  }
  int status = 0;
  for (int rep = 0; rep < repeats; ++rep) {
    for (const std::string& name : cases) {
      for (size_t k = 0; k < threads.size(); ++k) {
        // alternating order: forward on even repeats, backward on odd ones
        const size_t t = rep % 2 ? threads.size() - 1 - k : k;
        samples[name][t].push_back(FitOnce(configs[name], threads[t], fold_ahead));
      }
    }
  }
  std::printf("load average after: %s\n", LoadAverage().c_str());
  std::printf("%-16s %3s %8s %8s %7s %7s %7s %9s %7s %8s %9s %9s %8s %5s %10s %8s %8s\n", "case",
              "thr", "min [s]", "med [s]", "x min", "x med", "x pair", "serial s", "batch x",
              "batches", "wake s", "wait s", "cpu s", "iter", "serial cpu", "model x", "bound x");
  for (const std::string& name : cases) {
    const std::vector<std::vector<Sample>>& by_thread = samples[name];
    auto column = [](const std::vector<Sample>& v, double Sample::*field) {
      std::vector<double> out;
      for (const Sample& s : v) out.push_back(s.*field);
      return out;
    };
    const std::vector<double> base = column(by_thread[0], &Sample::wall);
    const double base_min = *std::min_element(base.begin(), base.end());
    const double base_med = Median(base);
    // the median time inside the batches (wall - serial) of the base thread count
    const double base_batch = base_med - Median(column(by_thread[0], &Sample::serial));
    const double base_serial = Median(column(by_thread[0], &Sample::serial_cpu_share));
    for (size_t t = 0; t < threads.size(); ++t) {
      const std::vector<Sample>& v = by_thread[t];
      const std::vector<double> wall = column(v, &Sample::wall);
      const double mn = *std::min_element(wall.begin(), wall.end()), med = Median(wall);
      const double serial = Median(column(v, &Sample::serial));
      std::vector<double> pair;  // repeat by repeat: the base's fit over this one's
      for (size_t r = 0; r < v.size(); ++r) pair.push_back(base[r] / wall[r]);
      // the task model's speed-up over the base (steps of the base's fit over this fit's steps on
      // the critical path at 2 workers), and with the base's serial CPU share added (Amdahl)
      const double model =
          Median(column(by_thread[0], &Sample::steps)) / Median(column(v, &Sample::critical_steps));
      std::printf(
          "%-16s %3d %8.4f %8.4f %7.3f %7.3f %7.3f %9.4f %7.3f %8.0f %9.4f %9.4f %8.4f %5d %9.2f%% "
          "%8.3f %8.3f\n",
          name.c_str(), threads[t], mn, med, base_min / mn, base_med / med, Median(pair), serial,
          base_batch / (med - serial), Median(column(v, &Sample::batches)),
          Median(column(v, &Sample::wake)), Median(column(v, &Sample::wait)),
          Median(column(v, &Sample::cpu)), v[0].iterations,
          100 * Median(column(v, &Sample::serial_cpu_share)), model,
          1 / (base_serial + (1 - base_serial) / model));
      for (const Sample& s : v) {
        if (s.final_cost != by_thread[0][0].final_cost ||
            s.iterations != by_thread[0][0].iterations) {
          std::printf(
              "ERROR: %s at %d threads: final cost %.17g in %d iterations, not %.17g in %d\n",
              name.c_str(), threads[t], s.final_cost, s.iterations, by_thread[0][0].final_cost,
              by_thread[0][0].iterations);
          status = 1;
          break;
        }
      }
    }
  }
  return status;
}

}  // namespace
}  // namespace mjsysid

// bad input (an experiment or its log missing or invalid): its message and exit 2, not an abort
int main(int argc, char** argv) {
  try {
    return mjsysid::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_threads: %s\n", e.what());
    return 2;
  }
}
