// The compressed residual blocks and the sharding of sysid/mpi/shards.h, without MPI: a block
// built piece by piece keeps the exact cost, gradient and Gauss-Newton matrix of its rows; the
// ranges are contiguous and balanced; the tree gives the same bits for any split into ranks; a
// block with the states first gives their Schur complement and back-substitution.
#include "sysid/mpi/shards.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <map>
#include <random>

namespace mjsysid::mpi {
namespace {

// truth: J^T J, J^T r and |r|^2 of 3 random pieces of 40, 7 and 1 rows x 5 columns; the block's
// [R; 0] and its last column must reproduce them to rounding (1e-12 relative)
TEST(CompressedBlockTest, KeepsCostGradientAndNormalMatrix) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const int n = 5;
  CompressedBlock block(n);
  RowMatrix J_all(0, n);
  Eigen::VectorXd r_all(0);
  for (int rows : {40, 7, 1}) {
    RowMatrix J(rows, n);
    Eigen::VectorXd r(rows);
    for (int i = 0; i < rows; ++i) {
      r[i] = normal(rng);
      for (int c = 0; c < n; ++c) J(i, c) = normal(rng) * (c + 1);
    }
    block.Add(J, r);
    RowMatrix stacked(J_all.rows() + rows, n);
    stacked << J_all, J;
    J_all = stacked;
    Eigen::VectorXd rs(r_all.size() + rows);
    rs << r_all, r;
    r_all = rs;
  }
  const Eigen::MatrixXd& R = block.Augmented();
  ASSERT_EQ(R.rows(), n + 1);
  ASSERT_EQ(R.cols(), n + 1);
  const Eigen::MatrixXd Jc = R.leftCols(n);
  const Eigen::VectorXd rc = R.col(n);
  const Eigen::MatrixXd JtJ = J_all.transpose() * J_all;
  const Eigen::VectorXd Jtr = J_all.transpose() * r_all;
  EXPECT_LT((Jc.transpose() * Jc - JtJ).norm(), 1e-12 * JtJ.norm());
  EXPECT_LT((Jc.transpose() * rc - Jtr).norm(), 1e-12 * Jtr.norm());
  EXPECT_NEAR(rc.squaredNorm(), r_all.squaredNorm(), 1e-12 * r_all.squaredNorm());
  // below the diagonal: zero (upper triangular, as sent)
  for (int i = 0; i <= n; ++i) {
    for (int c = 0; c < i; ++c) EXPECT_EQ(R(i, c), 0.0);
  }
}

// truth: 60 random rows, k = 4 state columns first, n = 3 parameter columns, random r. The
// eliminated block must give the Schur complement J_p^T J_p - J_p^T J_x (J_x^T J_x)^-1 J_x^T J_p,
// the cost left after the best state step at fixed p, and, with the reduced system's parameter
// step and StateStep, the full Gauss-Newton step (all to 1e-10 relative)
TEST(EliminateStatesTest, SchurComplementAndBackSubstitution) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  const int k = 4, n = 3, rows = 60;
  RowMatrix J(rows, k + n);
  Eigen::VectorXd r(rows);
  for (int i = 0; i < rows; ++i) {
    r[i] = normal(rng);
    for (int c = 0; c < k + n; ++c) J(i, c) = normal(rng) * (1 + 0.5 * c);
  }
  CompressedBlock block(k + n);
  block.Add(J.topRows(25), r.head(25));
  block.Add(J.bottomRows(rows - 25), r.tail(rows - 25));
  const EliminatedBlock e = EliminateStates(block.Augmented(), k);
  ASSERT_EQ(e.reduced.rows(), n + 1);
  ASSERT_EQ(e.reduced.cols(), n + 1);
  const Eigen::MatrixXd Jx = J.leftCols(k), Jp = J.rightCols(n);
  const Eigen::MatrixXd Hxx = Jx.transpose() * Jx;
  const Eigen::MatrixXd schur =
      Jp.transpose() * Jp - Jp.transpose() * Jx * Hxx.ldlt().solve(Jx.transpose() * Jp);
  const Eigen::MatrixXd Rpp = e.reduced.topLeftCorner(n, n);
  EXPECT_LT((Rpp.transpose() * Rpp - schur).norm(), 1e-10 * schur.norm());
  // the cost at the best state step for dp = 0
  const Eigen::VectorXd dx0 = -Hxx.ldlt().solve(Jx.transpose() * r);
  EXPECT_NEAR(e.reduced.col(n).squaredNorm(), (Jx * dx0 + r).squaredNorm(),
              1e-10 * r.squaredNorm());
  // the full Gauss-Newton step from the reduced system and the back-substitution
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd full = -H.ldlt().solve(J.transpose() * r);
  const Eigen::VectorXd dp =
      -Rpp.triangularView<Eigen::Upper>().solve(Eigen::VectorXd(e.reduced.col(n).head(n)));
  EXPECT_LT((dp - full.tail(n)).norm(), 1e-10 * full.norm());
  EXPECT_LT((e.StateStep(dp) - full.head(k)).norm(), 1e-10 * full.norm());
}

