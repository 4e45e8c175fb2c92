// run::RunFit (sysid/run/fit_experiment.h) as a sequence of stages, and the helpers of the result
// files; run::BuildProblem is in build_problem.cc.
#include "sysid/run/fit_experiment.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <system_error>

#include "core/identified_model.h"
#include "core/text.h"
#include "core/thread_pool.h"
#include "mjsysid/version.h"
#include "sysid/assess/derived_inertials.h"
#include "sysid/assess/metrics.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/warnings.h"
#include "sysid/run/initial_state_check.h"
#include "sysid/run/input_hashes.h"
#include "sysid/run/multi_start.h"
#include "sysid/run/output_folder.h"
#include "sysid/run/resume.h"
#include "sysid/run/validation.h"

namespace mjsysid::run {

namespace fs = std::filesystem;

int ExitCodeOf(FitStatus status) {
  switch (status) {
    case FitStatus::kConverged:
      return 0;
    case FitStatus::kModelMismatch:
      return 3;
    case FitStatus::kJacobianUnreliable:
    case FitStatus::kDidNotMove:
    case FitStatus::kSolverFailed:
      return 4;
    default:
      return 1;  // not converged, local minimum, interrupted
  }
}

std::vector<std::string> WriteIdentifiedModel(const io::ExperimentConfig& cfg,
                                              const std::string& model_name,
                                              const std::string& model_path,
                                              const std::vector<ParameterEstimate>& estimates,
                                              const std::string& out_path,
                                              const std::string& run_id) {
  // the estimates of the parameters that apply to this model
  std::vector<ParameterSpec> specs;
  std::vector<double> values;
  for (const io::ParameterSpec* p : cfg.ParametersOf(model_name)) {
    for (const ParameterEstimate& e : estimates) {
      if (e.name != p->name) continue;
      specs.push_back(p->target);
      values.push_back(e.value);
    }
  }

  // core writes them into the model's MJCF (and checks it); the run id as a comment before the
  // root element; saved atomically (a temporary file next to out_path, flushed, renamed over it)
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(model_path, specs, values, &warnings);
  io::WriteFileAtomically(out_path, run_id.empty() ? xml : io::RunIdComment(run_id) + "\n" + xml);
  for (std::string& w : warnings) w = out_path + ": " + w;
  return warnings;
}

std::vector<std::string> InputsOf(const io::ExperimentConfig& cfg) {
  std::vector<std::string> inputs = {cfg.source_file};
  for (const io::ModelSpec& ms : cfg.models) inputs.push_back(ms.path);
  for (const io::DataFile& df : cfg.data) inputs.push_back(df.path);
  return inputs;
}

std::string AtInitialValues(const io::ExperimentConfig& cfg, const Problem* problem) {
  std::string out;
  for (size_t i = 0; i < cfg.parameters.size(); ++i) {
    const FitParameter& p = problem && i < problem->parameters().size()
                                ? problem->parameters()[i]
                                : static_cast<const FitParameter&>(cfg.parameters[i]);
    out += (out.empty() ? "" : ", ") + p.name + " = " +
           (p.initial_auto ? std::string("auto") : FormatDigits(p.initial, 6));
  }
  return "at the initial values " + out + " (" + cfg.source_file + ")";
}

std::vector<std::string> FittedNames(const io::ExperimentConfig& cfg) {
  std::vector<std::string> names;
  for (const io::ParameterSpec& p : cfg.parameters) names.push_back(p.name);
  for (const io::MeasurementSpec& me : cfg.measurement) {
    if (me.delay.fit) names.push_back(me.sensor + ".delay");
    if (me.gain.fit) names.push_back(me.sensor + ".gain");
    if (me.bias.fit) names.push_back(me.sensor + ".bias");
  }
  for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
    if (cd.term.fit) names.push_back(FitControlDelay{cd.actuator}.Name());
  }
  return names;
}

