// The relative step of log variables (see variable_manifold.h).
#include "sysid/solve/variable_manifold.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {

bool EntersInverseDynamicsLinearly(ParameterKind kind) {
  switch (kind) {
    case ParameterKind::kBodyMass:
    case ParameterKind::kBodyMassInertia:
    case ParameterKind::kBodyInertia:
    case ParameterKind::kJointDamping:
    case ParameterKind::kJointFrictionLoss:
    case ParameterKind::kJointArmature:
    case ParameterKind::kJointStiffness:
    case ParameterKind::kActuatorGain:
    case ParameterKind::kActuatorBias:
    case ParameterKind::kActuatorGear:
    case ParameterKind::kTendonDamping:
    case ParameterKind::kTendonStiffness:
    case ParameterKind::kTendonFrictionLoss:
    case ParameterKind::kActuatorKp:
    case ParameterKind::kActuatorKv:
    case ParameterKind::kActuatorKi:
      return true;
    default:
      return false;
  }
}

bool RelativeStep(const FitParameter& p) {
  if (p.transform != Transform::kLog) return false;
  const ParameterKindInfo* info = FindParameterKind(p.target.kind);
  return info != nullptr && EntersInverseDynamicsLinearly(info->kind);
}

VariableManifold::VariableManifold(std::vector<bool> relative) : relative_(std::move(relative)) {}

bool VariableManifold::any_relative() const {
  return std::find(relative_.begin(), relative_.end(), true) != relative_.end();
}

double VariableManifold::Ratio(double delta) { return delta >= 0 ? 1.0 + delta : std::exp(delta); }

// z' = z + log(Ratio(delta)): z + log(1 + delta) growing, z + delta shrinking
bool VariableManifold::Plus(const double* z, const double* delta, double* z_plus_delta) const {
  for (size_t i = 0; i < relative_.size(); ++i) {
    const bool grows = relative_[i] && delta[i] > 0;
    z_plus_delta[i] = grows ? z[i] + std::log1p(delta[i]) : z[i] + delta[i];
  }
  return true;
}

bool VariableManifold::PlusJacobian(const double*, double* jacobian) const {
  const size_t n = relative_.size();
  std::fill(jacobian, jacobian + n * n, 0.0);
  for (size_t i = 0; i < n; ++i) jacobian[i * n + i] = 1.0;
  return true;
}

// the inverse of Plus: exp(y - z) - 1 where y > z (a relative variable grew), else y - z
bool VariableManifold::Minus(const double* y, const double* z, double* y_minus_z) const {
  for (size_t i = 0; i < relative_.size(); ++i) {
    const double d = y[i] - z[i];
    y_minus_z[i] = relative_[i] && d > 0 ? std::expm1(d) : d;
  }
  return true;
}

bool VariableManifold::MinusJacobian(const double* z, double* jacobian) const {
  return PlusJacobian(z, jacobian);
}

}  // namespace mjsysid
