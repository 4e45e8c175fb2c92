#include "sysid/solve/state_manifold.h"

#include <cstring>
#include <vector>

namespace mjsysid {

StateManifold::StateManifold(const mjModel* m) : m_(m), dims_(*m) {}

bool StateManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const int nq = dims_.nq, nv = dims_.nv, na = dims_.na;
  std::memcpy(x_plus_delta, x, sizeof(double) * dims_.nphys);
  mj_integratePos(m_, x_plus_delta, delta, 1.0);
  for (int i = 0; i < nv; ++i) x_plus_delta[nq + i] += delta[nv + i];
  for (int i = 0; i < na; ++i) x_plus_delta[nq + nv + i] += delta[2 * nv + i];
  return true;
}

bool StateManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  TangentDifference(*m_, x, y, 1.0, y_minus_x);
  return true;
}

// P (nphys x nx, row-major): identity for scalar coordinates, 0.5 q (x) [0, e_i] for quaternions
bool StateManifold::PlusJacobian(const double* x, double* jacobian) const {
  const int nphys = dims_.nphys, nx = dims_.nx, nq = dims_.nq, nv = dims_.nv;
  std::memset(jacobian, 0, sizeof(double) * nphys * nx);
  for (int j = 0; j < m_->njnt; ++j) {
    const int qa = m_->jnt_qposadr[j], da = m_->jnt_dofadr[j];
    int quat_q = -1, quat_d = -1;
    switch (m_->jnt_type[j]) {
      case mjJNT_FREE:
        for (int i = 0; i < 3; ++i) jacobian[(qa + i) * nx + da + i] = 1;
        quat_q = qa + 3;
        quat_d = da + 3;
        break;
      case mjJNT_BALL:
        quat_q = qa;
        quat_d = da;
        break;
      default:
        jacobian[qa * nx + da] = 1;
    }
    if (quat_q >= 0) {
      for (int i = 0; i < 3; ++i) {
        double e[4] = {0, 0, 0, 0}, col[4];
        e[i + 1] = 0.5;
        mju_mulQuat(col, x + quat_q, e);
        for (int r = 0; r < 4; ++r) jacobian[(quat_q + r) * nx + quat_d + i] = col[r];
      }
    }
  }
  // velocities and activations
  for (int i = 0; i < nx - nv; ++i) jacobian[(nq + i) * nx + nv + i] = 1;
  return true;
}

void StateManifold::PlusJacobianPseudoInverse(const double* x, double* pinv) const {
  // columns of P are orthogonal: P^T P is diagonal (1 for scalars, 1/4 for quaternion columns)
  const int nphys = dims_.nphys, nx = dims_.nx;
  std::vector<double> P(static_cast<size_t>(nphys) * nx);
  PlusJacobian(x, P.data());
  for (int c = 0; c < nx; ++c) {
    double norm2 = 0;
    for (int r = 0; r < nphys; ++r) norm2 += P[r * nx + c] * P[r * nx + c];
    for (int r = 0; r < nphys; ++r) pinv[c * nphys + r] = P[r * nx + c] / norm2;
  }
}

bool StateManifold::MinusJacobian(const double* x, double* jacobian) const {
  PlusJacobianPseudoInverse(x, jacobian);
  return true;
}

}  // namespace mjsysid
