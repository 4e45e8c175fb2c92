// `sysid fit` and the Jacobian part of `sysid check`: an experiment file and its logs turned into a
// Problem, fitted, and written to DIR (result.yaml, result.h5, <model>_identified.xml).
//
// Contract:
// - BuildProblem reads the models and every `data:` log, validates them against each other and the
//   config (io::ConfigError / io::LogError / ModelLoadError / ParameterError on bad input), and
//   maps them onto a Problem: one FitSequence per selected log sequence, fitted with the model
//   io::AssignSequences gives it (sysid/io/sequence_models.h: an explicit record, never a name);
//   with sensor_time: post, row k+1 of a log is taken as y_k (the first control row is kept, the
//   last dropped). The log's samples may come at any times (any rate, jitter, gaps; checked by
//   io::ValidateLogAgainstModel, whose warnings join BuiltProblem::warnings): the fit simulates
//   on the model's timestep from the first sample and reads each sample at its own time. A
//   `sequences:` entry with start/end fits that window only, from the logged state at its first
//   sample (estimated when the log has none).
// - RunFit refuses an output folder that holds an input or (without force) is foreign, and one that
//   another fit is writing (OutputError, sysid/run/output_folder.h). It writes everything into the
//   staging folder DIR.partial: checkpoint.yaml (status "running", the current values) after every
//   successful iteration, then the identified models, result.h5 and result.yaml (last), all with
//   one run id; only then does the staging folder replace DIR (one atomic rename). An
//   interruption (FitRunOptions::interrupt) writes the complete results of the last good iterate
//   the same way. A failed write (io::FileError / io::ResultError naming the file and the reason)
//   leaves DIR as it was. It never throws for a fit that merely fails to converge: see
//   FitRunOutcome. Every fitted sequence gets its per-channel metrics (sysid/assess/metrics.h); the
//   `validation:` sequences are simulated at the start and at the estimate
//   (sysid/run/validation.h) into FitResult::validation. With solver.starts (or
//   FitRunOptions::starts) > 1 the fit is sysid/run/multi_start.h's, without checkpoints.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/fit/memory_estimate.h"
#include "sysid/fit_observer.h"
#include "sysid/io/experiment.h"
#include "sysid/io/result.h"
#include "sysid/problem.h"

