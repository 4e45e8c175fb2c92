// Residual blocks as their thin-QR triangles: see sysid/compressed_cost.h.
#include "sysid/compressed_cost.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

namespace mjsysid {

CompressedCost::CompressedCost(std::unique_ptr<ceres::CostFunction> inner, CompressedBlocks* blocks)
    : inner_(std::move(inner)), blocks_(blocks) {
  int n = 0;
  for (const int size : inner_->parameter_block_sizes()) {
    mutable_parameter_block_sizes()->push_back(size);
    n += size;
  }
  set_num_residuals(n + 1);
  fold_.resize(n + 1, n + 1);
  fold_values_.resize(n);
}

bool CompressedCost::HoldsFoldAt(double const* const* parameters) const {
  const CompressedBlocks& B = *blocks_;
  if (!has_fold_ || !B.reuse_folds || fold_epoch_ != (B.epoch ? *B.epoch : 0)) return false;
  const std::vector<int32_t>& sizes = parameter_block_sizes();
  for (size_t b = 0, c0 = 0; b < sizes.size(); c0 += sizes[b], ++b) {
    if (std::memcmp(parameters[b], fold_values_.data() + c0, sizeof(double) * sizes[b]) != 0) {
      return false;
    }
  }
  return true;
}

void CompressedCost::KeepInputs(double const* const* parameters) const {
  const std::vector<int32_t>& sizes = parameter_block_sizes();
  for (size_t b = 0, c0 = 0; b < sizes.size(); c0 += sizes[b], ++b) {
    std::copy(parameters[b], parameters[b] + sizes[b], fold_values_.begin() + c0);
  }
  fold_epoch_ = blocks_->epoch ? *blocks_->epoch : 0;
}

bool CompressedCost::Evaluate(double const* const* parameters, double* residuals,
                              double** jacobians) const {
  CompressedBlocks& B = *blocks_;
  const int m = inner_->num_residuals();
  const int n = num_residuals() - 1;
  const std::vector<int32_t>& sizes = parameter_block_sizes();
  B.r.resize(m);

  // residuals only: any n + 1 values of norm |r| give the cost (at other values than the last
  // fold's: the fold is dropped, whatever the inner cost keeps aside may move)
  if (jacobians == nullptr) {
    if (!HoldsFoldAt(parameters)) has_fold_ = false;
    if (!inner_->Evaluate(parameters, B.r.data(), nullptr)) return false;
    WriteNorm(n, Eigen::Map<const Eigen::VectorXd>(B.r.data(), m).squaredNorm(), residuals);
    return true;
  }

  // the last fold at the same inputs: written out, the inner cost not called
  if (HoldsFoldAt(parameters)) {
    ++B.reused_folds;
    WriteTriangle(fold_, fold_last_, sizes, residuals, jacobians);
    return true;
  }

  // the inner residuals and every block's Jacobian (all columns enter the fold, whichever blocks
  // Ceres asks for)
  has_fold_ = false;
  B.jacobians.resize(std::max(B.jacobians.size(), sizes.size()));
  B.jacobian_ptrs.resize(sizes.size());
  for (size_t b = 0; b < sizes.size(); ++b) {
    B.jacobians[b].resize(static_cast<size_t>(m) * sizes[b]);
    B.jacobian_ptrs[b] = B.jacobians[b].data();
  }
  if (!inner_->Evaluate(parameters, B.r.data(), B.jacobian_ptrs.data())) return false;

  // the rows [J r], chunk by chunk (the fold's own chunks: the same bits as one call), into the
  // (n + 1)-wide triangle
  B.triangle.Reset(n + 1);
  for (int first = 0; first < m; first += RowTriangle::kChunkRows) {
    const int count = std::min(RowTriangle::kChunkRows, m - first);
    B.chunk.resize(count, n + 1);
    for (size_t b = 0, c0 = 0; b < sizes.size(); c0 += sizes[b], ++b) {
      B.chunk.middleCols(c0, sizes[b]) = Eigen::Map<const RowMatrix>(
          B.jacobians[b].data() + static_cast<size_t>(first) * sizes[b], count, sizes[b]);
    }
    B.chunk.col(n) = Eigen::Map<const Eigen::VectorXd>(B.r.data() + first, count);
    B.triangle.Add(B.chunk);
  }
  const Eigen::MatrixXd R = B.triangle.Square();

  // residuals (Q^T r, c): c^2 = |r|^2 - |Q^T r|^2, so the cost is the rows' to rounding
  const double sum = Eigen::Map<const Eigen::VectorXd>(B.r.data(), m).squaredNorm();
  const double projected = R.col(n).head(n).squaredNorm();
  const double last = std::sqrt(std::max(0.0, sum - projected));
  WriteTriangle(R, last, sizes, residuals, jacobians);
  ++B.folds;

  // kept as the last fold with its inputs
  fold_ = R;
  fold_last_ = last;
  KeepInputs(parameters);
  has_fold_ = true;
  return true;
}

void WriteTriangle(const Eigen::MatrixXd& r_aug, double last, const std::vector<int32_t>& sizes,
                   double* residuals, double** jacobians) {
  const int n = static_cast<int>(r_aug.cols()) - 1;
  for (int i = 0; i < n; ++i) residuals[i] = r_aug(i, n);
  residuals[n] = last;
  if (jacobians == nullptr) return;
  // Jacobian [R; 0], row-major per asked block
  for (size_t b = 0, c0 = 0; b < sizes.size(); c0 += sizes[b], ++b) {
    if (jacobians[b] == nullptr) continue;
    for (int i = 0; i <= n; ++i) {
      for (int c = 0; c < sizes[b]; ++c) jacobians[b][i * sizes[b] + c] = r_aug(i, c0 + c);
    }
  }
}

void WriteNorm(int n, double sum_squares, double* residuals) {
  std::fill(residuals, residuals + n, 0.0);
  residuals[n] = std::sqrt(sum_squares);
}

ceres::CostFunction* Compress(ceres::CostFunction* cost, CompressedBlocks* blocks) {
  int n = 0;
  for (const int size : cost->parameter_block_sizes()) n += size;
  if (cost->num_residuals() <= n + 1) return cost;
  blocks->hidden_rows += cost->num_residuals() - (n + 1);
  return new CompressedCost(std::unique_ptr<ceres::CostFunction>(cost), blocks);
}

int RealRows(const ceres::CostFunction& cost) {
  const auto* compressed = dynamic_cast<const CompressedCost*>(&cost);
  return compressed ? compressed->inner().num_residuals() : cost.num_residuals();
}

}  // namespace mjsysid
