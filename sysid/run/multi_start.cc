#include "sysid/run/multi_start.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>
#include <random>
#include <thread>

#include "core/text.h"
#include "sysid/assess/chi_square.h"
#include "sysid/fit_observer.h"

namespace mjsysid::run {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// z of the one-sided 1 - 1e-3 normal quantile: the cost excess test of a local minimum
constexpr double kZ95 = 1.959963984540054;
// an estimate without a finite interval "differs" above this relative difference
constexpr double kRelativeDifference = 1e-3;
// the error of a start that a stop signal kept from running
constexpr char kNotStarted[] = "not started (interrupted)";

// a uniform number in [0, 1) from the raw 64-bit output (the same on every platform, unlike
// std::uniform_real_distribution)
double Uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// 0..n-1 in a random order (Fisher-Yates on the raw output; std::shuffle is not portable)
std::vector<int> Permutation(int n, std::mt19937_64& rng) {
  std::vector<int> p(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) p[static_cast<size_t>(i)] = i;
  for (int i = n - 1; i > 0; --i) {
    std::swap(p[static_cast<size_t>(i)], p[static_cast<size_t>(rng() % (i + 1))]);
  }
  return p;
}

// the honest verdicts: the optimiser converged (the model may still not explain the data)
bool Honest(FitStatus s) { return s == FitStatus::kConverged || s == FitStatus::kModelMismatch; }

}  // namespace

RowMatrix SpreadStarts(const std::vector<FitParameter>& parameters, int n, std::uint64_t seed) {
  const auto np = static_cast<Eigen::Index>(parameters.size());
  RowMatrix out(n, np);
  std::mt19937_64 rng(seed);
  const int spread = n - 1;  // Latin hypercube points (start 0 is the experiment's own)
  for (Eigen::Index j = 0; j < np; ++j) {
    const FitParameter& p = parameters[static_cast<size_t>(j)];
    out(0, j) = p.initial;
    // the range in variable space: the bounds, else +-50 % of the start clipped to a bound
    double lo = p.ToVariable(p.lower), hi = p.ToVariable(p.upper);
    if (!std::isfinite(lo) || !std::isfinite(hi)) {
      const double half = p.initial != 0 ? 0.5 * std::abs(p.initial) : 0.5;
      const double plo = std::max(p.lower, p.initial - half);
      const double phi = std::min(p.upper, p.initial + half);
      lo = std::isfinite(lo) ? lo : p.ToVariable(plo);
      hi = std::isfinite(hi) ? hi : p.ToVariable(phi);
      if (!std::isfinite(lo)) lo = p.ToVariable(std::max(plo, 0.5 * p.initial));  // log, lower 0
    }
    // one point per stratum, strata in a random order
    const std::vector<int> strata = Permutation(spread, rng);
    for (int i = 0; i < spread; ++i) {
      const double u = (strata[static_cast<size_t>(i)] + Uniform(rng)) / spread;
      out(i + 1, j) = p.FromVariable(lo + u * (hi - lo));
    }
  }
  return out;
}

std::unique_ptr<Problem> ProblemFrom(const BuiltProblem& bp, const Eigen::VectorXd& initial) {
  auto problem = std::make_unique<Problem>();
  for (size_t m = 0; m < bp.models.size(); ++m) {
    problem->AddModel(bp.model_names[m], *bp.models[m]);
  }
  for (size_t j = 0; j < bp.parameters.size(); ++j) {
    FitParameter p = bp.parameters[j];
    p.initial = initial[static_cast<Eigen::Index>(j)];
    problem->AddParameter(p);
  }
  for (const FitMeasurement& me : bp.measurements) problem->AddMeasurement(me);
  for (const FitControlDelay& d : bp.control_delays) problem->AddControlDelay(d);
  for (const FitSequence& s : bp.sequences) problem->AddSequence(s);
  return problem;
}

