// The tests' own forward map of the log-Cholesky inertial variables (core/inertia_cholesky.h),
// taken from the pseudo-inertia J = U U^T directly rather than from core's formulas: mass,
// centre of mass and full inertia as MJCF attribute text, for models written by hand.
#pragma once

#include <cmath>
#include <string>

#include "core/text.h"

namespace mjsysid::test {

struct InertialText {
  std::string mass;         // kg
  std::string pos;          // "x y z", m
  std::string fullinertia;  // "ixx iyy izz ixy ixz iyz" about the centre of mass, kg m^2
};

inline InertialText InertialByHand(const double theta[10]) {
  // U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]
  const double ea = std::exp(theta[0]);
  const double u[4][4] = {{ea * std::exp(theta[1]), ea * theta[4], ea * theta[6], ea * theta[7]},
                          {0, ea * std::exp(theta[2]), ea * theta[5], ea * theta[8]},
                          {0, 0, ea * std::exp(theta[3]), ea * theta[9]},
                          {0, 0, 0, ea}};
  double j[4][4];
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      j[r][c] = 0;
      for (int k = 0; k < 4; ++k) j[r][c] += u[r][k] * u[c][k];
    }
  }
  // J = [[Sigma_o, m c], [m c^T, m]]; Sigma_c = Sigma_o - m c c^T; I_c = tr(Sigma_c) 1 - Sigma_c
  const double mass = j[3][3];
  const double com[3] = {j[0][3] / mass, j[1][3] / mass, j[2][3] / mass};
  double sigma[3][3], trace = 0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) sigma[r][c] = j[r][c] - mass * com[r] * com[c];
    trace += sigma[r][r];
  }
  const auto num = [](double v) { return FormatG17(v); };
  return {num(mass), num(com[0]) + " " + num(com[1]) + " " + num(com[2]),
          num(trace - sigma[0][0]) + " " + num(trace - sigma[1][1]) + " " +
              num(trace - sigma[2][2]) + " " + num(-sigma[0][1]) + " " + num(-sigma[0][2]) + " " +
              num(-sigma[1][2])};
}

}  // namespace mjsysid::test
