// The Jacobian at a fit's estimate as its thin-QR triangle, one Ceres residual block at a time,
// so that the uncertainty step never holds the whole m x n Jacobian (docs/numerics.md, "Memory").
//
// EvaluateTriangle evaluates every residual block of problem at the current parameter values
// (Ceres' EvaluateResidualBlock: the evaluation callback runs once, for the first block; Jacobians
// in the tangent space of each parameter block, robust losses of the problem applied) and adds
// the block's rows [J_b r_b] to a RowTriangle (sysid/solve/row_triangle.h) of width n + 1, n the
// sum of the tangent sizes of problem's parameter blocks in the order `blocks` gives (the caller
// passes the order it added them in, the column order of ceres::Problem::Evaluate's CRSMatrix;
// Ceres' own GetParameterBlocks lists them by memory address, which changes from run to run).
// blocks must name every parameter block of problem exactly once (else a broken invariant: abort).
// Result: R_aug, min(m, n + 1) x (n + 1), upper triangular, with R_aug^T R_aug = [J r]^T [J r] over
// the m rows, so R_aug.leftCols(n) stands for J and R_aug.col(n) for r in every quadratic form
// (cost 0.5 |r + J d|^2, J^T J, J^T r). Memory: the residuals and Jacobian of the largest residual
// block plus O(n^2); the rows go into the triangle in the blocks' order, in fixed chunks, so the
// same values give the same bits. A compressed block (sysid/solve/compressed_cost.h) asked at the
// inputs of its last fold writes that fold out (n + 1 rows, the same bits) instead of evaluating
// its inner cost again: after the solve's Jacobian at the point, nothing is chained or folded
// twice. Failure: returns false when a block cannot be evaluated (a failed or cancelled
// simulation).
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <vector>

namespace mjsysid {

struct EstimateTriangle {
  Eigen::MatrixXd r_aug;  // min(m, n + 1) x (n + 1), upper triangular: [R q; 0 rho]
  long long rows = 0;     // m, the residual rows (a compressed block's real rows, RealRows)
  double cost = 0;        // 0.5 |r|^2 summed over the blocks
  int n = 0;              // columns of J (tangent sizes of every parameter block)
};

bool EvaluateTriangle(const ceres::Problem& problem, const std::vector<double*>& blocks,
                      EstimateTriangle* out);

}  // namespace mjsysid
