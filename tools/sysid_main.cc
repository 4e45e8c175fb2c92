// sysid: the mjsysid command line (docs/cli.md).
//
// Each subcommand is a function RunX(const XArgs&) and one registration function AddX(app) that
// declares its arguments and returns the subcommand with a closure calling RunX; main() parses,
// runs the chosen one and maps exceptions to exit codes:
//   0 success
//   1 the run failed (a simulation failed, MuJoCo raised an error)
//   2 bad input (command line, experiment file, model, parameters, data files)
//   `sysid fit` also 1, 3, 4 for a fit whose status is not converged (run::ExitCodeOf)
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "mjsysid/version.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/csv.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/metrics.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/output_folder.h"
#include "sysid/run/resume.h"
#include "sysid/sim/simulate.h"
#include "tools/report/report.h"
#ifdef MJSYSID_WITH_MPI
#include "sysid/mpi/distributed_fit.h"
#include "sysid/mpi/sharded_rollout.h"
#endif

namespace {

namespace fs = std::filesystem;

constexpr int kExitOk = 0;
constexpr int kExitFailed = 1;
constexpr int kExitBadInput = 2;

const char* const kExitCodesFooter =
    "Exit codes: 0 success, 1 the run failed (simulation or MuJoCo error), 2 bad input (command "
    "line, experiment file, model, parameters or data files); `fit` writes its results and exits "
    "1 not_converged or interrupted, 3 model_mismatch, 4 jacobian_unreliable or did_not_move.";

// a bad input found by the command line itself (exit code 2)
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// a registered subcommand: its CLI11 app and what runs it
struct Command {
  CLI::App* app;
  std::function<int()> run;
};

// seconds since start
double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string Join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : sep) + s;
  return out;
}

// printf into a string
__attribute__((format(printf, 2, 3))) void Appendf(std::string* out, const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  if (n > 0) {
    std::vector<char> buf(static_cast<size_t>(n) + 1);
    std::vsnprintf(buf.data(), buf.size(), format, args);
    out->append(buf.data(), static_cast<size_t>(n));
  }
  va_end(args);
}

// a number written with %.17g, shown with 6 digits
std::string Short(const std::string& exact) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", std::stod(exact));
  return buf;
}

// a short description of a model's sizes
std::string ModelSizes(const mjModel& m) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), "nq=%d nv=%d nu=%d nsensor=%d, timestep %g s",
                static_cast<int>(m.nq), static_cast<int>(m.nv), static_cast<int>(m.nu),
                static_cast<int>(m.nsensor), m.opt.timestep);
  return buf;
}

// an option value that must be a whole number >= min (CLI11's own range checks print the
// largest double in full: 309 digits)
CLI::Validator WholeNumberAtLeast(long long min) {
  return CLI::Validator(
      [min](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0' || errno == ERANGE || v < min) {
          return "expected a whole number >= " + std::to_string(min) + ", got '" +
                 text.substr(0, 40) + (text.size() > 40 ? "...'" : "'");
        }
        return "";
      },
      "INT>=" + std::to_string(min));
}

// an option value that must be a finite number
CLI::Validator FiniteNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !std::isfinite(v)) {
          return "expected a finite number, got '" + text.substr(0, 40) +
                 (text.size() > 40 ? "...'" : "'");
        }
        return "";
      },
      "NUMBER");
}

// An HDF5 log output `out` (of --out): not one of `inputs`, and unless `force` either absent or
// an mjsysid log (a file ReadLog accepts); its folder created. Throws OutputError (exit 2).
void PrepareLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force) {
  mjsysid::run::CheckOutputFile(out, inputs, "--out");
  std::error_code ec;
  if (fs::exists(out, ec) && !force) {
    if (!fs::is_regular_file(out, ec)) {
      throw mjsysid::run::OutputError("--out " + out + ": exists and is not a file");
    }
    try {
      mjsysid::io::ReadLog(out);
    } catch (const mjsysid::io::LogError& e) {
      throw mjsysid::run::OutputError(
          "--out " + out +
          ": exists and is not an mjsysid log; not overwritten (hint: --force replaces it)");
    }
  }
  const fs::path parent = fs::path(out).parent_path();
  if (!parent.empty()) {
    fs::create_directories(parent, ec);
    if (ec) {
      throw InputError(out + ": cannot create the folder " + parent.string() + ": " + ec.message());
    }
  }
}

// ---------------------------------------------------------------------------------------------
// sysid rollout MODEL.xml

struct RolloutArgs {
  std::string model_path;
  int steps = 1000;
  double amplitude = 1.0;
};

// rolls a model out from its reference state under a sinusoidal control and prints a summary
int RunRollout(const RolloutArgs& args) {
  mjsysid::ModelPtr m = mjsysid::LoadModel(args.model_path);
  mjsysid::DataPtr d = mjsysid::MakeData(*m);
  std::printf("model %s: nq=%d nv=%d nu=%d nsensordata=%d timestep=%g\n", args.model_path.c_str(),
              static_cast<int>(m->nq), static_cast<int>(m->nv), static_cast<int>(m->nu),
              static_cast<int>(m->nsensordata), m->opt.timestep);
  for (int k = 0; k < args.steps; ++k) {
    for (int i = 0; i < m->nu; ++i) {
      d->ctrl[i] = args.amplitude * std::sin(2.0 * M_PI * (0.5 + 0.3 * i) * d->time);
    }
    mj_step(m.get(), d.get());
    const std::string warnings = mjsysid::SimulationWarnings(*d);
    if (!warnings.empty()) {
      std::fprintf(stderr, "sysid rollout: simulation warning at step %d: %s\n", k,
                   warnings.c_str());
      return kExitFailed;
    }
  }
  std::printf("rolled out %d steps to t=%.4f s\n", args.steps, d->time);
  for (int i = 0; i < m->nsensor; ++i) {
    const char* name = mj_id2name(m.get(), mjOBJ_SENSOR, i);
    std::printf("  sensor %-12s", name ? name : "?");
    for (int j = 0; j < m->sensor_dim[i]; ++j) {
      std::printf(" % .6f", d->sensordata[m->sensor_adr[i] + j]);
    }
    std::printf("\n");
  }
  return kExitOk;
}

