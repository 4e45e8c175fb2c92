#include "core/inertia_cholesky.h"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace mjsysid {
namespace {

using Matrix3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

// the inertia about the centre of mass in the body frame: R diag(I) R^T, R from the quaternion
Matrix3 InertiaInBodyFrame(const BodyInertial& b) {
  Matrix3 r;
  mju_quat2Mat(r.data(), b.quat);
  return r * Eigen::Vector3d(b.inertia[0], b.inertia[1], b.inertia[2]).asDiagonal() * r.transpose();
}

}  // namespace

const char* InertialVariableName(int i) {
  static const char* const kNames[kInertialVariables] = {"alpha", "d1",  "d2", "d3", "s12",
                                                         "s23",   "s13", "t1", "t2", "t3"};
  return i >= 0 && i < kInertialVariables ? kNames[i] : "";
}

BodyInertial BodyInertialOf(const mjModel& m, int b) {
  BodyInertial out;
  out.mass = m.body_mass[b];
  for (int k = 0; k < 3; ++k) out.com[k] = m.body_ipos[3 * b + k];
  for (int k = 0; k < 3; ++k) out.inertia[k] = m.body_inertia[3 * b + k];
  for (int k = 0; k < 4; ++k) out.quat[k] = m.body_iquat[4 * b + k];
  return out;
}

void SetBodyInertial(mjModel* m, int b, const BodyInertial& inertial) {
  m->body_mass[b] = inertial.mass;
  for (int k = 0; k < 3; ++k) m->body_ipos[3 * b + k] = inertial.com[k];
  for (int k = 0; k < 3; ++k) m->body_inertia[3 * b + k] = inertial.inertia[k];
  for (int k = 0; k < 4; ++k) m->body_iquat[4 * b + k] = inertial.quat[k];
}

bool ToLogCholesky(const BodyInertial& inertial, double theta[kInertialVariables]) {
  if (!(inertial.mass > 0)) return false;
  // second moment about the centre of mass per unit mass: A = (tr(I_c)/2 1 - I_c) / m
  const Matrix3 ic = InertiaInBodyFrame(inertial);
  const Matrix3 a = (0.5 * ic.trace() * Matrix3::Identity() - ic) / inertial.mass;

  // upper Cholesky factor A = L L^T (L upper triangular, positive diagonal), last row first
  const double l22sq = a(2, 2);
  if (!(l22sq > 0)) return false;
  const double l22 = std::sqrt(l22sq);
  const double l12 = a(1, 2) / l22, l02 = a(0, 2) / l22;
  const double l11sq = a(1, 1) - l12 * l12;
  if (!(l11sq > 0)) return false;
  const double l11 = std::sqrt(l11sq);
  const double l01 = (a(0, 1) - l02 * l12) / l11;
  const double l00sq = a(0, 0) - l01 * l01 - l02 * l02;
  if (!(l00sq > 0)) return false;

  // alpha, d1..d3, s12, s23, s13, t1..t3
  theta[0] = 0.5 * std::log(inertial.mass);
  theta[1] = 0.5 * std::log(l00sq);
  theta[2] = std::log(l11);
  theta[3] = std::log(l22);
  theta[4] = l01;
  theta[5] = l12;
  theta[6] = l02;
  for (int k = 0; k < 3; ++k) theta[7 + k] = inertial.com[k];
  return true;
}

BodyInertial FromLogCholesky(const double theta[kInertialVariables]) {
  BodyInertial out;
  out.mass = std::exp(2 * theta[0]);
  for (int k = 0; k < 3; ++k) out.com[k] = theta[7 + k];

  // Sigma_c = m L L^T, I_c = tr(Sigma_c) 1 - Sigma_c
  Matrix3 l = Matrix3::Zero();
  l(0, 0) = std::exp(theta[1]);
  l(1, 1) = std::exp(theta[2]);
  l(2, 2) = std::exp(theta[3]);
  l(0, 1) = theta[4];
  l(1, 2) = theta[5];
  l(0, 2) = theta[6];
  const Matrix3 sigma = out.mass * l * l.transpose();
  const Matrix3 ic = sigma.trace() * Matrix3::Identity() - sigma;

  // principal moments (ascending) and axes; the axes made a proper rotation
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(ic);
  Matrix3 axes = eig.eigenvectors();
  if (axes.determinant() < 0) axes.col(2) *= -1;
  for (int k = 0; k < 3; ++k) out.inertia[k] = eig.eigenvalues()[k];
  mju_mat2Quat(out.quat, axes.data());
  mju_normalize4(out.quat);
  return out;
}

void PhysicalInertial(const double theta[kInertialVariables], double physical[kInertialPhysical],
                      double* jacobian) {
  const auto evaluate = [](const double* t, double* out) {
    const BodyInertial b = FromLogCholesky(t);
    out[0] = b.mass;
    for (int k = 0; k < 3; ++k) out[1 + k] = b.com[k];
    for (int k = 0; k < 3; ++k) out[4 + k] = b.inertia[k];
  };
  evaluate(theta, physical);
  if (!jacobian) return;
  // central differences, one variable at a time
  const double step = 1e-6;
  double t[kInertialVariables], plus[kInertialPhysical], minus[kInertialPhysical];
  for (int j = 0; j < kInertialVariables; ++j) {
    for (int k = 0; k < kInertialVariables; ++k) t[k] = theta[k];
    t[j] = theta[j] + step;
    evaluate(t, plus);
    t[j] = theta[j] - step;
    evaluate(t, minus);
    for (int i = 0; i < kInertialPhysical; ++i) {
      jacobian[i * kInertialVariables + j] = (plus[i] - minus[i]) / (2 * step);
    }
  }
}

void PhysicalInertialCovariance(const double theta[kInertialVariables], const double* covariance,
                                double* physical_covariance) {
  using Jacobian = Eigen::Matrix<double, kInertialPhysical, kInertialVariables, Eigen::RowMajor>;
  using Covariance10 =
      Eigen::Matrix<double, kInertialVariables, kInertialVariables, Eigen::RowMajor>;
  using Covariance7 = Eigen::Matrix<double, kInertialPhysical, kInertialPhysical, Eigen::RowMajor>;
  double physical[kInertialPhysical];
  Jacobian g;
  PhysicalInertial(theta, physical, g.data());
  Eigen::Map<Covariance7> out(physical_covariance);
  out = g * Eigen::Map<const Covariance10>(covariance) * g.transpose();
}

}  // namespace mjsysid
