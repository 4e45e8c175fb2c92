// sysid check EXP.yaml: check an experiment, its models, data and Jacobians without fitting.
#include <cstdio>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/io/warnings.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/types.h"
#include "tools/sysid_cli.h"

namespace mjsysid::cli {
namespace {

struct CheckArgs {
  std::string experiment;
  bool jacobians = true;
  double tolerance = 1e-4;
  bool strict = false;
};

// the --help page of `sysid check`: description, arguments (into args) and footer
void DeclareCheck(CLI::App* sub, CheckArgs* args) {
  sub->description(
      "Check an experiment without fitting: the YAML file, its model(s) (exist, compile, names and "
      "parameters resolve) and its data files (readable, consistent with the models)");
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
  sub->footer(
      "Prints a summary and OK, or the first error. With data, also checks the Jacobians of every "
      "residual block at the initial values and prints the worst relative error per parameter.\n");
}

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
  // the fitted control delays (`controls: {delay: {..., fit: true}}`) are fitted values too
  for (const io::ExperimentConfig::ControlDelaySpec& cd : config.control_delays) {
    if (!cd.term.fit) continue;
    mjsysid::FitControlDelay delay;
    delay.actuator = cd.actuator;
    params.push_back(delay.Name() + " (control delay " +
                     (cd.actuator.empty() ? "of every actuator" : cd.actuator) + ")");
  }
  Appendf(&summary, "  parameters %s\n", params.empty() ? "none" : Join(params).c_str());
  std::vector<std::string> sensors;
  for (const io::SensorSpec& s : config.sensors) sensors.push_back(s.name);
  Appendf(&summary, "  sensors    %s\n", sensors.empty() ? "all" : Join(sensors).c_str());

  // data files: present, readable, consistent with the models
  for (const io::DataFile& data : config.data) {
    std::error_code ec;
    if (!std::filesystem::exists(data.path, ec)) {
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
    for (const std::string& w : io::GroupedWarningLines(built.warnings)) {
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
          std::string(e.what()) + "; " + mjsysid::run::AtInitialValues(config, built.problem.get()),
          e.sequence(), e.step());
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

}  // namespace

Command AddCheck(CLI::App* app) { return AddSubcommand(app, "check", DeclareCheck, RunCheck); }

}  // namespace mjsysid::cli