Command AddRollout(CLI::App* app) {
  auto args = std::make_shared<RolloutArgs>();
  CLI::App* sub = app->add_subcommand(
      "rollout",
      "Roll a model out from its reference state under a sine control and print the "
      "final sensor readings");
  sub->add_option("model", args->model_path, "MJCF (or MJB) model file")->required();
  sub->add_option("--steps", args->steps, "number of steps")
      ->check(WholeNumberAtLeast(1))
      ->capture_default_str();
  sub->add_option("--amplitude", args->amplitude, "control amplitude, in control units")
      ->check(FiniteNumber())
      ->capture_default_str();
  sub->footer(kExitCodesFooter);
  return {sub, [args] { return RunRollout(*args); }};
}

// ---------------------------------------------------------------------------------------------
// sysid simulate EXP.yaml

struct SimulateArgs {
  std::string experiment;
  std::string out;           // "" = the first data path of the experiment
  std::uint64_t seed = 0;    // used when has_seed
  bool has_seed = false;     // --seed given
  int threads = 0;           // used when has_threads
  bool has_threads = false;  // --threads given
  bool force = false;        // overwrite an --out that is not an mjsysid log
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
  if (out.empty()) {
    if (config.data.empty()) {
      throw InputError(args.experiment +
                       ": no output file: give --out LOG.h5 or a `data:` path in the experiment");
    }
    out = config.data.front().path;
  }
  WarnTruthOutsideBounds(config);

  // simulate, then write atomically (creating the folder)
  mjsysid::sim::SimulateSettings settings;
  settings.threads = args.has_threads ? args.threads : config.options.threads;
  std::vector<std::string> inputs = {args.experiment};
  for (const mjsysid::io::ModelSpec& spec : config.models) inputs.push_back(spec.path);
  mjsysid::run::CheckOutputFile(out, inputs, "--out");
#ifdef MJSYSID_WITH_MPI
  // under mpirun: the rollouts sharded across the ranks, the log written by rank 0 alone
  if (mjsysid::mpi::Size() > 1) settings.rollout = mjsysid::mpi::ShardedRollout;
#endif
  const mjsysid::io::Log log = mjsysid::sim::SimulateExperiment(config, settings);
#ifdef MJSYSID_WITH_MPI
  if (mjsysid::mpi::Rank() > 0) return kExitOk;
#endif
  PrepareLogOutput(out, inputs, args.force);
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
  std::printf("  wrote       %s in %.2f s\n", out.c_str(), Seconds(start));
  return kExitOk;
}

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
      "simulation threads, 0 = all cores (default: solver.threads of the experiment)");
  threads->check(CLI::Range(0, 4096));
  sub->add_flag("--force", args->force,
                "overwrite an existing --out file that is not an mjsysid log");
  sub->footer(std::string("Sequences are named seq0, seq1, ... (MODEL_seq0, ... with several "
                          "models); sensor rows are read before each step (sensor_time pre).\n") +
              kExitCodesFooter);
  return {sub, [args, seed, threads] {
            args->has_seed = seed->count() > 0;
            args->has_threads = threads->count() > 0;
            return RunSimulate(*args);
          }};
}

// ---------------------------------------------------------------------------------------------
// sysid check EXP.yaml

struct CheckArgs {
  std::string experiment;
  bool jacobians = true;
  double tolerance = 1e-4;
  bool strict = false;
};

