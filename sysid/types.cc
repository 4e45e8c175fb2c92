#include "sysid/types.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {

const char* LossTypeName(LossType loss) {
  switch (loss) {
    case LossType::kHuber:
      return "huber";
    case LossType::kCauchy:
      return "cauchy";
    default:
      return "none";
  }
}

double FitParameter::ToVariable(double p) const {
  switch (transform) {
    case Transform::kLog:
      return p > 0 ? std::log(p) : -std::numeric_limits<double>::infinity();
    case Transform::kScale:
      return p / scale;
    default:
      return p;
  }
}

double FitParameter::FromVariable(double z) const {
  switch (transform) {
    case Transform::kLog:
      return std::exp(z);
    case Transform::kScale:
      return z * scale;
    default:
      return z;
  }
}

bool FitParameter::AppliesTo(const std::string& model_name) const {
  return models.empty() || model_name.empty() ||
         std::find(models.begin(), models.end(), model_name) != models.end();
}

}  // namespace mjsysid
