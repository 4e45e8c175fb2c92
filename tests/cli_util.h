// Running the real `sysid` binary (MJSYSID_SYSID_BIN, set by tests/CMakeLists.txt) or another
// command from a test: its exit code and everything it printed.
#pragma once

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

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

// what a run printed on each stream, apart
struct CliStreams {
  int code = -1;    // exit code; -1 when killed by a signal (also by the timeout)
  std::string out;  // stdout
  std::string err;  // stderr
};

// runs `sysid <args>` (quoted by the caller) killed after `timeout_s` seconds: exit code, stdout
// and stderr apart (stderr goes through a file in the temp folder named by the pid); `shell`
// runs first in the same shell (e.g. "ulimit -v 300000; ")
inline CliStreams SysidStreams(const std::string& args, int timeout_s = 120,
                               const std::string& shell = "") {
  const std::string err_path = (std::filesystem::temp_directory_path() /
                                ("mjsysid_stderr_" + std::to_string(::getpid()) + ".txt"))
                                   .string();
  const std::string cmd = shell + "timeout -s KILL " + std::to_string(timeout_s) + " " +
                          std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>" + err_path;
  FILE* pipe = popen(cmd.c_str(), "r");
  CliStreams r;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) r.out.append(buf, n);
  const int status = pclose(pipe);
  if (WIFEXITED(status) && WEXITSTATUS(status) < 128) r.code = WEXITSTATUS(status);
  std::ifstream in(err_path, std::ios::binary);
  r.err.assign(std::istreambuf_iterator<char>(in), {});
  std::filesystem::remove(err_path);
  return r;
}

// how many times `needle` occurs in `hay` (overlapping occurrences counted)
inline int CountOf(const std::string& hay, const std::string& needle) {
  int n = 0;
  for (size_t at = hay.find(needle); at != std::string::npos; at = hay.find(needle, at + 1)) ++n;
  return n;
}

// runs `sysid fit <experiment> --out <out> --quiet` and kills it (SIGKILL) once its first
// checkpoint is on disk (its output discarded; <out>.partial/checkpoint.yaml, complete: with its
// input_hashes; polled every 0.2 ms, for at most 60 s): true when it was killed there, false when
// it ended first
inline bool FitKilledAtCheckpoint(const std::string& experiment, const std::string& out) {
  const std::string bin = MJSYSID_SYSID_BIN;
  const std::string cp = out + ".partial/checkpoint.yaml";
  const pid_t pid = fork();
  if (pid == 0) {
    const int null = open("/dev/null", O_WRONLY);  // its warnings are not the test's output
    if (null >= 0) {
      dup2(null, STDOUT_FILENO);
      dup2(null, STDERR_FILENO);
    }
    execl(bin.c_str(), bin.c_str(), "fit", experiment.c_str(), "--out", out.c_str(), "--quiet",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  auto has_checkpoint = [&cp] {
    std::ifstream in(cp, std::ios::binary);
    const std::string text(std::istreambuf_iterator<char>(in), {});
    return text.find("\ninput_hashes:") != std::string::npos;
  };
  for (int i = 0; i < 300000 && !has_checkpoint(); ++i) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  kill(pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFSIGNALED(status) && has_checkpoint();
}

}  // namespace mjsysid::test