namespace {

std::string NowIso() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

// The run's own events, to the caller's observer (none: nothing): the data's warnings, reported
// before the fit (those that recur per sequence once, with a count: io::GroupedWarningLines), and a
// checkpoint that could not be written.
void ReportDataWarnings(FitObserver* observer, const std::vector<std::string>& warnings) {
  if (!observer) return;
  for (const std::string& w : io::GroupedWarningLines(warnings)) observer->OnWarning(w);
}
void ReportCheckpointNotWritten(FitObserver* observer, const char* what) {
  if (observer) observer->OnWarning(std::string("checkpoint not written: ") + what);
}

// Resume base: takes the output folder; gives the checkpoint --resume continues from
// (sysid/run/resume.h), none without --resume. Throws OutputError when there is nothing to resume.
std::optional<io::FitResultFile> ResumeBase(const std::string& out_dir, bool resume) {
  if (!resume) return std::nullopt;
  std::optional<io::FitResultFile> base = FindCheckpoint(out_dir);
  if (!base) {
    throw OutputError("--resume " + out_dir + ": nothing to resume: no checkpoint " +
                      StagingFolder(out_dir) +
                      "/checkpoint.yaml and no interrupted result in the folder");
  }
  return base;
}

// Resume inputs: takes the checkpoint and the files this run reads; throws when they are not the
// files the checkpointed run read (a fit continued on other data would end on them with the old
// run's initial cost and trace). A checkpoint of an older version has no hashes: a warning.
void CheckResumeInputs(const std::string& out_dir, const io::FitResultFile& base,
                       const std::vector<io::InputHash>& inputs,
                       std::vector<std::string>* warnings) {
  if (base.input_hashes.empty()) {
    warnings->push_back("the checkpoint of run " + base.run_id +
                        " records no input hashes (written by an older mjsysid): the experiment, "
                        "models and logs were not checked against it");
    return;
  }
  const std::vector<std::string> changes = InputChanges(base.input_hashes, inputs);
  if (changes.empty()) return;
  std::string list;
  for (const std::string& c : changes) list += (list.empty() ? "" : "; ") + c;
  throw OutputError("--resume " + out_dir + ": the inputs changed since the checkpoint of run " +
                    base.run_id + " was written: " + list +
                    "; a resumed fit must see the files the fit started on (fit again without "
                    "--resume, or restore the file" +
                    (changes.size() > 1 ? "s" : "") + ")");
}

// how many whole fits from different starts, and the seed that draws them
struct Starts {
  int count = 1;
  std::uint64_t seed = 0;
};

// Starts: takes the experiment and the run's options (theirs over the config's); gives the
// starts. Multi-start: N whole fits, no checkpoints, so a resumed fit continues one start.
Starts ResolveStarts(const io::ExperimentConfig& cfg, const FitRunOptions& ro,
                     const std::string& out_dir, bool resumed) {
  Starts s;
  s.count = ro.starts >= 1 ? ro.starts : cfg.starts;
  s.seed = ro.seed >= 0 ? static_cast<std::uint64_t>(ro.seed) : cfg.start_seed;
  if (s.count > 1 && resumed) {
    throw OutputError("--resume " + out_dir + ": a resumed fit continues one start, not " +
                      std::to_string(s.count) +
                      " (--starts or solver.starts); resume with --starts 1, or fit again");
  }
  return s;
}

// Output folder: takes the folder, once the input is known good (bad input leaves nothing
// behind); throws for one that holds an input or (without force) is foreign, and when its parent
// cannot be created.
void PrepareOutputFolder(const io::ExperimentConfig& cfg, const FitRunOptions& ro,
                         const std::string& out_dir) {
  CheckOutputFolder(out_dir, InputsOf(cfg), ro.force);
  const fs::path parent = fs::absolute(out_dir).lexically_normal().parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) {
    // the folder comes from --out, or from `output:` (or its default) in the experiment
    const io::Mark where = ro.out_dir.empty() ? cfg.marks.Of("output") : io::Mark{"--out", 0, 0};
    throw io::ConfigError(where, "cannot create the output folder " + out_dir + ": " + ec.message(),
                          "a file of that name exists, or the parent folder is not writable");
  }
}

// Resume check: takes the locked folder and the checkpoint read before the lock; throws when
// another run changed the checkpoint in between.
void CheckCheckpointUnchanged(const std::string& out_dir, const io::FitResultFile& base) {
  const std::optional<io::FitResultFile> now = FindCheckpoint(out_dir);
  if (!now || now->run_id != base.run_id || now->iterations != base.iterations) {
    throw OutputError("--resume " + out_dir + ": the checkpoint changed while starting");
  }
}

