#include "sysid/solve/quiet_libraries.h"

#include <SuiteSparse_config.h>
#include <glog/logging.h>

#include <cstdarg>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

namespace mjsysid {
namespace {

constexpr size_t kMaxLines = 100;
constexpr size_t kMaxLineLength = 500;

std::mutex& Mutex() {
  static std::mutex m;
  return m;
}

// the captured lines and the line being printed (CHOLMOD prints one line in several calls)
std::vector<std::string>& Lines() {
  static std::vector<std::string> lines;
  return lines;
}
std::string& Partial() {
  static std::string partial;
  return partial;
}

// the line so far as a captured line (under the mutex)
void EndLine() {
  std::string& partial = Partial();
  if (partial.find_first_not_of(" \t") != std::string::npos && Lines().size() < kMaxLines) {
    Lines().push_back(partial.substr(0, kMaxLineLength));
  }
  partial.clear();
}

// SuiteSparse's printf: formatted into the captured lines instead of stdout
int CapturePrintf(const char* format, ...) {
  char buffer[1024];
  va_list args;
  va_start(args, format);
  const int n = std::vsnprintf(buffer, sizeof(buffer), format, args);
  va_end(args);
  if (n < 0) return n;
  std::lock_guard<std::mutex> lock(Mutex());
  for (const char* c = buffer; *c; ++c) {
    if (*c == '\n') {
      EndLine();
    } else if (Partial().size() < kMaxLineLength) {
      Partial() += *c;
    }
  }
  return n;
}

}  // namespace

void QuietThirdPartyLibraries(const char* program) {
  static std::once_flag once;
  std::call_once(once, [program] {
    if (!google::IsGoogleLoggingInitialized()) {
      FLAGS_logtostderr = true;
      FLAGS_minloglevel = google::GLOG_FATAL;
      google::InitGoogleLogging(program);
    }
    SuiteSparse_config.printf_func = CapturePrintf;
  });
}

std::vector<std::string> TakeThirdPartyMessages() {
  std::lock_guard<std::mutex> lock(Mutex());
  EndLine();  // a last line without its newline
  std::vector<std::string> lines;
  lines.swap(Lines());
  return lines;
}

}  // namespace mjsysid
