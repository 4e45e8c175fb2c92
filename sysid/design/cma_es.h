// CMA-ES (Hansen's covariance matrix adaptation evolution strategy, "The CMA Evolution Strategy:
// A Tutorial", 2016, default parameters): a derivative-free minimiser for the excitation search,
// used as ask / tell.
//
// Contract:
// - Ask() returns the next generation: lambda = 4 + floor(3 ln n) points drawn from
//   N(mean, sigma^2 C); Tell(scores) takes their scores in the same order (lower is better;
//   +inf for a point that failed) and updates mean, C (rank-one and rank-mu) and sigma (cumulative
//   step-size adaptation). Reproducible from the seed.
// - C is decomposed again every generation (n <= a few hundred here: O(n^3) is small next to a
//   candidate's rollouts).
// - Failure: n < 1, sigma <= 0, or scores of another length than the last Ask:
// std::invalid_argument.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

namespace mjsysid::design {

class CmaEs {
 public:
  CmaEs(const Eigen::VectorXd& mean, double sigma, std::uint64_t seed);

  int lambda() const { return lambda_; }
  double sigma() const { return sigma_; }
  const Eigen::VectorXd& mean() const { return mean_; }

  const std::vector<Eigen::VectorXd>& Ask();
  void Tell(const std::vector<double>& scores);

 private:
  int n_, lambda_, mu_;
  Eigen::VectorXd weights_;
  double mueff_, cc_, cs_, c1_, cmu_, damps_, chi_n_;
  Eigen::VectorXd mean_, pc_, ps_;
  Eigen::MatrixXd C_, B_;
  Eigen::VectorXd D_;  // sqrt of C's eigenvalues
  double sigma_;
  long generation_ = 0;
  std::mt19937_64 rng_;
  std::vector<Eigen::VectorXd> points_;
};

}  // namespace mjsysid::design