// Header: takes the experiment and the fit's options; gives what every result file (checkpoints
// too) says about the run: names, versions, time, a new run id and the solver settings.
void SetRunHeader(const io::ExperimentConfig& cfg, const FitOptions& options, const Starts& starts,
                  io::FitResultFile* file) {
  file->name = cfg.name;
  file->experiment = cfg.source_file;
  file->mjsysid_version = MJSYSID_VERSION;
  file->mujoco_version = MujocoVersion();
  file->created = NowIso();
  file->run_id = NewRunId();
  const SimulatorOptions sim_defaults;
  file->solver = {
      {"max_iterations", std::to_string(options.max_iterations)},
      {"function_tolerance", FormatG17(options.function_tolerance)},
      {"gradient_tolerance", FormatG17(options.gradient_tolerance)},
      {"parameter_tolerance", FormatG17(options.parameter_tolerance)},
      {"gauss_newton_stop", FormatG17(options.gauss_newton_stop)},
      {"global", options.global_stage ? "auto" : "off"},
      {"global_budget", FormatG17(options.global_budget)},
      {"timestep_check", options.timestep_check ? "auto" : "off"},
      {"subset_start", options.subset_start ? "auto" : "off"},
      {"jacobian", JacobianModeName(options.jacobian.mode)},
      {"differences", options.jacobian.central ? "central" : "forward"},
      {"relative_step", FormatG17(options.jacobian.relative_step)},
      {"threads", std::to_string(options.threads)},
      {"loss", LossTypeName(options.loss)},
      {"loss_scale", FormatG17(options.loss_scale)},
      {"estimate_initial_state", options.estimate_initial_state ? "true" : "false"},
      {"segment_steps", std::to_string(options.segment_steps)},
      {"continuity_weight", FormatG17(options.continuity_weight)},
      {"continuity_scale", options.continuity_relative ? "relative" : "absolute"},
      {"jumping_sensors", options.fit_jumping_sensors ? "fit" : "omit"},
      {"event_window", std::to_string(options.event_window)},
      {"hold_states_first", options.hold_states_first ? "true" : "false"},
      {"mujoco_solver_tolerance", "min(model, " + FormatG17(sim_defaults.solver_tolerance) + ")"},
      {"minimizer", "ceres levenberg-marquardt"},
      {"starts", std::to_string(starts.count)},
      {"seed", std::to_string(starts.seed)},
  };
}

// the experiment's known true values (simulate.truth) by name
std::map<std::string, double> TruthOf(const io::ExperimentConfig& cfg) {
  std::map<std::string, double> truth;
  for (const io::NamedValue& t : cfg.simulate.truth) truth[t.name] = t.value;
  return truth;
}

// the true value of each derived quantity (sysid/assess/derived_inertials.h) whose body has a truth
// for every body_inertial parameter (simulate.truth): the same derivation at the true values
void SetDerivedTruth(const BuiltProblem& bp, const std::map<std::string, double>& truth,
                     std::vector<DerivedQuantity>* derived) {
  if (derived->empty()) return;
  const auto n = static_cast<Eigen::Index>(bp.parameters.size());
  Eigen::VectorXd values = Eigen::VectorXd::Zero(n);
  std::map<std::string, bool> known;  // body -> every body_inertial parameter has a truth
  for (Eigen::Index v = 0; v < n; ++v) {
    const FitParameter& p = bp.parameters[static_cast<size_t>(v)];
    const auto it = truth.find(p.name);
    if (it != truth.end()) values[v] = it->second;
    if (p.target.kind != "body_inertial") continue;
    const bool has = it != truth.end();
    known[p.target.object] = known.count(p.target.object) ? known[p.target.object] && has : has;
  }
  for (size_t mi = 0; mi < bp.models.size(); ++mi) {
    const std::string prefix = bp.models.size() > 1 ? bp.model_names[mi] + "/" : "";
    for (const DerivedQuantity& t :
         DeriveInertials(*bp.models[mi], bp.model_names[mi], bp.parameters, values,
                         Eigen::VectorXd(), Eigen::MatrixXd(), prefix)) {
      const std::string body = t.name.substr(prefix.size(), t.name.rfind('.') - prefix.size());
      if (!known.count(body) || !known[body]) continue;
      for (DerivedQuantity& d : *derived) {
        if (d.name == t.name) d.truth = t.value;
      }
    }
  }
}

