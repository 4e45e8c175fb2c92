#include "sysid/residual_model.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {

// robust loss: rho and rho' at s = e^2, then rhat = sign(e) sqrt(rho) and
// d rhat / d e = rho'(s) 2e / (2 rhat) = rho'(s) e / rhat
double RobustResidual(LossType loss, double c, double e, double* derivative) {
  const double s = e * e;
  double rho = s, rho1 = 1;
  switch (loss) {
    case LossType::kNone:
      *derivative = 1;
      return e;
    case LossType::kHuber:
      if (s > c * c) {
        const double r = std::sqrt(s);
        rho = 2 * c * r - c * c;
        rho1 = c / r;
      }
      break;
    case LossType::kCauchy:
      rho = c * c * std::log1p(s / (c * c));
      rho1 = 1 / (1 + s / (c * c));
      break;
  }
  // at e = 0 every loss is quadratic: rhat = e, slope 1
  if (s == 0) {
    *derivative = 1;
    return 0;
  }
  const double rhat = std::copysign(std::sqrt(rho), e);
  *derivative = rho1 * e / rhat;
  return rhat;
}

// each term fitted (its value in m) or fixed at its initial value
MeasurementTerms CurrentTerms(const MeasurementTerms& initial, const TermIndex& index,
                              const double* m) {
  MeasurementTerms t;
  t.delay = index.delay >= 0 && m ? m[index.delay] : initial.delay;
  t.gain = index.gain >= 0 && m ? m[index.gain] : initial.gain;
  t.bias = index.bias >= 0 && m ? m[index.bias] : initial.bias;
  return t;
}

DelayedSample::DelayedSample(double k, int T, double delay, double dt) : dt_(dt) {
  // no delay at a whole step: sample k itself, the backward slope
  if (delay == 0 && k == std::floor(k)) {
    const int i = std::min(static_cast<int>(k), T - 1);
    i0_ = i;
    lo_ = i > 0 ? i - 1 : i;
    hi_ = i;
    return;
  }
  // between samples i0 and i0 + 1 at fraction a; held outside the signal
  const double q = k - delay / dt;
  const int i0 = static_cast<int>(std::floor(q));
  if (i0 < 0) {
    i0_ = 0;
    return;
  }
  if (i0 >= T - 1) {
    i0_ = T - 1;
    return;
  }
  interpolated_ = true;
  i0_ = i0;
  a_ = q - i0;
  lo_ = i0;
  hi_ = i0 + 1;
}

// e, the loss, then the chain rule through e = weight * (gain * y + bias - measured)
SensorResidual EvaluateSensorResidual(const DelayedSample& at, Signal simulated, double measured,
                                      double weight, const MeasurementTerms& terms, LossType loss,
                                      double loss_scale) {
  SensorResidual r;
  r.simulated = at.Value(simulated);
  const double e = weight * (terms.Apply(r.simulated) - measured);
  double de = 1;
  r.value = RobustResidual(loss, loss_scale, e, &de);
  const double f = de * weight;  // d r / d (gain * y + bias)
  r.d_simulated = f * terms.gain;
  r.d_delay = r.d_simulated * at.DerivativeByDelay(simulated);
  r.d_gain = f * r.simulated;
  r.d_bias = f;
  return r;
}

// column j of DyDp restricted to the channel's rows is the signal {dydp + column * ncol + j,
// ns * ncol}
void InterpolatedRow(const DelayedSample& at, const double* dydp, int ns, int column, int ncol,
                     double* row) {
  const Eigen::Index stride = static_cast<Eigen::Index>(ns) * ncol;
  for (int j = 0; j < ncol; ++j) {
    row[j] = at.Value({dydp + static_cast<Eigen::Index>(column) * ncol + j, stride});
  }
}

double PriorResidual(double p, double mean, double sigma, double dp_dz, double* derivative) {
  *derivative = dp_dz / sigma;
  return (p - mean) / sigma;
}

}  // namespace mjsysid
