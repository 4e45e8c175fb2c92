// The log-Cholesky parametrization of a rigid body's 10 inertial parameters (Rucker and Wensing,
// "Smooth Parameterization of Rigid-Body Inertia", IEEE RA-L 2022): every value of the 10
// variables is a physically consistent body (positive mass, centre of mass anywhere, inertia about
// the centre of mass positive definite and satisfying the triangle inequalities strictly).
//
// Contract (formulas in docs/numerics.md, "Full inertia: log-Cholesky"):
// - The variables theta[10] are, in this order: alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3.
//   With U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]
//   the pseudo-inertia about the body origin is J = U U^T = [[Sigma, h], [h^T, m]]: so
//   m = e^(2 alpha), c = t (centre of mass in the body frame, m), and the second moment about the
//   centre of mass is Sigma_c = m L L^T with L the upper 3x3 block of U / e^alpha (units m).
//   The inertia about the centre of mass is I_c = tr(Sigma_c) 1 - Sigma_c.
// - Units: alpha is ln(sqrt(m / 1 kg)), d_i are ln(L_ii / 1 m), s_ij and t_i are metres.
// - Matrices are 3x3, row-major, in the body frame. Nothing allocates.
#pragma once

#include <mujoco/mujoco.h>

namespace mjsysid {

// the number of log-Cholesky variables of one body
inline constexpr int kInertialVariables = 10;

// the name of variable i: "alpha", "d1", ..., "t3"
const char* InertialVariableName(int i);

// A body's inertial as MuJoCo holds it: mass (kg), centre of mass in the body frame (m), the
// principal moments (kg m^2) and the orientation of the principal axes in the body frame.
struct BodyInertial {
  double mass = 0;
  double com[3] = {0, 0, 0};
  double inertia[3] = {0, 0, 0};  // principal moments, ascending after FromLogCholesky
  double quat[4] = {1, 0, 0, 0};  // principal axes: columns of the rotation of this quaternion
};

// body b of m (body_mass, body_ipos, body_inertia, body_iquat)
BodyInertial BodyInertialOf(const mjModel& m, int b);

// writes body b of m (body_mass, body_ipos, body_inertia, body_iquat); mj_setConst must follow
void SetBodyInertial(mjModel* m, int b, const BodyInertial& inertial);

// The variables of a body. Returns false (theta untouched) when the body is not strictly
// physically consistent: mass <= 0, or a principal moment pair whose sum does not exceed the
// third (a point mass, a rod or a flat plate with zero thickness has no log-Cholesky variables).
bool ToLogCholesky(const BodyInertial& inertial, double theta[kInertialVariables]);

// The body of any variables: mass, centre of mass, and the inertia about the centre of mass
// eigen-decomposed into principal moments (ascending) and axes (a proper rotation).
BodyInertial FromLogCholesky(const double theta[kInertialVariables]);

// The physical quantities a user reads: mass, centre of mass x, y, z, principal moments
// (ascending): 7 values, and their Jacobian with respect to theta (7 x 10, row-major) by central
// differences of step 1e-6 (principal moments are smooth where they are distinct).
inline constexpr int kInertialPhysical = 7;
void PhysicalInertial(const double theta[kInertialVariables], double physical[kInertialPhysical],
                      double* jacobian);

// The covariance of the physical quantities (7 x 7, row-major) from that of the variables
// (10 x 10, row-major; zero rows and columns for variables not fitted) by the delta method,
// G C G^T with G the Jacobian of PhysicalInertial: a first-order propagation, valid while the
// standard errors are small against the variables' curvature scale (checked against Monte Carlo
// in tests/core/inertia_cholesky_test.cc).
void PhysicalInertialCovariance(const double theta[kInertialVariables], const double* covariance,
                                double* physical_covariance);

}  // namespace mjsysid
