// The progress lines of a fit between its iteration lines (FitOptions::verbose), so that a long
// log is never silent: the start (rollouts and Jacobians at the initial values, per model), the
// uncertainty step (the Jacobian at the estimate) and the interval check. One line each, on
// stderr, in the iteration lines' format (ProgressCallback, sysid/cost_functions.h):
//   "start  TEXT  S s", S the seconds since Problem::Fit began.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace mjsysid {

inline void PrintFitProgress(const char* stage, const std::string& text,
                             std::chrono::steady_clock::time_point fit_start) {
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - fit_start).count();
  std::fprintf(stderr, "%-5s  %-66s  %7.2f s\n", stage, text.c_str(), seconds);
  std::fflush(stderr);
}

}  // namespace mjsysid
