// Two whole fits compared bit for bit (tests of options that must not change a fit: fold reuse,
// folds ahead): status, iterations, termination, the covariance's Jacobian, final cost, warnings,
// every estimate and standard error (tolerance 0), and the simulator steps where asked.
#pragma once

#include <gtest/gtest.h>

#include <cstring>

#include "sysid/types.h"

namespace mjsysid::test {

// a and b the same doubles, bit for bit
inline ::testing::AssertionResult SameBits(double a, double b) {
  if (std::memcmp(&a, &b, sizeof(double)) == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << a << " vs " << b << " (" << a - b << ")";
}

// steps: the simulator steps compared too
inline void ExpectSameFit(const FitResult& a, const FitResult& b, bool steps) {
  EXPECT_EQ(a.outcome, b.outcome);
  EXPECT_EQ(a.converged, b.converged);
  EXPECT_EQ(a.iterations, b.iterations);
  if (steps) {
    EXPECT_EQ(a.diagnostics.simulation_steps, b.diagnostics.simulation_steps);
  }
  EXPECT_EQ(a.termination.kind, b.termination.kind);
  EXPECT_EQ(TerminationText(a.termination), TerminationText(b.termination));
  EXPECT_EQ(a.diagnostics.covariance_jacobian_iteration,
            b.diagnostics.covariance_jacobian_iteration);
  EXPECT_TRUE(SameBits(a.final_cost, b.final_cost));
  EXPECT_EQ(a.warnings, b.warnings);
  ASSERT_EQ(a.parameters.size(), b.parameters.size());
  for (size_t i = 0; i < a.parameters.size(); ++i) {
    EXPECT_TRUE(SameBits(a.parameters[i].value, b.parameters[i].value)) << a.parameters[i].name;
    EXPECT_TRUE(SameBits(a.parameters[i].std_error, b.parameters[i].std_error))
        << a.parameters[i].name;
  }
}

}  // namespace mjsysid::test
