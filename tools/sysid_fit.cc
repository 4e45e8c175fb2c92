// sysid fit EXP.yaml --out DIR: fit the experiment's parameters and print the estimates; under
// mpirun the sequences are sharded across the ranks (RunFitSharded).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sysid/assess/metrics.h"
#include "sysid/io/experiment.h"
#include "sysid/io/warnings.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/fit_table.h"
#include "sysid/run/output_folder.h"
#include "sysid/run/resume.h"
#include "tools/sysid_cli.h"
#ifdef MJSYSID_WITH_MPI
#include "sysid/mpi/distributed_fit.h"
#endif

namespace mjsysid::cli {
namespace {

std::atomic<bool> g_interrupted{false};
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

// first SIGINT, SIGTERM or SIGHUP: stop after the current iteration and write the results; the
// next one has the default action (the process ends at once; the previous result stays)
extern "C" void OnInterrupt(int) {
  g_interrupted.store(true);
  for (int s : kStopSignals) std::signal(s, SIG_DFL);
}

// installs (true) or removes (false) OnInterrupt for the stop signals
void CatchStopSignals(bool on) {
  for (int s : kStopSignals) std::signal(s, on ? OnInterrupt : SIG_DFL);
}

struct FitArgs {
  std::string experiment;
  std::string out;
  int threads = -1;
  bool quiet = false;
  bool verbose = false;
  bool force = false;
  std::string resume;       // --resume DIR
  int starts = 0;           // --starts N (0: solver.starts)
  long long seed = -1;      // --seed S (< 0: solver.seed)
  double memory_limit = 0;  // --memory-limit GB (0: solver.memory_limit_gb, else the default)
};

// the --help page of `sysid fit`: description, arguments (into args) and footer
void DeclareFit(CLI::App* sub, FitArgs* args) {
  sub->description("Fit the experiment's parameters to its data files (Ceres, analytic Jacobians)");
  sub->add_option("experiment", args->experiment,
                  "YAML experiment file (with --resume: default the checkpoint's)");
  sub->add_option("--out", args->out,
                  "output folder (default: the experiment's `output`, results/<name>)");
  sub->add_option("--threads", args->threads,
                  "simulation threads, 0 = all cores, at most 256 (default: solver.threads)")
      ->check(ThreadCountValidator());
  sub->add_option("--memory-limit", args->memory_limit,
                  "refuse the fit when its memory estimate exceeds GB gigabytes (1e9 bytes; "
                  "default: solver.memory_limit_gb, else 80 % of the available memory)")
      ->check(PositiveFiniteNumber());
  sub->add_flag("--quiet", args->quiet, "no progress table (warnings and the summary only)");
  sub->add_flag("--verbose", args->verbose,
                "explain the statistical stop's test under each iteration of the table, and say "
                "why the solver stopped, why these segments and what the reduced model left out");
  sub->add_flag("--force", args->force,
                "replace an existing --out folder that is not an mjsysid result folder (its files "
                "are deleted)");
  sub->add_option("--starts", args->starts,
                  "fit from N starts spread in the bounds, in parallel; keep the best, report the "
                  "spread and flag local minima (default: solver.starts, 1)")
      ->check(WholeNumberAtLeast(1));
  sub->add_option("--seed", args->seed, "seed of the spread starts (default: solver.seed, 0)")
      ->check(WholeNumberAtLeast(0));
  sub->add_option("--resume", args->resume,
                  "continue the fit of DIR from its checkpoint (DIR.partial/checkpoint.yaml of a "
                  "killed run, or DIR's interrupted result); writes into DIR; refused when the "
                  "experiment, a model or a log changed since (their SHA-256)");
  sub->footer(
      "Writes DIR/result.yaml (values, std, 95% intervals, flags, costs, versions), DIR/result.h5 "
      "(trace, Jacobian, covariance, signals) and DIR/<model>_identified.xml, all with one run id, "
      "into DIR.partial (with checkpoint.yaml after every successful iteration), which replaces "
      "DIR once complete. Ctrl-C, SIGTERM or SIGHUP stops after the current iteration and writes "
      "the results of the last good iterate; a second one exits at once and leaves DIR as it was. "
      "Exit code 1 when the fit did not converge. Under `mpirun -n N` (or srun) the sequences are "
      "sharded across the ranks and rank 0 writes (docs/cluster.md).\n");
}

std::string Flags(const mjsysid::ParameterEstimate& p) {
  std::vector<std::string> f;
  if (p.at_lower) f.push_back("at lower bound");
  if (p.at_upper) f.push_back("at upper bound");
  if (!p.identifiable) f.push_back("UNIDENTIFIABLE");
  return Join(f);
}

// a number for a table cell in format ("-" for NaN: no sigma, too few samples)
std::string Number(double x, const char* format) {
  if (!std::isfinite(x)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), format, x);
  return buf;
}

// a % fit for a table cell ("-" for NaN: a constant channel or a failed simulation)
std::string Percent(double x) { return Number(x, "%.1f"); }

// per sequence the worst and the median channel's % fit (sysid/assess/metrics.h), at the start and
// at the estimate; fitted sequences first, then the held-out ones (`validation:`)
void PrintFitQuality(const mjsysid::io::FitResultFile& f) {
  if (f.sequences.empty() && f.validation.empty()) return;
  std::printf(
      "  %% fit per channel, start -> estimate (100 = exact, 0 = no better than the mean)\n");
  std::printf("  %-24s %-10s %8s  %-22s %s\n", "sequence", "role", "channels", "worst", "median");
  for (const std::vector<mjsysid::SequenceResult>* list : {&f.sequences, &f.validation}) {
    for (const mjsysid::SequenceResult& s : *list) {
      const mjsysid::FitSummary a = mjsysid::SummarizeFits(s.channel_fits, true);
      const mjsysid::FitSummary b = mjsysid::SummarizeFits(s.channel_fits, false);
      std::printf("  %-24s %-10s %8zu  %6s -> %-12s %6s -> %s\n", s.name.c_str(),
                  list == &f.sequences ? "fit" : "validation", s.channel_fits.size(),
                  Percent(a.worst).c_str(), Percent(b.worst).c_str(), Percent(a.median).c_str(),
                  Percent(b.median).c_str());
      // multiple shooting: the row above is the estimate in one piece; the segments' beside it
      if (s.simulated_one_piece.rows() > 0) {
        std::vector<mjsysid::ChannelFit> segments = s.channel_fits;
        for (mjsysid::ChannelFit& c : segments) c.fit_final = c.fit_segments;
        const mjsysid::FitSummary g = mjsysid::SummarizeFits(segments, false);
        std::printf("  %-24s %-10s %8s  %6s    %-12s %6s    %s\n", "", "(segments)", "", "",
                    Percent(g.worst).c_str(), "", Percent(g.median).c_str());
      }
    }
  }
  bool segmented = false;
  for (const mjsysid::SequenceResult& s : f.sequences) {
    segmented = segmented || s.simulated_one_piece.rows() > 0;
  }
  if (segmented) {
    std::printf(
        "  (fitted in segments: each row is the estimate simulated in one piece from the "
        "sequence's first state, what the identified model gives; (segments): each segment from "
        "its own fitted state, what the fit fitted)\n");
  }
}

// the residuals at the estimate per channel (sysid/assess/residual_diagnostics.h): every channel
// when there are few, else the ones that are not white; then what the intervals came from
void PrintResiduals(const mjsysid::io::FitResultFile& f) {
  if (f.residuals.empty()) return;
  constexpr size_t kAllChannelsUpTo = 12;
  int white = 0;
  for (const mjsysid::ResidualDiagnostics& d : f.residuals) white += d.white ? 1 : 0;
  const bool all = f.residuals.size() <= kAllChannelsUpTo;
  if (!all && white == static_cast<int>(f.residuals.size())) {
    std::printf("  residuals: all %zu channels white\n", f.residuals.size());
  } else {
    std::printf("  residuals at the estimate%s (white: no correlation beyond chance)\n",
                all ? "" : ", channels that are not white");
    std::printf("  %-24s %12s %10s %10s %8s %12s  %s\n", "channel", "rms", "rms/sigma", "bias/se",
                "lag-1", "corr. time", "white");
    for (const mjsysid::ResidualDiagnostics& d : f.residuals) {
      if (!all && d.white) continue;
      std::printf("  %-24s %12.3g %10s %10s %8s %12s  %s\n", d.channel.c_str(), d.rms,
                  Number(d.ratio, "%.3g").c_str(), Number(d.bias_units, "%.2g").c_str(),
                  Number(d.lag1, "%.2f").c_str(), Number(d.tau, "%.3g").c_str(),
                  d.white ? "yes" : "NO");
    }
    if (!all) {
      std::printf("  (%d of %zu channels white: result.yaml `residuals` lists every channel)\n",
                  white, f.residuals.size());
    }
  }
  std::vector<std::string> seen;  // sigma: auto, sensor by sensor
  std::string from_log;
  for (const mjsysid::ResidualDiagnostics& d : f.residuals) {
    const std::string sensor = d.channel.substr(0, d.channel.find('['));
    if (!d.sigma_from_log || std::find(seen.begin(), seen.end(), sensor) != seen.end()) continue;
    seen.push_back(sensor);
    from_log += (from_log.empty() ? "" : ", ") + sensor + " " + Number(d.sigma, "%.3g");
  }
  if (!from_log.empty()) {
    std::printf("  sigma estimated from the log (sigma: auto): %s\n", from_log.c_str());
  }
  if (f.interval_inflation > 1) std::printf("  intervals from %s\n", f.intervals_from.c_str());
  if (!f.timestep_check.empty()) std::printf("  timestep check: %s\n", f.timestep_check.c_str());
  if (!f.subset_start.empty()) std::printf("  subset start: %s\n", f.subset_start.c_str());
}

// multi-start: how many starts ended with each status (local_minimum: in another minimum than the
// best, sysid/run/multi_start.h), and per estimated value the range over the starts
void PrintStarts(const mjsysid::io::FitResultFile& f) {
  if (f.starts.size() < 2) return;
  std::vector<std::pair<std::string, int>> counts;  // in order of first appearance
  for (const mjsysid::StartResult& s : f.starts) {
    const bool failed = !s.error.empty() && s.status != mjsysid::FitStatus::kInterrupted;
    const std::string what = failed ? "failed" : mjsysid::FitStatusName(s.status);
    auto it =
        std::find_if(counts.begin(), counts.end(), [&](const auto& c) { return c.first == what; });
    if (it == counts.end()) {
      counts.emplace_back(what, 1);
    } else {
      ++it->second;
    }
  }
  std::string list;
  for (const auto& [what, n] : counts) {
    list += (list.empty() ? "" : ", ") + std::to_string(n) + " " + what;
  }
  std::printf("  %zu starts (%s); the result is start %d's (lowest cost)\n", f.starts.size(),
              list.c_str(), f.best_start);
  std::printf("  %-24s %14s %14s %12s\n", "spread over the starts", "min", "max", "(max-min)/|v|");
  for (const mjsysid::ParameterSpread& s : f.start_spread) {
    std::printf("  %-24s %14.6g %14.6g %12.3g\n", s.name.c_str(), s.min, s.max, s.relative);
  }
}

// prints one summary line and the estimates against the start (and the truth, for simulated
// data); verbose: also why the solver stopped, why the segments, what the reduced model left out
// (all three are in result.yaml)
void PrintEstimates(const mjsysid::io::FitResultFile& f, bool verbose) {
  if (f.iterations < 0 || !(f.initial_cost >= 0) || !(f.final_cost >= 0)) {
    // Ceres' summary when it could not evaluate the start (iterations and costs -1)
    std::printf("%s: %s: the solver stopped before its first iteration (%s), %.2f s\n",
                f.name.c_str(), f.status.c_str(), mjsysid::TerminationText(f.termination).c_str(),
                f.seconds);
  } else {
    std::printf("%s: %s after %d iterations, cost %.6g -> %.6g, %.2f s\n", f.name.c_str(),
                f.status.c_str(), f.iterations, f.initial_cost, f.final_cost, f.seconds);
  }
  if (verbose) {
    std::printf("  stopped: %s\n", mjsysid::TerminationText(f.termination).c_str());
    const std::string segments = mjsysid::SegmentReasonText(f.segment_reason);
    if (!segments.empty()) std::printf("  segments: %s\n", segments.c_str());
    const mjsysid::FitResult::Diagnostics::Reduction& reduction = f.diagnostics.reduction;
    if (reduction.recorded) {
      std::printf("  reduced model: %s\n", mjsysid::ReductionText(reduction).c_str());
    }
  }
  std::printf("  %-24s %14s %14s %14s %12s  %-29s %s\n", "parameter", "initial", "estimate",
              "truth", "std", "95% interval", "flags");
  for (const mjsysid::ParameterEstimate& p : f.parameters) {
    char truth[32] = "-", ci[64];
    if (p.truth) std::snprintf(truth, sizeof(truth), "%.6g", *p.truth);
    std::snprintf(ci, sizeof(ci), "[%.6g, %.6g]", p.ci95_low, p.ci95_high);
    std::printf("  %-24s %14.6g %14.8g %14s %12.3g  %-29s %s\n", p.name.c_str(), p.initial, p.value,
                truth, p.std_error, ci, Flags(p).c_str());
  }
  // quantities derived from the estimate (body_inertial: mass, centre of mass, principal moments)
  if (!f.derived.empty()) {
    std::printf("  %-24s %14s %14s %14s %12s  %-29s %s\n", "derived", "unit", "value", "truth",
                "std", "95% interval", "from");
  }
  for (const mjsysid::DerivedQuantity& d : f.derived) {
    char truth[32] = "-", ci[64];
    if (d.truth) std::snprintf(truth, sizeof(truth), "%.6g", *d.truth);
    std::snprintf(ci, sizeof(ci), "[%.6g, %.6g]", d.ci95_low, d.ci95_high);
    std::printf("  %-24s %14s %14.8g %14s %12.3g  %-29s %s\n", d.name.c_str(), d.unit.c_str(),
                d.value, truth, d.std_error, ci, d.derived_from.c_str());
  }
  for (const std::string& u : f.uncertainty.unidentifiable)
    std::printf("  unidentifiable: %s\n", u.c_str());
  if (!f.intervals_valid) {
    std::printf("  intervals NOT VALID: the status is %s, not converged (see the warnings)\n",
                f.status.c_str());
  }
  PrintFitQuality(f);
  PrintResiduals(f);
  PrintStarts(f);
  std::fflush(stdout);
}

// the experiment file of `sysid fit`: --resume DIR: the checkpoint's unless given
std::string ExperimentOf(const FitArgs& args) {
  namespace io = mjsysid::io;
  std::string experiment = args.experiment;
  if (!args.resume.empty()) {
    if (!args.out.empty() && !mjsysid::run::SamePath(args.out, args.resume)) {
      throw InputError("--out " + args.out + " and --resume " + args.resume +
                       " differ: a resumed fit writes into the folder it resumes");
    }
    if (experiment.empty()) {
      const std::optional<io::FitResultFile> cp = mjsysid::run::FindCheckpoint(args.resume);
      if (!cp) {
        throw InputError("--resume " + args.resume + ": nothing to resume: no checkpoint " +
                         mjsysid::run::StagingFolder(args.resume) +
                         "/checkpoint.yaml and no interrupted result in the folder");
      }
      experiment = cp->experiment;
    }
  } else if (experiment.empty()) {
    throw InputError("the experiment file is required (sysid fit EXP.yaml), except with --resume");
  }
  return experiment;
}

// on_problem: set by the MPI-sharded fit (RunFitSharded), else empty
int RunFitHere(const FitArgs& args,
               const std::function<void(mjsysid::Problem&, mjsysid::FitOptions*)>& on_problem) {
  namespace io = mjsysid::io;
  SetActivity("reading the experiment and its logs (before the memory estimate)");
  const io::ExperimentConfig config = io::LoadExperiment(ExperimentOf(args));
  mjsysid::run::FitRunOptions options;
  options.on_problem = on_problem;
  options.out_dir = args.resume.empty() ? args.out : args.resume;
  options.resume = !args.resume.empty();
  options.threads = args.threads;
  options.memory_limit_gb = args.memory_limit;
  // named in the message if the fit still runs out of memory (tools/sysid_main.cc)
  options.on_memory_estimate = [&args](const mjsysid::MemoryEstimate& e, long long limit) {
    if (args.verbose) {
      std::fprintf(stderr, "memory: estimated %s (%lld samples, %lld bytes per sample), limit %s\n",
                   mjsysid::FormatGB(e.bytes).c_str(), e.samples, e.per_sample_bytes,
                   limit > 0 ? mjsysid::FormatGB(limit).c_str() : "none");
    }
    SetActivity("the fit (estimated " + mjsysid::FormatGB(e.bytes) + ", limit " +
                (limit > 0 ? mjsysid::FormatGB(limit) : std::string("none")) + ")");
  };
  // the fit's progress as one table on stderr (sysid/run/fit_table.h)
  mjsysid::run::FitTable table(
      [](const std::string& line) {
        std::fprintf(stderr, "%s\n", line.c_str());
        std::fflush(stderr);
      },
      args.verbose);
  options.observer = &table;
  options.verbose = !args.quiet;
  options.interrupt = &g_interrupted;
  options.force = args.force;
  options.on_estimates = [&table, &args](const mjsysid::io::FitResultFile& f) {
    table.Flush();  // the last iteration's row before the estimates
    PrintEstimates(f, args.verbose);
  };
  options.starts = args.starts;
  options.seed = args.seed;
  CatchStopSignals(true);
  const mjsysid::run::FitRunOutcome out = mjsysid::run::RunFit(config, options);
  CatchStopSignals(false);
  table.Flush();
  const io::FitResultFile& f = out.file;
  // the data's warnings were printed before the fit (FitRunOutcome::printed_warnings); those that
  // recur per sequence once, with a count
  const std::vector<std::string> after(f.warnings.begin() + out.printed_warnings, f.warnings.end());
  for (const std::string& w : io::GroupedWarningLines(after))
    std::fprintf(stderr, "sysid fit: warning: %s\n", w.c_str());
  std::printf("  wrote %s/{result.yaml, result.h5", out.out_dir.c_str());
  for (const auto& [model, file] : f.identified_models) std::printf(", %s", file.c_str());
  std::printf("} (run %s)\n", f.run_id.c_str());
  if (out.file.interrupted)
    std::fprintf(stderr, "sysid fit: interrupted: results of the last good iterate written\n");
  return out.exit_code;
}

#ifdef MJSYSID_WITH_MPI
// `mpirun -n N sysid fit` (sysid/mpi/distributed_fit.h): rank 0 fits and writes, the other ranks
// evaluate their share of the sequences; every rank reads and checks the input first, and rank 0
// reports the first rank's failure (exit 2)
int RunFitSharded(const FitArgs& args) {
  namespace mpi = mjsysid::mpi;
  if (mpi::Rank() > 0) {
    std::string failure;
    std::optional<mjsysid::io::ExperimentConfig> config;
    try {
      config = mjsysid::io::LoadExperiment(ExperimentOf(args));
    } catch (const std::exception& e) {
      failure = e.what();
    }
    return mpi::ServeFit(config ? &*config : nullptr, args.threads, failure);
  }
  mpi::ShardedResiduals shards;
  shards.SetInterrupt(&g_interrupted);  // a worker's stop signal stops the fit too
  int code = 0;
  try {
    // every start of --starts a whole sharded fit, one after another
    code = RunFitHere(args, [&](mjsysid::Problem& problem, mjsysid::FitOptions* /*options*/) {
      shards.NextProblem();
      problem.DistributeResiduals(&shards);
    });
  } catch (const mpi::RankError& e) {
    shards.Abandon(e.what());
    throw InputError(e.what());
  } catch (const std::exception& e) {
    shards.Abandon(e.what());
    throw;
  }
  shards.Finish();
  if (std::getenv("MJSYSID_MPI_STATS")) {
    // traffic and time of the evaluations (tools/bench/mpi_bench.sh reads this line)
    const mpi::ShardStats& st = shards.stats();
    std::fprintf(stderr,
                 "mpi stats: ranks %d evaluations %lld jacobian_evaluations %lld bytes %lld "
                 "seconds_mpi %.6f seconds_own_share %.6f\n",
                 mpi::Size(), st.evaluations, st.jacobian_evaluations, st.bytes, st.seconds_mpi,
                 st.seconds_own_share);
  }
  return code;
}
#endif

int RunFit(const FitArgs& args) {
#ifdef MJSYSID_WITH_MPI
  // under a launcher even with one rank: the same arithmetic (one tree) with any rank count
  if (mjsysid::mpi::Active()) return RunFitSharded(args);
#endif
  return RunFitHere(args, {});
}

}  // namespace

Command AddFit(CLI::App* app) { return AddSubcommand(app, "fit", DeclareFit, RunFit); }

}  // namespace mjsysid::cli
