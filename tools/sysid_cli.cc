// The helpers shared by the subcommands of sysid (tools/sysid_cli.h).
#include "tools/sysid_cli.h"

#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <system_error>
#include <vector>

#include "core/thread_pool.h"
#include "sysid/io/log.h"
#include "sysid/run/output_folder.h"

namespace mjsysid::cli {

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

}  // namespace mjsysid::cli
