// The helpers shared by the subcommands of sysid (tools/sysid_cli.h).
#include "tools/sysid_cli.h"

#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "core/thread_pool.h"
#include "sysid/io/log.h"
#include "sysid/run/output_folder.h"

namespace mjsysid::cli {

namespace fs = std::filesystem;

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string Join(const std::vector<std::string>& items, const char* sep) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : sep) + s;
  return out;
}

void Appendf(std::string* out, const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  if (n > 0) {
    std::vector<char> buf(static_cast<size_t>(n) + 1);
    std::vsnprintf(buf.data(), buf.size(), format, args);
    out->append(buf.data(), static_cast<size_t>(n));
  }
  va_end(args);
}

std::string Short(const std::string& exact) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", std::stod(exact));
  return buf;
}

std::string ModelSizes(const mjModel& m) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), "nq=%d nv=%d nu=%d nsensor=%d, timestep %g s",
                static_cast<int>(m.nq), static_cast<int>(m.nv), static_cast<int>(m.nu),
                static_cast<int>(m.nsensor), m.opt.timestep);
  return buf;
}

CLI::Validator WholeNumberAtLeast(long long min) {
  return CLI::Validator(
      [min](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0' || errno == ERANGE || v < min) {
          return "expected a whole number >= " + std::to_string(min) + ", got '" +
                 text.substr(0, 40) + (text.size() > 40 ? "...'" : "'");
        }
        return "";
      },
      "INT>=" + std::to_string(min));
}

namespace {
std::string g_activity;
}  // namespace

void SetActivity(const std::string& activity) { g_activity = activity; }
const std::string& Activity() { return g_activity; }

CLI::Validator ThreadCountValidator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0' || errno == ERANGE) {
          return "expected 0 (all cores) or a whole number from 1 to " +
                 std::to_string(kMaxThreads) + ", got '" + text.substr(0, 40) +
                 (text.size() > 40 ? "...'" : "'");
        }
        return ThreadRequestError(v);
      },
      "0.." + std::to_string(kMaxThreads));
}

CLI::Validator PositiveFiniteNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !std::isfinite(v) || !(v > 0)) {
          return "expected a finite number > 0, got '" + text.substr(0, 40) +
                 (text.size() > 40 ? "...'" : "'");
        }
        return "";
      },
      "NUMBER>0");
}

CLI::Validator FiniteNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !std::isfinite(v)) {
          return "expected a finite number, got '" + text.substr(0, 40) +
                 (text.size() > 40 ? "...'" : "'");
        }
        return "";
      },
      "NUMBER");
}

namespace {

// who wrote a log, from its `generator` attribute ("mjsysid VERSION simulate"), for messages:
// "sysid import (mjsysid 0.9.0)"; for a simulated log also the experiment it simulated
std::string WrittenBy(const mjsysid::io::Log& log) {
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
bool MayReplace(const mjsysid::io::Log& log, const LogWriter& writer) {
  if (writer.command != "simulate") return true;  // import: any mjsysid log (--out is explicit)
  const auto gen = log.attributes.find("generator");
  const auto exp = log.attributes.find("experiment");
  const std::string suffix = " simulate";
  return gen != log.attributes.end() && gen->second.rfind("mjsysid ", 0) == 0 &&
         gen->second.size() > suffix.size() &&
         gen->second.compare(gen->second.size() - suffix.size(), suffix.size(), suffix) == 0 &&
         exp != log.attributes.end() && mjsysid::run::SamePath(exp->second, writer.experiment);
}

}  // namespace

void CheckLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force,
                    const LogWriter& writer) {
  const std::string label = writer.label.empty() ? "--out " + out : writer.label;
  mjsysid::run::CheckOutputFile(out, inputs, "--out");
  std::error_code ec;
  if (!fs::exists(out, ec)) return;
  if (!fs::is_regular_file(out, ec)) {
    throw mjsysid::run::OutputError(label +
                                    ": exists and is not a file (a folder?); not replaced, "
                                    "--force or not (hint: choose another output file)");
  }
  if (force) return;
  const std::string hint = " (hint: --force replaces it, or --out LOG.h5 writes elsewhere)";
  mjsysid::io::Log log;
  try {
    log = mjsysid::io::ReadLog(out);
  } catch (const mjsysid::io::LogError& e) {
    throw mjsysid::run::OutputError(label + ": exists and is not an mjsysid log; not replaced" +
                                    hint);
  }
  if (!MayReplace(log, writer)) {
    throw mjsysid::run::OutputError(label + ": holds a log written by " + WrittenBy(log) +
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
      throw InputError(out + ": cannot create the folder " + parent.string() + ": " + ec.message());
    }
  }
}

}  // namespace mjsysid::cli
