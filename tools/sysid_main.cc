// sysid: the mjsysid command line (docs/cli.md).
//
// Each subcommand is a function RunX(const XArgs&) and one registration function AddX(app) that
// declares its arguments (mostly through cli::AddSubcommand and a DeclareX) and returns the
// subcommand with a closure calling RunX; main() parses, runs the chosen one and maps exceptions
// to exit codes:
//   0 success
//   1 the run failed (a simulation failed, MuJoCo raised an error)
//   2 bad input (command line, experiment file, model, parameters, data files)
//   `sysid fit` also 1, 3, 4 for a fit whose status is not converged (run::ExitCodeOf)
//   5 out of memory (std::bad_alloc anywhere; a fit over its memory estimate's limit is 2), or a
//     thread that could not start (the machine's limits on processes or memory)
//
// The subcommands live in one file each (tools/sysid_<subcommand>.cc), their shared helpers in
// tools/sysid_cli.h; this file is the CLI11 app, the dispatch and the exit codes.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <new>
#include <string>
#include <system_error>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "mjsysid/version.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/output_folder.h"
#include "sysid/solve/quiet_libraries.h"
#include "tools/sysid_cli.h"
#ifdef MJSYSID_WITH_MPI
#include "sysid/mpi/distributed_fit.h"
#endif

namespace {

namespace cli = mjsysid::cli;

// errors -> exit codes

// runs a subcommand, printing any error as "sysid NAME: message" and mapping it to an exit code
int RunGuarded(const std::string& name, const std::function<int()>& run) {
  auto fail = [&name](const char* what, int code) {
    std::fprintf(stderr, "sysid %s: %s\n", name.c_str(), what);
    return code;
  };
  try {
    return run();
  } catch (const std::bad_alloc&) {
    // one line, whatever the allocation was (no memory left to say more)
    const std::string& activity = cli::Activity();
    std::fprintf(stderr,
                 "sysid %s: out of memory (std::bad_alloc) during %s; reduce the data or raise "
                 "the machine's memory (docs/cli.md, \"Threads and memory\")\n",
                 name.c_str(), activity.empty() ? "the run" : activity.c_str());
    return cli::kExitOutOfMemory;
  } catch (const std::system_error& e) {
    // a thread that cannot start (EAGAIN: the limits on processes or address space, whose
    // stacks count, are reached): out of resources like memory, not a failed run
    if (e.code() != std::errc::resource_unavailable_try_again)
      return fail(e.what(), cli::kExitFailed);
    const std::string& activity = cli::Activity();
    std::fprintf(stderr,
                 "sysid %s: could not start a thread (%s) during %s: the machine's limits on "
                 "processes or memory are reached (ulimit -u, ulimit -v); use fewer threads "
                 "(--threads, solver.threads) or raise the limits (docs/cli.md, \"Threads and "
                 "memory\")\n",
                 name.c_str(), e.code().message().c_str(),
                 activity.empty() ? "the run" : activity.c_str());
    return cli::kExitOutOfMemory;
  } catch (const mjsysid::run::MemoryLimitError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::io::ConfigError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::io::LogError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::ModelLoadError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::ParameterError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const cli::InputError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::run::OutputError& e) {
    return fail(e.what(), cli::kExitBadInput);
  } catch (const mjsysid::SimulationError& e) {
    return fail(e.what(), cli::kExitFailed);
  } catch (const std::exception& e) {
    return fail(e.what(), cli::kExitFailed);
  }
}

}  // namespace

int main(int argc, char** argv) {
  mjsysid::InstallMujocoHandlers();
  // no third-party line on the terminal: glog FATAL only, SuiteSparse's printf into the fit's
  // warnings (sysid/solve/quiet_libraries.h)
  mjsysid::QuietThirdPartyLibraries(argv[0]);
#ifdef MJSYSID_WITH_MPI
  // only when started by an MPI launcher (mpirun, srun); ended by std::atexit at exit
  mjsysid::mpi::Initialize(&argc, &argv);
  std::atexit(mjsysid::mpi::Finalize);
#endif
  CLI::App app{
      "mjsysid: system identification for MuJoCo models.\n"
      "Run `sysid SUBCOMMAND --help` for the arguments of a subcommand."};
  app.set_version_flag("--version", std::string("mjsysid ") + MJSYSID_VERSION + " (MuJoCo " +
                                        mjsysid::MujocoVersion() + ")");
  app.require_subcommand(1);
  app.footer(std::string("Examples:\n"
                         "  sysid simulate experiments/pendulum.yaml\n"
                         "  sysid fit experiments/pendulum.yaml --out results/pendulum\n"
                         "  sysid report results/pendulum\n"
                         "  sysid check experiments/pendulum.yaml\n"
                         "  sysid rollout models/pendulum.xml --steps 500\n"
                         "  sysid design experiments/pendulum.yaml --out designs/pendulum\n") +
             cli::kExitCodesFooter);

  // subcommands, in the order --help lists them
  std::vector<cli::Command> commands;
  commands.push_back(cli::AddSimulate(&app));
  commands.push_back(cli::AddFit(&app));
  commands.push_back(cli::AddReport(&app));
  commands.push_back(cli::AddImport(&app));
  commands.push_back(cli::AddCheck(&app));
  commands.push_back(cli::AddRollout(&app));
  commands.push_back(cli::AddDesign(&app));

  // an unknown subcommand is named (CLI11 would say "A subcommand is required")
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const cli::Command& c : commands) names.push_back(c.app->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      std::string shown(argv[1]);
      if (shown.size() > 40) shown = shown.substr(0, 40) + "...";
      std::fprintf(stderr, "sysid: unknown subcommand '%s'; the subcommands: %s (sysid --help)\n",
                   shown.c_str(), cli::Join(names).c_str());
      return cli::kExitBadInput;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    // one line, "sysid SUBCOMMAND: message", as every other error
    const bool sub =
        argc > 1 && std::any_of(commands.begin(), commands.end(), [&](const cli::Command& c) {
          return c.app->get_name() == argv[1];
        });
    std::fprintf(stderr, "sysid%s%s: %s (hint: sysid%s%s --help)\n", sub ? " " : "",
                 sub ? argv[1] : "", e.what(), sub ? " " : "", sub ? argv[1] : "");
    return cli::kExitBadInput;
  }
  for (const cli::Command& c : commands) {
    if (!*c.app) continue;
#ifdef MJSYSID_WITH_MPI
    // under mpirun `fit` and `simulate` are sharded: every other subcommand runs on rank 0 alone
    // (one writer of its outputs)
    if (mjsysid::mpi::Rank() > 0 && c.app->get_name() != "fit" && c.app->get_name() != "simulate") {
      return cli::kExitOk;
    }
#endif
    const int code = RunGuarded(c.app->get_name(), c.run);
#ifndef __SANITIZE_ADDRESS__
    // HDF5 1.10 crashes in its exit handler (SIGSEGV in H5F__close_cb) when a write failed (full
    // disk, file size limit) and left a file it could not close: a failed run ends, its output
    // flushed, without the libraries' exit handlers (measured: exit 139 instead of 1 or 2).
    // Sanitizer builds keep them, for LeakSanitizer.
    if (code != cli::kExitOk) {
#ifdef MJSYSID_WITH_MPI
      mjsysid::mpi::Finalize();  // the other ranks left the fit: MPI ends cleanly
#endif
      std::fflush(nullptr);
      std::_Exit(code);
    }
#endif
    return code;
  }
  return cli::kExitBadInput;
}