// Checkpoints: after every good iteration, DIR.partial/checkpoint.{yaml,h5} with status running,
// the current values and the successful iterations so far; a resumed run continues the
// checkpoint's count, trace and clock. A checkpoint that cannot be written (full disk) does not
// stop the fit: its estimates are still printed; the warning is given once. Every referenced
// object must outlive the fit.
class CheckpointWriter {
 public:
  // header: the result file as it is during the fit (the run's header only)
  CheckpointWriter(const io::ExperimentConfig& cfg, const io::ExperimentConfig& run_cfg,
                   const BuiltProblem& bp, const std::optional<io::FitResultFile>& base,
                   const io::FitResultFile& header, const std::map<std::string, double>& truth,
                   const std::string& staging, const FitRunOptions& ro)
      : bp_(bp), base_(base), header_(header), truth_(truth), ro_(ro), names_(FittedNames(cfg)) {
    yaml_ = (fs::path(staging) / "checkpoint.yaml").string();
    h5_ = (fs::path(staging) / "checkpoint.h5").string();
    // the first run's start values
    for (const FitParameter& p : bp.parameters) first_initial_.push_back(p.initial);
    for (const FitMeasurement& me : run_cfg.measurement) {
      for (const FitMeasurement::Term* t : {&me.delay, &me.gain, &me.bias}) {
        if (t->fit) first_initial_.push_back(t->initial);
      }
    }
    for (const io::ExperimentConfig::ControlDelaySpec& cd : run_cfg.control_delays) {
      if (cd.term.fit) first_initial_.push_back(cd.term.initial);
    }
    if (base) {
      for (size_t i = 0; i < first_initial_.size(); ++i)
        first_initial_[i] = base->parameters[i].initial;
      progress_ = *base;
    }
  }

  // FitOptions::on_iteration
  void OnIteration(const IterationInfo& it) {
    if (base_ && it.iteration == 0) return;  // the checkpoint it starts from
    // `initial: auto`: the start values the fit solved (NaN in the config)
    for (size_t i = 0; i < bp_.parameters.size(); ++i) {
      if (std::isnan(first_initial_[i])) first_initial_[i] = bp_.problem->parameters()[i].initial;
    }
    IterationInfo entry = it;
    entry.iteration += base_ ? base_->iterations : 0;
    entry.seconds += base_ ? base_->seconds : 0;
    if (!base_ && it.iteration == 0) progress_.initial_cost = it.cost;
    progress_.trace.push_back(entry);
    Write(Checkpoint(it, entry));
    if (ro_.on_iteration) ro_.on_iteration(it);
  }

 private:
  // the checkpoint after iteration it (entry: it in the resumed count and clock)
  io::FitResultFile Checkpoint(const IterationInfo& it, const IterationInfo& entry) const {
    io::FitResultFile cp = header_;
    cp.status = "running";
    cp.termination.kind = FitTermination::Kind::kCheckpoint;
    cp.termination.iteration = entry.iteration;
    cp.iterations = entry.iteration;
    cp.initial_cost = progress_.initial_cost;
    cp.final_cost = it.cost;
    cp.seconds = entry.seconds;
    cp.trace = progress_.trace;
    for (int i = 0; i < it.parameters.size() && i < static_cast<int>(names_.size()); ++i) {
      ParameterEstimate e;
      e.name = names_[i];
      e.value = it.parameters[i];
      e.initial = first_initial_[i];
      e.std_error = std::numeric_limits<double>::quiet_NaN();
      e.ci95_low = e.ci95_high = std::numeric_limits<double>::quiet_NaN();
      if (truth_.count(e.name)) e.truth = truth_.at(e.name);
      cp.parameters.push_back(e);
    }
    return cp;
  }

  void Write(const io::FitResultFile& cp) {
    try {
      io::WriteResultH5(h5_, cp);
      io::WriteResultYaml(yaml_, cp);
    } catch (const io::ResultError& e) {
      if (failed_.empty()) {
        failed_ = e.what();
        ReportCheckpointNotWritten(ro_.observer, e.what());
      }
    }
  }

