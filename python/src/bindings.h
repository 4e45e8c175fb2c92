// Shared by the two files of the extension module mjsysid._mjsysid (python/CMakeLists.txt).
//
// A fit called from Python runs with the GIL released. FitGuard wraps the FitOptions (or the
// runner's options) of one such fit:
// - Ctrl-C: when the fit runs on Python's main thread, SIGINT is caught for its duration by a C
//   handler that sets the fit's interrupt flag (the same mechanism as `sysid fit`): the fit stops
//   after the current iteration and returns its result with status "interrupted"; Python's own
//   handler is restored afterwards (no KeyboardInterrupt is raised for that signal).
// - callback: a Python callable called with the IterationInfo after every successful iteration
//   (the GIL taken for the call). An exception it raises stops the fit after that iteration and
//   is raised again by the fit once it has returned.
#pragma once

#include <nanobind/nanobind.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "core/mujoco_env.h"
#include "core/thread_pool.h"
#include "sysid/io/experiment.h"
#include "sysid/io/result.h"
#include "sysid/types.h"

namespace mjsysid::python {

namespace nb = nanobind;

// one line of the progress table (sysid/run/fit_table.h) on the process's stderr, as `sysid fit`
inline void WriteStderrLine(const std::string& line) {
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

class FitGuard {
 public:
  // callback: None or a callable taking an IterationInfo. Call with the GIL held.
  explicit FitGuard(nb::object callback);
  // restores the SIGINT handler; call with the GIL held
  ~FitGuard();
  FitGuard(const FitGuard&) = delete;
  FitGuard& operator=(const FitGuard&) = delete;

  // the interrupt flag to give the fit
  const std::atomic<bool>* interrupt() const { return flag_; }
  // chains the Python callback after `previous` (may be empty)
  std::function<void(const IterationInfo&)> OnIteration(
      std::function<void(const IterationInfo&)> previous);
  // raises the callback's exception, if any; call with the GIL held after the fit
  void RaiseCallbackError();

 private:
  nb::object callback_;
  std::atomic<bool> own_flag_{false};  // off the main thread: set only by a failing callback
  std::atomic<bool>* flag_;
  bool sigint_installed_ = false;
  struct sigaction previous_ {};
  std::optional<nb::python_error> error_;
};

// registers the translation of mjsysid's exceptions into Python's: bad input (ConfigError,
// LogError, ModelLoadError, ParameterError, OutputError, MemoryLimitError, ResultError,
// std::invalid_argument) ->
// ValueError with the message `sysid` prints; SimulationError and MujocoError -> RuntimeError
void RegisterExceptions();

// a thread count passed from Python (`what`: the argument's name): 0 (all cores) or
// 1..kMaxThreads (core/thread_pool.h, the rule of the command line and the experiment file);
// else std::invalid_argument (ValueError); allow_default: -1 is accepted too (the experiment's)
inline int CheckedThreads(int threads, const std::string& what, bool allow_default = false) {
  if (allow_default && threads == -1) return threads;
  const std::string error = ThreadRequestError(threads);
  if (!error.empty()) throw std::invalid_argument(what + ": " + error);
  return threads;
}

// fit(model, parameters, sequences, options, callback): the library API on numpy arrays
void BindFitApi(nb::module_& m);
// mjsysid.design (design_api.cc)
void BindDesignApi(nb::module_& m);

// model: a path to an MJCF/MJB file, MJCF text (anything starting with '<'), a mujoco.MjModel or a
// mujoco.MjSpec (through its MJB bytes; fit_api.cc); `what` names the argument in errors
ModelPtr ModelOf(nb::handle model, const std::string& what);

// mjsysid.RolloutModel and Linearization: differentiable rollouts (rollout_api.cc)
void BindRolloutApi(nb::module_& m);

// an experiment given as a path (str, os.PathLike) or as a loaded ExperimentConfig (module.cc)
io::ExperimentConfig ConfigOf(nb::handle experiment);

// `sysid fit` as a function (fit_experiment): the outcome of run::RunFit, flattened
struct ExperimentFit : io::FitResultFile {
  std::string out_dir;
  int exit_code = 0;
};

// to_dict() of FitResult, ResultFile and ExperimentFit (result.yaml's keys) and to_pandas() of
// them and of SequenceResult (result_dict.cc)
void BindResultTables(nb::class_<FitResult>& fit_result,
                      nb::class_<io::FitResultFile, FitResult>& result_file,
                      nb::class_<ExperimentFit, io::FitResultFile>& experiment_fit,
                      nb::class_<SequenceResult>& sequence);

}  // namespace mjsysid::python
