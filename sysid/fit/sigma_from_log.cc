// WithSigmasFromLog (sysid/fit/sigma_from_log.h).
#include "sysid/fit/sigma_from_log.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sysid/assess/noise_estimate.h"

namespace mjsysid {
namespace {

// the relative floor of an estimated sigma: a noise-free log's estimate (its signal's curvature
// only) may be any small number, exactly 0 for a constant column
constexpr double kRelativeFloor = 1e-9;

// whether sequence sq fits sensor `name` (its list, or every sensor of its model)
bool Fits(const FitSequence& sq, const std::string& name) {
  if (sq.no_sensors) return false;
  return sq.sensors.empty() ||
         std::find(sq.sensors.begin(), sq.sensors.end(), name) != sq.sensors.end();
}

}  // namespace

double SigmaFromLog(const std::string& name, const std::vector<FitSequence>& sequences,
                    const std::function<const mjModel*(const std::string&)>& model_of) {
  const std::string where = "sensor '" + name + "' (sigma: auto): ";
  double weighted = 0, samples = 0, largest = 0;
  bool found = false;
  for (const FitSequence& sq : sequences) {
    if (!Fits(sq, name)) continue;
    const mjModel* m = model_of(sq.model);
    if (!m) continue;  // PrepareFit names the unknown model
    const int id = mj_name2id(m, mjOBJ_SENSOR, name.c_str());
    if (id < 0) continue;
    found = true;
    for (int c = 0; c < m->sensor_dim[id]; ++c) {
      const int col = m->sensor_adr[id] + c;
      if (col >= sq.measured.cols()) continue;  // PrepareFit names the wrong width
      const Eigen::VectorXd y = sq.measured.col(col);
      const Eigen::Index n = (!y.array().isNaN()).count();
      for (Eigen::Index k = 0; k < y.size(); ++k) {
        if (std::isfinite(y[k])) largest = std::max(largest, std::abs(y[k]));
      }
      const double s = EstimateNoiseStd(y, sq.time);  // (no times: the model's even steps)
      if (!std::isfinite(s)) continue;
      weighted += static_cast<double>(n) * s * s;
      samples += static_cast<double>(n);
    }
  }
  if (!found) {
    throw std::invalid_argument(where +
                                "no fitted sequence fits this sensor (no model has a sensor of "
                                "that name, or the sequences' sensors leave it out)");
  }
  if (!(samples > 0)) {
    throw std::invalid_argument(where +
                                "its logged columns are too short or too gappy for a noise "
                                "estimate (fewer than 8 runs of three consecutive measured "
                                "samples): give its sigma as a number");
  }
  if (!(largest > 0)) {
    throw std::invalid_argument(where +
                                "it reads 0 throughout the fitted sequences, so the log shows "
                                "no noise: give its sigma as a number");
  }
  return std::max(std::sqrt(weighted / samples), kRelativeFloor * largest);
}

FitOptions WithSigmasFromLog(const PreparedFit& fit, const FitOptions& options,
                             std::map<std::string, double>* sigmas) {
  FitOptions out = options;
  out.sensors_sigma_from_log.clear();
  for (const std::string& name : options.sensors_sigma_from_log) {
    const bool stated =
        std::find(options.sensors_with_sigma.begin(), options.sensors_with_sigma.end(), name) !=
        options.sensors_with_sigma.end();
    if (stated || options.sensor_weights.count(name)) {
      throw std::invalid_argument("sensor '" + name +
                                  "' (sigma: auto): it has a weight or sigma too; give one");
    }
    if (std::find(out.sensors_with_sigma.begin(), out.sensors_with_sigma.end(), name) !=
        out.sensors_with_sigma.end()) {
      throw std::invalid_argument("sensor '" + name + "' (sigma: auto) listed twice");
    }
    const double sigma = SigmaFromLog(name, fit.sequences, [&](const std::string& model) {
      for (const FitModel& mo : fit.models) {
        if (mo.name == model) return static_cast<const mjModel*>(mo.model.get());
      }
      return static_cast<const mjModel*>(nullptr);
    });
    out.sensor_weights[name] = 1.0 / sigma;
    out.sensors_with_sigma.push_back(name);
    if (sigmas) (*sigmas)[name] = sigma;
  }
  return out;
}

}  // namespace mjsysid
