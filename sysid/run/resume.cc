#include "sysid/run/resume.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <system_error>

#include "sysid/run/fit_experiment.h"
#include "sysid/run/output_folder.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;

}  // namespace

std::optional<io::FitResultFile> FindCheckpoint(const std::string& dir) {
  std::error_code ec;
  const fs::path staging(StagingFolder(dir));
  if (fs::exists(staging / "checkpoint.yaml", ec) && fs::exists(staging / "checkpoint.h5", ec)) {
    io::FitResultFile r = io::ReadResultFiles((staging / "checkpoint.yaml").string(),
                                              (staging / "checkpoint.h5").string());
    // checkpoint.h5 is written first: a kill between the two leaves it one iteration ahead
    while (!r.trace.empty() && r.trace.back().iteration > r.iterations) r.trace.pop_back();
    return r;
  }
  if (fs::exists(fs::path(dir) / "result.yaml", ec)) {
    io::FitResultFile r = io::ReadResult(dir);
    if (r.status == FitStatusName(FitStatus::kInterrupted)) return r;
  }
  return std::nullopt;
}

io::ExperimentConfig ResumedConfig(const io::ExperimentConfig& cfg,
                                   const io::FitResultFile& checkpoint) {
  const std::string what = "--resume: the checkpoint (run " + checkpoint.run_id + ") ";
  if (checkpoint.name != cfg.name) {
    throw OutputError(what + "is of experiment '" + checkpoint.name + "', not '" + cfg.name + "'");
  }
  if (cfg.options.estimate_initial_state || cfg.options.segment_steps > 0) {
    throw OutputError(what +
                      "cannot be resumed: the fit estimates initial states (initial_state: "
                      "{estimate: true} or multiple shooting), which are not checkpointed");
  }
  std::vector<std::string> names;
  for (const ParameterEstimate& e : checkpoint.parameters) names.push_back(e.name);
  if (names != FittedNames(cfg)) {
    throw OutputError(what + "has other parameters than " + cfg.source_file);
  }

  // start values: the checkpoint's, in FitResult order
  io::ExperimentConfig out = cfg;
  size_t k = 0;
  for (io::ParameterSpec& p : out.parameters) {
    p.initial = checkpoint.parameters[k++].value;
    p.initial_auto = false;  // an `initial: auto` start was solved by the run that checkpointed
  }
  for (io::MeasurementSpec& me : out.measurement) {
    for (FitMeasurement::Term* t : {&me.delay, &me.gain, &me.bias}) {
      if (t->fit) t->initial = checkpoint.parameters[k++].value;
    }
  }
  for (io::ExperimentConfig::ControlDelaySpec& cd : out.control_delays) {
    if (cd.term.fit) cd.term.initial = checkpoint.parameters[k++].value;
  }
  out.options.max_iterations = std::max(1, cfg.options.max_iterations - checkpoint.iterations);
  return out;
}

void AppendToCheckpoint(const io::FitResultFile& checkpoint, io::FitResultFile* resumed) {
  // the resumed fit's iteration 0 is the checkpoint's last iteration
  std::vector<IterationInfo> trace = checkpoint.trace;
  for (size_t i = 1; i < resumed->trace.size(); ++i) {
    IterationInfo it = resumed->trace[i];
    it.iteration += checkpoint.iterations;
    it.seconds += checkpoint.seconds;
    trace.push_back(it);
  }
  resumed->trace = trace;
  resumed->iterations += checkpoint.iterations;
  resumed->initial_cost = checkpoint.initial_cost;
  resumed->seconds += checkpoint.seconds;
  for (size_t i = 0; i < resumed->parameters.size() && i < checkpoint.parameters.size(); ++i) {
    resumed->parameters[i].initial = checkpoint.parameters[i].initial;
  }
}

}  // namespace mjsysid::run
