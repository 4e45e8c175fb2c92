// sysid design EXP.yaml: an excitation for the experiment's parameters (sysid/design/design.h),
// written as controls.csv and design.yaml (sysid/design/design_write.h).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "sysid/design/design.h"
#include "sysid/design/design_write.h"
#include "sysid/io/experiment.h"
#include "tools/report/design_page.h"
#include "tools/sysid_cli.h"

namespace mjsysid::cli {
namespace {

struct DesignArgs {
  std::string experiment;
  std::string out;  // "" = <experiment folder>/designs/<name>
  std::string criterion = "d_optimal";
  std::string contacts = "allow";
  design::DesignOptions options;
};

// the --help page of `sysid design`
void DeclareDesign(CLI::App* sub, DesignArgs* args) {
  design::DesignOptions& o = args->options;
  sub->description(
      "Design an excitation for the experiment's parameters: per actuator a Fourier series under "
      "a smooth start and end, searched for the most information (the core's Jacobians of the "
      "fitted sensors, weighted by their sigmas) within the amplitudes of simulate.excitation, "
      "the joint ranges and the other constraints; writes DIR/controls.csv and DIR/design.yaml "
      "(docs/design.md)");
  sub->add_option("experiment", args->experiment,
                  "YAML experiment file (docs/experiment-schema.md)")
      ->required();
  sub->add_option("--out", args->out,
                  "output folder (default: designs/<name> beside the experiment file)");
  sub->add_option("--duration", o.duration,
                  "seconds of excitation (default: simulate.steps x the model's timestep)")
      ->check(PositiveFiniteNumber());
  sub->add_option("--criterion", args->criterion,
                  "d_optimal (log det of the relative information), worst_relative_std or "
                  "condition_number")
      ->check(CLI::IsMember({"d_optimal", "worst_relative_std", "condition_number"}))
      ->capture_default_str();
  sub->add_option("--base-frequency", o.basis.base_frequency,
                  "Hz; the harmonics are multiples of it")
      ->check(PositiveFiniteNumber())
      ->capture_default_str();
  sub->add_option("--harmonics", o.basis.harmonics, "harmonics per actuator, 1 to 1000")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  sub->add_option("--ramp", o.basis.ramp, "seconds of smooth start and of smooth end")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  sub->add_option("--range-margin", o.range_margin,
                  "share of each limited joint's range kept free at both ends, in [0, 0.5)")
      ->check(CLI::Range(0.0, 0.499))
      ->capture_default_str();
  sub->add_option("--max-joint-speed", o.max_joint_speed,
                  "largest |qvel| of hinge (rad/s) and slide (m/s) joints (default: none)")
      ->check(PositiveFiniteNumber());
  sub->add_option("--contacts", args->contacts,
                  "allow (e.g. legged robots) or forbid contacts during the excitation")
      ->check(CLI::IsMember({"allow", "forbid"}))
      ->capture_default_str();
  sub->add_option("--evaluations", o.evaluations, "candidates tried, 1 to 100000")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  sub->add_option("--time-limit", o.time_limit, "seconds of search, at most 604800")
      ->check(CLI::Range(1e-3, 604800.0))
      ->capture_default_str();
  sub->add_option("--seed", o.seed, "random seed of the search")->capture_default_str();
  sub->add_flag("--at-truth", o.at_truth,
                "compute the information at simulate.truth (synthetic studies) instead of the "
                "parameters' initial values");
  sub->add_option("--threads", o.threads, "simulation threads, 0 = all cores, at most 256")
      ->check(ThreadCountValidator());
  sub->footer(
      "The design is simulated and checked against every constraint before it is written. "
      "Play DIR/controls.csv on the robot, or simulate it with `simulate.excitation: {type: "
      "file, path: DIR/controls.csv}`.\n");
}

std::string Pct(double relative) {
  if (!std::isfinite(relative)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g%%", 100 * relative);
  return buf;
}

int RunDesign(const DesignArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  const io::ExperimentConfig config = io::LoadExperiment(args.experiment);
  io::CheckModelFilesExist(config);
  design::DesignOptions options = args.options;
  design::ParseCriterion(args.criterion, &options.criterion);
  options.contacts = args.contacts == "allow";
  const std::string dir =
      args.out.empty() ? (std::filesystem::path(config.base_dir) / "designs" / config.name).string()
                       : args.out;
  try {
    design::CheckDesignOutputs(dir, config);
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }

  // the search, with a progress line every tenth of the budget
  SetActivity("the excitation design");
  std::fprintf(stderr, "  designing   %s: %d candidates at most, %.0f s at most\n",
               config.name.c_str(), options.evaluations, options.time_limit);
  int next = 0;
  design::DesignResult r;
  try {
    r = design::DesignExcitation(config, options, [&](const design::DesignProgress& p) {
      if (p.evaluation < next && p.evaluation != p.evaluations) return;
      next = p.evaluation + std::max(1, p.evaluations / 10);
      std::fprintf(stderr, "  candidate   %d/%d  best %s %.6g  worst relative std %s  %.1f s\n",
                   p.evaluation, p.evaluations, args.criterion.c_str(), p.best,
                   Pct(p.best_worst_relative_std).c_str(), p.seconds);
    });
  } catch (const design::DesignError& e) {
    throw InputError(e.what());
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  const auto [csv, yaml] = design::WriteDesign(r, dir, config);
  const std::string html = report::WriteDesignPage(r, config.source_file, dir);

  // summary: the predicted relative standard errors, current excitation beside the design
  std::printf("designed %s (%s)\n", config.name.c_str(), args.experiment.c_str());
  std::printf(
      "  excitation  %d steps (%.3g s), %s, %d candidates (%d met the constraints) in "
      "%.1f s\n",
      r.steps, (r.steps - 1) * r.timestep, design::CriterionName(r.options.criterion),
      r.evaluations, r.feasible, r.seconds);
  std::printf("  %-24s %14s %14s\n", "relative std", "current", "design");
  for (size_t j = 0; j < r.parameters.size(); ++j) {
    const auto k = static_cast<Eigen::Index>(j);
    std::printf("  %-24s %14s %14s\n", r.parameters[j].c_str(),
                Pct(r.current.info.relative_std[k]).c_str(),
                Pct(r.design.info.relative_std[k]).c_str());
  }
  std::printf("  %-24s %14s %14s\n", "worst", Pct(r.current.info.worst_relative_std).c_str(),
              Pct(r.design.info.worst_relative_std).c_str());
  if (r.time_limited) {
    std::printf(
        "  note        the time limit (%.0f s) ended the search after %d of %d candidates: "
        "another run may find another design (raise --time-limit to repeat it exactly)\n",
        r.options.time_limit, r.evaluations, r.options.evaluations);
  }
  if (!r.current.violation.empty()) {
    std::printf("  note        the current excitation breaks a constraint: %s\n",
                r.current.violation.c_str());
  }
  std::printf("  wrote       %s\n              %s\n              %s in %.1f s\n", csv.c_str(),
              yaml.c_str(), html.c_str(), Seconds(start));
  return kExitOk;
}

}  // namespace

Command AddDesign(CLI::App* app) { return AddSubcommand(app, "design", DeclareDesign, RunDesign); }

}  // namespace mjsysid::cli