// a block with no rows: zero cost, zero matrix
TEST(CompressedBlockTest, EmptyIsZero) {
  CompressedBlock block(3);
  block.Add(RowMatrix(0, 3), Eigen::VectorXd(0));
  EXPECT_EQ(block.Augmented().norm(), 0.0);
}

// costs 1..10 (total 55) over 3 ranks: segment s goes where the middle of its cost falls
// (middles 0.5, 2, 4.5, 8, 12.5, 18, 24.5, 32, 40.5, 50 against 18.33 and 36.67)
TEST(ShardRangesTest, ContiguousByCost) {
  const std::vector<double> cost = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  EXPECT_EQ(ShardRanges(cost, 3), (std::vector<int>{0, 6, 8, 10}));
  EXPECT_EQ(ShardRanges(cost, 1), (std::vector<int>{0, 10}));
  // more ranks than segments: empty ranges, still contiguous and covering
  EXPECT_EQ(ShardRanges({1, 1}, 4), (std::vector<int>{0, 0, 1, 1, 2}));  // middles 1, 3 of 4
}

// the maximal nodes of the tree over [0, 10) inside [3, 9): [3,4) [4,5) [5,7)... as the tree splits
// at mid = (lo + hi) / 2: [0,5) -> [0,2) [2,5) -> [2,3) [3,5); [5,10) -> [5,7) [7,10) -> [7,8)
// [8,10) -> [8,9) [9,10)
TEST(ShardRangesTest, CanonicalNodes) {
  using Nodes = std::vector<std::pair<int, int>>;
  EXPECT_EQ(CanonicalNodes(3, 9, 10), (Nodes{{3, 5}, {5, 7}, {7, 8}, {8, 9}}));
  EXPECT_EQ(CanonicalNodes(0, 10, 10), (Nodes{{0, 10}}));
  EXPECT_EQ(CanonicalNodes(4, 4, 10), Nodes{});
}

// truth: the root merged from the leaves on one rank; any split into contiguous ranges (1, 2, 3, 4
// and 7 ranks), each sending its canonical nodes, must give the same bits (EXPECT_EQ on doubles)
TEST(ShardRangesTest, TreeRootIsTheSameBitsForAnyRanks) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  const int n = 4, S = 11;
  std::vector<Eigen::MatrixXd> leaves;
  std::vector<double> sums;
  for (int s = 0; s < S; ++s) {
    RowMatrix J(20 + s, n);
    Eigen::VectorXd r(20 + s);
    for (Eigen::Index i = 0; i < J.rows(); ++i) {
      r[i] = normal(rng);
      for (int c = 0; c < n; ++c) J(i, c) = normal(rng);
    }
    CompressedBlock b(n);
    b.Add(J, r);
    leaves.push_back(b.Augmented());
    sums.push_back(r.squaredNorm());
  }
  auto leaf = [&](int lo, int hi) { return hi - lo == 1 ? &leaves[lo] : nullptr; };
  const Eigen::MatrixXd want = ReduceTree<Eigen::MatrixXd>(0, S, leaf, MergeBlocks);
  const double want_sum = ReduceTree<double>(
      0, S, [&](int lo, int hi) { return hi - lo == 1 ? &sums[lo] : nullptr; },
      [](double a, double b) { return a + b; });
  for (int ranks : {1, 2, 3, 4, 7}) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks");
    const std::vector<int> first = ShardRanges(std::vector<double>(S, 1.0), ranks);
    std::map<std::pair<int, int>, Eigen::MatrixXd> sent;
    std::map<std::pair<int, int>, double> sent_sums;
    for (int r = 0; r < ranks; ++r) {
      for (const auto& [lo, hi] : CanonicalNodes(first[r], first[r + 1], S)) {
        sent[{lo, hi}] = ReduceTree<Eigen::MatrixXd>(lo, hi, leaf, MergeBlocks);
        sent_sums[{lo, hi}] = ReduceTree<double>(
            lo, hi, [&](int a, int b) { return b - a == 1 ? &sums[a] : nullptr; },
            [](double a, double b) { return a + b; });
      }
    }
    const Eigen::MatrixXd got = ReduceTree<Eigen::MatrixXd>(
        0, S,
        [&](int lo, int hi) {
          const auto it = sent.find({lo, hi});
          return it == sent.end() ? nullptr : &it->second;
        },
        MergeBlocks);
    const double got_sum = ReduceTree<double>(
        0, S,
        [&](int lo, int hi) {
          const auto it = sent_sums.find({lo, hi});
          return it == sent_sums.end() ? nullptr : &it->second;
        },
        [](double a, double b) { return a + b; });
    EXPECT_TRUE(got == want);
    EXPECT_EQ(got_sum, want_sum);
  }
}

}  // namespace
}  // namespace mjsysid::mpi
