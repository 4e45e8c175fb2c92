// The residual model of a fit: the arithmetic that turns simulated sensor samples, and their
// Jacobian rows from the core, into weighted robust residuals and residual Jacobian rows. No
// MuJoCo and no Ceres here: unit-tested on hand-made signals
// (tests/sysid/solve/residual_model_test.cc).
//
// Model (sysid/problem.h). For sample k of a segment of T samples and one fitted sensor column
// (a Channel) with measurement terms (delay, gain, bias) and weight w = 1/sigma:
//   y   = y_sim(t_k - delay)            linear interpolation between samples (DelayedSample)
//   e   = w * (gain * y + bias - y_meas_k)
//   r   = rho_hat(e)                    rho_hat^2 = rho(e^2), sign of e (RobustResidual)
// Derivatives: d r / d y, d r / d delay, d r / d gain, d r / d bias (SensorResidual). The residual
// Jacobian row with respect to the core's columns (parameters p, then tangent x_0 directions) is
// d r / d y times the Jacobian rows dY/dp read at t_k - delay (InterpolatedRow); chaining it to
// the optimiser's variables (log/scale transforms, the state manifold) is the cost function's job
// (sysid/solve/cost_functions.h). Gaussian priors: r = (p - mean) / sigma (PriorResidual).
//
// Units: delay in seconds, dt the model timestep in seconds, everything else in the sensor's
// units (e) or in the weighted residual's units (r, loss scale).
//
// Failure: none is reported; non-finite inputs give non-finite outputs, which the caller checks.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace mjsysid {

// the robust loss applied to each scalar weighted residual e (FitOptions::loss): none rho(s) = s,
// Huber rho(s) = s for s <= c^2 else 2 c sqrt(s) - c^2, Cauchy rho(s) = c^2 log(1 + s / c^2)
enum class LossType { kNone, kHuber, kCauchy };

// Returns rhat = sign(e) sqrt(rho(e^2)) for the loss with scale c > 0 (weighted residual units),
// so that rhat^2 is the robust cost of e, and d rhat / d e in *derivative (1 at e = 0). Inline,
// like the rest of a residual row's arithmetic below: the cost functions run it for every
// measured cell at every evaluation.
inline double RobustResidual(LossType loss, double c, double e, double* derivative) {
  // robust loss: rho and rho' at s = e^2, then rhat = sign(e) sqrt(rho) and
  // d rhat / d e = rho'(s) 2e / (2 rhat) = rho'(s) e / rhat
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

// measured = gain * simulated(t - delay) + bias: the measurement terms of one sensor
struct MeasurementTerms {
  double delay = 0;  // s, >= 0 (a sensor that reports late)
  double gain = 1;
  double bias = 0;  // in the sensor's units

  // the measurement predicted from a simulated value read at t - delay
  double Apply(double simulated) const { return gain * simulated + bias; }
};

// where the fitted terms of one sensor sit in the vector m of fitted measurement terms
struct TermIndex {
  int delay = -1, gain = -1, bias = -1;  // index into m; -1: fixed at its initial value
};

// the terms at the fitted values m (nullptr: every term at its initial value)
MeasurementTerms CurrentTerms(const MeasurementTerms& initial, const TermIndex& index,
                              const double* m);

// A sampled signal read with a stride: sample i is data[i * stride]. Column c of a row-major
// T x n matrix M is {M.data() + c, n}.
struct Signal {
  const double* data = nullptr;
  Eigen::Index stride = 1;

  double operator[](Eigen::Index i) const { return data[i * stride]; }
};

// Where a measured sample at position k (in steps of dt from the signal's sample 0; a whole
// number for a sample on the simulation grid, any real >= 0 for a log at its own times) of a
// signal of T samples spaced dt, delayed by `delay` seconds, is read: y(t_k - delay), linear
// between the two samples around q = k - delay / dt; held at sample 0 before the start (q < 0)
// and at sample T - 1 past the end. The derivative by the delay is the slope of that
// interpolation, -(s[i0 + 1] - s[i0]) / dt, 0 where held; at delay 0 and a whole k it is the
// backward slope -(s[k] - s[k - 1]) / dt (0 at k = 0): one-sided, the forward one would read the
// future. Kinks at every q that is an integer (one per timestep of delay). The same weights read
// the Jacobian rows (InterpolatedRow), so an off-grid sample's row is interpolated like its value.
class DelayedSample {
 public:
  DelayedSample(double k, int T, double delay, double dt) : dt_(dt) {
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

  // the signal's value at t_k - delay
  double Value(Signal s) const {
    return interpolated_ ? (1 - a_) * s[i0_] + a_ * s[i0_ + 1] : s[i0_];
  }

  // d Value / d delay
  double DerivativeByDelay(Signal s) const { return lo_ == hi_ ? 0.0 : -(s[hi_] - s[lo_]) / dt_; }

 private:
  bool interpolated_ = false;  // (1 - a) s[i0] + a s[i0 + 1]; else s[i0] alone
  int i0_ = 0;
  double a_ = 0;
  int lo_ = 0, hi_ = 0;  // the slope's samples (equal: no slope)
  double dt_ = 1;
};

// one fitted sensor column of a sequence
struct Channel {
  int column = 0;        // in the rows of simulated and measured sensors (the model's sensordata)
  double weight = 1;     // 1/sigma, > 0
  int measurement = -1;  // index of its sensor's measurement terms, or -1 (delay 0, gain 1, bias 0)
};

// the residual of one channel at one sample and its derivatives
struct SensorResidual {
  double value = 0;        // r = rho_hat(e), e = weight * (gain * y + bias - measured)
  double simulated = 0;    // y, the simulated value read at t_k - delay
  double d_simulated = 0;  // d r / d y = rho_hat'(e) * weight * gain
  double d_delay = 0;      // d r / d delay = d_simulated * dy / d delay
  double d_gain = 0;       // d r / d gain = rho_hat'(e) * weight * y
  double d_bias = 0;       // d r / d bias = rho_hat'(e) * weight
};

// The residual of a channel with weight `weight` and terms `terms` against the measured value,
// with the simulated signal (its column of the segment's T x ns sensor rows) read at `at`, which
// must be DelayedSample(k, T, terms.delay, dt). loss_scale > 0 as in RobustResidual.
inline SensorResidual EvaluateSensorResidual(const DelayedSample& at, Signal simulated,
                                             double measured, double weight,
                                             const MeasurementTerms& terms, LossType loss,
                                             double loss_scale) {
  // e, the loss, then the chain rule through e = weight * (gain * y + bias - measured)
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

// The channel's Jacobian row read at `at` like the value: row[j] = dy/d(column j) at t_k - delay,
// from the core's DyDp (T*ns x ncol, row-major: row i*ns + column is d y_i[column] / d columns).
// The residual's row is SensorResidual::d_simulated * row.
inline void InterpolatedRow(const DelayedSample& at, const double* dydp, int ns, int column,
                            int ncol, double* row) {
  // column j of DyDp restricted to the channel's rows is the signal {dydp + column * ncol + j,
  // ns * ncol}
  const Eigen::Index stride = static_cast<Eigen::Index>(ns) * ncol;
  for (int j = 0; j < ncol; ++j) {
    row[j] = at.Value({dydp + static_cast<Eigen::Index>(column) * ncol + j, stride});
  }
}

// Gaussian prior on a physical parameter p: returns (p - mean) / sigma, and in *derivative its
// derivative by the optimiser variable z given dp_dz = dp/dz (sigma > 0).
double PriorResidual(double p, double mean, double sigma, double dp_dz, double* derivative);

}  // namespace mjsysid