// checks the experiment file, its models and its data files; prints a summary and OK
int RunCheck(const CheckArgs& args) {
  namespace io = mjsysid::io;
  const io::ExperimentConfig config = io::LoadExperiment(args.experiment);
  io::CheckModelFilesExist(config);
  std::string summary;  // printed with OK at the end; an error prints only itself
  Appendf(&summary, "experiment %s (%s)\n", config.name.c_str(), config.source_file.c_str());

  // models: they compile, the config's names exist in them, the parameters resolve
  for (const io::ModelSpec& spec : config.models) {
    mjsysid::ModelPtr m = mjsysid::LoadModel(spec.path);
    io::ValidateExperimentAgainstModel(config, *m, spec.name);
    const size_t nparams = config.ParametersOf(spec.name).size();
    Appendf(&summary, "  model      %s: %s (%s), %zu parameters\n", spec.name.c_str(),
            spec.path.c_str(), ModelSizes(*m).c_str(), nparams);
  }
  std::vector<std::string> params;
  for (const io::ParameterSpec& p : config.parameters) {
    const mjsysid::ParameterSpec& t = p.target;
    params.push_back(p.name + " (" + t.kind + " " + (t.object.empty() ? t.field : t.object) +
                     (t.index ? "[" + std::to_string(t.index) + "]" : "") + ")");
  }
  Appendf(&summary, "  parameters %s\n", params.empty() ? "none" : Join(params).c_str());
  std::vector<std::string> sensors;
  for (const io::SensorSpec& s : config.sensors) sensors.push_back(s.name);
  Appendf(&summary, "  sensors    %s\n", sensors.empty() ? "all" : Join(sensors).c_str());

  // data files: present, readable, consistent with the models
  for (const io::DataFile& data : config.data) {
    std::error_code ec;
    if (!fs::exists(data.path, ec)) {
      throw io::ConfigError(data.mark, "data file not found: " + data.path,
                            "`sysid simulate " + args.experiment + "` writes it");
    }
    const io::Log log = io::ReadLog(data.path);
    if (log.sensor_time != (config.sensor_time == io::SensorTime::kPre ? "pre" : "post")) {
      std::fprintf(stderr,
                   "sysid check: warning: %s records sensor_time '%s', the experiment says '%s'\n",
                   data.path.c_str(), log.sensor_time.c_str(),
                   config.sensor_time == io::SensorTime::kPre ? "pre" : "post");
    }
    std::vector<std::string> names;
    for (const io::Sequence& seq : log.sequences) {
      names.push_back(seq.name + " (" + std::to_string(seq.time.size()) + ")");
    }
    Appendf(&summary, "  data       %s: %zu sequences: %s\n", data.path.c_str(),
            log.sequences.size(), Join(names).c_str());
  }
  if (config.data.empty()) Appendf(&summary, "  data       none (`sysid simulate` writes it)\n");

  // the data as `fit` takes it (one validation: each sequence against the model it belongs to,
  // the selected sequences exist, the sample period), then the Jacobians of every residual block
  // against Ceres' numeric differentiation
  if (!config.data.empty()) {
    mjsysid::run::BuiltProblem built = mjsysid::run::BuildProblem(config);
    for (const std::string& w : built.warnings) {
      std::fprintf(stderr, "sysid check: warning: %s\n", w.c_str());
    }
    // what is fitted and what is held out (`validation:`)
    std::vector<std::string> fitted, held_out;
    for (const mjsysid::FitSequence& s : built.sequences) fitted.push_back(s.name);
    for (const mjsysid::FitSequence& s : built.validation) held_out.push_back(s.name);
    Appendf(&summary, "  fitted     %s\n", Join(fitted).c_str());
    if (!held_out.empty()) {
      Appendf(&summary, "  validation %s (held out: simulated, not fitted)\n",
              Join(held_out).c_str());
    }
    if (!args.jacobians) {
      std::printf("%sOK\n", summary.c_str());
      return kExitOk;
    }
    mjsysid::JacobianCheck check;
    try {
      check = built.problem->CheckJacobians(built.options);
    } catch (const mjsysid::SimulationError& e) {
      throw mjsysid::SimulationError(
          std::string(e.what()) + "; " + mjsysid::run::AtInitialValues(config), e.sequence(),
          e.step());
    }
    Appendf(&summary,
            "  jacobians  core (%s differences) vs ceres::GradientChecker, "
            "column-scaled relative error:\n",
            built.options.jacobian.central ? "central" : "forward");
    for (const auto& [name, err] : check.per_variable) {
      Appendf(&summary, "             %-32s %.2e\n", name.c_str(), err);
    }
    Appendf(&summary, "  worst      %.2e (%s)\n", check.worst_relative_error,
            check.worst_where.c_str());
    if (check.worst_relative_error > args.tolerance) {
      // friction and contact make residuals non-smooth: Ceres' Ridders differences (steps of
      // ~1e-5 relative and up) then see kinks that the core's local differences do not
      Appendf(&summary,
              "  warning    the worst error exceeds --tolerance %.1e: the residuals are not "
              "smooth at the scale of Ceres' numeric steps (friction, contact), or the "
              "Jacobian is wrong; compare `jacobian: whole_rollout` with `differences: "
              "central` before trusting the fit\n",
              args.tolerance);
      if (args.strict) {
        std::printf("%s", summary.c_str());
        return kExitFailed;
      }
    }
  }
  std::printf("%sOK\n", summary.c_str());
  return kExitOk;
}

Command AddCheck(CLI::App* app) {
  auto args = std::make_shared<CheckArgs>();
  CLI::App* sub = app->add_subcommand(
      "check",
      "Check an experiment without fitting: the YAML file, its model(s) (exist, compile, names "
      "and parameters resolve) and its data files (readable, consistent with the models)");
  sub->add_option("experiment", args->experiment,
                  "YAML experiment file (docs/experiment-schema.md)")
      ->required();
  sub->add_flag("!--no-jacobians", args->jacobians,
                "skip the Jacobian check (core vs ceres::GradientChecker at the initial values)");
  sub->add_option("--tolerance", args->tolerance,
                  "largest acceptable column-scaled relative Jacobian error")
      ->check(FiniteNumber())
      ->capture_default_str();
  sub->add_flag("--strict", args->strict, "exit 1 when the Jacobian error exceeds --tolerance");
  sub->footer(std::string("Prints a summary and OK, or the first error. With data, also checks "
                          "the Jacobians of every residual block at the initial values and prints "
                          "the worst relative error per parameter.\n") +
              kExitCodesFooter);
  return {sub, [args] { return RunCheck(*args); }};
}

// ---------------------------------------------------------------------------------------------
// sysid fit EXP.yaml --out DIR

std::atomic<bool> g_interrupted{false};
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

// first SIGINT, SIGTERM or SIGHUP: stop after the current iteration and write the results; the
// next one has the default action (the process ends at once; the previous result stays)
extern "C" void OnInterrupt(int) {
  g_interrupted.store(true);
  for (int s : kStopSignals) std::signal(s, SIG_DFL);
}

