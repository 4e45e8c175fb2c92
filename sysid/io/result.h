// Results of a fit on disk: DIR/result.yaml (human-readable summary) and DIR/result.h5 (arrays).
//
// Contract:
// - Both writers are atomic (write PATH.tmp-<pid>, fsync, rename): a reader never sees a half file,
//   and an interrupted fit leaves the last complete write (the last good iterate) in place.
// - result.yaml keys (schema "mjsysid-result", version 1):
//     format, format_version, name, experiment, status, termination, created, mjsysid_version,
//     mujoco_version, jacobian_mode, iterations, initial_cost, final_cost, residual_variance,
//     num_residuals, wall_time_s, solver (map of setting -> value as text),
//     parameters (list of {name, value, initial, std, ci95: [lo, hi], flags: [...], truth?}),
//     unidentifiable (list of text), warnings (list of text), identified_models (map model -> file)
//   std and ci95 bounds that are infinite are written as .inf / -.inf; flags are any of
//   at_lower_bound, at_upper_bound, unidentifiable.
// - result.h5 layout: root attributes format = "mjsysid-result", format_version = 1, status;
//   /parameters/{value, initial, std, ci95_low, ci95_high} (np) with string attribute `names`;
//   /covariance (np x np); /jacobian (nres x np); /trace/{iteration, cost, step_norm,
//   gradient_norm, seconds, successful} (nit) and /trace/parameters (nit x np);
//   /sequences/<name>/{time (T), measured, simulated_initial, simulated_final (T x ns)} with
//   attributes model, sensor_names (strings), sensor_dims (ints).
// - Read* throw ResultError naming the file and the key/dataset on missing or malformed content.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/state.h"

namespace mjsysid::io {

class ResultError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ResultParameter {
  std::string name;
  double value = 0, initial = 0;
  double std_error = 0;  // +inf when unidentifiable
  double ci95_low = 0, ci95_high = 0;
  bool at_lower = false, at_upper = false, identifiable = true;
  std::optional<double> truth;  // from the experiment's simulate.truth, when known
};

struct ResultTraceEntry {
  int iteration = 0;
  double cost = 0, step_norm = 0, gradient_norm = 0, seconds = 0;
  bool successful = true;
  std::vector<double> parameters;  // np, physical values after the iteration
};

struct ResultSequence {
  std::string name, model;
  std::vector<std::string> sensor_names;  // fitted sensors
  std::vector<int> sensor_dims;           // their dimensions; columns below are these, in order
  Eigen::VectorXd time;                   // T
  RowMatrix measured, simulated_initial, simulated_final;  // T x sum(sensor_dims)
};

struct FitResultFile {
  std::string name, experiment, status, termination, created;
  std::string mjsysid_version, mujoco_version, jacobian_mode;
  int iterations = 0, num_residuals = 0;
  double initial_cost = 0, final_cost = 0, residual_variance = 0, wall_time_s = 0;
  std::map<std::string, std::string> solver;
  std::vector<ResultParameter> parameters;
  std::vector<std::string> unidentifiable, warnings;
  std::map<std::string, std::string> identified_models;  // model name -> file name in DIR
  std::vector<ResultTraceEntry> trace;
  Eigen::MatrixXd covariance;  // np x np
  RowMatrix jacobian;          // nres x np
  std::vector<ResultSequence> sequences;
};

void WriteResultYaml(const std::string& path, const FitResultFile& result);
void WriteResultH5(const std::string& path, const FitResultFile& result);

// reads DIR/result.yaml and DIR/result.h5 into one FitResultFile
FitResultFile ReadResult(const std::string& dir);

}  // namespace mjsysid::io
