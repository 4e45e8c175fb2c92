// Running the real `sysid` binary from a test (MJSYSID_SYSID_BIN, set by tests/CMakeLists.txt):
// its exit code and everything it printed.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace mjsysid::test {

struct CliRun {
  int code;            // exit code; -1 when it did not exit normally
  std::string output;  // stdout and stderr
};

// runs `sysid <args>` through the shell (args quoted by the caller)
inline CliRun Sysid(const std::string& args) {
  const std::string cmd = std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) out.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// runs `sysid <args>` and returns what it printed on stderr alone (stdout discarded), in order
inline CliRun SysidStderr(const std::string& args) {
  const std::string cmd = std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>&1 >/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string err;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) err.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, err};
}

}  // namespace mjsysid::test
