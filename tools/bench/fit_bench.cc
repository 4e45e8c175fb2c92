// bench_fit: run time against parameter error of whole fits, per experiment and method, side by
// side with the peers (issue 6).
//
// For every case (an experiment file with a `simulate:` block: its log is simulated when missing)
// and every method it fits the same data from the same start within the same bounds, and records
// wall time, LM iterations, simulation step calls, initial and final cost and the parameter
// error against the truth of `simulate.truth`:
// - ours/<mode>/<differences>/<threads>t: Problem::Fit with the core Jacobians, mode directional
//   or matrix, forward or central differences, 1 or 2 simulator threads;
// - ours/directional/forward+auto/<threads>t: ours from the equation-error start (every
//   parameter `initial: auto`, sysid/data/equation_error.h), 1 and 2 threads, method `auto`;
// - oracle/whole/forward/2t: Problem::Fit with whole-rollout finite differences (kWholeRollout);
// - full-model/directional/forward/<threads>t: ours without the reduced model
//   (solver.reduce_model: false, core/reduced_model.h), method `full` (issue 15 item 6):
//   the same estimate bit for bit, so only the time differs from ours/directional/forward;
// - ours (every row above but `+auto`) runs with the subset start (solver.subset_start: auto,
//   sysid/fit/subset_start.h; off by default for now);
// - ours/directional/forward-subset/<threads>t: ours without the subset start
//   (solver.subset_start: off, sysid/fit/subset_start.h), method `nosubset` (issue 38): every
//   iteration on all the data, as before the subset start existed;
// - ceres-numdiff/forward/1t: what a C++ user writes by hand: ceres::DynamicNumericDiffCostFunction
//   around a plain mj_step loop over every sequence (one residual block, Ceres' default relative
//   step), same residual, bounds, log transforms and solver settings as ours;
// - mujoco.sysid/<threads>t: rows read from the peer driver's peer_result.json files
//   (tools/peer/mujoco_sysid_fit.py, run by tools/bench/run_fit_benchmarks.sh) in
//   --peer-dir/<case>-<threads>t/ (parameters with `transform: log` optimised as log p, like ours)
//   and mujoco.sysid/physical from <case>-phys-2t/ (physical units, the peer's own way).
// Also, per case, the nominal step time t_step (1-thread rollouts of every sequence with the model
// file's parameter values) and, per row, the ratio of the time per iteration to the floor
// (1 + np) * sum(T) * t_step / threads; for ours directional forward also the path floor: the
// step time at each iterate of the row's fit (the point whose Jacobian and trial the iteration
// simulates, FitResult::trace) relative to the nominal one (RelativeStepTimeAt), averaged over
// the iterations and times t_step, since a contact-rich model's step cost depends on its
// parameters.
//
// Output: a table on stdout, DIR/fit_bench.csv, DIR/fit_bench.json (rows, machine, versions,
// command), DIR/fit_bench.md (the table in Markdown) and DIR/error_vs_time.svg (one panel per
// case). Timings are wall clock; nothing here is asserted.
//
// Units: fit_bench.h (a row, a case), fit_bench_host.cc (step times, host probe, load, repeats),
// fit_bench_methods.cc (the methods' fits), fit_bench_output.cc (table and files).
#include "tools/bench/fit_bench.h"

#include <ceres/ceres.h>
#include <mujoco/mujoco.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "mjsysid/version.h"
#include "sysid/solve/fit_ledger.h"

