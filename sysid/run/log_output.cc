// The rule on replacing an existing log output: sysid/run/log_output.h.
#include "sysid/run/log_output.h"

#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/run/output_folder.h"

namespace mjsysid::run {

namespace fs = std::filesystem;

namespace {

// who wrote a log, from its `generator` attribute ("mjsysid VERSION simulate"), for messages:
// "sysid import (mjsysid 0.9.0)"; for a simulated log also the experiment it simulated
std::string WrittenBy(const io::Log& log) {
  const auto gen = log.attributes.find("generator");
  if (gen == log.attributes.end()) return "a program that does not say (no generator attribute)";
  const std::string& g = gen->second;
  const size_t space = g.rfind(' ');
  if (g.rfind("mjsysid ", 0) != 0 || space == std::string::npos || space < 8) {
    return "'" + g + "' (its generator attribute)";
  }
  const std::string command = g.substr(space + 1);
  std::string by = "sysid " + command + " (" + g.substr(0, space) + ")";
  if (command == "simulate") {
    const auto exp = log.attributes.find("experiment");
    by +=
        " of " + (exp == log.attributes.end() ? std::string("an unnamed experiment") : exp->second);
  }
  return by;
}

// true when `writer` may replace the existing mjsysid log `log` without --force
bool MayReplace(const io::Log& log, const LogWriter& writer) {
  if (writer.command != "simulate") return true;  // import: any mjsysid log (--out is explicit)
  const auto gen = log.attributes.find("generator");
  const auto exp = log.attributes.find("experiment");
  const std::string suffix = " simulate";
  return gen != log.attributes.end() && gen->second.rfind("mjsysid ", 0) == 0 &&
         gen->second.size() > suffix.size() &&
         gen->second.compare(gen->second.size() - suffix.size(), suffix.size(), suffix) == 0 &&
         exp != log.attributes.end() && SamePath(exp->second, writer.experiment);
}

}  // namespace

void CheckLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force,
                    const LogWriter& writer) {
  const std::string label = writer.label.empty() ? writer.option + " " + out : writer.label;
  CheckOutputFile(out, inputs, writer.option);
  std::error_code ec;
  if (!fs::exists(out, ec)) return;
  if (!fs::is_regular_file(out, ec)) {
    throw OutputError(label + ": exists and is not a file (a folder?); not replaced, even with " +
                      writer.force_hint.substr(0, writer.force_hint.find(' ')) +
                      " (hint: choose another output file)");
  }
  if (force) return;
  const std::string hint = " (hint: " + writer.force_hint + ")";
  io::Log log;
  try {
    log = io::ReadLog(out);
  } catch (const io::LogError& e) {
    throw OutputError(label + ": exists and is not an mjsysid log; not replaced" + hint);
  }
  if (!MayReplace(log, writer)) {
    throw OutputError(label + ": holds a log written by " + WrittenBy(log) +
                      ", not by sysid simulate of this experiment; not replaced, "
                      "nothing simulated" +
                      hint);
  }
}

void PrepareLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force,
                      const LogWriter& writer) {
  CheckLogOutput(out, inputs, force, writer);
  std::error_code ec;
  const fs::path parent = fs::path(out).parent_path();
  if (!parent.empty()) {
    fs::create_directories(parent, ec);
    if (ec) {
      throw OutputError(out + ": cannot create the folder " + parent.string() + ": " +
                        ec.message());
    }
  }
}

}  // namespace mjsysid::run
