// The retraction of the optimiser's variables z (FitParameter::ToVariable) as a Ceres manifold:
// how a Levenberg-Marquardt step delta (tangent space, one entry per variable) moves z.
//
// A parameter without a transform or with `scale` moves by z + delta, and so does a log variable
// of a kind that does not enter the dynamics linearly. A log variable of a kind that does
// (EntersInverseDynamicsLinearly; Problem::Fit uses this only where the nominal rollouts have no
// contact) grows by the relative step p' = p (1 + delta) (z' = z + log(1 + delta), delta > 0)
// and shrinks as log p does, p' = p exp(delta) (z' = z + delta, delta <= 0): p stays positive
// and the two branches meet with equal slope at delta = 0. The retraction's Jacobian at
// delta = 0 is the identity, so the Jacobians Ceres sees (and the covariance) are those of
// z = log p; only the way a step is taken changes.
//
// Why: such a residual is about linear in p, so the Gauss-Newton step is accurate in p, not in
// log p. With z + delta the LM crawled wherever log p sat far below its optimum (the pendulum's
// friction loss at 0.001 after the first step: 18 iterations in log space, 5 in physical units);
// growing by the physical step fixes that, shrinking as log p keeps the value off zero and off
// its lower bound. Measured on the benchmark cases: BENCHMARKS.md "Whole fits".
#pragma once

#include <ceres/manifold.h>

#include <vector>

#include "sysid/types.h"

namespace mjsysid {

// whether a kind's value enters MuJoCo's inverse dynamics (the generalized force of a given
// qpos, qvel, qacc, ctrl) linearly: masses and inertias (with the centre of mass fixed), joint and
// tendon damping, stiffness and friction loss (times the sign of the velocity), armature,
// actuator gains, biases and gears, servo gains. Not: centre of mass, contact friction and
// solver parameters, delays, DC-motor parameters, log-Cholesky inertials, mjModel fields.
bool EntersInverseDynamicsLinearly(ParameterKind kind);

// whether a parameter takes the relative step: optimised as log p and of a kind that enters
// the dynamics linearly
bool RelativeStep(const FitParameter& p);

class VariableManifold : public ceres::Manifold {
 public:
  // one entry per variable of the block, in block order: whether it takes the relative step
  // (RelativeStep of its parameter)
  explicit VariableManifold(std::vector<bool> relative);

  int AmbientSize() const override { return static_cast<int>(relative_.size()); }
  int TangentSize() const override { return static_cast<int>(relative_.size()); }
  // z' = z + log(Ratio(delta)) for a relative variable, z' = z + delta for the others
  bool Plus(const double* z, const double* delta, double* z_plus_delta) const override;
  // the identity at delta = 0 (AmbientSize x TangentSize, row-major)
  bool PlusJacobian(const double* z, double* jacobian) const override;
  // the inverse of Plus: delta with Plus(z, delta) = y
  bool Minus(const double* y, const double* z, double* y_minus_z) const override;
  bool MinusJacobian(const double* z, double* jacobian) const override;

  // p' / p of a relative variable's tangent step delta: 1 + delta (delta > 0), else exp(delta);
  // > 0 for every finite delta
  static double Ratio(double delta);

  // whether any variable takes the relative step (otherwise the plain Euclidean step is used)
  bool any_relative() const;

 private:
  std::vector<bool> relative_;
};

}  // namespace mjsysid
