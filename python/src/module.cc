// mjsysid._mjsysid: the Python module (nanobind). What the command line offers, as functions
// (load_experiment, simulate, check, fit_experiment, report, read_log, write_log, read_result),
// the plain data of a fit (sysid/types.h) and of a log (sysid/io/log.h) as Python classes with
// numpy arrays, and the library API (fit_api.cc). Every function calls the C++ layers
// (sysid/run, sysid/sim, sysid/io, tools/report); nothing is computed here.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bindings.h"
#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/text.h"
#include "mjsysid/version.h"
#include "pickle.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/fit_table.h"
#include "sysid/run/log_output.h"
#include "sysid/run/output_folder.h"
#include "sysid/sim/simulate.h"
#include "sysid/solve/quiet_libraries.h"
#include "tools/report/report.h"

namespace mjsysid::python {

// pickling (pickle.h): ExperimentFit's fields after its ResultFile's
void Fields(Archive& a, ExperimentFit& f) {
  a(static_cast<io::FitResultFile&>(f), f.out_dir, f.exit_code);
}

namespace {

namespace fs = std::filesystem;
using nb::arg;

// the flag SIGINT sets during a fit on the main thread (one such fit at a time: the GIL is held
// while a fit starts, and a second main-thread fit cannot start before the first returns)
std::atomic<bool> g_sigint{false};
extern "C" void OnSigint(int) { g_sigint.store(true); }

bool OnMainThread() {
  nb::module_ threading = nb::module_::import_("threading");
  return threading.attr("current_thread")().is(threading.attr("main_thread")());
}

// __getstate__ / __setstate__ of a result class T (pickle.h): the state is bytes
template <typename T>
nb::bytes StateOf(const T& result) {
  const std::string bytes = Pickled(result);
  return nb::bytes(bytes.data(), bytes.size());
}
template <typename T>
void SetState(T& result, const nb::bytes& state) {
  T read;  // read first: a bad state leaves nothing half made
  Unpickle(std::string(state.c_str(), state.size()), &read);
  new (&result) T(std::move(read));
}

// simulate: the experiment's `simulate` block; written to `out`, else to the first `data:` path
// (as `sysid simulate`), unless write is false
io::Log Simulate(nb::handle experiment, std::optional<std::string> out,
                 std::optional<unsigned long long> seed, std::optional<int> threads, bool write,
                 bool force) {
  io::ExperimentConfig config = ConfigOf(experiment);
  io::CheckModelFilesExist(config);
  if (seed) config.simulate.seed = *seed;
  std::string path = out.value_or("");
  if (write && path.empty()) {
    if (config.data.empty()) {
      throw std::invalid_argument(config.source_file +
                                  ": no output file: give out= or a `data:` path in the "
                                  "experiment (or write=False)");
    }
    path = config.data.front().path;
  }
  std::vector<std::string> inputs = {config.source_file};
  for (const io::ModelSpec& spec : config.models) inputs.push_back(spec.path);
  // the CLI's rule: an existing log is replaced only when simulate wrote it for this experiment
  run::LogWriter writer{"simulate", config.source_file, "out=" + path, "out",
                        "force=True replaces it, or out= writes elsewhere"};
  if (write) run::CheckLogOutput(path, inputs, force, writer);
  sim::SimulateSettings settings;
  settings.threads = threads ? CheckedThreads(*threads, "threads") : config.options.threads;
  io::Log log;
  {
    nb::gil_scoped_release release;
    log = sim::SimulateExperiment(config, settings);
    if (write) {
      run::PrepareLogOutput(path, inputs, force, writer);  // checked again, as the CLI does
      io::WriteLog(path, log);
    }
  }
  return log;
}

// check: the experiment, its models and data (BuildProblem), then the Jacobians of every residual
// block against ceres::GradientChecker (as `sysid check`); a dict
nb::dict Check(nb::handle experiment, bool jacobians) {
  const io::ExperimentConfig config = ConfigOf(experiment);
  io::CheckModelFilesExist(config);
  nb::dict out;
  out["name"] = config.name;
  out["data"] = !config.data.empty();
  if (config.data.empty()) return out;
  run::BuiltProblem built = run::BuildProblem(config);
  out["warnings"] = built.warnings;
  if (!jacobians) return out;
  JacobianCheck check;
  {
    nb::gil_scoped_release release;
    check = built.problem->CheckJacobians(built.options);
  }
  out["worst_relative_error"] = check.worst_relative_error;
  out["worst_where"] = check.worst_where;
  nb::dict per;
  for (const auto& [name, err] : check.per_variable) per[nb::str(name.c_str())] = err;
  out["per_variable"] = per;
  return out;
}

// fit_experiment: `sysid fit` (writes DIR/result.yaml, result.h5, identified models)
ExperimentFit FitExperiment(nb::handle experiment, std::optional<std::string> out, int threads,
                            bool verbose, bool force, bool resume, nb::object callback) {
  const io::ExperimentConfig config = ConfigOf(experiment);
  run::FitRunOptions options;
  options.out_dir = out.value_or("");
  options.threads = CheckedThreads(threads, "threads", /*allow_default=*/true);
  options.verbose = verbose;
  options.force = force;
  options.resume = resume;
  FitGuard guard(std::move(callback));
  options.interrupt = guard.interrupt();
  options.on_iteration = guard.OnIteration(nullptr);
  // the data's warnings and, verbose, the progress table on stderr (sysid/run/fit_table.h)
  run::FitTable table(WriteStderrLine, false);
  options.observer = &table;
  run::FitRunOutcome outcome;
  {
    nb::gil_scoped_release release;
    outcome = run::RunFit(config, options);
  }
  table.Flush();
  guard.RaiseCallbackError();
  ExperimentFit fit;
  static_cast<io::FitResultFile&>(fit) = std::move(outcome.file);
  fit.out_dir = outcome.out_dir;
  fit.exit_code = outcome.exit_code;
  return fit;
}

// report: `sysid report DIR`; returns the summary it prints
std::string Report(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw std::invalid_argument(dir +
                                ": no such folder (a fit writes result.yaml and result.h5 into "
                                "its output folder)");
  }
  std::string summary;
  nb::gil_scoped_release release;
  report::WriteReport(dir, &summary);
  return summary;
}

// a log checked against a model before it is written (as `sysid import`)
void WriteLogChecked(const std::string& path, const io::Log& log,
                     std::optional<std::string> model) {
  if (model) {
    ModelPtr m = LoadModel(*model);
    io::ValidateLogAgainstModel(log, *m, path);
  }
  nb::gil_scoped_release release;
  io::WriteLog(path, log);
}

// estimate name -> value
nb::dict Estimates(const FitResult& r) {
  nb::dict d;
  for (const ParameterEstimate& p : r.parameters) d[nb::str(p.name.c_str())] = p.value;
  return d;
}

}  // namespace

