// Running the real `sysid` binary (MJSYSID_SYSID_BIN, set by tests/CMakeLists.txt) or another
// command from a test: its exit code and everything it printed.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace mjsysid::test {

struct CliRun {
  int code;            // exit code; -1 when it did not exit normally
  std::string output;  // stdout and stderr
};

// runs `cmd` through the shell as written (its own redirections): the exit code and its stdout
inline CliRun RunShell(const std::string& cmd) {
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) out.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// runs `cmd` through the shell: the exit code and what it printed (stdout and stderr)
inline CliRun Shell(const std::string& cmd) { return RunShell(cmd + " 2>&1"); }

// runs `sysid <args>` through the shell (args quoted by the caller)
inline CliRun Sysid(const std::string& args) {
  return Shell(std::string(MJSYSID_SYSID_BIN) + " " + args);
}

// runs `sysid <args>` and returns what it printed on stderr alone (stdout discarded), in order
inline CliRun SysidStderr(const std::string& args) {
  return RunShell(std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>&1 >/dev/null");
}

}  // namespace mjsysid::test
