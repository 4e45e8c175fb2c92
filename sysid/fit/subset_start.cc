// The subset start (sysid/fit/subset_start.h).
#include "sysid/fit/subset_start.h"

#include <algorithm>
#include <exception>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/data/event_windows.h"
#include "sysid/fit/pass.h"
#include "sysid/fit/records.h"
#include "sysid/fit/restart.h"
#include "sysid/fit_observer.h"

namespace mjsysid {
namespace {

// the first n samples of sequence s: its sample rows (measured, time, logged states) and, where
// the controls share the samples' rows (no ctrl_time), its controls; controls with their own
// times are kept whole (those after the last sample are never simulated)
FitSequence Prefix(const FitSequence& s, int n) {
  FitSequence p = s;
  const auto rows = [n](RowMatrix* m) {
    if (m->rows() > n) m->conservativeResize(n, Eigen::NoChange);
  };
  rows(&p.measured);
  rows(&p.qpos);
  rows(&p.qvel);
  rows(&p.act);
  if (p.time.size() > n) p.time.conservativeResize(n);
  if (p.ctrl_time.size() == 0) rows(&p.ctrl);
  return p;
}

// Sets the problem's sequences to their prefixes while it lives, and puts the whole sequences back
// when it goes out of scope (a throw included). The cells a previous fit's event windows masked
// are restored before the sequences are copied (the data as given), and those the subset's pass
// masked (rows of the prefixes) before they are put back.
class SequencePrefixes {
 public:
  SequencePrefixes(PreparedFit* fit, const std::vector<int>& lengths) : fit_(fit) {
    RestoreEventWindows(*fit);
    whole_ = fit->sequences;
    for (size_t q = 0; q < whole_.size(); ++q) fit->sequences[q] = Prefix(whole_[q], lengths[q]);
  }
  ~SequencePrefixes() {
    RestoreEventWindows(*fit_);
    fit_->sequences = std::move(whole_);
  }
  SequencePrefixes(const SequencePrefixes&) = delete;
  SequencePrefixes& operator=(const SequencePrefixes&) = delete;

 private:
  PreparedFit* fit_;
  std::vector<FitSequence> whole_;
};

// why the subset start does not apply ("" when it does)
std::string NotApplicable(const PreparedFit& fit, const FitOptions& options) {
  if (fit.params.empty()) return "no parameters";
  for (const FitParameter& p : fit.params) {
    if (p.initial_auto) return "initial: auto gives the start";
  }
  if (options.segment_steps > 0) return "segments given";
  if (options.estimate_initial_state) return "initial states estimated";
  if (fit.shards) return "sharded";
  return "";
}

}  // namespace

SubsetStartRun SubsetStart(const FitParts& parts, const FitOptions& options) {
  PreparedFit& fit = *parts.fit;
  SubsetStartRun run;
  if (!options.subset_start || !NotApplicable(fit, options).empty()) return run;
  // each sequence's prefix, and whether it saves anything
  std::vector<int> lengths;
  long long whole = 0, subset = 0;
  for (const FitSequence& s : fit.sequences) {
    const int T = static_cast<int>(s.measured.rows());
    const int n =
        std::min(T, std::max(kSubsetMinSamples, (T + kSubsetDivisor - 1) / kSubsetDivisor));
    lengths.push_back(n);
    whole += T;
    subset += n;
  }
  if (2 * subset > whole) return run;

  for (const FitParameter& p : fit.params) run.user_starts.push_back(p.initial);
  const std::string what = "the first " + std::to_string(subset) + " of " + std::to_string(whole) +
                           " samples (1/" + std::to_string(kSubsetDivisor) + " of each sequence)";
  if (options.observer) options.observer->OnStage(FitStage::kSubset, "start on " + what, 0);
  run.ran = true;
  std::string why_not;
  std::vector<double> estimate;
  try {
    const SequencePrefixes prefixes(&fit, lengths);
    FitPass pass(parts, options);
    const bool warned = pass.Solve() == FitPass::Stop::kJacobianWarning;
    pass.FinishRecords();
    run.records = std::move(pass.result());
    estimate = pass.Estimate();
    if (warned || pass.plan().segment_steps != 0) {
      why_not = "the subset's fit chose segments";
    } else if (options.interrupt && options.interrupt->load()) {
      why_not = "interrupted";
    } else if (!(pass.SolvedCost() < pass.SolvedInitialCost())) {
      why_not = "its cost did not decrease";
    }
    for (size_t g = 0; g < estimate.size() && why_not.empty(); ++g) {
      const FitParameter& p = fit.params[g];
      for (const bool lower : {true, false}) {
        const double bound = lower ? p.lower : p.upper;
        if (OnBound(estimate[g], bound, lower) && !OnBound(run.user_starts[g], bound, lower)) {
          why_not = p.name + " ran to its " + (lower ? "lower" : "upper") + " bound";
        }
      }
    }
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    // (bad input is the local fit's to report, on all the data)
    why_not = std::string("its pass failed: ") + e.what();
  }
  run.kept = why_not.empty();
  if (run.kept) StartAt(&fit, estimate, false);
  run.text = "ran on " + what + " in " + FormatDigits(run.records.seconds, 3) + " s; " +
             (run.kept ? "its estimate was the start of the fit on all the data"
                       : "not used (" + why_not + "): the fit started from the given starts");
  return run;
}

void JoinSubsetStart(const FitParts& parts, SubsetStartRun run, FitResult* result) {
  if (!run.ran) return;
  PreparedFit& fit = *parts.fit;
  for (size_t g = 0; g < run.user_starts.size(); ++g) {
    fit.params[g].initial = run.user_starts[g];
    if (result && g < result->parameters.size()) result->parameters[g].initial = run.user_starts[g];
  }
  if (!result) return;
  run.records.trace.clear();  // the subset's costs are of other data
  AddRecords(run.records, "subset start", true, result);
  result->subset_start = std::move(run.text);
}

}  // namespace mjsysid
