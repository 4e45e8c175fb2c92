// The initial-state check (see initial_state_check.h).
#include "sysid/run/initial_state_check.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <new>
#include <string>

#include "core/text.h"

namespace mjsysid::run {

void CheckLoggedInitialStates(const io::ExperimentConfig& run_cfg, const BuiltProblem& bp,
                              const FitOptions& options, long long memory_left,
                              io::FitResultFile* file) {
  const FitResult& r = *file;
  if (r.outcome != FitStatus::kModelMismatch || bp.options.estimate_initial_state ||
      bp.sequences.empty() || r.parameters.empty()) {
    return;
  }
  for (const FitSequence& s : bp.sequences) {
    if (s.qpos.rows() == 0) return;  // started from the model's reference state, not a log row
  }

  // the same experiment with the initial states estimated, from the fit's estimate: no global
  // stage, few iterations, no progress of its own
  io::ExperimentConfig cfg = run_cfg;
  cfg.options.estimate_initial_state = true;
  for (io::ParameterSpec& p : cfg.parameters) {
    for (const ParameterEstimate& e : r.parameters) {
      if (e.name == p.name && std::isfinite(e.value)) p.initial = e.value, p.initial_auto = false;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  FitResult check;
  try {
    BuiltProblem b = BuildProblem(cfg, options.threads);
    if (EstimateRunMemory(b, 1).bytes > memory_left) return;
    if (options.observer) {
      options.observer->OnStage(FitStage::kCheck,
                                "the fit again with the initial states estimated (diagnosis)",
                                r.seconds);
    }
    FitOptions o = b.options;
    o.global_stage = false;
    o.timestep_check = false;  // a refit that ends model_mismatch says nothing anyway
    o.max_iterations = std::min(o.max_iterations, kInitialStateCheckIterations);
    o.threads = options.threads;
    o.interrupt = options.interrupt;
    o.observer = nullptr;
    o.verbose = false;
    check = b.problem->Fit(o);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    return;  // the check cannot say anything; the fit's own warnings stand
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (check.outcome != FitStatus::kConverged) return;

  // how far the estimates moved, in the check's standard errors
  double moved = 0;
  for (const ParameterEstimate& e : check.parameters) {
    for (const ParameterEstimate& f : r.parameters) {
      if (e.name == f.name && e.std_error > 0 && std::isfinite(e.std_error)) {
        moved = std::max(moved, std::abs(e.value - f.value) / e.std_error);
      }
    }
  }
  file->warnings.push_back(
      "model mismatch from the logged initial states: fitted again with the initial states "
      "estimated (initial_state: {estimate: true}) from this estimate, the fit converges "
      "(weighted residual variance " +
      FormatDigits(check.chi2_ratio, 3) + " against " + FormatDigits(r.chi2_ratio, 3) +
      " here; the estimates move by up to " + FormatDigits(moved, 2) +
      " of its standard errors; the check took " + FormatDigits(seconds, 2) +
      " s): each sequence's first logged row carries noise its simulation cannot leave; set "
      "initial_state: {estimate: true}");
}

}  // namespace mjsysid::run
