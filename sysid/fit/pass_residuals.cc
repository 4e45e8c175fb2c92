// Stage 9 of a fit pass (sysid/fit/pass.h): the residuals at the estimate, channel by channel, and
// what they mean for the intervals.
#include <cmath>
#include <string>

#include "core/text.h"
#include "sysid/assess/residual_diagnostics.h"
#include "sysid/fit/pass.h"

namespace mjsysid {

// 9. Whiteness, bias, ratio to sigma and correlation time of every fitted channel's residuals
// (sysid/assess/residual_diagnostics.h), one warning per channel that fails. The covariance from
// the Jacobian assumes independent residuals; residuals correlated over tau samples carry the
// information of n / tau (measured on robot-style logs, tests/sysid/assess/
// correlated_coverage_test.cc: the truth 4-9 standard errors off without the factor), so when a
// channel is not white the covariance is multiplied by the largest such tau. Then the derived
// inertials from the final covariance.
void FitPass::Residuals() {
  result_.residuals = DiagnoseFitResiduals(result_.sequences, options_);
  for (const ResidualDiagnostics& d : result_.residuals) {
    const std::string sentence = ResidualSentence(d);
    if (!sentence.empty()) result_.warnings.push_back("residuals: " + sentence);
  }
  std::string channel;
  const double factor = CorrelationInflation(result_.residuals, &channel);
  result_.interval_inflation = 1;
  result_.intervals_from = "white residuals: s^2 (J^T J)^-1";
  if (evaluated_ && factor > 1) {
    result_.interval_inflation = factor;
    result_.intervals_from = "correlated residuals: s^2 (J^T J)^-1 x " + FormatDigits(factor, 3) +
                             ", the correlation time (samples) of '" + channel + "'";
    WidenIntervals(Eigen::VectorXd::Constant(np_ + nm_, std::sqrt(factor)));
    result_.warnings.push_back(
        "the residuals are correlated (over " + FormatDigits(factor, 3) + " samples in '" +
        channel + "'), so the data hold fewer independent samples than rows: the intervals are " +
        "widened x" + FormatDigits(std::sqrt(factor), 3) +
        " (docs/real-logs.md, \"Residual diagnostics\")");
  }
  DerivedQuantities();
}

}  // namespace mjsysid
