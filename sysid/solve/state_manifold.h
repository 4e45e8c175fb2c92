// The physical state [qpos, qvel, act] of a MuJoCo model as a Ceres manifold.
//
// Ambient size nq + nv + na, tangent size 2 nv + na (the core's tangent layout). Plus moves qpos
// with mj_integratePos, so ball and free joint quaternions stay unit and are perturbed in their
// body frame; Minus is mj_differentiatePos (docs/numerics.md, "Tangent-space sensitivities"). The
// core's Jacobians are in tangent space: a cost function turns a tangent-space Jacobian J_t
// (rows x nx) into the ambient one Ceres asks for as J_a = J_t P^+, with P = PlusJacobian and P^+
// from PlusJacobianPseudoInverse, so that J_a P = J_t exactly.
#pragma once

#include <ceres/manifold.h>
#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <vector>

#include "core/state.h"

namespace mjsysid {

class StateManifold : public ceres::Manifold {
 public:
  // m must outlive the manifold
  explicit StateManifold(const mjModel* m);

  int AmbientSize() const override { return dims_.nphys; }
  int TangentSize() const override { return dims_.nx; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;

  // P^+ (nx x nphys, row-major) at x: the pseudo-inverse of PlusJacobian
  void PlusJacobianPseudoInverse(const double* x, double* pinv) const;
  std::vector<double> PlusJacobianPseudoInverse(const double* x) const {
    std::vector<double> pinv(static_cast<size_t>(TangentSize()) * AmbientSize());
    PlusJacobianPseudoInverse(x, pinv.data());
    return pinv;
  }

 private:
  const mjModel* m_;
  StateDims dims_;
};

}  // namespace mjsysid