io::ExperimentConfig ConfigOf(nb::handle experiment) {
  if (nb::isinstance<io::ExperimentConfig>(experiment)) {
    return nb::cast<io::ExperimentConfig>(experiment);
  }
  if (nb::isinstance<nb::str>(experiment) || nb::hasattr(experiment, "__fspath__")) {
    return io::LoadExperiment(nb::cast<std::string>(nb::str(experiment)));
  }
  throw nb::type_error("experiment: expected a path (str, os.PathLike) or an Experiment");
}

// --- FitGuard (bindings.h) ---

FitGuard::FitGuard(nb::object callback) : callback_(std::move(callback)), flag_(&own_flag_) {
  if (callback_.is_none()) callback_ = nb::object();
  if (callback_.is_valid() && !PyCallable_Check(callback_.ptr())) {
    throw nb::type_error("callback: expected a callable taking an IterationInfo, or None");
  }
  if (OnMainThread()) {
    g_sigint.store(false);
    struct sigaction action {};
    action.sa_handler = OnSigint;
    sigemptyset(&action.sa_mask);
    if (sigaction(SIGINT, &action, &previous_) == 0) {
      sigint_installed_ = true;
      flag_ = &g_sigint;
    }
  }
}

FitGuard::~FitGuard() {
  if (sigint_installed_) sigaction(SIGINT, &previous_, nullptr);
}

std::function<void(const IterationInfo&)> FitGuard::OnIteration(
    std::function<void(const IterationInfo&)> previous) {
  return [this, previous](const IterationInfo& it) {
    if (previous) previous(it);
    if (!callback_.is_valid() || error_) return;
    nb::gil_scoped_acquire gil;
    try {
      callback_(it);
    } catch (nb::python_error& e) {
      error_.emplace(std::move(e));
      flag_->store(true);
    }
  };
}

void FitGuard::RaiseCallbackError() {
  if (error_) {
    nb::python_error e = std::move(*error_);
    error_.reset();
    throw e;
  }
}

