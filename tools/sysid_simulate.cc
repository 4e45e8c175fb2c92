// sysid simulate EXP.yaml: simulate the experiment's `simulate` block into an HDF5 log.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/sim/simulate.h"
#include "tools/sysid_cli.h"
#ifdef MJSYSID_WITH_MPI
#include "sysid/mpi/distributed_fit.h"
#include "sysid/mpi/sharded_rollout.h"
#endif

namespace mjsysid::cli {
namespace {

struct SimulateArgs {
  std::string experiment;
  std::string out;           // "" = the first data path of the experiment
  std::uint64_t seed = 0;    // used when has_seed
  bool has_seed = false;     // --seed given
  int threads = 0;           // used when has_threads
  bool has_threads = false;  // --threads given
  bool force = false;        // replace an output log simulate did not write for this experiment
};

// warns (stderr) about truth values outside their parameter's bounds: a fit could not reach them
void WarnTruthOutsideBounds(const mjsysid::io::ExperimentConfig& config) {
  for (const mjsysid::io::NamedValue& t : config.simulate.truth) {
    const mjsysid::io::ParameterSpec* p = config.FindParameter(t.name);
    if (p && (t.value < p->lower || t.value > p->upper)) {
      std::fprintf(stderr,
                   "sysid simulate: warning: %s: truth %s = %g lies outside the parameter's "
                   "bounds [%g, %g]\n",
                   t.mark.ToString().c_str(), t.name.c_str(), t.value, p->lower, p->upper);
    }
    const auto* d = config.FindFittedControlDelay(t.name);
    if (d && (t.value < d->term.lower || t.value > d->term.upper)) {
      std::fprintf(stderr,
                   "sysid simulate: warning: %s: truth %s = %g lies outside the control delay's "
                   "bounds [%g, %g]\n",
                   t.mark.ToString().c_str(), t.name.c_str(), t.value, d->term.lower,
                   d->term.upper);
    }
  }
}

// simulates the experiment's `simulate` block and writes the log
int RunSimulate(const SimulateArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  mjsysid::io::ExperimentConfig config = mjsysid::io::LoadExperiment(args.experiment);
  mjsysid::io::CheckModelFilesExist(config);
  if (args.has_seed) config.simulate.seed = args.seed;

  // the output: --out, else the first `data:` path
  std::string out = args.out;
  LogWriter writer{"simulate", config.source_file, ""};
  if (out.empty()) {
    if (config.data.empty()) {
      throw InputError(args.experiment +
                       ": no output file: give --out LOG.h5 or a `data:` path in the experiment");
    }
    out = config.data.front().path;
    writer.label = out + " (the first `data:` path of " + args.experiment + ")";
  }
  std::vector<std::string> inputs = {args.experiment};
  for (const mjsysid::io::ModelSpec& spec : config.models) inputs.push_back(spec.path);
  // an existing log is replaced only when simulate wrote it for this experiment (or --force):
  // checked before simulating, and again before writing
  run::CheckLogOutput(out, inputs, args.force, writer);
  WarnTruthOutsideBounds(config);

  // simulate, then write atomically (creating the folder)
  mjsysid::sim::SimulateSettings settings;
  settings.threads = args.has_threads ? args.threads : config.options.threads;
  settings.progress = [&start](const std::string& line) {
    std::fprintf(stderr, "  simulating  %s  %.2f s\n", line.c_str(), Seconds(start));
  };
#ifdef MJSYSID_WITH_MPI
  // under mpirun: the rollouts sharded across the ranks, the log written by rank 0 alone
  if (mjsysid::mpi::Size() > 1) settings.rollout = mjsysid::mpi::ShardedRollout;
  if (mjsysid::mpi::Rank() > 0) settings.progress = nullptr;  // rank 0 speaks
#endif
  const mjsysid::io::Log log = mjsysid::sim::SimulateExperiment(config, settings);
#ifdef MJSYSID_WITH_MPI
  if (mjsysid::mpi::Rank() > 0) return kExitOk;
#endif
  PrepareLogOutput(out, inputs, args.force, writer);
  mjsysid::io::WriteLog(out, log);

  // summary
  const mjsysid::io::Sequence& first = log.sequences.front();
  std::vector<std::string> sensors;
  for (size_t i = 0; i < first.sensor_names.size(); ++i) {
    std::string s = first.sensor_names[i];
    if (first.sensor_dims[i] > 1) s += "(" + std::to_string(first.sensor_dims[i]) + ")";
    auto noise = log.attributes.find("noise." + first.sensor_names[i]);
    if (noise != log.attributes.end() && noise->second != "0") {
      s += " sigma " + Short(noise->second);
    }
    sensors.push_back(s);
  }
  std::vector<std::string> models;
  for (const mjsysid::io::ModelSpec& spec : config.models) models.push_back(spec.name);
  std::printf("simulated %s (%s)\n", config.name.c_str(), args.experiment.c_str());
  std::printf("  models      %s\n", Join(models).c_str());
  std::printf("  sequences   %d%s x %d steps (%.3g s each), seed %llu\n", config.simulate.sequences,
              config.models.size() > 1 ? " per model" : "", config.simulate.steps,
              first.time[first.time.size() - 1] +
                  (first.time.size() > 1 ? first.time[1] - first.time[0] : 0.0),
              static_cast<unsigned long long>(config.simulate.seed));
  std::printf("  excitation  %s\n", log.attributes.at("excitation").c_str());
  std::printf("  sensors     %s\n", Join(sensors).c_str());
  std::string from_model;
  if (auto it = log.attributes.find("truth_from_model"); it != log.attributes.end()) {
    from_model = "," + it->second + ",";
  }
  for (const mjsysid::io::ParameterSpec& p : config.parameters) {
    const bool kept = from_model.find("," + p.name + ",") != std::string::npos;
    // one value, or one per model when they differ
    std::vector<std::string> keys = {p.name};
    for (const mjsysid::io::ModelSpec& spec : config.models) {
      keys.push_back(spec.name + "." + p.name);
    }
    for (const std::string& key : keys) {
      auto it = log.attributes.find("truth." + key);
      if (it == log.attributes.end()) continue;
      std::printf("  truth       %s = %s%s\n", key.c_str(), Short(it->second).c_str(),
                  kept ? " (model value)" : "");
    }
  }
  // the fitted control delays as simulated (their truth, else their initial value)
  for (const mjsysid::io::ExperimentConfig::ControlDelaySpec& cd : config.control_delays) {
    if (!cd.term.fit) continue;
    const std::string name = mjsysid::FitControlDelay{cd.actuator}.Name();
    bool given = false;
    for (const mjsysid::io::NamedValue& t : config.simulate.truth) given = given || t.name == name;
    auto it = log.attributes.find("truth." + name);
    if (it == log.attributes.end()) continue;
    std::printf("  truth       %s = %s%s\n", name.c_str(), Short(it->second).c_str(),
                given ? "" : " (its initial value)");
  }
  std::printf("  wrote       %s in %.2f s\n", out.c_str(), Seconds(start));
  return kExitOk;
}

}  // namespace

Command AddSimulate(CLI::App* app) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* sub = app->add_subcommand(
      "simulate",
      "Simulate the experiment's `simulate` block (true parameter values, excitation, noise) "
      "and write a synthetic HDF5 log");
  sub->add_option("experiment", args->experiment,
                  "YAML experiment file (docs/experiment-schema.md)")
      ->required();
  sub->add_option("--out", args->out,
                  "output HDF5 log (default: the first `data:` path of the experiment, relative to "
                  "the YAML file; --out is relative to the current directory); written "
                  "atomically, folders created");
  CLI::Option* seed = sub->add_option("--seed", args->seed,
                                      "random seed (default: simulate.seed of the experiment)");
  CLI::Option* threads = sub->add_option(
      "--threads", args->threads,
      "simulation threads, 0 = all cores, at most 256 (default: solver.threads of the "
      "experiment)");
  threads->check(ThreadCountValidator());
  sub->add_flag("--force", args->force,
                "replace an existing output log that sysid simulate did not write for this "
                "experiment (a log from sysid import or another experiment, or a file that is "
                "not an mjsysid log); never an input or a folder");
  sub->footer(std::string("Sequences are named seq0, seq1, ... (MODEL_seq0, ... with several "
                          "models); sensor rows are read before each step (sensor_time pre).\n") +
              kExitCodesFooter);
  return {sub, [args, seed, threads] {
            args->has_seed = seed->count() > 0;
            args->has_threads = threads->count() > 0;
            return RunSimulate(*args);
          }};
}

}  // namespace mjsysid::cli
