// Restarting a prepared fit from another point (sysid/fit/restart.h).
#include "sysid/fit/restart.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {
namespace {

// v moved off a bound it lies on (restart.h, StartAt)
double OffBounds(const FitParameter& p, double v) {
  const auto step = [](double bound, double other) {
    if (bound != 0) return 1e-3 * std::abs(bound);
    return 1e-3 * (std::isfinite(other) ? std::abs(other - bound) : 1.0);
  };
  if (OnBound(v, p.lower, true)) v = p.lower + step(p.lower, p.upper);
  if (OnBound(v, p.upper, false)) v = p.upper - step(p.upper, p.lower);
  return std::clamp(v, p.lower, p.upper);
}

}  // namespace

std::vector<double> EstimateOf(const FitResult& r, size_t np) {
  std::vector<double> x(np);
  for (size_t g = 0; g < np; ++g) x[g] = r.parameters[g].value;
  return x;
}

void StartAt(PreparedFit* fit, const std::vector<double>& x, bool off_bounds) {
  for (size_t g = 0; g < fit->params.size(); ++g) {
    fit->params[g].initial = off_bounds ? OffBounds(fit->params[g], x[g]) : x[g];
  }
}

KeepStarts::KeepStarts(PreparedFit* fit) : fit_(fit) {
  for (const FitParameter& p : fit->params) starts_.push_back(p.initial);
}

KeepStarts::~KeepStarts() {
  for (size_t g = 0; g < starts_.size(); ++g) fit_->params[g].initial = starts_[g];
}

}  // namespace mjsysid
