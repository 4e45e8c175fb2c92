// Restarting a prepared fit from another point: the global stage's rounds
// (sysid/fit/global_stage.cc) and auto's one-piece comparison (sysid/fit/policy.cc) run further
// passes from a result's estimate, and the user's starts come back however they end.
#pragma once

#include <vector>

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// the physical estimates of a result's first np parameters (np <= r.parameters.size())
std::vector<double> EstimateOf(const FitResult& r, size_t np);

// the parameters' starts set to x (physical values, one per parameter); off_bounds: a value on a
// bound moved inside by 1e-3 of the bound's magnitude (of the range, or 1, at a bound of 0), so
// that a solve from there is not a start on the bound
void StartAt(PreparedFit* fit, const std::vector<double>& x, bool off_bounds);

// Keeps the parameters' starts of a prepared fit and puts them back when it goes out of scope (a
// throw included)
class KeepStarts {
 public:
  explicit KeepStarts(PreparedFit* fit);
  ~KeepStarts();
  KeepStarts(const KeepStarts&) = delete;
  KeepStarts& operator=(const KeepStarts&) = delete;
  // the starts kept (physical values)
  const std::vector<double>& starts() const { return starts_; }

 private:
  PreparedFit* fit_;
  std::vector<double> starts_;
};

}  // namespace mjsysid
