// The global stage (sysid/fit/global_stage.h): horizon continuation rounds from the local fit's
// estimate, the better point kept.
#include "sysid/fit/global_stage.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/assess/chi_square.h"
#include "sysid/fit/pass.h"
#include "sysid/fit/records.h"
#include "sysid/fit/restart.h"
#include "sysid/fit_observer.h"
#include "sysid/solve/progress.h"

namespace mjsysid {
namespace {

// the statuses after which the stage runs
bool Unfinished(FitStatus s) {
  return s == FitStatus::kNotConverged || s == FitStatus::kModelMismatch ||
         s == FitStatus::kJacobianUnreliable || s == FitStatus::kDidNotMove;
}

// what the stage did so far, for its warning
struct Record {
  int rounds = 0;    // rounds that ran to the end
  int improved = 0;  // rounds whose end replaced the best
  bool out_of_budget = false;
  bool interrupted = false;
  bool no_data_states = false;
  std::string failure;  // what a pass that failed threw ("": none)
  double seconds = 0;
  double last_cost = -1;  // the last round's final cost (-1: none ended)
};

// how the rounds were cut short, for the stage's warning ("" when they were not)
std::string Ending(const Record& rec) {
  if (!rec.failure.empty()) return "; a pass failed and ended the stage: " + rec.failure;
  if (rec.interrupted) return "; interrupted, the best point so far kept";
  return "";
}

bool Interrupted(const FitOptions& options) {
  return options.interrupt && options.interrupt->load();
}

}  // namespace

FitResult GlobalStage(const FitParts& parts, const FitOptions& options, const LocalMode& mode,
                      FitResult local) {
  PreparedFit& fit = *parts.fit;
  const size_t np = fit.params.size();
  if (!options.global_stage || local.interrupted || !Unfinished(local.outcome) || np == 0 ||
      local.iterations < 0 || fit.shards || local.parameters.size() < np) {
    return local;
  }
  const auto start = std::chrono::steady_clock::now();
  // the budget in simulation steps (the same rounds on any machine, at any load)
  const double budget = options.global_budget *
                        static_cast<double>(std::max(local.diagnostics.simulation_steps, 1LL));
  const double local_seconds = local.seconds;  // the stages' times count from the fit's start
  // the user's starts back in the problem however the stage ends (a throw included)
  const KeepStarts keep(&fit);
  const std::vector<double>& user_starts = keep.starts();

  FitResult best = std::move(local);
  // the local fit, kept aside once a round replaces it (its signals and cost stay the start's)
  FitResult local_fit;
  bool replaced = false;
  std::vector<PassRecord> passes = {RecordOf("local fit", best)};
  size_t best_pass = 0;  // passes[best_pass] is best's
  Record rec;
  long long spent = 0;  // the stage's simulation steps so far
  // whether the next pass may start: not after an interrupt or once the budget is spent (says
  // which in rec)
  const auto may_start = [&] {
    rec.interrupted = Interrupted(options);
    rec.out_of_budget = !rec.interrupted && static_cast<double>(spent) >= budget;
    return !rec.interrupted && !rec.out_of_budget;
  };
  try {
    for (int round = 1; round <= kMaxGlobalRounds; ++round) {
      if (!may_start()) break;
      const std::string tag = "global stage round " + std::to_string(round);
      // 1. continuation: short segments held on the data, jumping sensors left out
      FitOptions held = options;
      held.segment_steps = kContinuationSteps;
      held.hold_states_first = true;
      held.continuation = {true, true, true};
      StartAt(&fit, EstimateOf(best, np), true);
      if (options.observer) {
        options.observer->OnStage(
            FitStage::kGlobal,
            tag + ": " + std::to_string(kContinuationSteps) + "-step segments held on the data",
            local_seconds + SecondsSince(start));
      }
      std::vector<double> continued;
      {
        FitPass pass(parts, held);
        pass.Solve();
        pass.FinishRecords();
        passes.push_back(RecordOf(tag + " continuation", pass.result()));
        spent += pass.result().diagnostics.simulation_steps;
        if (!pass.StatesFromData()) {
          rec.no_data_states = true;
          break;
        }
        continued = pass.Estimate();
      }
      if (!may_start()) break;
      // 2. the local fit's horizon from there, its segment states held on the data first
      FitOptions own = options;
      own.segment_steps = mode.segment_steps;
      own.continuation.contact_segments = mode.contact_segments;
      own.continuation.hold_states = true;
      StartAt(&fit, continued, true);
      if (options.observer) {
        options.observer->OnStage(FitStage::kGlobal, tag + ": the local fit's horizon from there",
                                  local_seconds + SecondsSince(start));
      }
      FitPass pass(parts, own);
      pass.Solve();
      pass.Assess();
      FitResult& r = pass.result();
      passes.push_back(RecordOf(tag, r));
      spent += r.diagnostics.simulation_steps;
      ++rec.rounds;
      rec.last_cost = r.final_cost;
      rec.interrupted = r.interrupted;
      const bool lower =
          !r.interrupted && std::isfinite(r.final_cost) && r.final_cost >= 0 &&
          AboveByMoreThanNoise(best.final_cost, r.final_cost, r.uncertainty.residual_variance,
                               static_cast<int>(r.parameters.size()));
      if (!lower) break;
      ++rec.improved;
      if (!replaced) local_fit = std::move(best);
      replaced = true;
      best = std::move(r);
      best_pass = passes.size() - 1;
    }
  } catch (const std::bad_alloc&) {
    throw;  // out of memory: the caller's (exit 5)
  } catch (const std::exception& e) {
    // a pass that failed ends the stage; the best point so far stands
    rec.failure = e.what();
  }
  rec.seconds = SecondsSince(start);
  JoinRecords(passes, best_pass, &best);

  if (replaced) {
    // the kept point, with the user's starts and the local fit's initial cost and signals
    best.initial_cost = local_fit.initial_cost;
    for (size_t g = 0; g < np; ++g) best.parameters[g].initial = user_starts[g];
    for (size_t q = 0; q < best.sequences.size() && q < local_fit.sequences.size(); ++q) {
      SequenceResult& s = best.sequences[q];
      const SequenceResult& l = local_fit.sequences[q];
      if (s.sensor_names == l.sensor_names &&
          s.simulated_initial.rows() == l.simulated_initial.rows()) {
        s.simulated_initial = l.simulated_initial;
        s.state_simulated_initial = l.state_simulated_initial;
      }
    }
    best.segment_reason.choice = local_fit.segment_reason.choice;
    best.warnings.push_back(
        "global stage: the local fit ended " + std::string(FitStatusName(local_fit.outcome)) +
        " at cost " + FormatDigits(local_fit.final_cost, 4) + "; horizon continuation (" +
        std::to_string(kContinuationSteps) +
        "-step segments held on the data, then the local fit's horizon) found cost " +
        FormatDigits(best.final_cost, 4) + " (" + std::to_string(rec.improved) + " of " +
        std::to_string(rec.rounds) + " round(s) lower, " + FormatDigits(rec.seconds, 3) + " s, " +
        std::to_string(spent) + " simulation steps of a budget of " + FormatDigits(budget, 3) +
        (rec.out_of_budget ? ", which ended the rounds" : "") +
        "): the local fit had stopped in another minimum; this result is the lower point" +
        Ending(rec));
    return best;
  }
  std::string what;
  if (rec.no_data_states) {
    what =
        "not run: the segment states cannot come from the data (no logged qpos/qvel, and not "
        "every joint a hinge or slide with position and velocity sensors)";
  } else if (rec.rounds == 0) {
    what = rec.interrupted || !rec.failure.empty()
               ? "no round ended"
               : "not run: its budget (" + FormatDigits(budget, 3) +
                     " simulation steps, global_budget x the local fit's) was "
                     "spent";
  } else {
    what = "horizon continuation ended at cost " + FormatDigits(rec.last_cost, 4) +
           ", not lower than the local fit's " + FormatDigits(best.final_cost, 4) +
           " by more than the noise explains (" + FormatDigits(rec.seconds, 3) +
           " s): no better point found from here; the local result stands";
  }
  best.warnings.push_back("global stage: " + what + Ending(rec));
  return best;
}

}  // namespace mjsysid