FitResult FitFromStarts(const BuiltProblem& bp, const FitOptions& options, int n,
                        std::uint64_t seed, bool progress,
                        const std::function<void(Problem&, FitOptions*)>& on_problem) {
  const auto wall = std::chrono::steady_clock::now();
  const RowMatrix starts = SpreadStarts(bp.parameters, n, seed);

  // the measurement terms and control delays keep their experiment values at every start
  std::vector<double> term_starts;
  for (const FitMeasurement& me : bp.measurements) {
    for (const FitMeasurement::Term* t : {&me.delay, &me.gain, &me.bias}) {
      if (t->fit) term_starts.push_back(t->initial);
    }
  }
  for (const FitControlDelay& d : bp.control_delays) term_starts.push_back(d.initial);

  // min(n, threads) fits at a time, the simulator threads divided among them
  const int threads = std::max(1, options.threads);
  // (sharded across MPI ranks: one at a time)
  const int concurrent = on_problem ? 1 : std::min(n, threads);
  FitOptions per_fit = options;
  per_fit.threads = std::max(1, threads / concurrent);
  per_fit.verbose = false;
  per_fit.observer = nullptr;  // the starts run side by side: only OnStartDone reports
  per_fit.on_iteration = nullptr;

  std::vector<FitResult> fits(static_cast<size_t>(n));
  std::vector<StartResult> records(static_cast<size_t>(n));
  std::vector<std::exception_ptr> errors(static_cast<size_t>(n));
  std::atomic<int> next{0}, finished{0};
  std::mutex report;
  auto work = [&]() {
    for (int k = next++; k < n; k = next++) {
      StartResult& rec = records[static_cast<size_t>(k)];
      rec.start.resize(starts.cols() + static_cast<Eigen::Index>(term_starts.size()));
      rec.start << starts.row(k).transpose(),
          Eigen::Map<const Eigen::VectorXd>(term_starts.data(),
                                            static_cast<Eigen::Index>(term_starts.size()));
      // start 0 always runs (a fit stops itself after its first iteration when interrupted)
      if (k > 0 && options.interrupt && options.interrupt->load()) {
        rec.status = FitStatus::kInterrupted;
        rec.initial_cost = rec.final_cost = kInf;
        rec.error = kNotStarted;
        continue;
      }
      try {
        // a Problem of its own: the same models, measurement terms and sequences
        const std::unique_ptr<Problem> problem = ProblemFrom(bp, starts.row(k).transpose());
        FitOptions fit_options = per_fit;
        if (on_problem) on_problem(*problem, &fit_options);
        FitResult& r = fits[static_cast<size_t>(k)];
        r = problem->Fit(fit_options);
        rec.estimate.resize(static_cast<Eigen::Index>(r.parameters.size()));
        for (size_t j = 0; j < r.parameters.size(); ++j) {
          rec.estimate[static_cast<Eigen::Index>(j)] = r.parameters[j].value;
        }
        rec.initial_cost = r.initial_cost;
        rec.final_cost = r.final_cost;
        rec.status = r.outcome;
        rec.iterations = r.iterations;
      } catch (const std::exception& e) {
        errors[static_cast<size_t>(k)] = std::current_exception();
        rec.error = e.what();
        rec.initial_cost = rec.final_cost = kInf;
        rec.status = FitStatus::kNotConverged;
      }
      // one event per finished start, one at a time
      const int done = ++finished;
      if (progress && options.observer) {
        const std::lock_guard<std::mutex> lock(report);
        options.observer->OnStartDone(k, done, n, rec);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < concurrent; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();

  // the best: the lowest final cost of an honest verdict, else the lowest of all
  int best = -1;
  for (const bool honest_only : {true, false}) {
    for (int k = 0; k < n; ++k) {
      const StartResult& r = records[static_cast<size_t>(k)];
      if (!r.error.empty() || (honest_only && !Honest(r.status))) continue;
      if (best < 0 || r.final_cost < records[static_cast<size_t>(best)].final_cost) best = k;
    }
    if (best >= 0) break;
  }
  if (best < 0) {
    // every start failed: the experiment's own start's error, as a single fit gives it
    for (const std::exception_ptr& e : errors) {
      if (e) std::rethrow_exception(e);
    }
  }

  FitResult result = std::move(fits[static_cast<size_t>(best)]);
  result.starts = records;
  result.best_start = best;
  result.diagnostics.simulation_steps = 0;
  for (const FitResult& f : fits)
    result.diagnostics.simulation_steps += f.diagnostics.simulation_steps;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();

  // the spread of each estimated value over the starts that ran
  for (size_t j = 0; j < result.parameters.size(); ++j) {
    ParameterSpread s;
    s.name = result.parameters[j].name;
    s.min = kInf;
    s.max = -kInf;
    for (const StartResult& r : records) {
      if (!r.error.empty() || r.estimate.size() <= static_cast<Eigen::Index>(j)) continue;
      s.min = std::min(s.min, r.estimate[static_cast<Eigen::Index>(j)]);
      s.max = std::max(s.max, r.estimate[static_cast<Eigen::Index>(j)]);
    }
    const double v = std::abs(result.parameters[j].value);
    s.relative = s.max > s.min ? (v > 0 ? (s.max - s.min) / v : kInf) : 0;
    result.start_spread.push_back(s);
  }
  for (const std::string& w : LocalMinimaWarnings(result)) result.warnings.push_back(w);
  // the starts in another minimum say so (their fits' own verdicts are in that warning)
  for (size_t k : StartsInOtherMinima(result)) result.starts[k].status = FitStatus::kLocalMinimum;
  // a stop signal: the run is interrupted, whatever the best start's own verdict
  int unfinished = 0;
  for (const StartResult& r : records) unfinished += r.status == FitStatus::kInterrupted ? 1 : 0;
  if (options.interrupt && options.interrupt->load()) {
    result.outcome = FitStatus::kInterrupted;
    result.interrupted = true;
    result.intervals_valid = false;
    result.warnings.push_back("interrupted: " + std::to_string(unfinished) + " of " +
                              std::to_string(n) +
                              " starts did not finish; the result is the best start's of those "
                              "that ran (start " +
                              std::to_string(best) + ")");
  }
  for (const StartResult& r : records) {
    if (!r.error.empty() && r.error != kNotStarted) {
      result.warnings.push_back("a start failed: " + r.error);
    }
  }
  return result;
}

namespace {

// whether start k of a multi-start result ended in another minimum (multi_start.h, "Local
// minima"); *differ: the estimates that differ from the best's, *names gains their names
bool InOtherMinimum(const FitResult& result, size_t k, std::string* differ,
                    std::vector<std::string>* names) {
  const auto b = static_cast<size_t>(result.best_start);
  const StartResult& best = result.starts[b];
  const StartResult& r = result.starts[k];
  // a start stopped by a signal is not at a minimum
  if (k == b || !r.error.empty() || r.status == FitStatus::kInterrupted ||
      r.estimate.size() != best.estimate.size()) {
    return false;
  }
  // a cost excess the noise does not explain
  if (!AboveByMoreThanNoise(r.final_cost, best.final_cost, result.uncertainty.residual_variance,
                            static_cast<int>(result.parameters.size()))) {
    return false;
  }
  // estimates outside the best one's intervals
  for (size_t j = 0; j < result.parameters.size(); ++j) {
    const ParameterEstimate& e = result.parameters[j];
    const double d = std::abs(r.estimate[static_cast<Eigen::Index>(j)] - e.value);
    const double half = kZ95 * e.std_error;
    const bool differs = std::isfinite(half) && half > 0
                             ? d > half
                             : d > kRelativeDifference * std::max(std::abs(e.value), 1e-300);
    if (!differs) continue;
    *differ += (differ->empty() ? "" : ", ") + e.name + " " +
               FormatDigits(r.estimate[static_cast<Eigen::Index>(j)], 4) + " (best " +
               FormatDigits(e.value, 4) + ")";
    if (std::find(names->begin(), names->end(), e.name) == names->end()) {
      names->push_back(e.name);
    }
  }
  return !differ->empty();
}

}  // namespace

std::vector<size_t> StartsInOtherMinima(const FitResult& result) {
  std::vector<size_t> out;
  std::vector<std::string> names;
  for (size_t k = 0; k < result.starts.size() && result.starts.size() >= 2; ++k) {
    std::string differ;
    if (InOtherMinimum(result, k, &differ, &names)) out.push_back(k);
  }
  return out;
}

std::vector<std::string> LocalMinimaWarnings(const FitResult& result) {
  std::vector<std::string> out;
  if (result.starts.size() < 2) return out;
  const auto b = static_cast<size_t>(result.best_start);
  const StartResult& best = result.starts[b];
  std::string detail;
  int count = 0;
  std::vector<std::string> names;  // parameters that differ at any such start
  for (size_t k = 0; k < result.starts.size(); ++k) {
    const StartResult& r = result.starts[k];
    std::string differ;
    if (!InOtherMinimum(result, k, &differ, &names)) continue;
    ++count;
    detail += "; start " + std::to_string(k) + " (its fit ended " + FitStatusName(r.status) + ", " +
              std::to_string(r.iterations) + " iterations) ended at cost " +
              FormatDigits(r.final_cost, 6) + " with " + differ;
  }
  if (count == 0) return out;
  std::string list;
  for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
  out.push_back("local minima: " + std::to_string(count) + " of " +
                std::to_string(result.starts.size()) +
                " starts ended in another minimum (cost above the best " +
                FormatDigits(best.final_cost, 6) + " of start " + std::to_string(b) +
                " by more than the noise explains) with different " + list + detail +
                ". The estimate depends on the start: the result is the best start's; narrow the "
                "bounds or excite the system more to remove the other minima");
  return out;
}

}  // namespace mjsysid::run
