// The sharding and the compressed residual blocks of sysid/mpi/shards.h.
#include "sysid/mpi/shards.h"

#include <algorithm>
#include <numeric>

namespace mjsysid::mpi {

std::vector<int> ShardRanges(const std::vector<double>& cost, int ranks) {
  // each segment to the rank whose share of the total holds the middle of its cost
  const int size = static_cast<int>(cost.size());
  ranks = std::max(ranks, 1);
  double total = 0;
  for (double c : cost) total += c;
  std::vector<int> first(ranks + 1, size);
  first[0] = 0;
  double before = 0;
  int rank = 0;
  for (int s = 0; s < size; ++s) {
    const double middle = total > 0 ? (before + 0.5 * cost[s]) / total : (s + 0.5) / size;
    const int r = std::min(ranks - 1, static_cast<int>(middle * ranks));
    while (rank < r) first[++rank] = s;
    before += cost[s];
  }
  while (rank < ranks) first[++rank] = size;
  return first;
}

namespace {
void Collect(int lo, int hi, int first, int last, std::vector<std::pair<int, int>>* out) {
  if (hi <= first || lo >= last || lo >= hi) return;  // disjoint or empty
  if (first <= lo && hi <= last) {
    out->emplace_back(lo, hi);
    return;
  }
  const int mid = (lo + hi) / 2;
  Collect(lo, mid, first, last, out);
  Collect(mid, hi, first, last, out);
}
}  // namespace

std::vector<std::pair<int, int>> CanonicalNodes(int first, int last, int size) {
  std::vector<std::pair<int, int>> out;
  Collect(0, size, first, last, &out);
  return out;
}

Eigen::MatrixXd MergeBlocks(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  RowMatrix stacked(a.rows() + b.rows(), a.cols());
  stacked << a, b;
  RowTriangle triangle(static_cast<int>(a.cols()));
  triangle.Add(stacked);
  return triangle.Square();
}

CompressedBlock::CompressedBlock(int n) { Reset(n); }

void CompressedBlock::Reset(int n) { triangle_.Reset(n + 1); }

void CompressedBlock::Add(const Eigen::Ref<const RowMatrix>& J,
                          const Eigen::Ref<const Eigen::VectorXd>& r) {
  triangle_.Add(J, r);
}

EliminatedBlock EliminateStates(const Eigen::MatrixXd& r_aug, int k) {
  // the blocks of the triangle with the state columns first (shards.h)
  const int n = static_cast<int>(r_aug.cols()) - k - 1;
  EliminatedBlock out;
  out.reduced = r_aug.bottomRightCorner(n + 1, n + 1);
  out.R_xx = r_aug.topLeftCorner(k, k);
  out.R_xp = r_aug.block(0, k, k, n);
  out.q_x = r_aug.block(0, k + n, k, 1);
  return out;
}

Eigen::VectorXd EliminatedBlock::StateStep(const Eigen::Ref<const Eigen::VectorXd>& dp) const {
  // back-substitution: R_xx dx = -(R_xp dp + q_x)
  const Eigen::VectorXd rhs = -(R_xp * dp + q_x);
  return R_xx.triangularView<Eigen::Upper>().solve(rhs);
}

}  // namespace mjsysid::mpi