namespace mjsysid {
namespace bench {
namespace {

namespace fs = std::filesystem;

// the command line
struct Options {
  std::string cases_arg =
      "spring_mass,pendulum,double_pendulum,cartpole,arm5,box_floor,humanoid,arm7";
  std::string methods_arg = "ours,auto,nosubset,full,oracle,numdiff,peer";
  std::string out_dir = "results/bench", peer_dir, experiments = MJSYSID_EXPERIMENTS_DIR;
  std::vector<std::string> caps;
  std::string ours_arg;
  Repeats repeats;
  bool print_ledger = false;
  // parsed
  std::vector<std::string> cases, methods, ours;
  std::map<std::string, int> cap;  // --max-iterations per case
};

void AddOptions(CLI::App* app, Options* o) {
  app->add_option("--cases", o->cases_arg, "comma-separated experiment names")
      ->capture_default_str();
  app->add_option("--methods", o->methods_arg,
                  "comma-separated: ours, auto (ours from initial: auto), oracle, numdiff, peer, "
                  "full (ours directional forward without the reduced model, 1 and 2 threads), "
                  "nosubset (ours directional forward without the subset start, 1 and 2 threads)")
      ->capture_default_str();
  app->add_option("--out", o->out_dir, "output folder")->capture_default_str();
  app->add_option("--peer-dir", o->peer_dir, "folder of the peer driver's results (<case>-<n>t/)");
  app->add_option("--experiments", o->experiments, "folder of the experiment files")
      ->capture_default_str();
  app->add_option("--ours", o->ours_arg,
                  "comma-separated configurations of ours to run, e.g. "
                  "directional/forward/1,matrix/central/2 (default: all eight)");
  app->add_option(
         "--idle-wait", o->repeats.idle_wait,
         "seconds to wait before each row for other processes to leave the cores it "
         "needs (<= 0.5 busy core per thread of the row); rows that still are not idle say "
         "so in their note")
      ->capture_default_str();
  app->add_option("--repeats", o->repeats.repeats,
                  "runs per row of ours and numeric diff: the fastest is the row's wall time "
                  "(repeated while the runs add up to less than --repeat-budget seconds)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--repeat-budget", o->repeats.repeat_budget,
                  "seconds of fitting per row that allow a repeat")
      ->capture_default_str();
  app->add_option("--max-iterations", o->caps, "per-case iteration cap, e.g. humanoid=10");
  app->add_flag(
      "--ledger", o->print_ledger,
      "print under each row of ours its fit's steps and time by phase (sysid/solve/fit_ledger.h)");
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// the lists and the per-case iteration caps; false (after a message) for a malformed cap
bool ParseLists(Options* o) {
  for (const std::string& c : o->caps) {
    const size_t eq = c.find('=');
    char* end = nullptr;
    const long n = eq == std::string::npos ? 0 : std::strtol(c.c_str() + eq + 1, &end, 10);
    if (eq == std::string::npos || end == c.c_str() + eq + 1 || *end != '\0' || n <= 0) {
      std::fprintf(stderr, "bench_fit: --max-iterations expects case=N with N > 0, got '%s'\n",
                   c.c_str());
      return false;
    }
    o->cap[c.substr(0, eq)] = static_cast<int>(n);
  }
  o->cases = Split(o->cases_arg);
  o->methods = Split(o->methods_arg);
  o->ours = Split(o->ours_arg);
  return true;
}

// a measured row completed (case, load note, errors, floors), printed (with its ledger under
// --ledger), added, and the CSV rewritten so that each row is on disk as soon as it exists
void AddRow(const Options& o, Case* c, Row r, std::vector<Row>* rows) {
  const std::string load = LoadNote(r);
  if (!load.empty()) r.note += (r.note.empty() ? "" : "; ") + load;
  r.case_name = c->name;
  r.sequences = c->sequences;
  r.samples = c->samples;
  Errors(*c, &r);
  Floor(c, &r);
  PrintRow(r);
  if (o.print_ledger && std::isfinite(r.cpu_s)) {
    std::printf("  process CPU time during the fit: %.4f s\n", r.cpu_s);
  }
  if (o.print_ledger && !r.path.empty()) {
    std::printf(
        "  t_step on the path: first iterate %.3f us, last %.3f us, mean %.3f us (the "
        "case's t_step %.3f us)\n",
        RelativeStepTimeAt(c, r.path.front()) * c->t_step * 1e6,
        RelativeStepTimeAt(c, r.path.back()) * c->t_step * 1e6, r.path_t_step_us, r.t_step_us);
  }
  if (o.print_ledger && !r.ledger.empty()) {
    std::printf("  ledger (model loading and log reading before the fit: %.4f s):\n%s", r.build_s,
                FormatLedger(r.ledger, r.samples).c_str());
  }
  rows->push_back(std::move(r));
  WriteCsv(o.out_dir + "/fit_bench.csv", *rows);
}

// every method of the case that --methods and --ours ask for, in the table's order
void RunMethods(const Options& o, Case* cp, int max_it, std::vector<Row>* rows) {
  const Case& c = *cp;
  const std::string& name = c.name;
  auto want = [&](const char* m) {
    return std::find(o.methods.begin(), o.methods.end(), m) != o.methods.end();
  };
  auto measure = [&](int threads, const std::function<Row()>& fit) {
    return MeasureRow(cp, threads, o.repeats, fit);
  };
  auto add = [&](Row r) { AddRow(o, cp, std::move(r), rows); };
  if (want("ours")) {
    for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
      for (bool central : {false, true}) {
        for (int threads : {1, 2}) {
          const std::string m =
              std::string("ours/") + JacobianModeName(mode) + (central ? "/central" : "/forward");
          const std::string config = m.substr(5) + "/" + std::to_string(threads);
          if (!o.ours.empty() && std::find(o.ours.begin(), o.ours.end(), config) == o.ours.end())
            continue;
          add(measure(threads, [&] { return FitOurs(c, m, mode, central, threads, max_it); }));
        }
      }
    }
  }
  if (want("auto")) {
    // the equation-error start: every parameter `initial: auto`, directional forward, 1 and 2
    // threads
    for (int threads : {1, 2}) {
      add(measure(threads, [&] {
        return FitOurs(c, "ours/directional/forward+auto", JacobianMode::kDirectional, false,
                       threads, max_it, true);
      }));
    }
  }
  if (want("nosubset")) {
    // the subset start's share: ours directional forward with every iteration on all the data
    for (int threads : {1, 2}) {
      add(measure(threads, [&] {
        return FitOurs(c, "ours/directional/forward-subset", JacobianMode::kDirectional, false,
                       threads, max_it, false, true, false);
      }));
    }
  }
  if (want("full")) {
    // the reduced model's share: ours directional forward on the model as given
    for (int threads : {1, 2}) {
      add(measure(threads, [&] {
        return FitOurs(c, "full-model/directional/forward", JacobianMode::kDirectional, false,
                       threads, max_it, false, false);
      }));
    }
  }
  if (want("oracle")) {
    add(measure(2, [&] {
      return FitOurs(c, "oracle/whole/forward", JacobianMode::kWholeRollout, false, 2, max_it);
    }));
  }
  if (want("numdiff")) add(measure(1, [&] { return FitNumDiff(c, max_it); }));
  if (want("peer")) {
    for (int threads : {1, 2}) {
      add(PeerRow(c, o.peer_dir + "/" + name + "-" + std::to_string(threads) + "t", threads,
                  "mujoco.sysid"));
    }
    add(PeerRow(c, o.peer_dir + "/" + name + "-phys-2t", 2, "mujoco.sysid/physical"));
  }
}

// one case: loaded (its log simulated when missing), its step time measured, its rows, and their
// floors again with the case's t_step as it ends; false (after a message) when it cannot load
bool RunCase(const Options& o, const std::string& name, std::vector<Row>* rows) {
  Case c;
  try {
    c = LoadCase(o.experiments, name);
    Row load;
    WaitForIdle(1, o.repeats.idle_wait, &load);
    if (!load.idle)
      std::printf("%s: step time measured %s\n", name.c_str(), LoadNote(load).c_str());
    MeasureStep(&c);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_fit: case %s: %s\n", name.c_str(), e.what());
    return false;
  }
  const int max_it = o.cap.count(name) ? o.cap.at(name) : 0;
  const size_t first_row = rows->size();
  const double first_t_step_us = c.t_step * 1e6;
  RunMethods(o, &c, max_it, rows);
  // the floors again with the case's t_step as it ends (the fastest of every probe of the case)
  if (c.t_step * 1e6 < first_t_step_us * 0.99) {
    std::printf(
        "%s: t_step %.4f -> %.4f us by a later probe: its rows' floor ratios in the "
        "files use the latter\n",
        name.c_str(), first_t_step_us, c.t_step * 1e6);
  }
  for (size_t i = first_row; i < rows->size(); ++i) Floor(&c, &(*rows)[i]);
  WriteCsv(o.out_dir + "/fit_bench.csv", *rows);
  return true;
}

int Main(int argc, char** argv) {
  CLI::App app{"bench_fit: run time against parameter error of whole fits, per method"};
  Options o;
  AddOptions(&app, &o);
  CLI11_PARSE(app, argc, argv);
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);