  const BuiltProblem& bp_;
  const std::optional<io::FitResultFile>& base_;
  const io::FitResultFile& header_;
  const std::map<std::string, double>& truth_;
  const FitRunOptions& ro_;
  const std::vector<std::string> names_;
  std::string yaml_, h5_;
  std::vector<double> first_initial_;
  io::FitResultFile progress_;  // the checkpoint so far
  std::string failed_;          // the first checkpoint write failure
};

// Fit: takes the built problem and the fit's options (on_problem may change both); gives the
// fit, from several starts when starts.count > 1. A simulation that fails here fails at the start
// (trial points that fail are rejected): its message names the initial values.
FitResult FitProblem(const io::ExperimentConfig& run_cfg, const Starts& starts,
                     const FitRunOptions& ro, BuiltProblem* bp, FitOptions* options) {
  try {
    if (starts.count > 1) {
      // one line per finished start even without progress (as the data's warnings): the starts
      // report to the runner's observer, never the fits inside them
      FitOptions multi = *options;
      multi.observer = ro.observer;
      return FitFromStarts(*bp, multi, starts.count, starts.seed, /*progress=*/true, ro.on_problem);
    }
    if (ro.on_problem) ro.on_problem(*bp->problem, options);
    return bp->problem->Fit(*options);
  } catch (const SimulationError& e) {
    throw SimulationError(
        std::string(e.what()) + "; " +
            AtInitialValues(run_cfg, starts.count > 1 ? nullptr : bp->problem.get()),
        e.sequence(), e.step());
  }
}

// Metrics and validation: takes the fit; gives the fit metrics per channel of every fitted
// sequence, and the held-out sequences simulated at the start and at the estimate (never
// fitted), with theirs.
void AssessFit(const BuiltProblem& bp, int threads, io::FitResultFile* file) {
  for (SequenceResult& sr : file->sequences) sr.channel_fits = ChannelFits(sr);
  for (FitSequence sq : bp.validation) {
    const size_t mi = static_cast<size_t>(
        std::find(bp.model_names.begin(), bp.model_names.end(), sq.model) - bp.model_names.begin());
    const mjModel& vm = *bp.models[mi];
    ApplyFittedControlDelays(vm, bp.control_delays, file->parameters, &sq);  // as fitted
    file->validation.push_back(SimulateHeldOut(vm, bp.parameters, bp.measurements, file->parameters,
                                               sq, threads, &file->warnings));
  }
}

// Status and truth: takes the fit; gives its status (and an interruption's termination), the
// truth where known, the run's warnings first, and out's exit code and printed warnings.
void Conclude(const BuiltProblem& bp, const std::map<std::string, double>& truth,
              io::FitResultFile* file, FitRunOutcome* out) {
  const FitResult& r = *file;
  file->status = FitStatusName(r.outcome);
  if (r.iterations < 0) {
    // the solver stopped before its first iteration (Ceres' summary: -1 iterations, costs -1):
    // no iteration and no cost, as result.yaml says it (iterations: 0, costs .nan)
    file->iterations = 0;
    file->initial_cost = file->final_cost = std::numeric_limits<double>::quiet_NaN();
  }
  if (r.interrupted) {
    file->termination.kind = FitTermination::Kind::kInterrupted;
    file->termination.iteration = r.iterations;
  }
  for (ParameterEstimate& e : file->parameters) {
    if (truth.count(e.name)) e.truth = truth.at(e.name);
  }
  SetDerivedTruth(bp, truth, &file->derived);
  file->warnings.insert(file->warnings.begin(), bp.warnings.begin(), bp.warnings.end());
  out->printed_warnings = static_cast<int>(bp.warnings.size());
  out->exit_code = ExitCodeOf(r.outcome);
}

