#include "sysid/assess/derived_inertials.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/inertia_cholesky.h"
#include "core/parameters.h"
#include "sysid/assess/uncertainty.h"

namespace mjsysid {

std::vector<DerivedQuantity> DeriveInertials(const mjModel& model, const std::string& model_name,
                                             const std::vector<FitParameter>& params,
                                             const Eigen::VectorXd& values,
                                             const Eigen::VectorXd& std_errors,
                                             const Eigen::MatrixXd& covariance,
                                             const std::string& prefix) {
  // the body_inertial parameters of this model, grouped by body: variable index -> parameter
  std::map<int, std::map<int, int>> bodies;
  for (int v = 0; v < static_cast<int>(params.size()); ++v) {
    const FitParameter& p = params[v];
    if (p.target.kind != "body_inertial" || !p.AppliesTo(model_name)) continue;
    const int b = mj_name2id(&model, mjOBJ_BODY, p.target.object.c_str());
    if (b <= 0 || p.target.index < 0 || p.target.index >= kInertialVariables) continue;
    bodies[b][p.target.index] = v;
  }
  std::vector<DerivedQuantity> out;
  for (const auto& [b, variables] : bodies) {
    // the 10 variables: the model's, then the estimates; their covariance (zero where not fitted)
    double theta[kInertialVariables];
    if (!ToLogCholesky(BodyInertialOf(model, b), theta)) continue;  // Resolve refused it already
    double cov10[kInertialVariables * kInertialVariables] = {};
    bool has_covariance = covariance.rows() == static_cast<Eigen::Index>(params.size());
    bool unidentifiable = false;
    std::string from;
    for (const auto& [i, v] : variables) {
      theta[i] = values[v];
      if (has_covariance) {
        for (const auto& [j, w] : variables) {
          cov10[i * kInertialVariables + j] = covariance(v, w);
        }
      }
      if (std_errors.size() > v && !std::isfinite(std_errors[v]) && !std::isnan(std_errors[v])) {
        unidentifiable = true;
      }
      from += (from.empty() ? "" : ", ") + params[v].name;
    }
    double physical[kInertialPhysical];
    double cov7[kInertialPhysical * kInertialPhysical];
    PhysicalInertial(theta, physical, nullptr);
    PhysicalInertialCovariance(theta, cov10, cov7);

    // the 7 quantities, each with its delta-method interval
    const char* suffix[kInertialPhysical] = {"mass",       "com[0]",     "com[1]",    "com[2]",
                                             "inertia[0]", "inertia[1]", "inertia[2]"};
    const char* unit[kInertialPhysical] = {"kg", "m", "m", "m", "kg m^2", "kg m^2", "kg m^2"};
    const std::string body = mj_id2name(&model, mjOBJ_BODY, b);
    for (int k = 0; k < kInertialPhysical; ++k) {
      DerivedQuantity d;
      d.name = prefix + body + "." + suffix[k];
      d.unit = unit[k];
      d.value = physical[k];
      if (unidentifiable) {
        d.std_error = std::numeric_limits<double>::infinity();
      } else if (has_covariance) {
        d.std_error = std::sqrt(std::max(0.0, cov7[k * kInertialPhysical + k]));
      }
      d.ci95_low = d.value - kZ95 * d.std_error;
      d.ci95_high = d.value + kZ95 * d.std_error;
      d.derived_from = "body_inertial (" + from + ") by the delta method";
      out.push_back(std::move(d));
    }
  }
  return out;
}

}  // namespace mjsysid
