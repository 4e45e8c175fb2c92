// Residual blocks as their thin-QR triangles: see sysid/compressed_cost.h.
#include "sysid/solve/compressed_cost.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <utility>

namespace mjsysid {

CompressedCost::CompressedCost(std::unique_ptr<ceres::CostFunction> inner, CompressedBlocks* blocks)
    : inner_(std::move(inner)),
      foldable_(dynamic_cast<const FoldableCost*>(inner_.get())),
      blocks_(blocks) {
  int n = 0;
  for (const int size : inner_->parameter_block_sizes()) {
    mutable_parameter_block_sizes()->push_back(size);
    n += size;
  }
  set_num_residuals(n + 1);
  fold_.resize(n + 1, n + 1);
  fold_values_.resize(n);
}

// a fold made ahead is written out once even where reuse is off (it is the request's own fold)
bool CompressedCost::HoldsFoldAt(double const* const* parameters) const {
  const CompressedBlocks& B = *blocks_;
  if (!has_fold_ || !(B.reuse_folds || ahead_) || fold_epoch_ != (B.epoch ? *B.epoch : 0)) {
    return false;
  }
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

bool CompressedCost::Fold(double const* const* parameters, FoldScratch* scratch, bool ahead) const {
  FoldScratch& S = *scratch;
  const int m = inner_->num_residuals();
  const int n = num_residuals() - 1;
  const std::vector<int32_t>& sizes = parameter_block_sizes();

  // the inner residuals and every block's Jacobian (all columns enter the fold, whichever blocks
  // Ceres asks for)
  has_fold_ = false;
  ahead_ = false;
  S.r.resize(m);
  S.jacobians.resize(std::max(S.jacobians.size(), sizes.size()));
  S.jacobian_ptrs.resize(sizes.size());
  for (size_t b = 0; b < sizes.size(); ++b) {
    S.jacobians[b].resize(static_cast<size_t>(m) * sizes[b]);
    S.jacobian_ptrs[b] = S.jacobians[b].data();
  }
  const bool ok = ahead ? foldable_->Rows(parameters, S.r.data(), S.jacobian_ptrs.data())
                        : inner_->Evaluate(parameters, S.r.data(), S.jacobian_ptrs.data());
  if (!ok) return false;

  // the rows [J r], chunk by chunk (the fold's own chunks: the same bits as one call), into the
  // (n + 1)-wide triangle
  S.triangle.Reset(n + 1);
  for (int first = 0; first < m; first += RowTriangle::kChunkRows) {
    const int count = std::min(RowTriangle::kChunkRows, m - first);
    S.chunk.resize(count, n + 1);
    for (size_t b = 0, c0 = 0; b < sizes.size(); c0 += sizes[b], ++b) {
      S.chunk.middleCols(c0, sizes[b]) = Eigen::Map<const RowMatrix>(
          S.jacobians[b].data() + static_cast<size_t>(first) * sizes[b], count, sizes[b]);
    }
    S.chunk.col(n) = Eigen::Map<const Eigen::VectorXd>(S.r.data() + first, count);
    S.triangle.Add(S.chunk);
  }
  fold_ = S.triangle.Square();

  // c^2 = |r|^2 - |Q^T r|^2, so the cost is the rows' to rounding; kept as the last fold with its
  // inputs
  const double sum = Eigen::Map<const Eigen::VectorXd>(S.r.data(), m).squaredNorm();
  const double projected = fold_.col(n).head(n).squaredNorm();
  fold_last_ = std::sqrt(std::max(0.0, sum - projected));
  KeepInputs(parameters);
  has_fold_ = true;
  ahead_ = ahead;
  return true;
}

bool CompressedCost::FoldAheadAt(double const* const* parameters, FoldScratch* scratch) const {
  return foldable_ != nullptr && Fold(parameters, scratch, true);
}

bool CompressedCost::Evaluate(double const* const* parameters, double* residuals,
                              double** jacobians) const {
  CompressedBlocks& B = *blocks_;
  const int m = inner_->num_residuals();
  const int n = num_residuals() - 1;
  const std::vector<int32_t>& sizes = parameter_block_sizes();

  // residuals only: any n + 1 values of norm |r| give the cost (at other values than the last
  // fold's: the fold is dropped, whatever the inner cost keeps aside may move)
  if (jacobians == nullptr) {
    std::vector<double>& r = B.scratch[0].r;
    r.resize(m);
    if (!HoldsFoldAt(parameters)) has_fold_ = false;
    if (!inner_->Evaluate(parameters, r.data(), nullptr)) return false;
    WriteNorm(n, Eigen::Map<const Eigen::VectorXd>(r.data(), m).squaredNorm(), residuals);
    return true;
  }

  // the last fold at the same inputs: written out, the inner cost not called; made ahead: its
  // first write-out is this request's fold, with the inner cost's side effects now
  if (HoldsFoldAt(parameters)) {
    if (ahead_) {
      ahead_ = false;
      foldable_->NoteRows();
      ++B.folds;
      ++B.ahead_folds;
    } else {
      ++B.reused_folds;
    }
    WriteTriangle(fold_, fold_last_, sizes, residuals, jacobians);
    return true;
  }

  // residuals (Q^T r, c) and the Jacobian [R; 0] of a new fold
  if (!Fold(parameters, &B.scratch[0], false)) return false;
  ++B.folds;
  WriteTriangle(fold_, fold_last_, sizes, residuals, jacobians);
  return true;
}

int FoldAhead(CompressedBlocks* blocks, int workers,
              const std::function<void(int, const std::function<void(int, int)>&)>& parallel_for) {
  // the blocks to fold: no last fold at these values yet, their rows ready (fit thread)
  std::vector<const CompressedBlocks::Member*> todo;
  for (const CompressedBlocks::Member& member : blocks->members) {
    const double* const* parameters = member.parameters.data();
    if (member.cost->foldable() == nullptr || member.cost->HoldsFoldAt(parameters)) continue;
    if (member.cost->foldable()->PrepareRows(parameters)) todo.push_back(&member);
  }
  if (todo.empty()) return 0;
  // one task per block, each with its worker's scratch, writing only its block's fold; a throw
  // is a failed block (Evaluate meets it again)
  if (static_cast<int>(blocks->scratch.size()) < workers) blocks->scratch.resize(workers);
  parallel_for(static_cast<int>(todo.size()), [&](int worker, int i) {
    try {
      todo[i]->cost->FoldAheadAt(todo[i]->parameters.data(), &blocks->scratch[worker]);
    } catch (const std::exception&) {
    }
  });
  return static_cast<int>(todo.size());
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

ceres::CostFunction* Compress(ceres::CostFunction* cost, CompressedBlocks* blocks,
                              const std::vector<double*>& parameters) {
  int n = 0;
  for (const int size : cost->parameter_block_sizes()) n += size;
  if (cost->num_residuals() <= n + 1) return cost;
  blocks->hidden_rows += cost->num_residuals() - (n + 1);
  auto* compressed = new CompressedCost(std::unique_ptr<ceres::CostFunction>(cost), blocks);
  if (compressed->foldable() && !parameters.empty()) {
    blocks->members.push_back({compressed, {parameters.begin(), parameters.end()}});
  }
  return compressed;
}

int RealRows(const ceres::CostFunction& cost) {
  const auto* compressed = dynamic_cast<const CompressedCost*>(&cost);
  return compressed ? compressed->inner().num_residuals() : cost.num_residuals();
}

}  // namespace mjsysid
