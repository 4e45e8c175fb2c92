// Third-party libraries that would print on the terminal: Ceres logs through glog, and SuiteSparse
// (CHOLMOD under Ceres' sparse solvers, SPQR under the uncertainty step) prints its errors with
// printf, e.g. "CHOLMOD error: problem too large. file: ... line: ..." on stdout (issue 32: no raw
// third-party line may reach the user). The fit reports what happened itself (its status,
// termination and warnings), so:
// - glog logs only FATAL (to stderr, before an abort) and writes no file; left alone when the
//   process had initialized glog itself;
// - SuiteSparse's printf is captured, line by line, into a process-wide list that a fit takes
//   into its warnings (FitPass::Decide).
// The CLI (tools/sysid_main.cc) and the Python module (python/src/module.cc) call
// QuietThirdPartyLibraries once at start-up; more calls do nothing.
#pragma once

#include <string>
#include <vector>

namespace mjsysid {

// program: glog's program name
void QuietThirdPartyLibraries(const char* program);

// the SuiteSparse lines captured since the last call (at most the first 100, each at most 500
// characters), in order; thread-safe. With several fits at once (starts) a line goes to the first
// fit that asks.
std::vector<std::string> TakeThirdPartyMessages();

}  // namespace mjsysid
