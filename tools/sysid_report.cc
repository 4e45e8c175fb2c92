// sysid report DIR: plot a fit's results into DIR/report.html.
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <system_error>

#include "sysid/io/atomic_file.h"
#include "sysid/run/output_folder.h"
#include "tools/report/report.h"
#include "tools/sysid_cli.h"

namespace mjsysid::cli {
namespace {

namespace fs = std::filesystem;

struct ReportArgs {
  std::string dir;
  bool no_video = false;
};

// the --help page of `sysid report`: description, arguments (into args) and footer
void DeclareReport(CLI::App* sub, ReportArgs* args) {
  sub->description("Plot a fit's results: measured vs simulated signals, parameters, cost trace");
  sub->add_option("dir", args->dir, "output folder of `sysid fit` (result.yaml, result.h5)")
      ->required();
  sub->add_flag("--no-video", args->no_video,
                "no motion clip (by default the first sequence is re-simulated at the initial "
                "and the fitted values and rendered offscreen, side by side)");
  sub->footer(
      "Writes DIR/report.html (self-contained: no network), DIR/cost.png, DIR/parameters.png, "
      "DIR/seq_<name>.png and DIR/motion.webp (the initial and fitted simulation, animated; needs "
      "the experiment file and its logs, and OSMesa; without them the page says why).\n");
}

int RunReport(const ReportArgs& args) {
  // no fit may replace the folder while the report writes into it (a folder whose parent is not
  // writable has no lock, and no fit can replace it); the pages are no inputs
  std::optional<mjsysid::run::FolderLock> lock;
  try {
    lock.emplace(args.dir, "sysid report");
  } catch (const mjsysid::io::FileError&) {
  }
  std::error_code ec;
  if (!fs::is_directory(args.dir, ec)) {
    throw InputError(args.dir +
                     ": no such folder (a fit writes result.yaml and result.h5 into its "
                     "output folder)");
  }
  const fs::path dir(args.dir);
  for (const char* page : {"report.html", "cost.png", "parameters.png", "motion.webp"}) {
    mjsysid::run::CheckOutputFile((dir / page).string(),
                                  {(dir / "result.yaml").string(), (dir / "result.h5").string()},
                                  "report");
  }
  std::string summary;
  try {
    mjsysid::report::ReportOptions options;
    options.motion.enabled = !args.no_video;
    options.motion.progress = [](const std::string& line) {
      std::fprintf(stderr, "%s\n", line.c_str());
    };
    mjsysid::report::WriteReport(args.dir, options, &summary);
  } catch (const mjsysid::io::ResultError& e) {
    throw InputError(e.what());
  }
  std::printf("%s", summary.c_str());
  return kExitOk;
}

}  // namespace

Command AddReport(CLI::App* app) { return AddSubcommand(app, "report", DeclareReport, RunReport); }

}  // namespace mjsysid::cli