// Files: takes the results; writes the identified models, result.h5, then result.yaml (which says
// the run is complete) into the staging folder and removes its checkpoint. A model that cannot be
// written adds a warning; a disk that refuses a write throws.
void WriteResultFiles(const io::ExperimentConfig& cfg, const std::string& staging,
                      io::FitResultFile* file) {
  for (size_t i = 0; i < cfg.models.size(); ++i) {
    const std::string fname = cfg.models[i].name + "_identified.xml";
    try {
      const std::vector<std::string> w =
          WriteIdentifiedModel(cfg, cfg.models[i].name, cfg.models[i].path, file->parameters,
                               (fs::path(staging) / fname).string(), file->run_id);
      file->warnings.insert(file->warnings.end(), w.begin(), w.end());
      file->identified_models[cfg.models[i].name] = fname;
    } catch (const io::FileError&) {
      throw;  // the disk refused: not a property of the model
    } catch (const std::exception& e) {
      file->warnings.push_back(std::string("identified model not written: ") + e.what());
    }
  }
  io::WriteResultH5((fs::path(staging) / "result.h5").string(), *file);
  std::error_code ec;
  fs::remove((fs::path(staging) / "checkpoint.yaml").string(), ec);
  fs::remove((fs::path(staging) / "checkpoint.h5").string(), ec);
  io::WriteResultYaml((fs::path(staging) / "result.yaml").string(), *file);
}

}  // namespace

MemoryEstimate EstimateRunMemory(const BuiltProblem& bp, int starts) {
  MemoryEstimateInput in;
  for (const ModelPtr& m : bp.models) {
    MemoryEstimateInput::Model mm;
    mm.nq = static_cast<int>(m->nq);
    mm.nv = static_cast<int>(m->nv);
    mm.na = static_cast<int>(m->na);
    mm.nu = static_cast<int>(m->nu);
    mm.nsensordata = static_cast<int>(m->nsensordata);
    const DataPtr d = MakeData(*m);
    mm.data_bytes = static_cast<long long>(d->nbuffer) + static_cast<long long>(d->narena);
    in.models.push_back(mm);
  }
  for (const FitSequence& s : bp.sequences) {
    MemoryEstimateInput::Sequence ms;
    const auto it = std::find(bp.model_names.begin(), bp.model_names.end(), s.model);
    ms.model = it == bp.model_names.end() ? 0 : static_cast<int>(it - bp.model_names.begin());
    ms.samples = s.measured.rows();
    ms.log_doubles = s.time.size() + s.ctrl.size() + s.ctrl_time.size() + s.measured.size() +
                     s.qpos.size() + s.qvel.size() + s.act.size();
    in.sequences.push_back(ms);
  }
  in.variables = static_cast<int>(bp.parameters.size() + bp.control_delays.size());
  for (const FitMeasurement& me : bp.measurements) {
    for (const FitMeasurement::Term* t : {&me.delay, &me.gain, &me.bias}) {
      in.variables += t->fit ? 1 : 0;
    }
  }
  in.multiple_shooting = bp.options.segment_steps > 0;
  in.segment_samples = std::max(0, bp.options.segment_steps);
  const int threads = ThreadCount(bp.options.threads);
  // multi-start: min(starts, threads) fits at a time, the threads divided (sysid/run/multi_start)
  in.concurrent_fits = starts > 1 ? std::min(starts, threads) : 1;
  in.threads = std::max(1, threads / in.concurrent_fits);
  in.compress_blocks = bp.options.advanced.compress_blocks;
  return EstimateFitMemory(in);
}

long long MemoryLimitBytes(const io::ExperimentConfig& config, double limit_gb,
                           std::string* source) {
  if (limit_gb > 0) {
    *source = "--memory-limit";
    return static_cast<long long>(limit_gb * 1e9);
  }
  if (config.memory_limit_gb > 0) {
    *source = "solver.memory_limit_gb";  // the message starts with the file
    return static_cast<long long>(config.memory_limit_gb * 1e9);
  }
  const long long available = AvailableMemoryBytes();
  char share[64];
  std::snprintf(share, sizeof(share), "%.0f %% of the %s available", 100 * kDefaultMemoryShare,
                FormatGB(available).c_str());
  *source = share;
  return static_cast<long long>(kDefaultMemoryShare * static_cast<double>(available));
}

void CheckRunMemory(const io::ExperimentConfig& config, const MemoryEstimate& estimate,
                    long long limit, const std::string& source) {
  if (limit <= 0 || estimate.bytes <= limit) return;
  throw MemoryLimitError(
      config.source_file + ": the fit needs an estimated " + FormatGB(estimate.bytes) + " (" +
      std::to_string(estimate.samples) + " samples, " + std::to_string(estimate.per_sample_bytes) +
      " bytes per sample, docs/numerics.md \"Memory estimate\"), more than the limit of " +
      FormatGB(limit) + " (" + source +
      "); fit fewer or shorter sequences (`sequences:` windows), fewer starts or threads, or "
      "raise the limit with `sysid fit --memory-limit GB` or solver.memory_limit_gb");
}

