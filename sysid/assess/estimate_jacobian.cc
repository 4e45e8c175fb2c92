// The Jacobian at the estimate, block by block, into its thin-QR triangle: see
// sysid/estimate_jacobian.h.
#include "sysid/assess/estimate_jacobian.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <vector>

#include "core/invariant.h"
#include "core/state.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/solve/compressed_cost.h"

namespace mjsysid {

bool EvaluateTriangle(const ceres::Problem& problem, const std::vector<double*>& blocks,
                      EstimateTriangle* out) {
  // the columns: every parameter block in the caller's order, its tangent size wide
  MJSYSID_DEMAND(static_cast<int>(blocks.size()) == problem.NumParameterBlocks(),
                 "EvaluateTriangle needs every parameter block");
  std::map<const double*, int> first_column;
  int n = 0;
  for (double* b : blocks) {
    first_column[b] = n;
    n += problem.ParameterBlockTangentSize(b);
  }
  RowTriangle triangle(n + 1);
  std::vector<ceres::ResidualBlockId> residual_blocks;
  problem.GetResidualBlocks(&residual_blocks);

  // per residual block: its residuals and Jacobians (buffers reused, sized to the largest
  // block), then its rows [J_b r_b] chunk by chunk into the triangle
  std::vector<double> residuals;
  std::vector<std::vector<double>> jacobians;
  std::vector<double*> jacobian_ptrs;
  std::vector<double*> parameters;
  RowMatrix chunk;
  double cost = 0;
  long long rows = 0;
  for (size_t i = 0; i < residual_blocks.size(); ++i) {
    const ceres::ResidualBlockId id = residual_blocks[i];
    problem.GetParameterBlocksForResidualBlock(id, &parameters);
    const int m = problem.GetCostFunctionForResidualBlock(id)->num_residuals();
    residuals.resize(m);
    jacobians.resize(std::max(jacobians.size(), parameters.size()));
    jacobian_ptrs.resize(parameters.size());
    for (size_t p = 0; p < parameters.size(); ++p) {
      jacobians[p].resize(static_cast<size_t>(m) *
                          problem.ParameterBlockTangentSize(parameters[p]));
      jacobian_ptrs[p] = jacobians[p].data();
    }
    // the evaluation callback (prefetch of every segment) once, at the first block
    double block_cost = 0;
    const bool ok = i == 0 ? problem.EvaluateResidualBlock(id, true, &block_cost, residuals.data(),
                                                           jacobian_ptrs.data())
                           : problem.EvaluateResidualBlockAssumingParametersUnchanged(
                                 id, true, &block_cost, residuals.data(), jacobian_ptrs.data());
    if (!ok) return false;
    cost += block_cost;
    rows += RealRows(*problem.GetCostFunctionForResidualBlock(id));  // a compressed block's too
    for (int first = 0; first < m; first += RowTriangle::kChunkRows) {
      const int count = std::min(RowTriangle::kChunkRows, m - first);
      chunk.setZero(count, n + 1);
      for (size_t p = 0; p < parameters.size(); ++p) {
        const int width = problem.ParameterBlockTangentSize(parameters[p]);
        chunk.middleCols(first_column.at(parameters[p]), width) = Eigen::Map<const RowMatrix>(
            jacobians[p].data() + static_cast<size_t>(first) * width, count, width);
      }
      chunk.col(n) = Eigen::Map<const Eigen::VectorXd>(residuals.data() + first, count);
      triangle.Add(chunk);
    }
  }
  out->r_aug = triangle.R();
  out->rows = rows;
  out->cost = cost;
  out->n = n;
  return true;
}

}  // namespace mjsysid
