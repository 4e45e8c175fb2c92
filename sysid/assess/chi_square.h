// Chi-square quantiles and the test that one fit's cost lies above another's by more than the
// noise explains (multi-start local minima, sysid/run/multi_start.h; the global stage,
// sysid/fit/global_stage.h). Header-only arithmetic, no dependencies.
#pragma once

namespace mjsysid {

// the chi-square quantile with dof degrees of freedom at standard normal z (Wilson-Hilferty);
// 0 when dof <= 0
double Chi2Quantile(double dof, double z);

// Two fits of one cost function (0.5 |r|^2) near their minima: `higher` lies above `lower` by
// more than the noise explains when 2 (higher - lower) / s2 exceeds the chi-square quantile with
// np degrees of freedom (np >= 1) at a one-sided false-alarm rate of 1e-3. s2: the residual
// variance at `lower` (not positive or not finite: 1, weighted residuals).
bool AboveByMoreThanNoise(double higher, double lower, double s2, int np);

}  // namespace mjsysid
