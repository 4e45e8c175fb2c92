#include "sysid/design/cma_es.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace mjsysid::design {

CmaEs::CmaEs(const Eigen::VectorXd& mean, double sigma, std::uint64_t seed)
    : n_(static_cast<int>(mean.size())), mean_(mean), sigma_(sigma), rng_(seed) {
  if (n_ < 1 || !(sigma > 0)) throw std::invalid_argument("CmaEs: n < 1 or sigma <= 0");
  const double n = n_;
  // selection and recombination: the best mu of lambda, log-decreasing weights
  lambda_ = 4 + static_cast<int>(std::floor(3 * std::log(n)));
  mu_ = lambda_ / 2;
  weights_.resize(mu_);
  for (int i = 0; i < mu_; ++i) weights_[i] = std::log(0.5 * (lambda_ + 1)) - std::log(i + 1.0);
  weights_ /= weights_.sum();
  mueff_ = 1.0 / weights_.squaredNorm();
  // adaptation rates of the tutorial's defaults
  cc_ = (4 + mueff_ / n) / (n + 4 + 2 * mueff_ / n);
  cs_ = (mueff_ + 2) / (n + mueff_ + 5);
  c1_ = 2 / ((n + 1.3) * (n + 1.3) + mueff_);
  cmu_ = std::min(1 - c1_, 2 * (mueff_ - 2 + 1 / mueff_) / ((n + 2) * (n + 2) + mueff_));
  damps_ = 1 + 2 * std::max(0.0, std::sqrt((mueff_ - 1) / (n + 1)) - 1) + cs_;
  chi_n_ = std::sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n));
  pc_ = ps_ = Eigen::VectorXd::Zero(n_);
  C_ = B_ = Eigen::MatrixXd::Identity(n_, n_);
  D_ = Eigen::VectorXd::Ones(n_);
}

const std::vector<Eigen::VectorXd>& CmaEs::Ask() {
  std::normal_distribution<double> normal(0.0, 1.0);
  points_.assign(lambda_, Eigen::VectorXd(n_));
  for (Eigen::VectorXd& x : points_) {
    Eigen::VectorXd z(n_);
    for (int i = 0; i < n_; ++i) z[i] = normal(rng_);
    x = mean_ + sigma_ * (B_ * D_.cwiseProduct(z));
  }
  return points_;
}

void CmaEs::Tell(const std::vector<double>& scores) {
  if (static_cast<int>(scores.size()) != lambda_ || points_.size() != scores.size()) {
    throw std::invalid_argument("CmaEs::Tell: one score per point of the last Ask");
  }
  // the best mu points, recombined into the new mean
  std::vector<int> order(lambda_);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&scores](int a, int b) { return scores[a] < scores[b]; });
  const Eigen::VectorXd old = mean_;
  mean_.setZero();
  for (int i = 0; i < mu_; ++i) mean_ += weights_[i] * points_[order[i]];
  const Eigen::VectorXd step = (mean_ - old) / sigma_;

  // evolution paths: C^-1/2 step for sigma, step for C (stalled while sigma's path is long)
  const Eigen::VectorXd invsqrt_step = B_ * (B_.transpose() * step).cwiseQuotient(D_);
  ps_ = (1 - cs_) * ps_ + std::sqrt(cs_ * (2 - cs_) * mueff_) * invsqrt_step;
  ++generation_;
  const double ps_norm = ps_.norm() / std::sqrt(1 - std::pow(1 - cs_, 2.0 * generation_));
  const bool hsig = ps_norm / chi_n_ < 1.4 + 2.0 / (n_ + 1);
  pc_ = (1 - cc_) * pc_ + (hsig ? std::sqrt(cc_ * (2 - cc_) * mueff_) : 0.0) * step;

  // covariance: rank-one (pc) and rank-mu (the selected steps) updates
  Eigen::MatrixXd rank_mu = Eigen::MatrixXd::Zero(n_, n_);
  for (int i = 0; i < mu_; ++i) {
    const Eigen::VectorXd y = (points_[order[i]] - old) / sigma_;
    rank_mu += weights_[i] * y * y.transpose();
  }
  C_ = (1 - c1_ - cmu_) * C_ + c1_ * (pc_ * pc_.transpose() + (hsig ? 0.0 : cc_ * (2 - cc_)) * C_) +
       cmu_ * rank_mu;
  sigma_ *= std::exp((cs_ / damps_) * (ps_.norm() / chi_n_ - 1));

  // C = B D^2 B^T again (symmetrised; eigenvalues kept positive)
  C_ = 0.5 * (C_ + C_.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C_);
  B_ = eig.eigenvectors();
  D_ = eig.eigenvalues().cwiseMax(1e-20).cwiseSqrt();
}

}  // namespace mjsysid::design
