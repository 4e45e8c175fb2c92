#include "sysid/design/fourier.h"

#include <cmath>
#include <stdexcept>

namespace mjsysid::design {

double Window(double t, double duration, double ramp) {
  const double edge = std::min(t, duration - t);
  if (edge <= 0) return 0.0;
  if (edge >= ramp) return 1.0;
  return 0.5 * (1.0 - std::cos(M_PI * edge / ramp));
}

RowMatrix FourierShapes(const FourierBasis& basis, const Eigen::VectorXd& coefficients, int nu,
                        int steps, double dt) {
  const int H = basis.harmonics;
  if (H < 1 || nu < 0 || steps < 2 || !(dt > 0) || !(basis.base_frequency > 0) ||
      coefficients.size() != static_cast<Eigen::Index>(nu) * CoefficientsPerActuator(basis)) {
    throw std::invalid_argument("FourierShapes: bad sizes, frequency or timestep");
  }
  // the horizon ends at the last sample, so that the last control is back at the centre
  const double duration = (steps - 1) * dt;
  if (!(basis.ramp >= 0) || 2 * basis.ramp > duration) {
    throw std::invalid_argument("FourierShapes: the ramp is longer than half the duration");
  }
  RowMatrix g = RowMatrix::Zero(steps, nu);
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt;
    const double w = Window(t, duration, basis.ramp);
    if (w == 0) continue;
    for (int i = 0; i < nu; ++i) {
      g(k, i) += w * coefficients[static_cast<Eigen::Index>(i) * (2 * H + 1) + H];
    }
    for (int h = 1; h <= H; ++h) {
      const double phase = 2 * M_PI * h * basis.base_frequency * t;
      const double s = std::sin(phase), c = std::cos(phase);
      for (int i = 0; i < nu; ++i) {
        const double* a = coefficients.data() + static_cast<Eigen::Index>(i) * (2 * H + 1);
        g(k, i) += w * (a[h - 1] * s + a[H + h] * c);
      }
    }
  }
  // each actuator's peak scaled to exactly 1
  for (int i = 0; i < nu; ++i) {
    const double peak = g.col(i).cwiseAbs().maxCoeff();
    if (peak > 0) g.col(i) /= peak;
  }
  return g;
}

RowMatrix DesignControls(const RowMatrix& shapes, const Eigen::VectorXd& centre,
                         const Eigen::VectorXd& amplitude, double scale) {
  RowMatrix u(shapes.rows(), shapes.cols());
  for (Eigen::Index i = 0; i < shapes.cols(); ++i) {
    u.col(i) = (scale * amplitude[i]) * shapes.col(i).array() + centre[i];
  }
  return u;
}

}  // namespace mjsysid::design