FitRunOutcome RunFit(const io::ExperimentConfig& cfg, const FitRunOptions& ro) {
  FitRunOutcome out;
  out.out_dir = ro.out_dir.empty() ? cfg.output : ro.out_dir;
  // a folder this run must not replace is refused before any work (checked again below)
  CheckOutputFolder(out.out_dir, InputsOf(cfg), ro.force);

  // the input: the checkpoint a --resume starts from, the problem, the starts
  const std::optional<io::FitResultFile> base = ResumeBase(out.out_dir, ro.resume);
  // the files this run reads, by content, before they are read
  const std::vector<io::InputHash> inputs = HashInputs(cfg);
  std::vector<std::string> resume_warnings;
  if (base) CheckResumeInputs(out.out_dir, *base, inputs, &resume_warnings);
  const io::ExperimentConfig run_cfg = base ? ResumedConfig(cfg, *base) : cfg;
  BuiltProblem bp = BuildProblem(run_cfg, ro.threads);
  const Starts starts = ResolveStarts(cfg, ro, out.out_dir, base.has_value());
  // the memory the fit will hold, against the limit, before anything is simulated or written
  std::string memory_source;
  const long long memory_limit = MemoryLimitBytes(cfg, ro.memory_limit_gb, &memory_source);
  const MemoryEstimate memory = EstimateRunMemory(bp, starts.count);
  if (ro.on_memory_estimate) ro.on_memory_estimate(memory, memory_limit);
  CheckRunMemory(cfg, memory, memory_limit, memory_source);

  // the output folder; one fit at a time into it; everything written into the staging folder
  // DIR.partial, which replaces DIR only once complete
  PrepareOutputFolder(cfg, ro, out.out_dir);
  const FolderLock lock(out.out_dir, "sysid fit of " + cfg.source_file);
  if (base) CheckCheckpointUnchanged(out.out_dir, *base);
  const std::string staging =
      CreateStagingFolder(out.out_dir, /*keep_checkpoint=*/base.has_value());

  // the fit's options, the run's header, a checkpoint after every good iteration
  FitOptions options = bp.options;
  options.verbose = ro.verbose && options.verbose;
  options.observer = options.verbose ? ro.observer : nullptr;
  options.interrupt = ro.interrupt;
  io::FitResultFile& file = out.file;
  SetRunHeader(cfg, options, starts, &file);
  file.input_hashes = inputs;
  const std::map<std::string, double> truth = TruthOf(cfg);
  CheckpointWriter checkpoints(cfg, run_cfg, bp, base, file, truth, staging, ro);
  options.on_iteration = [&checkpoints](const IterationInfo& it) { checkpoints.OnIteration(it); };

  // the fit, continued from the checkpoint when resumed
  ReportDataWarnings(ro.observer, bp.warnings);
  static_cast<FitResult&>(file) = FitProblem(run_cfg, starts, ro, &bp, &options);
  // a model_mismatch that the logged first rows' noise may explain: tested by fitting them (not
  // for a resumed, multi-start or sharded fit), in the memory the fit left under the limit
  if (!base && starts.count == 1 && !ro.on_problem) {
    CheckLoggedInitialStates(run_cfg, bp, options, memory_limit - memory.bytes, &file);
  }
  if (base) {
    AppendToCheckpoint(*base, &file);
    file.warnings.push_back("resumed from the checkpoint of run " + base->run_id +
                            " after iteration " + std::to_string(base->iterations));
    file.warnings.insert(file.warnings.end(), resume_warnings.begin(), resume_warnings.end());
  }

  // the assessment and verdict; the estimates are shown before any file is written (a full disk
  // loses no result); then the files, and the staging folder replaces DIR
  AssessFit(bp, options.threads, &file);
  Conclude(bp, truth, &file, &out);
  if (ro.on_estimates) ro.on_estimates(file);
  WriteResultFiles(cfg, staging, &file);
  PublishFolder(staging, out.out_dir);
  return out;
}

}  // namespace mjsysid::run
