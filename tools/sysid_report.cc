// sysid report DIR: plot a fit's results into DIR/report.html.
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include "sysid/io/atomic_file.h"
#include "sysid/io/result.h"
#include "sysid/run/input_hashes.h"
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
  sub->add_option("dir", args->dir,
                  "output folder of `sysid fit` (result.yaml, result.h5; the path of its "
                  "result.yaml or result.h5 stands for the folder)")
      ->required();
  sub->add_flag("--no-video", args->no_video,
                "no motion clip (by default the first sequence is re-simulated at the initial "
                "and the fitted values and rendered offscreen, side by side)");
  sub->footer(
      "Writes DIR/report.html (self-contained: no network), DIR/cost.png, DIR/parameters.png, "
      "DIR/seq_<name>.png and DIR/motion.webp (the initial and fitted simulation, animated; needs "
      "the experiment file and its logs, and OSMesa; without them the page says why). The clip "
      "is refused (exit 2) when the experiment, a model or a log changed since the fit (their "
      "SHA-256 in result.yaml's input_hashes): fit again, or use --no-video.\n");
}

// the motion clip re-simulates the fit's inputs: refuses ones changed since the fit (exit 2);
// warns when the result records none (written by an older mjsysid). Inputs that are gone are left
// to the clip, whose page says it could not read them.
void CheckInputsOfTheClip(const std::string& dir, const mjsysid::io::FitResultFile& result) {
  if (result.input_hashes.empty()) {
    std::fprintf(stderr,
                 "sysid report: warning: %s/result.yaml records no input hashes (written by an "
                 "older mjsysid): the motion clip re-simulates the experiment's files as they are "
                 "now, unchecked\n",
                 dir.c_str());
    return;
  }
  std::vector<mjsysid::io::InputHash> now = mjsysid::run::HashAgain(result.input_hashes);
  for (size_t i = 0; i < now.size(); ++i) {
    if (now[i].sha256.empty()) now[i].sha256 = result.input_hashes[i].sha256;  // gone: the clip's
  }
  const std::vector<std::string> changes = mjsysid::run::InputChanges(result.input_hashes, now);
  if (changes.empty()) return;
  std::string list;
  for (const std::string& c : changes) list += (list.empty() ? "" : "; ") + c;
  throw InputError(dir + ": " + list + " since the fit (run " + result.run_id +
                   "): the motion clip would re-simulate other inputs than the fit's (hint: fit "
                   "again, sysid fit " +
                   result.experiment + " --out " + dir +
                   ", or report without the clip: sysid report --no-video " + dir + ")");
}

// the folder to report: DIR itself; a fit's own result.yaml or result.h5 stands for its folder
std::string ReportFolder(const std::string& given) {
  std::error_code ec;
  const fs::path p(given);
  if (fs::is_regular_file(p, ec) &&
      (p.filename() == "result.yaml" || p.filename() == "result.h5")) {
    return p.has_parent_path() ? p.parent_path().string() : ".";
  }
  return given;
}

// a folder to report is a folder: another file, or nothing, is bad input saying so
void CheckReportFolder(const std::string& dir) {
  std::error_code ec;
  if (fs::is_directory(dir, ec)) return;
  if (fs::exists(dir, ec)) {
    throw InputError(dir +
                     ": is a file, not a folder: sysid report takes the output folder of `sysid "
                     "fit` (the folder holding result.yaml and result.h5)");
  }
  throw InputError(dir +
                   ": no such folder (sysid report takes the output folder of `sysid fit`, which "
                   "writes result.yaml and result.h5 into it)");
}

int RunReport(const ReportArgs& given) {
  ReportArgs args = given;
  args.dir = ReportFolder(given.dir);
  // no fit may replace the folder while the report writes into it (a folder whose parent is not
  // writable has no lock, and no fit can replace it); the pages are no inputs
  std::optional<mjsysid::run::FolderLock> lock;
  try {
    lock.emplace(args.dir, "sysid report");
  } catch (const mjsysid::io::FileError&) {
  }
  // after the lock: a folder a running fit has not published yet is "in use", not missing
  CheckReportFolder(args.dir);
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
    const mjsysid::io::FitResultFile result = mjsysid::io::ReadResult(args.dir);
    if (options.motion.enabled) CheckInputsOfTheClip(args.dir, result);
    mjsysid::report::WriteReport(result, args.dir, options, &summary);
  } catch (const mjsysid::io::ResultError& e) {
    throw InputError(e.what());
  }
  std::printf("%s", summary.c_str());
  return kExitOk;
}

}  // namespace

Command AddReport(CLI::App* app) { return AddSubcommand(app, "report", DeclareReport, RunReport); }

}  // namespace mjsysid::cli
