// Rollout derivatives from one-step blocks (StepBlocks, core/simulator.h): the chain rule over a
// whole horizon in both directions, and the maps between MuJoCo's tangent space and the
// coordinates of a physics vector. What the Python package's differentiable rollouts
// (docs/python.md, "Gradients through physics") are made of.
//
// Shapes (one sequence of T steps; nx = 2nv+na tangent, nphys = nq+nv+na coordinates, ns sensors,
// nu controls, np parameters; all matrices row-major, row k of a stack is step or state k):
// - tangent states dx: (T+1) x nx, sensors dy: T x ns, controls du: T x nu, parameters dp: np.
// - The recursion (forward, Jacobian-vector product):
//     dx_{k+1} = A_k dx_k + B_k du_k + F_k dp,   dy_k = C_k dx_k + D_k du_k + G_k dp.
// - Its transpose (backward, vector-Jacobian product) for cotangents gx ((T+1) x nx), gy (T x ns):
//     l_T = gx_T,  l_k = gx_k + A_k^T l_{k+1} + C_k^T gy_k,
//     gu_k = B_k^T l_{k+1} + D_k^T gy_k,  gp = sum_k F_k^T l_{k+1} + G_k^T gy_k,  gx_0 = l_0.
// Blocks missing from StepBlocks (no controls or no parameters) contribute nothing: du and dp are
// then ignored, and gu, gp are returned zero.
//
// Coordinates (ball and free joints, docs/numerics.md "Tangent-space sensitivities"): a state x is
// moved along a tangent vector d as mj_integratePos does, q <- q * exp(w/2) for a quaternion q and
// angular part w (body frame); every other coordinate adds. A rollout's initial state is taken
// with each quaternion normalised first (q / |q|), so its derivative in the input's coordinates
// is d(normalise)/dq: the radial direction has none.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>

#include "core/simulator.h"
#include "core/state.h"

namespace mjsysid {

// dx, dy (sized here) from the tangent initial direction dx0 (nx), du (T x nu or empty) and dp (np
// or empty) through the blocks b
void ChainForward(const StepBlocks& b, const Eigen::VectorXd& dx0, const RowMatrix& du,
                  const Eigen::VectorXd& dp, RowMatrix* dx, RowMatrix* dy);

// gx0 (nx), gu (T x nu), gp (np) (sized here; gu and gp zero without their blocks) from the
// cotangents gx ((T+1) x nx, or empty: zeros) and gy (T x ns, or empty: zeros)
void ChainBackward(const StepBlocks& b, const RowMatrix& gx, const RowMatrix& gy,
                   Eigen::VectorXd* gx0, RowMatrix* gu, Eigen::VectorXd* gp);

// Full Jacobians of the states (tangent rows) and sensors, sized here (none of them empty unless
// its blocks are):
// - x0 (tangent columns): DxDx0 ((T+1) nx x nx), DyDx0 (T ns x nx);
// - parameters: DxDp ((T+1) nx x np), DyDp (T ns x np);
// - controls: DxDu ((T+1) nx x T nu), DyDu (T ns x T nu), column j nu + i is control i of step j
//   (lower block triangular: state k depends on the controls of steps j < k, sensor k on j <= k).
// Any output pointer may be null (not computed).
void ChainJacobians(const StepBlocks& b, RowMatrix* DxDx0, RowMatrix* DyDx0, RowMatrix* DxDp,
                    RowMatrix* DyDp, RowMatrix* DxDu, RowMatrix* DyDu);

// x with every ball and free joint quaternion normalised (nphys); a zero quaternion becomes the
// identity (as mj_normalizeQuat)
void NormalizedPhysics(const mjModel& m, const double* x, double* out);

// dcoords (nphys) = d(x (+) d)/dd * d at d = 0: the coordinate change of moving the normalised
// physics vector x along the tangent vector d (nx)
void TangentToCoordinates(const mjModel& m, const double* x, const double* d, double* dcoords);
// its transpose: the tangent cotangent g (nx) of a coordinate cotangent gcoords (nphys) at x
void CoordinatesToTangentCotangent(const mjModel& m, const double* x, const double* gcoords,
                                   double* g);

// d (nx) = d(normalise(x) (-) normalise(x0))/dx0 * dcoords at x0 = x (raw, not normalised): the
// tangent direction of a change of the initial state's coordinates (rollouts start from the
// normalised state)
void CoordinatesToTangent(const mjModel& m, const double* x, const double* dcoords, double* d);
// its transpose: the coordinate gradient gcoords (nphys) of a tangent cotangent g (nx) at raw x
void TangentCotangentToCoordinates(const mjModel& m, const double* x, const double* g,
                                   double* gcoords);

}  // namespace mjsysid
