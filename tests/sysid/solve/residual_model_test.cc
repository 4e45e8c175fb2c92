// the residual arithmetic on hand-made signals: values against hand-computed numbers, derivatives
// against central finite differences (one-sided where the model is one-sided). No MuJoCo.
//
// Tolerances: hand values 1e-12 relative (a few roundings); finite differences with step h have
// truncation error ~h^2 |f'''| and rounding error ~1e-16 |f| / h, both below 1e-7 of the
// derivatives checked here, and each check uses 1e-6 relative: a sign or a factor error (2x, a
// missing weight, gain or 1/dt) is off by far more.
#include "sysid/solve/residual_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

namespace mjsysid {
namespace {

constexpr double kDt = 0.01;
constexpr int kT = 10;

// relative error of a against b, scaled by max(|b|, 1e-300)
double Relative(double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-300); }

// central difference of f at x with step h
double Central(const std::function<double(double)>& f, double x, double h) {
  return (f(x + h) - f(x - h)) / (2 * h);
}

const char* Name(LossType loss) {
  return loss == LossType::kHuber ? "huber" : loss == LossType::kCauchy ? "cauchy" : "none";
}

// s_i = i^2 + 0.5 i (curved, so that interpolation and the samples differ), plus shift
std::vector<double> Samples(double shift = 0) {
  std::vector<double> s(kT);
  for (int i = 0; i < kT; ++i) s[i] = i * i + 0.5 * i + shift;
  return s;
}

// ---------------------------------------------------------------------------------------------
// robust loss

TEST(RobustResidualTest, HandValues) {
  double d = 0;
  // none: identity
  EXPECT_EQ(RobustResidual(LossType::kNone, 1.0, -2.5, &d), -2.5);
  EXPECT_EQ(d, 1.0);
  // Huber c = 1 inside the quadratic zone: identity
  EXPECT_NEAR(RobustResidual(LossType::kHuber, 1.0, 0.5, &d), 0.5, 1e-15);
  EXPECT_NEAR(d, 1.0, 1e-15);
  // Huber c = 1, e = 3: rho = 2*1*3 - 1 = 5, rhat = sqrt(5), rhat' = (c/|e|) e / rhat = 1/sqrt(5)
  EXPECT_NEAR(RobustResidual(LossType::kHuber, 1.0, 3.0, &d), 2.23606797749979, 1e-12);
  EXPECT_NEAR(d, 0.4472135954999579, 1e-12);
  // odd in e: -sqrt(5), same slope
  EXPECT_NEAR(RobustResidual(LossType::kHuber, 1.0, -3.0, &d), -2.23606797749979, 1e-12);
  EXPECT_NEAR(d, 0.4472135954999579, 1e-12);
  // Cauchy c = 2, e = 2: rho = 4 log 2, rhat = 2 sqrt(log 2), rhat' = (1/2) * 2 / rhat
  EXPECT_NEAR(RobustResidual(LossType::kCauchy, 2.0, 2.0, &d), 1.6651092223153954, 1e-12);
  EXPECT_NEAR(d, 0.6005612043932249, 1e-12);
  // zero: every loss is quadratic there
  for (LossType loss : {LossType::kNone, LossType::kHuber, LossType::kCauchy}) {
    EXPECT_EQ(RobustResidual(loss, 1.5, 0.0, &d), 0.0);
    EXPECT_EQ(d, 1.0);
  }
}

// rhat^2 is the robust cost rho(e^2) (Ceres' convention for a loss on a scalar residual)
TEST(RobustResidualTest, SquareIsTheLoss) {
  const double c = 1.5;
  for (double e : {-7.0, -0.3, 0.9, 4.0}) {
    double d = 0;
    const double h = RobustResidual(LossType::kHuber, c, e, &d);
    const double huber = std::abs(e) <= c ? e * e : 2 * c * std::abs(e) - c * c;
    EXPECT_LT(Relative(h * h, huber), 1e-12) << e;
    const double y = RobustResidual(LossType::kCauchy, c, e, &d);
    EXPECT_LT(Relative(y * y, c * c * std::log(1 + e * e / (c * c))), 1e-12) << e;
  }
}

TEST(RobustResidualTest, DerivativeMatchesFiniteDifferences) {
  const double c = 1.5;
  // away from the Huber kink at |e| = c
  for (LossType loss : {LossType::kNone, LossType::kHuber, LossType::kCauchy}) {
    for (double e : {-5.0, -1.7, -0.2, 0.4, 2.7, 8.0}) {
      double d = 0;
      RobustResidual(loss, c, e, &d);
      const double fd = Central(
          [&](double x) {
            double unused;
            return RobustResidual(loss, c, x, &unused);
          },
          e, 1e-6);
      EXPECT_LT(Relative(d, fd), 1e-6) << Name(loss) << " e " << e;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// delay

TEST(DelayedSampleTest, HandValues) {
  const std::vector<double> s = Samples();
  const Signal sig{s.data(), 1};
  // k = 5, delay 2.3 dt: between samples 2 (5.0) and 3 (10.5) at 0.7
  const DelayedSample mid(5, kT, 0.023, kDt);
  EXPECT_LT(Relative(mid.Value(sig), 0.3 * 5.0 + 0.7 * 10.5), 1e-12);
  EXPECT_LT(Relative(mid.DerivativeByDelay(sig), -(10.5 - 5.0) / kDt), 1e-12);
  // no delay: the sample, the backward slope -(s5 - s4) / dt
  const DelayedSample now(5, kT, 0.0, kDt);
  EXPECT_EQ(now.Value(sig), 27.5);
  EXPECT_LT(Relative(now.DerivativeByDelay(sig), -(27.5 - 18.0) / kDt), 1e-12);
  // no delay at the first sample: no slope
  const DelayedSample first(0, kT, 0.0, kDt);
  EXPECT_EQ(first.Value(sig), 0.0);
  EXPECT_EQ(first.DerivativeByDelay(sig), 0.0);
  // before the start (q = 1 - 5 < 0): held at sample 0, no slope
  const DelayedSample before(1, kT, 0.05, kDt);
  EXPECT_EQ(before.Value(sig), 0.0);
  EXPECT_EQ(before.DerivativeByDelay(sig), 0.0);
  // a strided signal: column 1 of a row-major kT x 3 matrix holding s in that column
  std::vector<double> m(3 * kT, -1.0);
  for (int i = 0; i < kT; ++i) m[3 * i + 1] = s[i];
  EXPECT_EQ(mid.Value({m.data() + 1, 3}), mid.Value(sig));
  EXPECT_EQ(mid.DerivativeByDelay({m.data() + 1, 3}), mid.DerivativeByDelay(sig));
}

TEST(DelayedSampleTest, DerivativeMatchesFiniteDifferences) {
  const std::vector<double> s = Samples();
  const Signal sig{s.data(), 1};
  auto value = [&](int k) {
    return [&, k](double delay) { return DelayedSample(k, kT, delay, kDt).Value(sig); };
  };
  // inside an interval between two samples (the kinks are at multiples of dt): central
  for (int k : {3, 5, 9}) {
    for (double delay : {0.004, 0.023, 0.0161}) {
      const double d = DelayedSample(k, kT, delay, kDt).DerivativeByDelay(sig);
      EXPECT_LT(Relative(d, Central(value(k), delay, 1e-7)), 1e-6) << k << " " << delay;
    }
  }
  // at delay 0 the slope is the one of delays just above 0 (delays are >= 0): one-sided
  for (int k : {1, 4, 9}) {
    const double h = 1e-7;
    const double d = DelayedSample(k, kT, 0.0, kDt).DerivativeByDelay(sig);
    EXPECT_LT(Relative(d, (value(k)(h) - value(k)(0.0)) / h), 1e-6) << k;
  }
}

// ---------------------------------------------------------------------------------------------
// sensor residual: weight, gain, bias, delay, loss

TEST(SensorResidualTest, HandValues) {
  const std::vector<double> s = Samples();
  const MeasurementTerms terms{0.023, 1.2, -0.3};
  const DelayedSample at(5, kT, terms.delay, kDt);
  // y = 8.85; e = 100 (1.2 * 8.85 - 0.3 - 10.3) = 2
  const SensorResidual r =
      EvaluateSensorResidual(at, {s.data(), 1}, 10.3, 100.0, terms, LossType::kNone, 1.0);
  EXPECT_LT(Relative(r.simulated, 8.85), 1e-12);
  EXPECT_LT(Relative(r.value, 2.0), 1e-9);  // e is a difference of ~10: 1e-15 * 10 * 100 / 2
  EXPECT_LT(Relative(r.d_simulated, 100 * 1.2), 1e-12);
  EXPECT_LT(Relative(r.d_gain, 100 * 8.85), 1e-12);
  EXPECT_LT(Relative(r.d_bias, 100.0), 1e-12);
  EXPECT_LT(Relative(r.d_delay, 100 * 1.2 * -(10.5 - 5.0) / kDt), 1e-12);
  // Huber c = 1 at e = 2: rhat = sqrt(3), rhat' = (1/2) 2 / sqrt(3) = 1/sqrt(3), times weight 100
  const SensorResidual h =
      EvaluateSensorResidual(at, {s.data(), 1}, 10.3, 100.0, terms, LossType::kHuber, 1.0);
  EXPECT_LT(Relative(h.value, std::sqrt(3.0)), 1e-9);
  EXPECT_LT(Relative(h.d_bias, 100 / std::sqrt(3.0)), 1e-9);
  // the measurement equation
  EXPECT_EQ(terms.Apply(8.85), 1.2 * 8.85 - 0.3);
}

// d r / d {y, delay, gain, bias} against central differences, for every loss, in the robust
// zone of Huber and Cauchy (e = 3, c = 1.5)
TEST(SensorResidualTest, DerivativesMatchFiniteDifferences) {
  const double measured = 10.29, weight = 100;
  const MeasurementTerms base{0.023, 1.2, -0.3};
  for (LossType loss : {LossType::kNone, LossType::kHuber, LossType::kCauchy}) {
    auto value = [&](const MeasurementTerms& t, double shift) {
      const std::vector<double> s = Samples(shift);
      const DelayedSample at(5, kT, t.delay, kDt);
      return EvaluateSensorResidual(at, {s.data(), 1}, measured, weight, t, loss, 1.5).value;
    };
    const std::vector<double> s = Samples();
    const SensorResidual r = EvaluateSensorResidual(
        DelayedSample(5, kT, base.delay, kDt), {s.data(), 1}, measured, weight, base, loss, 1.5);
    ASSERT_GT(std::abs(100 * (base.Apply(r.simulated) - measured)), 1.5);  // |e| > c
    // y: shifting every sample by h shifts the interpolated value by h
    const double fd_y = Central([&](double x) { return value(base, x); }, 0.0, 1e-7);
    EXPECT_LT(Relative(r.d_simulated, fd_y), 1e-6) << Name(loss);
    const double fd_delay = Central(
        [&](double x) {
          MeasurementTerms t = base;
          t.delay = x;
          return value(t, 0);
        },
        base.delay, 1e-8);
    EXPECT_LT(Relative(r.d_delay, fd_delay), 1e-6) << Name(loss);
    const double fd_gain = Central(
        [&](double x) {
          MeasurementTerms t = base;
          t.gain = x;
          return value(t, 0);
        },
        base.gain, 1e-7);
    EXPECT_LT(Relative(r.d_gain, fd_gain), 1e-6) << Name(loss);
    const double fd_bias = Central(
        [&](double x) {
          MeasurementTerms t = base;
          t.bias = x;
          return value(t, 0);
        },
        base.bias, 1e-7);
    EXPECT_LT(Relative(r.d_bias, fd_bias), 1e-6) << Name(loss);
  }
}

// the residual's Jacobian row: d_simulated * InterpolatedRow is d r / d p when the simulated
// signal depends on p through the rows of dY/dp
TEST(SensorResidualTest, JacobianRowChainsThroughTheDelay) {
  const int ns = 2, ncol = 3, column = 1;
  // dY/dp: row i * ns + c, column j = (j + 1) i^2 + 100 c
  std::vector<double> dydp(static_cast<size_t>(kT) * ns * ncol);
  for (int i = 0; i < kT; ++i) {
    for (int c = 0; c < ns; ++c) {
      for (int j = 0; j < ncol; ++j) dydp[(i * ns + c) * ncol + j] = (j + 1) * i * i + 100.0 * c;
    }
  }
  const DelayedSample at(5, kT, 0.023, kDt);
  std::vector<double> row(ncol);
  InterpolatedRow(at, dydp.data(), ns, column, ncol, row.data());
  // between samples 2 and 3 at 0.7
  EXPECT_LT(Relative(row[0], 0.3 * 104 + 0.7 * 109), 1e-12);
  EXPECT_LT(Relative(row[2], 0.3 * 112 + 0.7 * 127), 1e-12);
  // y_i(p) = s_i + sum_j p_j dY_ij: a signal linear in p, the rows its exact derivative
  const MeasurementTerms terms{0.023, 1.2, -0.3};
  auto residual = [&](int j, double pj) {
    std::vector<double> y = Samples();
    for (int i = 0; i < kT; ++i) y[i] += pj * dydp[(i * ns + column) * ncol + j];
    return EvaluateSensorResidual(at, {y.data(), 1}, 10.29, 100.0, terms, LossType::kCauchy, 1.0)
        .value;
  };
  const SensorResidual r = EvaluateSensorResidual(at, {Samples().data(), 1}, 10.29, 100.0, terms,
                                                  LossType::kCauchy, 1.0);
  for (int j = 0; j < ncol; ++j) {
    const double fd = Central([&](double p) { return residual(j, p); }, 0.0, 1e-8);
    EXPECT_LT(Relative(r.d_simulated * row[j], fd), 1e-6) << j;
  }
}

// ---------------------------------------------------------------------------------------------
// measurement terms and priors

TEST(CurrentTermsTest, FittedFromMFixedFromInitial) {
  const MeasurementTerms initial{0.01, 1.1, 0.2};
  TermIndex index;
  index.gain = 1;
  index.bias = 0;
  const double m[2] = {-0.5, 2.0};
  const MeasurementTerms t = CurrentTerms(initial, index, m);
  EXPECT_EQ(t.delay, 0.01);
  EXPECT_EQ(t.gain, 2.0);
  EXPECT_EQ(t.bias, -0.5);
  const MeasurementTerms none = CurrentTerms(initial, index, nullptr);
  EXPECT_EQ(none.gain, 1.1);
  EXPECT_EQ(none.bias, 0.2);
}

TEST(PriorResidualTest, HandValueAndFiniteDifference) {
  // p = 1.5, mean 1, sigma 0.25: r = 2; log transform dp/dz = p: dr/dz = 1.5 / 0.25 = 6
  double d = 0;
  EXPECT_EQ(PriorResidual(1.5, 1.0, 0.25, 1.5, &d), 2.0);
  EXPECT_EQ(d, 6.0);
  // r(z) = (exp(z) - 1) / 0.25
  const double z = std::log(1.5);
  const double fd = Central(
      [](double x) {
        double unused;
        return PriorResidual(std::exp(x), 1.0, 0.25, std::exp(x), &unused);
      },
      z, 1e-6);
  PriorResidual(std::exp(z), 1.0, 0.25, std::exp(z), &d);
  EXPECT_LT(Relative(d, fd), 1e-6);
}

}  // namespace
}  // namespace mjsysid
