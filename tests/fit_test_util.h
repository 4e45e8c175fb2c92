// Helpers of tests that run fits (sysid/problem.h): the estimate of a named variable.
#pragma once

#include <stdexcept>
#include <string>

#include "sysid/types.h"

namespace mjsysid::test {

// the estimate named `name` of a fit result; throws when there is none
inline const ParameterEstimate& Estimate(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters) {
    if (p.name == name) return p;
  }
  throw std::runtime_error("no estimate " + name);
}

}  // namespace mjsysid::test
