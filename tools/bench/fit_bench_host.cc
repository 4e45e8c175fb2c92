// bench_fit: the measurements around the fits: the case's step times and floors, the host's
// speed probe, the machine's load before each row, and the repeats of a row.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/io/log.h"
#include "sysid/sim/simulate.h"
#include "tools/bench/fit_bench.h"

namespace mjsysid {
namespace bench {
namespace {

namespace fs = std::filesystem;

// seconds per step of 1-thread rollouts (mj_step's calls, the sensor stage included) of every
// sequence on the full model, with the fitted parameters at values (b.parameters' order) or,
// values nullptr, at the model file's values: the fastest of passes over every sequence, repeated
// for at least min_seconds and min_reps passes
double StepTime(const run::BuiltProblem& b, const Eigen::VectorXd* values, double min_seconds,
                int min_reps) {
  double best = INFINITY;
  for (size_t mi = 0; mi < b.models.size(); ++mi) {
    std::vector<ParameterSpec> specs;
    std::vector<double> at;
    for (size_t i = 0; values && i < b.parameters.size(); ++i) {
      if (!b.parameters[i].AppliesTo(b.model_names[mi])) continue;
      specs.push_back(b.parameters[i].target);
      at.push_back((*values)[static_cast<Eigen::Index>(i)]);
    }
    SimulatorOptions so;
    so.threads = 1;
    // the floor is mj_step's work: MuJoCo's sensor stage runs even where a fit copies encoders
    so.copy_state_sensors = false;
    Simulator sim(*b.models[mi], specs, so);
    if (!at.empty()) sim.SetParameters(Eigen::Map<const Eigen::VectorXd>(at.data(), at.size()));
    std::vector<SequenceInput> ins;
    for (const FitSequence& s : b.sequences) {
      if (s.model == b.model_names[mi]) ins.push_back({s.x0, s.ctrl});
    }
    if (ins.empty()) continue;
    std::vector<Trajectory> trs;
    sim.Rollout(ins, &trs);  // warm up
    const auto t0 = Clock::now();
    int reps = 0;
    do {
      sim.ResetStepCount();
      const auto t1 = Clock::now();
      sim.Rollout(ins, &trs);
      best = std::min(best, Seconds(t1) / static_cast<double>(sim.StepCount()));
      ++reps;
    } while (Seconds(t0) < min_seconds || reps < min_reps);
  }
  return best;
}

// The host's speed now: the case's nominal step time (fastest of 3 passes, >= 0.05 s) over the
// fastest measured for the case, which it lowers when faster. This virtual machine's speed changes
// from outside (by up to 2x for minutes, BENCHMARKS.md "The machine on 2026-11-23"), which the
// load check cannot see: the probe can.
double HostSlowness(Case* c) {
  const double now = StepTime(*c->built, nullptr, 0.05, 3);
  c->t_step = std::min(c->t_step, now);
  return now / c->t_step;
}

// the jiffies of all cpus: {busy, total} from the first line of /proc/stat
std::pair<double, double> CpuJiffies() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  in >> cpu;
  double v[8] = {0, 0, 0, 0, 0, 0, 0, 0}, total = 0;
  for (double& x : v) {
    in >> x;
    total += x;
  }
  return {total - v[3] - v[4], total};  // idle and iowait are not busy
}

// the cores other processes kept busy over `seconds` (this program sleeps meanwhile) and the
// 1-minute load average (/proc/loadavg; it also counts this program's previous row for a minute,
// which is why the decision uses the first number)
std::pair<double, double> MachineLoad(double seconds) {
  const auto [busy0, total0] = CpuJiffies();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const auto [busy1, total1] = CpuJiffies();
  const double cores = std::thread::hardware_concurrency();
  const double others = total1 > total0 ? cores * (busy1 - busy0) / (total1 - total0) : NAN;
  double load1 = NAN;
  std::ifstream("/proc/loadavg") >> load1;
  return {others, load1};
}

// the host counts as steady around a row when its probe (HostSlowness) stays within 8 % of the
// fastest; a row that was not is measured again after kHostWait seconds, up to kMaxAttempts in all
constexpr double kSteadyHost = 1.08;
constexpr int kMaxAttempts = 3;
constexpr double kHostWait = 10;

}  // namespace

// the process's CPU time (all threads), seconds
double ProcessCpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

void Errors(const Case& c, Row* row) {
  double worst = 0, sum = 0;
  int n = 0;
  for (const auto& [name, value] : row->estimates) {
    const auto it = c.truth.find(name);
    if (it == c.truth.end() || it->second == 0) continue;
    const double e = std::abs(value / it->second - 1.0);
    worst = std::max(worst, std::isfinite(e) ? e : INFINITY);
    sum += e * e;
    ++n;
  }
  row->max_rel_error = n ? worst : NAN;
  row->rms_rel_error = n ? std::sqrt(sum / n) : NAN;
}

// the row's floor ratios with the case's t_step as it stands (the fastest measured so far)
void Floor(Case* c, Row* row) {
  row->t_step_us = c->t_step * 1e6;
  if (!(row->iterations > 0) || !std::isfinite(row->wall_s)) return;
  const double per_t_step = (1.0 + row->np) * static_cast<double>(c->samples) / row->threads;
  row->floor_ratio = row->wall_s / row->iterations / (per_t_step * c->t_step);
  if (row->path.empty()) return;
  double sum = 0;
  for (const Eigen::VectorXd& p : row->path) sum += RelativeStepTimeAt(c, p);
  const double t_step = c->t_step * sum / static_cast<double>(row->path.size());
  row->path_t_step_us = t_step * 1e6;
  row->path_floor_ratio = row->wall_s / row->iterations / (per_t_step * t_step);
}

// loads the case and simulates its log when it is missing
Case LoadCase(const std::string& experiments_dir, const std::string& name) {
  Case c;
  c.name = name;
  c.config = io::LoadExperiment(experiments_dir + "/" + name + ".yaml");
  for (const io::NamedValue& t : c.config.simulate.truth) c.truth[t.name] = t.value;
  for (const io::DataFile& d : c.config.data) {
    if (!fs::exists(d.path)) {
      std::fprintf(stderr, "bench_fit: simulating %s -> %s\n", name.c_str(), d.path.c_str());
      fs::create_directories(fs::path(d.path).parent_path());
      io::WriteLog(d.path, sim::SimulateExperiment(c.config));
    }
  }
  return c;
}

void MeasureStep(Case* c) {
  c->built = std::make_shared<run::BuiltProblem>(run::BuildProblem(c->config, 1));
  c->sequences = static_cast<int>(c->built->sequences.size());
  c->samples = 0;
  for (const FitSequence& s : c->built->sequences) c->samples += s.ctrl.rows();
  c->t_step = StepTime(*c->built, nullptr, 0.3, 3);
}

// the step time at the fitted parameters' values over the nominal step time: the fastest of each
// over three alternating rounds (nominal, at the values, ..., nominal; >= 0.04 s and 2 passes
// each), so that a slow spell of the host has to cover every round of one to move the ratio;
// measured once per point
double RelativeStepTimeAt(Case* c, const Eigen::VectorXd& values) {
  const std::vector<double> key(values.data(), values.data() + values.size());
  const auto it = c->relative_t_step_at.find(key);
  if (it != c->relative_t_step_at.end()) return it->second;
  double nominal = StepTime(*c->built, nullptr, 0.04, 2), at = INFINITY;
  for (int round = 0; round < 3; ++round) {
    at = std::min(at, StepTime(*c->built, &values, 0.04, 2));
    nominal = std::min(nominal, StepTime(*c->built, nullptr, 0.04, 2));
  }
  c->t_step = std::min(c->t_step, nominal);
  return c->relative_t_step_at[key] = at / nominal;
}

void WaitForIdle(int threads, double wait_s, Row* row) {
  const auto t0 = Clock::now();
  do {
    std::tie(row->others_cores, row->load1) = MachineLoad(1.0);
    row->idle = row->others_cores <= 0.5 * threads;
  } while (!row->idle && Seconds(t0) < wait_s);
}

// the row's load note ("" when idle)
std::string LoadNote(const Row& r) {
  if (r.idle) return "";
  return "not idle: others used " + Num(r.others_cores, "%.2f") + " cores, load average " +
         Num(r.load1, "%.2f");
}

std::string Machine() {
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown";
}

namespace {

// one measurement of a row: the load checked (and waited for) and the host probed first, the
// fastest of up to --repeats runs, repeated while their wall time adds up to less than
// --repeat-budget seconds (the same rule as the peer driver's --repeats), the host probed after
Row MeasureOnce(Case* c, int threads, const Repeats& rp, const std::function<Row()>& fit) {
  Row before;
  WaitForIdle(threads, rp.idle_wait, &before);
  const double slow_before = HostSlowness(c);
  Row r = fit();
  double spent = r.wall_s;
  for (int k = 1; k < rp.repeats && std::isfinite(spent) && spent < rp.repeat_budget; ++k) {
    Row again = fit();
    spent += again.wall_s;
    if (again.iterations != r.iterations || again.steps != r.steps ||
        again.estimates != r.estimates) {
      r.note += std::string(r.note.empty() ? "" : "; ") +
                "a repeated run differed (iterations, steps or estimates)";
      break;
    }
    ++r.runs;
    if (again.wall_s < r.wall_s) {
      again.runs = r.runs;
      again.note = r.note;
      r = std::move(again);
    }
  }
  r.others_cores = before.others_cores;
  r.load1 = before.load1;
  r.idle = before.idle;
  r.host_slowness = std::max(slow_before, HostSlowness(c));
  return r;
}

}  // namespace

// a row measured while the host ran slow (HostSlowness above kSteadyHost before or after it)
// is measured again, up to kMaxAttempts times in all, kHostWait seconds apart; the first
// steady attempt stays, else the fastest, which then says the host was slow around it
Row MeasureRow(Case* c, int threads, const Repeats& rp, const std::function<Row()>& fit) {
  Row r = MeasureOnce(c, threads, rp, fit);
  for (int a = 1; a < kMaxAttempts && r.host_slowness > kSteadyHost; ++a) {
    std::this_thread::sleep_for(std::chrono::duration<double>(kHostWait));
    Row again = MeasureOnce(c, threads, rp, fit);
    again.attempts = r.attempts + 1;
    if (again.wall_s < r.wall_s || again.host_slowness <= kSteadyHost) {
      r = std::move(again);
    } else {
      r.attempts = again.attempts;
    }
  }
  if (r.host_slowness > kSteadyHost) {
    r.note += std::string(r.note.empty() ? "" : "; ") + "host slow: probe " +
              Num(r.host_slowness, "%.2f") + "x the case's fastest";
  }
  return r;
}

}  // namespace bench
}  // namespace mjsysid