// installs (true) or removes (false) OnInterrupt for the stop signals
void CatchStopSignals(bool on) {
  for (int s : kStopSignals) std::signal(s, on ? OnInterrupt : SIG_DFL);
}

struct FitArgs {
  std::string experiment;
  std::string out;
  int threads = -1;
  bool quiet = false;
  bool force = false;
  std::string resume;   // --resume DIR
  int starts = 0;       // --starts N (0: solver.starts)
  long long seed = -1;  // --seed S (< 0: solver.seed)
};

std::string Flags(const mjsysid::ParameterEstimate& p) {
  std::vector<std::string> f;
  if (p.at_lower) f.push_back("at lower bound");
  if (p.at_upper) f.push_back("at upper bound");
  if (!p.identifiable) f.push_back("UNIDENTIFIABLE");
  return Join(f);
}

// a % fit for a table cell ("-" for NaN: a constant channel or a failed simulation)
std::string Percent(double x) {
  if (!std::isfinite(x)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", x);
  return buf;
}

// per sequence the worst and the median channel's % fit (sysid/metrics.h), at the start and at the
// estimate; fitted sequences first, then the held-out ones (`validation:`)
void PrintFitQuality(const mjsysid::io::FitResultFile& f) {
  if (f.sequences.empty() && f.validation.empty()) return;
  std::printf(
      "  %% fit per channel, start -> estimate (100 = exact, 0 = no better than the mean)\n");
  std::printf("  %-24s %-10s %8s  %-22s %s\n", "sequence", "role", "channels", "worst", "median");
  for (const std::vector<mjsysid::SequenceResult>* list : {&f.sequences, &f.validation}) {
    for (const mjsysid::SequenceResult& s : *list) {
      const mjsysid::FitSummary a = mjsysid::SummarizeFits(s.channel_fits, true);
      const mjsysid::FitSummary b = mjsysid::SummarizeFits(s.channel_fits, false);
      std::printf("  %-24s %-10s %8zu  %6s -> %-12s %6s -> %s\n", s.name.c_str(),
                  list == &f.sequences ? "fit" : "validation", s.channel_fits.size(),
                  Percent(a.worst).c_str(), Percent(b.worst).c_str(), Percent(a.median).c_str(),
                  Percent(b.median).c_str());
    }
  }
}

// multi-start: per estimated value the range over the starts, and how many starts ended where
void PrintStarts(const mjsysid::io::FitResultFile& f) {
  if (f.starts.size() < 2) return;
  int honest = 0, failed = 0;
  for (const mjsysid::StartResult& s : f.starts) {
    failed += s.error.empty() || s.status == mjsysid::FitStatus::kInterrupted ? 0 : 1;
    honest += s.error.empty() && (s.status == mjsysid::FitStatus::kConverged ||
                                  s.status == mjsysid::FitStatus::kModelMismatch)
                  ? 1
                  : 0;
  }
  int stopped = 0;
  for (const mjsysid::StartResult& s : f.starts) {
    stopped += s.status == mjsysid::FitStatus::kInterrupted ? 1 : 0;
  }
  std::printf(
      "  %zu starts (%d converged, %d failed, %d interrupted); the result is start %d's (lowest "
      "cost)\n",
      f.starts.size(), honest, failed, stopped, f.best_start);
  std::printf("  %-24s %14s %14s %12s\n", "spread over the starts", "min", "max", "(max-min)/|v|");
  for (const mjsysid::ParameterSpread& s : f.start_spread) {
    std::printf("  %-24s %14.6g %14.6g %12.3g\n", s.name.c_str(), s.min, s.max, s.relative);
  }
}

// prints the estimates against the start (and the truth, for simulated data)
void PrintEstimates(const mjsysid::io::FitResultFile& f) {
  std::printf("%s: %s after %d iterations (%s), cost %.6g -> %.6g, %.2f s\n", f.name.c_str(),
              f.status.c_str(), f.iterations, f.termination.c_str(), f.initial_cost, f.final_cost,
              f.seconds);
  if (!f.segment_reason.empty()) std::printf("  %s\n", f.segment_reason.c_str());
  std::printf("  %-24s %14s %14s %14s %12s  %-29s %s\n", "parameter", "initial", "estimate",
              "truth", "std", "95% interval", "flags");
  for (const mjsysid::ParameterEstimate& p : f.parameters) {
    char truth[32] = "-", ci[64];
    if (p.truth) std::snprintf(truth, sizeof(truth), "%.6g", *p.truth);
    std::snprintf(ci, sizeof(ci), "[%.6g, %.6g]", p.ci95_low, p.ci95_high);
    std::printf("  %-24s %14.6g %14.8g %14s %12.3g  %-29s %s\n", p.name.c_str(), p.initial, p.value,
                truth, p.std_error, ci, Flags(p).c_str());
  }
  // quantities derived from the estimate (body_inertial: mass, centre of mass, principal moments)
  if (!f.derived.empty()) {
    std::printf("  %-24s %14s %14s %14s %12s  %-29s %s\n", "derived", "unit", "value", "truth",
                "std", "95% interval", "from");
  }
  for (const mjsysid::DerivedQuantity& d : f.derived) {
    char truth[32] = "-", ci[64];
    if (d.truth) std::snprintf(truth, sizeof(truth), "%.6g", *d.truth);
    std::snprintf(ci, sizeof(ci), "[%.6g, %.6g]", d.ci95_low, d.ci95_high);
    std::printf("  %-24s %14s %14.8g %14s %12.3g  %-29s %s\n", d.name.c_str(), d.unit.c_str(),
                d.value, truth, d.std_error, ci, d.derived_from.c_str());
  }
  for (const std::string& u : f.uncertainty.unidentifiable)
    std::printf("  unidentifiable: %s\n", u.c_str());
  if (!f.intervals_valid) {
    std::printf("  intervals NOT VALID: the status is %s, not converged (see the warnings)\n",
                f.status.c_str());
  }
  PrintFitQuality(f);
  PrintStarts(f);
  std::fflush(stdout);
}

// the experiment file of `sysid fit`: --resume DIR: the checkpoint's unless given
std::string ExperimentOf(const FitArgs& args) {
  namespace io = mjsysid::io;
  std::string experiment = args.experiment;
  if (!args.resume.empty()) {
    if (!args.out.empty() && !mjsysid::run::SamePath(args.out, args.resume)) {
      throw InputError("--out " + args.out + " and --resume " + args.resume +
                       " differ: a resumed fit writes into the folder it resumes");
    }
    if (experiment.empty()) {
      const std::optional<io::FitResultFile> cp = mjsysid::run::FindCheckpoint(args.resume);
      if (!cp) {
        throw InputError("--resume " + args.resume + ": nothing to resume: no checkpoint " +
                         mjsysid::run::StagingFolder(args.resume) +
                         "/checkpoint.yaml and no interrupted result in the folder");
      }
      experiment = cp->experiment;
    }
  } else if (experiment.empty()) {
    throw InputError("the experiment file is required (sysid fit EXP.yaml), except with --resume");
  }
  return experiment;
}

// on_problem: set by the MPI-sharded fit (RunFitSharded), else empty
int RunFitHere(const FitArgs& args,
               const std::function<void(mjsysid::Problem&, mjsysid::FitOptions*)>& on_problem) {
  namespace io = mjsysid::io;
  const io::ExperimentConfig config = io::LoadExperiment(ExperimentOf(args));
  mjsysid::run::FitRunOptions options;
  options.on_problem = on_problem;
  options.out_dir = args.resume.empty() ? args.out : args.resume;
  options.resume = !args.resume.empty();
  options.threads = args.threads;
  options.verbose = !args.quiet;
  options.interrupt = &g_interrupted;
  options.force = args.force;
  options.on_estimates = PrintEstimates;
  options.starts = args.starts;
  options.seed = args.seed;
  CatchStopSignals(true);
  const mjsysid::run::FitRunOutcome out = mjsysid::run::RunFit(config, options);
  CatchStopSignals(false);
  const io::FitResultFile& f = out.file;
  // the data's warnings were printed before the fit (FitRunOutcome::printed_warnings)
  for (size_t i = static_cast<size_t>(out.printed_warnings); i < f.warnings.size(); ++i)
    std::fprintf(stderr, "sysid fit: warning: %s\n", f.warnings[i].c_str());
  std::printf("  wrote %s/{result.yaml, result.h5", out.out_dir.c_str());
  for (const auto& [model, file] : f.identified_models) std::printf(", %s", file.c_str());
  std::printf("} (run %s)\n", f.run_id.c_str());
  if (out.file.interrupted)
    std::fprintf(stderr, "sysid fit: interrupted: results of the last good iterate written\n");
  return out.exit_code;
}

#ifdef MJSYSID_WITH_MPI
// `mpirun -n N sysid fit` (sysid/mpi/distributed_fit.h): rank 0 fits and writes, the other ranks
// evaluate their share of the sequences; every rank reads and checks the input first, and rank 0
// reports the first rank's failure (exit 2)
int RunFitSharded(const FitArgs& args) {
  namespace mpi = mjsysid::mpi;
  if (mpi::Rank() > 0) {
    std::string failure;
    std::optional<mjsysid::io::ExperimentConfig> config;
    try {
      config = mjsysid::io::LoadExperiment(ExperimentOf(args));
    } catch (const std::exception& e) {
      failure = e.what();
    }
    return mpi::ServeFit(config ? &*config : nullptr, args.threads, failure);
  }
  mpi::ShardedResiduals shards;
  shards.SetInterrupt(&g_interrupted);  // a worker's stop signal stops the fit too
  int code = 0;
  try {
    // every start of --starts a whole sharded fit, one after another
    code = RunFitHere(args, [&](mjsysid::Problem& problem, mjsysid::FitOptions* /*options*/) {
      shards.NextProblem();
      problem.DistributeResiduals(&shards);
    });
  } catch (const mpi::RankError& e) {
    shards.Abandon(e.what());
    throw InputError(e.what());
  } catch (const std::exception& e) {
    shards.Abandon(e.what());
    throw;
  }
  shards.Finish();
  if (std::getenv("MJSYSID_MPI_STATS")) {
    // traffic and time of the evaluations (tools/bench/mpi_bench.sh reads this line)
    const mpi::ShardStats& st = shards.stats();
    std::fprintf(stderr,
                 "mpi stats: ranks %d evaluations %lld jacobian_evaluations %lld bytes %lld "
                 "seconds_mpi %.6f seconds_own_share %.6f\n",
                 mpi::Size(), st.evaluations, st.jacobian_evaluations, st.bytes, st.seconds_mpi,
                 st.seconds_own_share);
  }
  return code;
}
#endif

int RunFit(const FitArgs& args) {
#ifdef MJSYSID_WITH_MPI
  // under a launcher even with one rank: the same arithmetic (one tree) with any rank count
  if (mjsysid::mpi::Active()) return RunFitSharded(args);
#endif
  return RunFitHere(args, {});
}

Command AddFit(CLI::App* app) {
  auto args = std::make_shared<FitArgs>();
  CLI::App* sub = app->add_subcommand(
      "fit", "Fit the experiment's parameters to its data files (Ceres, analytic Jacobians)");
  sub->add_option("experiment", args->experiment,
                  "YAML experiment file (with --resume: default the checkpoint's)");
  sub->add_option("--out", args->out,
                  "output folder (default: the experiment's `output`, results/<name>)");
  sub->add_option("--threads", args->threads, "simulation threads (default: solver.threads)")
      ->check(WholeNumberAtLeast(0));
  sub->add_flag("--quiet", args->quiet, "no progress line per iteration");
  sub->add_flag("--force", args->force,
                "replace an existing --out folder that is not an mjsysid result folder (its files "
                "are deleted)");
  sub->add_option("--starts", args->starts,
                  "fit from N starts spread in the bounds, in parallel; keep the best, report the "
                  "spread and flag local minima (default: solver.starts, 1)")
      ->check(WholeNumberAtLeast(1));
  sub->add_option("--seed", args->seed, "seed of the spread starts (default: solver.seed, 0)")
      ->check(WholeNumberAtLeast(0));
  sub->add_option("--resume", args->resume,
                  "continue the fit of DIR from its checkpoint (DIR.partial/checkpoint.yaml of a "
                  "killed run, or DIR's interrupted result); writes into DIR");
  sub->footer(
      std::string("Writes DIR/result.yaml (values, std, 95% intervals, flags, costs, versions), "
                  "DIR/result.h5 (trace, Jacobian, covariance, signals) and "
                  "DIR/<model>_identified.xml, all with one run id, into DIR.partial (with "
                  "checkpoint.yaml after every successful iteration), which replaces DIR once "
                  "complete. Ctrl-C, SIGTERM or SIGHUP stops after the current iteration and "
                  "writes the results of the last good iterate; a second one exits at once and "
                  "leaves DIR as it was. Exit code 1 when the fit did not converge. Under "
                  "`mpirun -n N` (or srun) the sequences are sharded across the ranks and rank 0 "
                  "writes (docs/cluster.md).\n") +
      kExitCodesFooter);
  return {sub, [args] { return RunFit(*args); }};
}

// ---------------------------------------------------------------------------------------------
// sysid report DIR

struct ReportArgs {
  std::string dir;
  bool no_video = false;
};

int RunReport(const ReportArgs& args) {
  // no fit may replace the folder while the report writes into it (a folder whose parent is not
  // writable has no lock, and no fit can replace it); the pages are no inputs
  std::optional<mjsysid::run::FolderLock> lock;
  try {
    lock.emplace(args.dir, "sysid report");
  } catch (const mjsysid::io::FileError&) {
  }
  std::error_code ec;
  if (!fs::is_directory(args.dir, ec)) {
    throw InputError(args.dir +
                     ": no such folder (a fit writes result.yaml and result.h5 into its "
                     "output folder)");
  }
  const fs::path dir(args.dir);
  for (const char* page : {"report.html", "cost.png", "parameters.png", "motion.webp"}) {
    mjsysid::run::CheckOutputFile((dir / page).string(),
                                  {(dir / "result.yaml").string(), (dir / "result.h5").string()},
                                  "report");
  }
  std::string summary;
  try {
    mjsysid::report::ReportOptions options;
    options.motion.enabled = !args.no_video;
    options.motion.progress = [](const std::string& line) {
      std::fprintf(stderr, "%s\n", line.c_str());
    };
    mjsysid::report::WriteReport(args.dir, options, &summary);
  } catch (const mjsysid::io::ResultError& e) {
    throw InputError(e.what());
  }
  std::printf("%s", summary.c_str());
  return kExitOk;
}

Command AddReport(CLI::App* app) {
  auto args = std::make_shared<ReportArgs>();
  CLI::App* sub = app->add_subcommand(
      "report", "Plot a fit's results: measured vs simulated signals, parameters, cost trace");
  sub->add_option("dir", args->dir, "output folder of `sysid fit` (result.yaml, result.h5)")
      ->required();
  sub->add_flag("--no-video", args->no_video,
                "no motion clip (by default the first sequence is re-simulated at the initial "
                "and the fitted values and rendered offscreen, side by side)");
  sub->footer(std::string("Writes DIR/report.html (self-contained: no network), DIR/cost.png, "
                          "DIR/parameters.png, DIR/seq_<name>.png and DIR/motion.webp (the "
                          "initial and fitted simulation, animated; needs the experiment file "
                          "and its logs, and OSMesa; without them the page says why).\n") +
              kExitCodesFooter);
  return {sub, [args] { return RunReport(*args); }};
}

// ---------------------------------------------------------------------------------------------
// sysid import MODEL.xml CSV... --out LOG.h5

struct ImportArgs {
  std::string model;
  std::vector<std::string> csv;
  std::string out;
  std::string sensor_time = "pre";
  bool force = false;   // overwrite an --out that is not an mjsysid log
  std::string mapping;  // ROS bags / MCAP: topic -> actuators, sensors, joints (YAML)
};

// a ROS 1 bag, a ROS 2 storage file, an MCAP file or a ROS 2 bag folder (metadata.yaml)
bool IsBag(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  std::error_code ec;
  return ext == ".bag" || ext == ".db3" || ext == ".mcap" ||
         (fs::is_directory(path, ec) && fs::exists(fs::path(path) / "metadata.yaml", ec));
}

// the Python that imports bags: $MJSYSID_PYTHON, else $MJSYSID_VENV/bin/python, else the venv
// the build used (MJSYSID_DEFAULT_VENV, the source tree's .venv)
std::string BagPython() {
  if (const char* py = std::getenv("MJSYSID_PYTHON"); py && *py) return py;
  const char* venv = std::getenv("MJSYSID_VENV");
  return (fs::path(venv && *venv ? venv : MJSYSID_DEFAULT_VENV) / "bin" / "python").string();
}

// runs argv (argv[0] a path) and returns its exit code; 127 when it cannot be started
int RunChild(const std::vector<std::string>& argv, bool quiet) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    if (quiet) {
      const int null = open("/dev/null", O_WRONLY);
      if (null >= 0) {
        dup2(null, STDOUT_FILENO);
        dup2(null, STDERR_FILENO);
      }
    }
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// ROS bags / MCAP files: `python -m mjsysid.bags` (python/mjsysid/bags.py) writes the log
int RunImportBags(const ImportArgs& args) {
  if (args.mapping.empty()) {
    throw InputError(
        "ROS bags and MCAP files need --mapping MAP.yaml (topic -> actuators, "
        "sensors; JointState by joint name; docs/cli.md)");
  }
  for (const std::string& path : args.csv) {
    if (!IsBag(path)) {
      throw InputError(path + ": CSV files and bags cannot be imported together");
    }
  }
  const std::string python = BagPython();
  if (access(python.c_str(), X_OK) != 0) {
    throw InputError("importing bags needs the Python package mjsysid: no Python at " + python +
                     " (run tools/bootstrap.sh, or set MJSYSID_PYTHON to a python that has "
                     "mjsysid, rosbags and PyYAML)");
  }
  if (RunChild({python, "-c", "import mjsysid.bags"}, /*quiet=*/true) != 0) {
    throw InputError(python +
                     " cannot import mjsysid.bags (the Python package mjsysid with rosbags and "
                     "PyYAML: run tools/bootstrap.sh, or pip install . and -r "
                     "tools/deps/requirements.txt into that environment)");
  }
  std::vector<std::string> inputs = {args.model, args.mapping};
  inputs.insert(inputs.end(), args.csv.begin(), args.csv.end());
  PrepareLogOutput(args.out, inputs, args.force);
  std::vector<std::string> argv = {
      python,   "-m",        "mjsysid.bags", args.model,      "--out",
      args.out, "--mapping", args.mapping,   "--sensor-time", args.sensor_time};
  argv.insert(argv.end(), args.csv.begin(), args.csv.end());
  return RunChild(argv, /*quiet=*/false);
}

// CSV files (one sequence each, named after the file) into one validated HDF5 log
int RunImport(const ImportArgs& args) {
  namespace io = mjsysid::io;
  if (std::any_of(args.csv.begin(), args.csv.end(), IsBag)) return RunImportBags(args);
  mjsysid::ModelPtr m = mjsysid::LoadModel(args.model);
  io::Log log;
  log.sensor_time = args.sensor_time;
  log.attributes["generator"] = std::string("mjsysid ") + MJSYSID_VERSION + " import";
  log.attributes["model"] = fs::absolute(args.model).string();
  // each argument one sequence: a file, or [NAME=]A.csv+B.csv+... (one sequence from several
  // files at their own rates, io::ImportCsvFiles; named NAME, else after the first file)
  std::vector<std::string> files;
  for (const std::string& arg : args.csv) {
    std::error_code ec;
    std::string name, list = arg;
    std::vector<std::string> paths;
    if (fs::exists(arg, ec)) {
      paths = {arg};
    } else {
      const size_t eq = arg.find('=');
      if (eq != std::string::npos) {
        name = arg.substr(0, eq);
        list = arg.substr(eq + 1);
      }
      for (size_t at = 0;;) {
        const size_t plus = list.find('+', at);
        paths.push_back(list.substr(at, plus == std::string::npos ? plus : plus - at));
        if (plus == std::string::npos) break;
        at = plus + 1;
      }
    }
    if (name.empty()) name = fs::path(paths[0]).stem().string();
    log.sequences.push_back(io::ImportCsvFiles(paths, *m, name));
    files.insert(files.end(), paths.begin(), paths.end());
  }
  std::vector<std::string> warnings;
  io::ValidateLogAgainstModel(log, *m, args.out, &warnings);
  for (const std::string& w : warnings)
    std::fprintf(stderr, "sysid import: warning: %s\n", w.c_str());
  std::vector<std::string> inputs = {args.model};
  inputs.insert(inputs.end(), files.begin(), files.end());
  PrepareLogOutput(args.out, inputs, args.force);
  io::WriteLog(args.out, log);
  std::printf("imported %zu sequence(s) into %s\n", log.sequences.size(), args.out.c_str());
  for (const io::Sequence& s : log.sequences) {
    std::printf("  %-16s %6zu samples, sensors: %s", s.name.c_str(),
                static_cast<size_t>(s.time.size()), Join(s.sensor_names).c_str());
    if (s.ctrl_time.size())
      std::printf("; controls at their own %zu times", static_cast<size_t>(s.ctrl_time.size()));
    std::printf("\n");
  }
  return kExitOk;
}

Command AddImport(CLI::App* app) {
  auto args = std::make_shared<ImportArgs>();
  CLI::App* sub = app->add_subcommand(
      "import",
      "Convert CSV logs (header row of names), ROS bags or MCAP files into an HDF5 log that "
      "`fit` reads");
  sub->add_option("model", args->model, "MJCF model the logs were recorded on")->required();
  sub->add_option("csv", args->csv,
                  "CSV files, ROS bags or MCAP files, one sequence each (named after the file); "
                  "[NAME=]A.csv+B.csv+...: one sequence from several CSV files, each with its "
                  "own time column (controls in one, sensors at their own rates)")
      ->required();
  sub->add_option("--out", args->out, "HDF5 log to write (atomically)")->required();
  sub->add_option("--sensor-time", args->sensor_time,
                  "pre: sensors read before the step (y_k at x_k); post: after it")
      ->check(CLI::IsMember({"pre", "post"}))
      ->capture_default_str();
  sub->add_flag("--force", args->force, "overwrite an existing --out that is not an mjsysid log");
  sub->add_option("--mapping", args->mapping,
                  "ROS bags (.bag, ROS 2 folders, .db3) and MCAP files: YAML mapping of topics "
                  "to actuators, sensors and joints (docs/cli.md)");
  sub->footer(std::string("CSV columns: time, one per actuator (its name), one per sensor "
                          "component (NAME or NAME[i]), optional qpos[i], qvel[i], act[i]; "
                          "any order. Checked against the model before writing. ROS bags and "
                          "MCAP files (with --mapping) are read by the Python package mjsysid "
                          "(rosbags) in the project venv.\n") +
              kExitCodesFooter);
  return {sub, [args] { return RunImport(*args); }};
}

// ---------------------------------------------------------------------------------------------
// errors -> exit codes

// runs a subcommand, printing any error as "sysid NAME: message" and mapping it to an exit code
int RunGuarded(const std::string& name, const std::function<int()>& run) {
  auto fail = [&name](const char* what, int code) {
    std::fprintf(stderr, "sysid %s: %s\n", name.c_str(), what);
    return code;
  };
  try {
    return run();
  } catch (const mjsysid::io::ConfigError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const mjsysid::io::LogError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const mjsysid::ModelLoadError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const mjsysid::ParameterError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const InputError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const mjsysid::run::OutputError& e) {
    return fail(e.what(), kExitBadInput);
  } catch (const mjsysid::SimulationError& e) {
    return fail(e.what(), kExitFailed);
  } catch (const std::exception& e) {
    return fail(e.what(), kExitFailed);
  }
}

}  // namespace

