// The excitation family `sysid design` searches: per actuator a Fourier series (a multisine on a
// harmonic grid, as in Swevers et al.'s periodic excitation trajectories) under a smooth window.
//
// Contract:
// - Actuator i's shape, at t_k = k * dt (k = 0 .. steps-1):
//     g_i(t) = w(t) * (b_i0 + sum_{h=1..H} (a_ih sin(2 pi h f t) + b_ih cos(2 pi h f t))),
//   f = base_frequency (Hz), H = harmonics, then divided by max_k |g_i(t_k)| so that its peak is
//   exactly 1 (an all-zero shape stays zero). The constant b_i0 lets a design hold an offset
//   (e.g. turn a joint one way, where friction then acts the same way throughout). The window w
//   rises from 0 to 1 over the first `ramp` seconds and falls back to 0 over the last `ramp`
//   seconds as a raised cosine (value and slope 0 at both ends), so the robot starts from and
//   returns to its rest command smoothly.
// - Coefficients: one vector of nu * (2H + 1) values, actuator by actuator, each actuator's
//   a_1..a_H then b_0..b_H (CoefficientsPerActuator). Only the shape matters: a coefficient vector
//   and any positive multiple of it give the same signal.
// - The control is u_i(t) = centre_i + scale * amplitude_i * g_i(t) (DesignControls), so
//   |u_i - centre_i| <= scale * amplitude_i with equality at the peak.
// - Failure: bad sizes or a non-positive frequency, dt or ramp longer than half the duration
//   throw std::invalid_argument.
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/state.h"

namespace mjsysid::design {

struct FourierBasis {
  double base_frequency = 0.2;  // Hz: the harmonics are h * base_frequency, h = 1 .. harmonics
  int harmonics = 10;
  double ramp = 0.5;  // s, the raised-cosine start and end of the window
};

// 2 H + 1
inline int CoefficientsPerActuator(const FourierBasis& basis) { return 2 * basis.harmonics + 1; }

// the window w(t) of a horizon of `duration` seconds (see the contract)
double Window(double t, double duration, double ramp);

// the shapes g (steps x nu, peak 1 per column) of the coefficients (nu * (2 H + 1))
RowMatrix FourierShapes(const FourierBasis& basis, const Eigen::VectorXd& coefficients, int nu,
                        int steps, double dt);

// centre + scale * amplitude (per actuator) * shapes, steps x nu
RowMatrix DesignControls(const RowMatrix& shapes, const Eigen::VectorXd& centre,
                         const Eigen::VectorXd& amplitude, double scale);

}  // namespace mjsysid::design
