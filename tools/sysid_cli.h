// The pieces shared by the subcommands of the sysid command line (tools/sysid_main.cc): exit
// codes, the bad-input error, a registered subcommand, text helpers and option validators.
// Each subcommand file (tools/sysid_<subcommand>.cc) defines one AddX(app) declared below.
#pragma once

#include <mujoco/mujoco.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/run/log_output.h"

namespace mjsysid::cli {

constexpr int kExitOk = 0;
constexpr int kExitFailed = 1;
constexpr int kExitBadInput = 2;

constexpr int kExitOutOfMemory = 5;

const char* const kExitCodesFooter =
    "Exit codes: 0 success, 1 the run failed (simulation or MuJoCo error), 2 bad input (command "
    "line, experiment file, model, parameters or data files, a fit over its memory limit); `fit` "
    "writes its results and exits 1 not_converged, local_minimum or interrupted, 3 model_mismatch, "
    "4 jacobian_unreliable, did_not_move or solver_failed; 5 out of memory.";

// what the subcommand is doing, named when it runs out of memory (std::bad_alloc, exit 5;
// tools/sysid_main.cc); "" until set
void SetActivity(const std::string& activity);
const std::string& Activity();

// a bad input found by the command line itself (exit code 2)
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// a registered subcommand: its CLI11 app and what runs it
struct Command {
  CLI::App* app;
  std::function<int()> run;
};

// Adds the subcommand `name` to app: declare(sub, args) writes its --help page (description,
// arguments into a new Args, footer), the exit codes end the footer, and the returned Command
// runs run(*args).
template <typename Args>
Command AddSubcommand(CLI::App* app, const std::string& name, void (*declare)(CLI::App*, Args*),
                      int (*run)(const Args&)) {
  auto args = std::make_shared<Args>();
  CLI::App* sub = app->add_subcommand(name);
  sub->footer("");  // not the parent's, which CLI11 copies into a new subcommand
  declare(sub, args.get());
  sub->footer(sub->get_footer() + kExitCodesFooter);
  return {sub, [args, run] { return run(*args); }};
}

// seconds since start
double Seconds(std::chrono::steady_clock::time_point start);

// the items joined with sep
std::string Join(const std::vector<std::string>& items, const char* sep = ", ");

// printf into a string
__attribute__((format(printf, 2, 3))) void Appendf(std::string* out, const char* format, ...);

// a number written with %.17g, shown with 6 digits
std::string Short(const std::string& exact);

// a short description of a model's sizes
std::string ModelSizes(const mjModel& m);

// an option value that must be a whole number >= min (CLI11's own range checks print the
// largest double in full: 309 digits)
CLI::Validator WholeNumberAtLeast(long long min);

// a thread count: 0 (all cores) or 1..kMaxThreads (core/thread_pool.h, one rule everywhere)
CLI::Validator ThreadCountValidator();

// an option value that must be a finite number
CLI::Validator FiniteNumber();

// an option value that must be a finite number > 0
CLI::Validator PositiveFiniteNumber();

using run::LogWriter;
using run::PrepareLogOutput;

// the subcommands: each declares its arguments on `app` and returns what runs it
Command AddSimulate(CLI::App* app);  // tools/sysid_simulate.cc
Command AddFit(CLI::App* app);       // tools/sysid_fit.cc
Command AddReport(CLI::App* app);    // tools/sysid_report.cc
Command AddImport(CLI::App* app);    // tools/sysid_import.cc
Command AddCheck(CLI::App* app);     // tools/sysid_check.cc
Command AddRollout(CLI::App* app);   // tools/sysid_rollout.cc
Command AddDesign(CLI::App* app);    // tools/sysid_design.cc

}  // namespace mjsysid::cli