void RegisterExceptions() {
  nb::register_exception_translator([](const std::exception_ptr& p, void*) {
    try {
      std::rethrow_exception(p);
    } catch (const io::ConfigError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const io::LogError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const io::ResultError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const ModelLoadError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const ParameterError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const run::OutputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const run::MemoryLimitError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const SimulationError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
}

}  // namespace mjsysid::python

NB_MODULE(_mjsysid, m) {
  namespace nb = nanobind;
  namespace io = mjsysid::io;
  using namespace mjsysid;
  using namespace mjsysid::python;
  using nb::arg;
  InstallMujocoHandlers();
  // as in the CLI: no third-party line on the terminal (glog FATAL only unless the process
  // initialized glog itself; SuiteSparse's printf into the fit's warnings)
  QuietThirdPartyLibraries("mjsysid");
  RegisterExceptions();
  // objects held by Python's own state at exit (e.g. a Linearization an autograd graph keeps) are
  // freed by the OS; nanobind's leak report would only alarm the user
  nb::set_leak_warnings(false);
  m.doc() = "mjsysid: system identification for MuJoCo models (C++ library bindings)";
  m.attr("__version__") = MJSYSID_VERSION;
  m.def("mujoco_version", &MujocoVersion, "X.Y.Z of the libmujoco loaded in this process");

  // --- results of a fit (sysid/types.h) ---
  nb::class_<ResidualDiagnostics>(
      m, "ResidualDiagnostics",
      "One fitted channel's residuals at the estimate, pooled over the fitted sequences "
      "(result.yaml `residuals`, docs/real-logs.md \"Residual diagnostics\")")
      .def_ro("channel", &ResidualDiagnostics::channel, "sensor, or sensor[i] for a wider one")
      .def_ro("samples", &ResidualDiagnostics::samples, "measured rows")
      .def_ro("mean", &ResidualDiagnostics::mean, "bias, the channel's units")
      .def_ro("rms", &ResidualDiagnostics::rms,
              "RMS of the residuals (simulated - measured), the channel's units")
      .def_ro("sigma", &ResidualDiagnostics::sigma, "the stated or estimated sigma (NaN: none)")
      .def_ro("sigma_from_log", &ResidualDiagnostics::sigma_from_log,
              "sigma estimated from the log (sensor_sigmas 'auto')")
      .def_ro("rms_over_sigma", &ResidualDiagnostics::ratio, "rms / sigma (NaN without a sigma)")
      .def_ro("bias_std_errors", &ResidualDiagnostics::bias_units,
              "|mean| in standard errors of a mean of these (correlated) residuals")
      .def_ro("lag1", &ResidualDiagnostics::lag1, "autocorrelation at one sample")
      .def_ro("correlation_samples", &ResidualDiagnostics::tau,
              "integrated correlation time in samples (1: white)")
      .def_ro("portmanteau_p", &ResidualDiagnostics::portmanteau_p, "Ljung-Box p-value")
      .def_ro("white", &ResidualDiagnostics::white,
              "the residuals pass the whiteness test (portmanteau)")
      .def("__repr__", [](const ResidualDiagnostics& d) {
        return "ResidualDiagnostics(" + d.channel + ", rms " + std::to_string(d.rms) +
               ", correlation_samples " + std::to_string(d.tau) +
               (d.white ? ", white)" : ", not white)");
      });

  nb::class_<ParameterEstimate>(m, "ParameterEstimate",
                                "One estimated variable: a physical parameter or a measurement "
                                "term (SENSOR.delay, SENSOR.gain, SENSOR.bias)")
      .def_ro("name", &ParameterEstimate::name,
              "the parameter's name as given (or SENSOR.delay, controls.delay, ...)")
      .def_ro("value", &ParameterEstimate::value, "the estimate (physical units)")
      .def_ro("initial", &ParameterEstimate::initial,
              "where the fit started (initial 'auto': the solved equation-error start)")
      .def_ro("std_error", &ParameterEstimate::std_error, "+inf unidentifiable, 0 on a bound")
      .def_prop_ro(
          "ci95",
          [](const ParameterEstimate& p) { return std::make_pair(p.ci95_low, p.ci95_high); },
          "(low, high): the 95 % interval (valid when the result's intervals_valid)")
      .def_ro("at_lower", &ParameterEstimate::at_lower,
              "stopped on its lower bound (then fixed there: std_error 0)")
      .def_ro("at_upper", &ParameterEstimate::at_upper,
              "stopped on its upper bound (then fixed there: std_error 0)")
      .def_ro("identifiable", &ParameterEstimate::identifiable,
              "False: the data do not determine it (std_error +inf)")
      .def_ro("timestep_bias", &ParameterEstimate::timestep_bias,
              "the model timestep's bias of the value (the timestep check), None: not run")
      .def_ro("truth", &ParameterEstimate::truth, "the true value (simulated data), else None")
      .def("__repr__", [](const ParameterEstimate& p) {
        return "ParameterEstimate(" + p.name + " = " + FormatDigits(p.value, 6) + " +- " +
               FormatDigits(p.std_error, 2) + ", initial " + FormatDigits(p.initial, 6) +
               (p.truth ? ", truth " + FormatDigits(*p.truth, 6) : std::string()) +
               (p.at_lower ? ", at its lower bound" : "") +
               (p.at_upper ? ", at its upper bound" : "") +
               (p.identifiable ? "" : ", unidentifiable") + ")";
      });

  nb::class_<IterationInfo>(m, "IterationInfo", "One iteration of the solver")
      .def_ro("iteration", &IterationInfo::iteration, "0: the start, then one per iteration")
      .def_ro("cost", &IterationInfo::cost, "0.5 |r|^2")
      .def_ro("step_norm", &IterationInfo::step_norm,
              "size of the step in the optimiser's variables")
      .def_ro("gradient_norm", &IterationInfo::gradient_norm,
              "max norm of the gradient in the optimiser's variables")
      .def_ro("seconds", &IterationInfo::seconds, "since the fit started")
      .def_ro("successful", &IterationInfo::successful, "the step was accepted")
      .def_ro("parameters", &IterationInfo::parameters,
              "physical values after the iteration (FitResult.parameters order)");

  nb::class_<ChannelFit>(m, "ChannelFit",
                         "How well one channel (a sensor column) is reproduced, as MATLAB's "
                         "`compare`: NRMSE = RMS(simulated - measured) / std(measured), % fit = "
                         "100 (1 - NRMSE); NaN for a constant measured column "
                         "(sysid/assess/metrics.h)")
      .def_ro("channel", &ChannelFit::channel, "sensor, or sensor[i] for a wider one")
      .def_ro("fit_initial", &ChannelFit::fit_initial, "% fit at the initial parameters")
      .def_ro("fit_final", &ChannelFit::fit_final,
              "% fit at the estimate (a fit in segments: simulated in one piece)")
      .def_ro("nrmse_initial", &ChannelFit::nrmse_initial,
              "RMS(simulated - measured) / std(measured) at the initial parameters")
      .def_ro("nrmse_final", &ChannelFit::nrmse_final,
              "the same at the estimate (a fit in segments: simulated in one piece)")
      .def_ro("fit_segments", &ChannelFit::fit_segments,
              "a fit in segments: % fit segment by segment; NaN for a fit in one piece")
      .def_ro("nrmse_segments", &ChannelFit::nrmse_segments,
              "a fit in segments: segment by segment; NaN for a fit in one piece")
      .def("__repr__", [](const ChannelFit& f) {
        return "ChannelFit(" + f.channel + ", fit " + FormatDigits(f.fit_initial, 4) + " % -> " +
               FormatDigits(f.fit_final, 4) + " %" +
               (std::isnan(f.fit_segments)
                    ? std::string()
                    : ", segments " + FormatDigits(f.fit_segments, 4) + " %") +
               ")";
      });

  nb::class_<SequenceResult> sequence_result(
      m, "SequenceResult", "Fitted sensor columns of one sequence (T rows, model order)");
  sequence_result.def_ro("name", &SequenceResult::name, "the sequence's name")
      .def_ro("model", &SequenceResult::model, "the model it was fitted with")
      .def_ro("sensor_names", &SequenceResult::sensor_names, "the fitted sensors, in model order")
      .def_ro("sensor_dims", &SequenceResult::sensor_dims,
              "their dimensions: the columns of measured, in order")
      .def_ro("time", &SequenceResult::time, "T sample times (s)")
      .def_ro("measured", &SequenceResult::measured,
              "T x columns of the fitted sensors (NaN: not measured)")
      .def_ro("simulated_initial", &SequenceResult::simulated_initial,
              "T x columns, at the initial parameters")
      .def_ro("simulated_final", &SequenceResult::simulated_final,
              "at the estimate; segment by segment for a fit in segments")
      .def_ro("simulated_one_piece", &SequenceResult::simulated_one_piece,
              "a fit in segments: the estimate simulated in one piece from the first state "
              "(empty for a fit in one piece)")
      .def_ro("x0_final", &SequenceResult::x0_final,
              "the estimated initial physics state (or the given one); may be empty")
      .def_ro("state_names", &SequenceResult::state_names,
              "fitted states: qpos:<joint>, qvel:<joint>, act:<actuator>")
      .def_ro(
          "state_dims", &SequenceResult::state_dims,
          "their widths in physics coordinates (a free joint's qpos 7, a ball joint's 4, else 1)")
      .def_ro("state_measured", &SequenceResult::state_measured,
              "T x sum(state_dims) logged states (NaN: not measured)")
      .def_ro("state_simulated_initial", &SequenceResult::state_simulated_initial,
              "T x sum(state_dims) at the initial parameters")
      .def_ro("state_simulated_final", &SequenceResult::state_simulated_final,
              "T x sum(state_dims) at the estimate")
      .def_ro("channel_fits", &SequenceResult::channel_fits,
              "per column of measured: % fit and NRMSE, initial and final (a list of "
              "ChannelFit)")
      .def("__repr__", [](const SequenceResult& r) {
        std::string fits;
        for (const ChannelFit& f : r.channel_fits) {
          fits += (fits.empty() ? "" : ", ") + f.channel + " " + FormatDigits(f.fit_final, 4);
        }
        return "SequenceResult(" + r.name + ", model " + r.model + ", " +
               std::to_string(r.measured.rows()) + " samples, " +
               std::to_string(r.measured.cols()) + " channels" +
               (fits.empty() ? std::string() : "; % fit " + fits) + ")";
      });

  nb::class_<LedgerRow>(m, "LedgerRow",
                        "One phase of a fit's ledger (sysid/solve/fit_ledger.h): entries, "
                        "simulator steps and seconds")
      .def_ro("phase", &LedgerRow::phase,
              "the phase's name (sysid/solve/fit_ledger.h FitPhaseName), e.g. \"solve: Jacobians\"")
      .def_ro("entries", &LedgerRow::entries, "how often the fit entered the phase")
      .def_ro("steps", &LedgerRow::steps, "simulator steps in the phase")
      .def_ro("seconds", &LedgerRow::seconds, "wall time in the phase")
      .def_ro("critical_steps", &LedgerRow::critical_steps,
              "of steps, those on the critical path at 2 workers")
      .def_ro("batch_seconds", &LedgerRow::batch_seconds,
              "of seconds, those inside the simulators' batches")
      .def_ro("batches", &LedgerRow::batches, "the simulators' parallel batches in the phase")
      .def_ro("wake_seconds", &LedgerRow::wake_seconds,
              "of batch_seconds, from each batch's publication to its last worker's start")
      .def_ro("wait_seconds", &LedgerRow::wait_seconds,
              "of batch_seconds, the fit thread's wait for the workers after its own last task")
      .def_ro("batch_cpu_seconds", &LedgerRow::batch_cpu_seconds,
              "the fit thread's CPU time inside the batches");

  nb::class_<StartResult>(m, "StartResult",
                          "One fit of a multi-start run (options starts, solver.starts; "
                          "sysid/run/multi_start.h): where it started, where it ended")
      .def_ro("start", &StartResult::start, "physical start values (FitResult.parameters order)")
      .def_ro("estimate", &StartResult::estimate, "the fit's values; empty when the fit failed")
      .def_ro("initial_cost", &StartResult::initial_cost, "+inf when the fit failed")
      .def_ro("final_cost", &StartResult::final_cost, "+inf when the fit failed")
      .def_prop_ro(
          "status", [](const StartResult& r) { return FitStatusName(r.status); },
          "the fit's own status; local_minimum: it ended in another minimum than the best")
      .def_ro("iterations", &StartResult::iterations, "the fit's iterations")
      .def_ro("error", &StartResult::error, "why the fit failed; \"\" otherwise");

  nb::class_<ParameterSpread>(m, "ParameterSpread",
                              "The spread of one estimated value over the starts of a multi-start "
                              "run that did not fail")
      .def_ro("name", &ParameterSpread::name, "the estimated value's name")
      .def_ro("min", &ParameterSpread::min, "the lowest estimate")
      .def_ro("max", &ParameterSpread::max, "the highest estimate")
      .def_ro("relative", &ParameterSpread::relative,
              "(max - min) / |best estimate| (inf when the best is 0 and max > min)");

  nb::class_<DerivedQuantity>(
      m, "DerivedQuantity",
      "A quantity computed from estimated variables, not itself estimated "
      "(a body's mass, centre of mass, principal moments from body_inertial; "
      "sysid/assess/derived_inertials.h), with a first-order standard "
      "error and 95 % interval")
      .def_ro("name", &DerivedQuantity::name, "e.g. payload.mass, payload.com[0]")
      .def_ro("unit", &DerivedQuantity::unit, "kg, m, kg m^2")
      .def_ro("value", &DerivedQuantity::value, "at the estimate")
      .def_ro("std_error", &DerivedQuantity::std_error,
              "NaN without intervals, +inf when an estimate it depends on is unidentifiable")
      .def_prop_ro(
          "ci95", [](const DerivedQuantity& d) { return std::make_pair(d.ci95_low, d.ci95_high); },
          "(low, high): the 95 % interval")
      .def_ro("derived_from", &DerivedQuantity::derived_from,
              "how: the estimated variables and the method, one line")
      .def_ro("truth", &DerivedQuantity::truth, "the true value (simulated data), else None");

  using Diagnostics = FitResult::Diagnostics;
  nb::class_<Diagnostics>(m, "FitDiagnostics",
                          "How a fit got its answer, not the answer (FitResult::Diagnostics, "
                          "sysid/types.h)")
      .def_ro("simulation_steps", &Diagnostics::simulation_steps, "step calls of all simulators")
      .def_ro("jacobian_mode", &Diagnostics::jacobian_mode, "the Jacobian mode used")
      .def_prop_ro(
          "reduction",
          [](const Diagnostics& d) {
            const Diagnostics::Reduction& r = d.reduction;
            nb::dict out;
            out["used"] = r.used;
            out["collision_pairs"] = r.collision_pairs;
            out["collision_pairs_off"] = r.collision_pairs_off;
            out["geoms_off"] = r.geoms_off;
            out["disabled"] = r.disabled;
            out["guard_trips"] = r.guard_trips;
            out["text"] = ReductionText(r);
            return out;
          },
          "the reduced model (reduce_model): dict used, collision_pairs, collision_pairs_off, "
          "geoms_off, disabled, guard_trips, text (as result.yaml's `reduced:`)")
      .def_ro("ledger", &Diagnostics::ledger,
              "the fit's steps and seconds by phase (a list of LedgerRow; steps add up to "
              "simulation_steps)")
      .def_ro("covariance_jacobian_iteration", &Diagnostics::covariance_jacobian_iteration,
              "-1: covariance, std errors and jacobian from the estimate's own Jacobian; else "
              "the iteration whose Jacobian they use (the stop before the last Jacobian)")
      .def_ro("last_step_std_errors", &Diagnostics::last_step_std_errors,
              "that stop: the last step's largest size in standard errors (NaN otherwise)")
      .def_ro("folds", &Diagnostics::folds, "the compressed blocks' folds made")
      .def_ro("reused_folds", &Diagnostics::reused_folds,
              "Jacobian requests answered with a block's last fold (reuse_folds)")
      .def_ro("ahead_folds", &Diagnostics::ahead_folds,
              "of the folds, those made ahead on the workers (fold_ahead)");

  nb::class_<FitResult> fit_result(m, "FitResult", "The result of a fit (sysid/types.h)");
  fit_result
      .def_ro("parameters", &FitResult::parameters,
              "a list of ParameterEstimate, in the order given (then the fitted measurement terms "
              "and control delays)")
      .def_prop_ro("estimates", &Estimates, "dict: name -> estimated value")
      .def_prop_ro(
          "status", [](const FitResult& r) { return FitStatusName(r.outcome); },
          "converged, not_converged, model_mismatch, jacobian_unreliable, "
          "did_not_move, interrupted, solver_failed or local_minimum")
      .def_ro("initial_cost", &FitResult::initial_cost, "0.5 |r|^2 at the start")
      .def_ro("final_cost", &FitResult::final_cost, "0.5 |r|^2 at the estimate")
      .def_ro("iterations", &FitResult::iterations, "the solver's iterations")
      .def_ro("converged", &FitResult::converged,
              "the optimiser reported convergence (the verdict is status)")
      .def_ro("interrupted", &FitResult::interrupted,
              "stopped by an interrupt (Ctrl-C) before it ended by itself")
      .def_ro("intervals_valid", &FitResult::intervals_valid,
              "std_error and ci95 mean something: status converged (and the uncertainty step ran)")
      .def_ro("chi2_ratio", &FitResult::chi2_ratio,
              "with sigmas: the weighted residual variance sum(r^2) / (m - p) of the sensors with "
              "a sigma (expected 1); NaN without sigmas")
      .def_ro(
          "sensor_chi2_ratio", &FitResult::sensor_chi2_ratio,
          "with sigmas: sensor (or fitted state) -> its weighted residual variance (expected 1)")
      .def_ro("sensor_noise_ratio", &FitResult::sensor_noise_ratio,
              "sensors without a sigma: sensor -> residual RMS at the estimate over the noise the "
              "log itself shows (about 1 when the model explains the data; absent where the log "
              "gives no noise estimate: a warning 'model check not possible' then)")
      .def_ro("sigma_from_log", &FitResult::sigma_from_log,
              "sensor -> sigma estimated from the log (sensor_sigmas 'auto')")
      .def_ro("residuals", &FitResult::residuals,
              "per fitted channel: bias, rms / sigma, whiteness, correlation time")
      .def_ro("interval_inflation", &FitResult::interval_inflation,
              "the factor on the covariance for correlated residuals (1: white)")
      .def_ro("intervals_from", &FitResult::intervals_from,
              "what the intervals come from (white or correlated residuals)")
      .def_ro("timestep_check", &FitResult::timestep_check,
              "the timestep check: what it ran and found (\"\": not run)")
      .def_ro("subset_start", &FitResult::subset_start,
              "the subset start: what it ran and whether it gave the start (\"\": not run)")
      .def_prop_ro(
          "termination", [](const FitResult& r) { return TerminationText(r.termination); },
          "why the optimiser stopped, one line (result.yaml's termination)")
      .def_prop_ro(
          "termination_kind",
          [](const FitResult& r) { return TerminationKindName(r.termination.kind); },
          "solver_convergence, iteration_limit, solver_failure, callback_stop, callback_abort, "
          "gauss_newton_stop, interrupted, checkpoint; none (no solve) or unknown (a file "
          "written before the kinds)")
      .def_ro("num_residuals", &FitResult::num_residuals,
              "rows of the residual vector at the estimate")
      .def_prop_ro(
          "covariance",
          [](const FitResult& r) -> Eigen::MatrixXd { return r.uncertainty.covariance; },
          "np x np covariance of the estimates, parameters order (zero rows for fixed and "
          "unidentifiable ones)")
      .def_prop_ro(
          "unidentifiable", [](const FitResult& r) { return r.uncertainty.unidentifiable; },
          "one line per direction the data do not determine (result.yaml unidentifiable)")
      .def_ro("jacobian", &FitResult::jacobian,
              "dr/dp at the estimate as its thin-QR triangle R (np x np, R^T R = J^T J)")
      .def_ro("trace", &FitResult::trace, "a list of IterationInfo, one per successful iteration")
      .def_ro("validation", &FitResult::validation,
              "held-out sequences (the experiment's validation:), a list of SequenceResult "
              "simulated at the start and at the estimate, never fitted")
      .def_ro("starts", &FitResult::starts,
              "a multi-start fit: every start in order (a list of StartResult); empty for one "
              "start")
      .def_ro("best_start", &FitResult::best_start,
              "a multi-start fit: the index in starts of the start this result is")
      .def_ro("start_spread", &FitResult::start_spread,
              "a multi-start fit: per estimated value its spread over the starts (a list of "
              "ParameterSpread)")
      .def_ro("derived", &FitResult::derived,
              "quantities derived from the estimate (a list of DerivedQuantity; empty when none)")
      .def_ro("sequences", &FitResult::sequences,
              "a list of SequenceResult, one per fitted sequence")
      .def_ro("warnings", &FitResult::warnings, "what the fit found worth saying, one string each")
      .def_ro("seconds", &FitResult::seconds, "wall time of the fit (result.yaml wall_time_s)")
      .def_ro("segment_steps_used", &FitResult::segment_steps_used,
              "multiple shooting: steps per segment (0: single shooting)")
      .def_prop_ro(
          "segment_reason", [](const FitResult& r) { return SegmentReasonText(r.segment_reason); },
          "why (multiple_shooting: auto's choice, or the given segment_steps)")
      .def_ro("gauss_newton_converged", &FitResult::gauss_newton_converged,
              "ended by the statistical stop (gauss_newton_stop, docs/numerics.md \"Stopping\")")
      .def_ro("diagnostics", &FitResult::diagnostics,
              "how the fit got its answer: simulation steps, Jacobian mode, reduced model, "
              "ledger, the covariance's Jacobian, folds (FitDiagnostics)")
      .def("__getstate__", &StateOf<FitResult>)
      .def("__setstate__", &SetState<FitResult>)
      .def("__repr__", [](const FitResult& r) {
        std::string estimates;
        for (const ParameterEstimate& p : r.parameters) {
          estimates += (estimates.empty() ? "" : ", ") + p.name + " = " + FormatDigits(p.value, 6) +
                       " +- " + FormatDigits(p.std_error, 2);
        }
        return std::string("FitResult(") + FitStatusName(r.outcome) + ", " +
               std::to_string(r.iterations) + " iterations, cost " +
               FormatDigits(r.initial_cost, 4) + " -> " + FormatDigits(r.final_cost, 4) + "; " +
               estimates + "; " + std::to_string(r.sequences.size()) + " sequence" +
               (r.sequences.size() == 1 ? "" : "s") + ", " + std::to_string(r.warnings.size()) +
               " warning" + (r.warnings.size() == 1 ? "" : "s") + ")";
      });

  nb::class_<io::FitResultFile, FitResult> result_file(
      m, "ResultFile", "A fit as stored in DIR/result.yaml + result.h5");
  result_file.def_ro("name", &io::FitResultFile::name, "the experiment's name")
      .def_ro("experiment", &io::FitResultFile::experiment, "the experiment file's path")
      .def_ro("created", &io::FitResultFile::created,
              "when the fit ran (UTC, YYYY-MM-DDTHH:MM:SSZ)")
      .def_ro("run_id", &io::FitResultFile::run_id,
              "the run that wrote the files (\"\" in results of older versions)")
      .def_ro("mjsysid_version", &io::FitResultFile::mjsysid_version,
              "the mjsysid that wrote the result")
      .def_ro("mujoco_version", &io::FitResultFile::mujoco_version, "the MuJoCo it ran with")
      .def_ro("solver", &io::FitResultFile::solver,
              "the fit's settings as text (result.yaml solver)")
      .def_ro("identified_models", &io::FitResultFile::identified_models,
              "model name -> file of the identified model in the folder")
      .def("__getstate__", &StateOf<io::FitResultFile>)
      .def("__setstate__", &SetState<io::FitResultFile>);

  nb::class_<ExperimentFit, io::FitResultFile> experiment_fit(
      m, "ExperimentFit", "The outcome of fit_experiment (`sysid fit`)");
  experiment_fit
      .def_ro("out_dir", &ExperimentFit::out_dir,
              "the folder written: result.yaml, result.h5, the identified models")
      .def_ro("exit_code", &ExperimentFit::exit_code, "the exit code `sysid fit` would give")
      .def("__getstate__", &StateOf<ExperimentFit>)
      .def("__setstate__", &SetState<ExperimentFit>);
  BindResultTables(fit_result, result_file, experiment_fit, sequence_result);

  // --- logs (sysid/io/log.h) ---
  nb::class_<io::Sequence>(m, "Sequence",
                           "One logged rollout: time (T), ctrl (T x nu, or Tc x nu at "
                           "ctrl_time), sensordata (T x ns), optional qpos/qvel/act (T x "
                           "nq|nv|na, else 0 x 0)")
      .def(nb::init<>())
      .def_rw("name", &io::Sequence::name, "the sequence's name")
      .def_rw("time", &io::Sequence::time, "T sample times (s)")
      .def_rw("ctrl", &io::Sequence::ctrl, "T x nu controls (Tc x nu at ctrl_time)")
      .def_rw("sensordata", &io::Sequence::sensordata,
              "T x nsensordata, the model's sensor layout (NaN: not measured)")
      .def_rw("qpos", &io::Sequence::qpos, "T x nq logged positions, or 0 x 0")
      .def_rw("qvel", &io::Sequence::qvel, "T x nv logged velocities, or 0 x 0")
      .def_rw("act", &io::Sequence::act, "T x na logged activations, or 0 x 0")
      .def_rw("sensor_names", &io::Sequence::sensor_names, "the logged sensors, in model order")
      .def_rw("sensor_dims", &io::Sequence::sensor_dims,
              "their dimensions (the sensordata columns, in order)")
      .def_rw("actuator_names", &io::Sequence::actuator_names,
              "the logged actuators (the ctrl columns, in order)")
      // the controls' own times (dataset ctrl_time; empty: one control row per `time`): what
      // the bag reader writes for commands at their own stamps
      .def_rw("ctrl_time", &io::Sequence::ctrl_time,
              "the controls' own times (Tc, seconds); empty: ctrl has one row per time");

  nb::class_<io::Log>(m, "Log", "Sequences recorded with one sensor_time convention")
      .def(nb::init<>())
      .def_rw("sequences", &io::Log::sequences, "a list of Sequence (assign a whole list)")
      .def_rw("sensor_time", &io::Log::sensor_time, "pre (y_k before the step) or post")
      .def_rw("attributes", &io::Log::attributes,
              "the file's attributes (text): truth.<name>, ...");

  // --- experiments (sysid/io/experiment.h) ---
  nb::class_<io::ExperimentConfig>(m, "Experiment", "A loaded YAML experiment file")
      .def_ro("name", &io::ExperimentConfig::name, "the experiment's name")
      .def_ro("source_file", &io::ExperimentConfig::source_file, "the YAML file read")
      .def_ro("output", &io::ExperimentConfig::output, "the output folder of a fit")
      .def_prop_ro(
          "models",
          [](const io::ExperimentConfig& c) {
            std::map<std::string, std::string> out;
            for (const io::ModelSpec& s : c.models) out[s.name] = s.path;
            return out;
          },
          "model name -> MJCF path")
      .def_prop_ro(
          "data",
          [](const io::ExperimentConfig& c) {
            std::vector<std::string> out;
            for (const io::DataFile& d : c.data) out.push_back(d.path);
            return out;
          },
          "the logs' paths (`data:`)")
      .def_prop_ro(
          "parameters",
          [](const io::ExperimentConfig& c) {
            std::vector<std::string> out;
            for (const io::ParameterSpec& p : c.parameters) out.push_back(p.name);
            return out;
          },
          "the parameters' names")
      .def_prop_ro(
          "truth",
          [](const io::ExperimentConfig& c) {
            std::map<std::string, double> out;
            for (const io::NamedValue& t : c.simulate.truth) out[t.name] = t.value;
            return out;
          },
          "name -> true value (simulate.truth)");

  // --- what the command line offers ---
  m.def("load_experiment", &io::LoadExperiment, arg("path"),
        "Reads and checks a YAML experiment file (docs/experiment-schema.md)");
  m.def("simulate", &Simulate, arg("experiment"), arg("out") = nb::none(), arg("seed") = nb::none(),
        arg("threads") = nb::none(), arg("write") = true, arg("force") = false,
        "`sysid simulate`: the experiment's synthetic log; written to out (default: its first "
        "`data:` path) unless write=False. An existing log that simulate did not write for this "
        "experiment is replaced only with force=True (ValueError otherwise). Returns the Log.");
  m.def("check", &Check, arg("experiment"), arg("jacobians") = true,
        "`sysid check`: validates the experiment, models and data; with data, the core's "
        "Jacobians against ceres::GradientChecker. Returns a dict (worst_relative_error, "
        "worst_where, per_variable).");
  m.def("fit_experiment", &FitExperiment, arg("experiment"), arg("out") = nb::none(),
        arg("threads") = -1, arg("verbose") = false, arg("force") = false, arg("resume") = false,
        arg("callback") = nb::none(),
        "`sysid fit`: fits the experiment and writes out (default: its `output`) as the command "
        "line does. The GIL is released during the fit; callback(IterationInfo) after every "
        "successful iteration; Ctrl-C stops after the current iteration (status interrupted).");
  m.def("report", &Report, arg("dir"),
        "`sysid report DIR`: writes report.html and the PNG plots; returns the summary");
  m.def("read_result", &io::ReadResult, arg("dir"), "Reads DIR/result.yaml and DIR/result.h5");
  m.def("read_log", &io::ReadLog, arg("path"), "Reads and checks an HDF5 log");
  m.def("write_log", &WriteLogChecked, arg("path"), arg("log"), arg("model") = nb::none(),
        "Writes an HDF5 log atomically; with model (an MJCF path), checked against it first as "
        "`sysid import` does");
  BindFitApi(m);
  BindDesignApi(m);
  BindRolloutApi(m);
}
