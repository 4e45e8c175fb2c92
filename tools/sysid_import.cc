// sysid import MODEL.xml CSV... --out LOG.h5: CSV logs, ROS bags or MCAP files into an HDF5 log.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "core/mujoco_env.h"
#include "core/text.h"
#include "mjsysid/version.h"
#include "sysid/io/csv.h"
#include "sysid/io/log.h"
#include "sysid/io/plain_name.h"
#include "sysid/io/time_base.h"
#include "sysid/io/warnings.h"
#include "tools/sysid_cli.h"

namespace mjsysid::cli {
namespace {

namespace fs = std::filesystem;

struct ImportArgs {
  std::string model;
  std::vector<std::string> csv;
  std::string out;
  std::string sensor_time = "pre";
  bool force = false;           // replace an --out that is not an mjsysid log
  std::string mapping;          // ROS bags / MCAP: topic -> actuators, sensors, joints (YAML)
  std::string time_scale_text;  // as given, for the bag importer ("": not given)
};

// the --help page of `sysid import`: description, arguments (into args) and footer
void DeclareImport(CLI::App* sub, ImportArgs* args) {
  sub->description(
      "Convert CSV logs (header row of names), ROS bags or MCAP files into an HDF5 log that `fit` "
      "reads");
  sub->add_option("model", args->model, "MJCF model the logs were recorded on")->required();
  sub->add_option("csv", args->csv,
                  "CSV files, ROS bags or MCAP files, one sequence each (named after the file); "
                  "[NAME=]A.csv+B.csv+...: one sequence from several CSV files, each with its "
                  "own time column (controls in one, sensors at their own rates)")
      ->required();
  sub->add_option("--out", args->out, "HDF5 log to write (atomically)")->required();
  sub->add_option("--sensor-time", args->sensor_time,
                  "pre: sensors read before the step (y_k at x_k); post: after it")
      ->check(CLI::IsMember({"pre", "post"}))
      ->capture_default_str();
  sub->add_option("--time-scale", args->time_scale_text,
                  "multiply the time column(s) by FACTOR to get seconds: 0.001 for milliseconds, "
                  "1e-9 for nanoseconds (finite, > 0)")
      ->type_name("FACTOR");
  sub->add_flag("--force", args->force,
                "replace an existing --out file that is not an mjsysid log (an mjsysid log is "
                "replaced without it); never an input or a folder");
  sub->add_option("--mapping", args->mapping,
                  "ROS bags (.bag, ROS 2 folders, .db3) and MCAP files: YAML mapping of topics "
                  "to actuators, sensors and joints (docs/cli.md)");
  sub->footer(
      "CSV columns: time, one per actuator (its name), one per sensor component (NAME or NAME[i]), "
      "optional qpos[i], qvel[i], act[i]; any order. Checked against the model before writing. ROS "
      "bags and MCAP files (with --mapping) are read by the Python package mjsysid (rosbags) in "
      "the project venv.\n");
}

// a ROS 1 bag, a ROS 2 storage file, an MCAP file or a ROS 2 bag folder (metadata.yaml)
bool IsBag(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  std::error_code ec;
  return ext == ".bag" || ext == ".db3" || ext == ".mcap" ||
         (fs::is_directory(path, ec) && fs::exists(fs::path(path) / "metadata.yaml", ec));
}

// the Python that imports bags: $MJSYSID_PYTHON, else $MJSYSID_VENV/bin/python, else the venv
// the build used (MJSYSID_DEFAULT_VENV, the source tree's .venv)
std::string BagPython() {
  if (const char* py = std::getenv("MJSYSID_PYTHON"); py && *py) return py;
  const char* venv = std::getenv("MJSYSID_VENV");
  return (fs::path(venv && *venv ? venv : MJSYSID_DEFAULT_VENV) / "bin" / "python").string();
}

// runs argv (argv[0] a path) and returns its exit code; 127 when it cannot be started
int RunChild(const std::vector<std::string>& argv, bool quiet) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    if (quiet) {
      const int null = open("/dev/null", O_WRONLY);
      if (null >= 0) {
        dup2(null, STDOUT_FILENO);
        dup2(null, STDERR_FILENO);
      }
    }
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// ROS bags / MCAP files: `python -m mjsysid.bags` (python/mjsysid/bags.py) writes the log
int RunImportBags(const ImportArgs& args) {
  if (args.mapping.empty()) {
    throw InputError(
        "ROS bags and MCAP files need --mapping MAP.yaml (topic -> actuators, "
        "sensors; JointState by joint name; docs/cli.md)");
  }
  for (const std::string& path : args.csv) {
    if (!IsBag(path)) {
      throw InputError(path + ": CSV files and bags cannot be imported together");
    }
  }
  const std::string python = BagPython();
  if (access(python.c_str(), X_OK) != 0) {
    throw InputError("importing bags needs the Python package mjsysid: no Python at " + python +
                     " (run tools/bootstrap.sh, or set MJSYSID_PYTHON to a python that has "
                     "mjsysid, rosbags and PyYAML)");
  }
  if (RunChild({python, "-c", "import mjsysid.bags"}, /*quiet=*/true) != 0) {
    throw InputError(python +
                     " cannot import mjsysid.bags (the Python package mjsysid with rosbags and "
                     "PyYAML: run tools/bootstrap.sh, or pip install . and -r "
                     "tools/deps/requirements.txt into that environment)");
  }
  std::vector<std::string> inputs = {args.model, args.mapping};
  inputs.insert(inputs.end(), args.csv.begin(), args.csv.end());
  PrepareLogOutput(args.out, inputs, args.force, LogWriter{"import", "", ""});
  std::vector<std::string> argv = {
      python,   "-m",        "mjsysid.bags", args.model,      "--out",
      args.out, "--mapping", args.mapping,   "--sensor-time", args.sensor_time};
  if (!args.time_scale_text.empty()) {
    argv.insert(argv.end(), {"--time-scale", args.time_scale_text});
  }
  argv.insert(argv.end(), args.csv.begin(), args.csv.end());
  return RunChild(argv, /*quiet=*/false);
}

// --time-scale FACTOR: a finite number > 0 (parsed whole), else InputError
double TimeScale(const std::string& text) {
  if (text.empty()) return 1;
  double factor = 0;
  size_t used = 0;
  try {
    factor = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || !std::isfinite(factor) || !(factor > 0)) {
    throw InputError(
        "--time-scale: expected a finite number > 0 (the factor from the logged "
        "time unit to seconds: 0.001 for milliseconds, 1e-9 for nanoseconds), got '" +
        text + "'");
  }
  return factor;
}

// CSV files (one sequence each, named after the file) into one validated HDF5 log
int RunImport(const ImportArgs& args) {
  namespace io = mjsysid::io;
  const double time_scale = TimeScale(args.time_scale_text);
  if (std::any_of(args.csv.begin(), args.csv.end(), IsBag)) return RunImportBags(args);
  mjsysid::ModelPtr m = mjsysid::LoadModel(args.model);
  io::Log log;
  log.sensor_time = args.sensor_time;
  log.attributes["generator"] = std::string("mjsysid ") + MJSYSID_VERSION + " import";
  log.attributes["model"] = fs::absolute(args.model).string();
  // each argument one sequence: a file, or [NAME=]A.csv+B.csv+... (one sequence from several
  // files at their own rates, io::ImportCsvFiles; named NAME, else after the first file)
  std::vector<std::string> files, warnings;
  for (const std::string& arg : args.csv) {
    std::error_code ec;
    std::string name, list = arg;
    std::vector<std::string> paths;
    if (fs::exists(arg, ec)) {
      paths = {arg};
    } else {
      const size_t eq = arg.find('=');
      if (eq != std::string::npos) {
        name = arg.substr(0, eq);
        list = arg.substr(eq + 1);
      }
      for (size_t at = 0;;) {
        const size_t plus = list.find('+', at);
        paths.push_back(list.substr(at, plus == std::string::npos ? plus : plus - at));
        if (plus == std::string::npos) break;
        at = plus + 1;
      }
    }
    if (name.empty()) name = fs::path(paths[0]).stem().string();
    if (const std::string why = io::PlainNameProblem(name); !why.empty()) {
      throw InputError(arg + ": the sequence name " + mjsysid::Quote(name) +
                       " is not a plain name: " + why + " (hint: name it NAME=" + paths[0] +
                       " with " + io::kPlainNameRule + ")");
    }
    // the sequence checked alone against the model, its messages and warnings naming its CSV
    // file(s), where the problem is (not the --out log, which does not exist yet)
    io::Log one;
    one.sensor_time = log.sensor_time;
    one.attributes = log.attributes;
    one.sequences.push_back(io::ImportCsvFiles(paths, *m, name));
    if (time_scale != 1) io::ScaleTime(time_scale, arg, &one.sequences.back());
    std::string csv_files;
    for (const std::string& p : paths) csv_files += (csv_files.empty() ? "" : "+") + p;
    io::ValidateLogAgainstModel(one, *m, csv_files, &warnings);
    log.sequences.push_back(std::move(one.sequences[0]));
    files.insert(files.end(), paths.begin(), paths.end());
  }
  // the log as a whole (sequence names unique across the files)
  io::ValidateLogAgainstModel(log, *m, args.out);
  for (const std::string& w : io::GroupedWarningLines(warnings))
    std::fprintf(stderr, "sysid import: warning: %s\n", w.c_str());
  std::vector<std::string> inputs = {args.model};
  inputs.insert(inputs.end(), files.begin(), files.end());
  PrepareLogOutput(args.out, inputs, args.force, LogWriter{"import", "", ""});
  io::WriteLog(args.out, log);
  std::printf("imported %zu sequence(s) into %s\n", log.sequences.size(), args.out.c_str());
  for (const io::Sequence& s : log.sequences) {
    std::printf("  %-16s %6zu samples, sensors: %s", s.name.c_str(),
                static_cast<size_t>(s.time.size()), Join(s.sensor_names).c_str());
    if (s.ctrl_time.size())
      std::printf("; controls at their own %zu times", static_cast<size_t>(s.ctrl_time.size()));
    std::printf("\n");
  }
  return kExitOk;
}

}  // namespace

Command AddImport(CLI::App* app) { return AddSubcommand(app, "import", DeclareImport, RunImport); }

}  // namespace mjsysid::cli
