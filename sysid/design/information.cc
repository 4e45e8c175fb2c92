#include "sysid/design/information.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace mjsysid::design {

const char* CriterionName(DesignCriterion c) {
  switch (c) {
    case DesignCriterion::kDOptimal:
      return "d_optimal";
    case DesignCriterion::kWorstRelativeStd:
      return "worst_relative_std";
    case DesignCriterion::kConditionNumber:
      return "condition_number";
  }
  return "?";
}

bool ParseCriterion(const std::string& name, DesignCriterion* out) {
  for (DesignCriterion c : {DesignCriterion::kDOptimal, DesignCriterion::kWorstRelativeStd,
                            DesignCriterion::kConditionNumber}) {
    if (name == CriterionName(c)) {
      *out = c;
      return true;
    }
  }
  return false;
}

Information InformationOf(const std::vector<Sensitivity>& jacobians, int ns,
                          const SensorWeights& sensors, const Eigen::VectorXd& values,
                          const Eigen::VectorXd& prior_precision) {
  const Eigen::Index np = values.size();
  const double inf = std::numeric_limits<double>::infinity();
  Information info;
  info.fisher = prior_precision.asDiagonal();

  // F += J_k^T W J_k, the weighted rows of every sample gathered in blocks
  for (const Sensitivity& s : jacobians) {
    const Eigen::Index T = ns > 0 ? s.DyDp.rows() / ns : 0;
    const Eigen::Index nc = static_cast<Eigen::Index>(sensors.columns.size());
    Eigen::MatrixXd rows(T * nc, np);
    for (Eigen::Index k = 0; k < T; ++k) {
      for (Eigen::Index c = 0; c < nc; ++c) {
        rows.row(k * nc + c) =
            s.DyDp.row(k * ns + sensors.columns[c]).leftCols(np) / sensors.sigma[c];
      }
    }
    info.fisher.selfadjointView<Eigen::Lower>().rankUpdate(rows.transpose());
  }
  info.fisher.triangularView<Eigen::StrictlyUpper>() =
      info.fisher.triangularView<Eigen::StrictlyLower>().transpose();

  // the relative information R = D F D and its eigenvalues
  Eigen::VectorXd d(np);
  for (Eigen::Index j = 0; j < np; ++j) d[j] = values[j] != 0 ? std::abs(values[j]) : 1.0;
  const Eigen::MatrixXd R = d.asDiagonal() * info.fisher * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(R);
  const Eigen::VectorXd lambda = eig.eigenvalues();
  // singular: an eigenvalue at the rounding level of the largest
  const bool singular =
      np > 0 && !(lambda[0] > lambda[np - 1] * 1e-14 && lambda[0] > 0 && lambda.allFinite());
  info.std = Eigen::VectorXd::Constant(np, inf);
  info.relative_std = Eigen::VectorXd::Constant(np, inf);
  if (singular) {
    info.log_det = -inf;
    info.worst_relative_std = inf;
    info.condition = inf;
    return info;
  }
  const Eigen::MatrixXd Rinv =
      eig.eigenvectors() * lambda.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  info.log_det = np > 0 ? lambda.array().log().sum() : 0.0;
  info.condition = np > 0 ? lambda[np - 1] / lambda[0] : 1.0;
  info.worst_relative_std = 0;
  for (Eigen::Index j = 0; j < np; ++j) {
    info.relative_std[j] = std::sqrt(Rinv(j, j));
    info.std[j] = info.relative_std[j] * d[j];
    info.worst_relative_std = std::max(info.worst_relative_std, info.relative_std[j]);
  }
  return info;
}

double CriterionValue(const Information& info, DesignCriterion criterion) {
  switch (criterion) {
    case DesignCriterion::kDOptimal:
      return -info.log_det;
    case DesignCriterion::kWorstRelativeStd:
      return info.worst_relative_std;
    case DesignCriterion::kConditionNumber:
      return info.condition;
  }
  return std::numeric_limits<double>::infinity();
}

double SearchScore(const Information& info, DesignCriterion criterion) {
  if (criterion != DesignCriterion::kWorstRelativeStd || !std::isfinite(info.worst_relative_std)) {
    return CriterionValue(info, criterion);
  }
  // the 8-norm of the relative standard errors, divided by the largest against overflow
  double sum = 0;
  for (Eigen::Index j = 0; j < info.relative_std.size(); ++j) {
    sum += std::pow(info.relative_std[j] / info.worst_relative_std, 8);
  }
  return info.worst_relative_std * std::pow(sum, 1.0 / 8);
}

}  // namespace mjsysid::design