  InstallMujocoHandlers();
  if (!ParseLists(&o)) return 2;
  fs::create_directories(o.out_dir);
  std::printf("machine: %s, %u hardware threads; MuJoCo %s, Ceres %s, mjsysid %s (%s)\n",
              Machine().c_str(), std::thread::hardware_concurrency(), mj_versionString(),
              CERES_VERSION_STRING, MJSYSID_VERSION, MJSYSID_BUILD_TYPE);
  PrintHeader();
  std::vector<Row> rows;
  for (const std::string& name : o.cases) {
    if (!RunCase(o, name, &rows)) return 2;
  }
  std::vector<Ratio> ratios;
  for (const bool own : {false, true}) {
    const std::vector<Ratio> some = Ratios(o.cases, rows, own);
    std::printf(
        "\nours%s against the best peer at equal threads (speed-up = peer wall / our wall)\n"
        "case,threads,ours,wall_s,iterations,peer,peer_wall_s,speedup,peer_fewest_iterations,"
        "load\n",
        own ? " from the experiment's own starts" : "");
    for (const Ratio& q : some) std::printf("%s\n", RatioLine(q, ",").c_str());
    ratios.insert(ratios.end(), some.begin(), some.end());
  }
  WriteMarkdown(o.out_dir + "/fit_bench.md", rows, ratios);
  WriteJson(o.out_dir + "/fit_bench.json", rows, ratios, command);
  WriteSvg(o.out_dir + "/error_vs_time.svg", o.cases, rows);
  std::printf("wrote %s/{fit_bench.csv, fit_bench.json, fit_bench.md, error_vs_time.svg}\n",
              o.out_dir.c_str());
  return 0;
}

}  // namespace
}  // namespace bench
}  // namespace mjsysid

int main(int argc, char** argv) { return mjsysid::bench::Main(argc, argv); }