int main(int argc, char** argv) {
  mjsysid::InstallMujocoHandlers();
#ifdef MJSYSID_WITH_MPI
  // only when started by an MPI launcher (mpirun, srun); ended by std::atexit at exit
  mjsysid::mpi::Initialize(&argc, &argv);
  std::atexit(mjsysid::mpi::Finalize);
#endif
  CLI::App app{
      "mjsysid: system identification for MuJoCo models.\n"
      "Run `sysid SUBCOMMAND --help` for the arguments of a subcommand."};
  app.set_version_flag("--version", std::string("mjsysid ") + MJSYSID_VERSION + " (MuJoCo " +
                                        mjsysid::MujocoVersion() + ")");
  app.require_subcommand(1);
  app.footer(std::string("Examples:\n"
                         "  sysid simulate experiments/pendulum.yaml\n"
                         "  sysid fit experiments/pendulum.yaml --out results/pendulum\n"
                         "  sysid report results/pendulum\n"
                         "  sysid check experiments/pendulum.yaml\n"
                         "  sysid rollout models/pendulum.xml --steps 500\n") +
             kExitCodesFooter);

  // subcommands, in the order --help lists them
  std::vector<Command> commands;
  commands.push_back(AddSimulate(&app));
  commands.push_back(AddFit(&app));
  commands.push_back(AddReport(&app));
  commands.push_back(AddImport(&app));
  commands.push_back(AddCheck(&app));
  commands.push_back(AddRollout(&app));

  // an unknown subcommand is named (CLI11 would say "A subcommand is required")
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const Command& c : commands) names.push_back(c.app->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      std::string shown(argv[1]);
      if (shown.size() > 40) shown = shown.substr(0, 40) + "...";
      std::fprintf(stderr, "sysid: unknown subcommand '%s'; the subcommands: %s (sysid --help)\n",
                   shown.c_str(), Join(names).c_str());
      return kExitBadInput;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    // one line, "sysid SUBCOMMAND: message", as every other error
    const bool sub =
        argc > 1 && std::any_of(commands.begin(), commands.end(),
                                [&](const Command& c) { return c.app->get_name() == argv[1]; });
    std::fprintf(stderr, "sysid%s%s: %s (hint: sysid%s%s --help)\n", sub ? " " : "",
                 sub ? argv[1] : "", e.what(), sub ? " " : "", sub ? argv[1] : "");
    return kExitBadInput;
  }
  for (const Command& c : commands) {
    if (!*c.app) continue;
#ifdef MJSYSID_WITH_MPI
    // under mpirun `fit` and `simulate` are sharded: every other subcommand runs on rank 0 alone
    // (one writer of its outputs)
    if (mjsysid::mpi::Rank() > 0 && c.app->get_name() != "fit" && c.app->get_name() != "simulate") {
      return kExitOk;
    }
#endif
    const int code = RunGuarded(c.app->get_name(), c.run);
#ifndef __SANITIZE_ADDRESS__
    // HDF5 1.10 crashes in its exit handler (SIGSEGV in H5F__close_cb) when a write failed (full
    // disk, file size limit) and left a file it could not close: a failed run ends, its output
    // flushed, without the libraries' exit handlers (measured: exit 139 instead of 1 or 2).
    // Sanitizer builds keep them, for LeakSanitizer.
    if (code != kExitOk) {
#ifdef MJSYSID_WITH_MPI
      mjsysid::mpi::Finalize();  // the other ranks left the fit: MPI ends cleanly
#endif
      std::fflush(nullptr);
      std::_Exit(code);
    }
#endif
    return code;
  }
  return kExitBadInput;
}