namespace mjsysid::run {

struct BuiltProblem {
  std::unique_ptr<Problem> problem;
  FitOptions options;
  std::vector<std::string> model_names;
  std::vector<ModelPtr> models;  // as loaded (before any fit)
  std::vector<std::string> warnings;
  // what was added to the problem, for programs that build their own fit of the same data
  // (tools/bench): parameters, measurement terms and sequences, in the order added
  std::vector<FitParameter> parameters;
  std::vector<FitMeasurement> measurements;
  std::vector<FitSequence> sequences;
  // the `validation:` sequences, read and checked like the fitted ones but not added to the
  // problem (RunFit simulates them at the start and at the estimate: sysid/run/validation.h)
  std::vector<FitSequence> validation;
  // a window (`sequences: [{name, start, end}]`) without a logged state at its start: the
  // initial states are estimated (options.estimate_initial_state)
  bool estimate_initial_state = false;
  // the fitted control delays added to the problem (experiment `controls.delay`), in order
  std::vector<FitControlDelay> control_delays;
};

// threads < 0: the config's solver.threads
BuiltProblem BuildProblem(const io::ExperimentConfig& config, int threads = -1);

// a fit whose memory estimate exceeds the limit (EstimateRunMemory, CheckRunMemory): refused
// before anything is simulated or written (bad input for `sysid fit`: exit 2)
class MemoryLimitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// the memory estimate (sysid/fit/memory_estimate.h) of fitting bp from `starts` starts
MemoryEstimate EstimateRunMemory(const BuiltProblem& bp, int starts);

// The limit a fit is held to, bytes: limit_gb * 1e9 when > 0 (--memory-limit), else the
// experiment's solver.memory_limit_gb when given, else kDefaultMemoryShare of
// AvailableMemoryBytes() (none when that cannot be read: 0). *source: where it came from, for the
// message (which names the experiment file already).
long long MemoryLimitBytes(const io::ExperimentConfig& config, double limit_gb,
                           std::string* source);

// Throws MemoryLimitError when the estimate exceeds the limit (0: no limit), naming both and how
// to reduce the fit or raise the limit.
void CheckRunMemory(const io::ExperimentConfig& config, const MemoryEstimate& estimate,
                    long long limit, const std::string& source);

struct FitRunOptions {
  std::string out_dir;  // "" = config.output
  int threads = -1;     // < 0: the config's solver.threads
  // the fit's memory limit in GB (`sysid fit --memory-limit`); <= 0: the experiment's
  // solver.memory_limit_gb, else the default (MemoryLimitBytes)
  double memory_limit_gb = 0;
  // called with the memory estimate and the limit once the problem is built, before the check
  // (the CLI names them if the fit still runs out of memory)
  std::function<void(const MemoryEstimate&, long long limit)> on_memory_estimate;
  // the fit's events (sysid/fit_observer.h; borrowed, nullptr: none): the data's warnings before
  // the fit and a checkpoint that cannot be written always, the fit's progress when verbose and
  // the experiment's solver.verbose are both set
  FitObserver* observer = nullptr;
  bool verbose = true;
  const std::atomic<bool>* interrupt = nullptr;  // set (e.g. by SIGINT) to stop after an iteration
  bool force = false;   // replace an existing output folder that is not an mjsysid result
  bool resume = false;  // continue from the folder's checkpoint (sysid/run/resume.h)
  // called with the results before any file is written (the CLI prints the estimates)
  std::function<void(const io::FitResultFile&)> on_estimates;
  // called after every successful iteration, once its checkpoint is written (e.g. the Python
  // module's iteration callback); iteration numbers as in Problem::Fit (not the resumed count)
  std::function<void(const IterationInfo&)> on_iteration;
  // multi-start (sysid/run/multi_start.h): < 1 / < 0: the config's solver.starts / solver.seed
  int starts = 0;
  long long seed = -1;
  // called with the built problem and its options just before a single-start fit (sysid/mpi/:
  // the residuals sharded across MPI ranks, the options it supports)
  std::function<void(Problem&, FitOptions*)> on_problem;
};

struct FitRunOutcome {
  io::FitResultFile file;  // the fit (a FitResult) and what the run adds
  std::string out_dir;
  int exit_code = 0;  // ExitCodeOf(file.outcome)
  // the first file.warnings that RunFit already reported (FitObserver::OnWarning) before the fit
  // (the data's warnings, shown early); a front end shows the rest
  int printed_warnings = 0;
};

// the exit code of `sysid fit` for a fit's status (docs/cli.md): 0 converged; 1 not converged,
// local_minimum or interrupted; 3 model_mismatch; 4 jacobian_unreliable, did_not_move or
// solver_failed (2 is bad input)
int ExitCodeOf(FitStatus status);

FitRunOutcome RunFit(const io::ExperimentConfig& config, const FitRunOptions& options);

// the files a fit reads: the experiment, its models and its data logs
std::vector<std::string> InputsOf(const io::ExperimentConfig& config);

// "at the initial values NAME = VALUE, ... (EXP.yaml)", for a simulation that fails at the start:
// the values of problem->parameters() (the solved `initial: auto` starts, once solved) when given,
// else the config's; an `initial: auto` start not solved yet reads "NAME = auto"
std::string AtInitialValues(const io::ExperimentConfig& config, const Problem* problem = nullptr);

// the names of the fitted values in FitResult order: the parameters, then the measurement terms
// (SENSOR.delay, SENSOR.gain, SENSOR.bias)
std::vector<std::string> FittedNames(const io::ExperimentConfig& config);

// Writes the model of model_path with the fitted values of the parameters that apply to it into
// out_path (atomically) as MJCF, and checks that the written file compiles to those values. A
// non-empty run_id is written as io::RunIdComment before the root element.
// Returns warnings (e.g. "field" arrays without an MJCF home, core/field_mjcf.h).
std::vector<std::string> WriteIdentifiedModel(const io::ExperimentConfig& config,
                                              const std::string& model_name,
                                              const std::string& model_path,
                                              const std::vector<ParameterEstimate>& estimates,
                                              const std::string& out_path,
                                              const std::string& run_id = "");

}  // namespace mjsysid::run
