// The experiment behind a fit's results, loaded again for the report: the motion clip
// (tools/report/motion.h) and the input plots (tools/report/interactive.h) need the logged
// controls and states, which the result files do not keep.
//
// Where they come from: result.yaml names the experiment file; it is loaded and its models and logs
// mapped to sequences as the fit did (run::BuildProblem, one thread). Never an error: when the
// results name no experiment, one of the files the fit read changed since (result.yaml's
// input_hashes, sysid/run/input_hashes.h), or the experiment cannot be read, `note` says why and
// there are no sequences.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"

namespace mjsysid::report {

struct LoggedExperiment {
  std::string note;  // why there is nothing ("" when the experiment was loaded)
  run::BuiltProblem built;

  // the fitted or held-out sequence of that name; nullptr when the experiment has none
  const FitSequence* Sequence(const std::string& name) const;
  // the model of a sequence (as loaded, before any fit); nullptr when not found
  const mjModel* ModelOf(const FitSequence& sequence) const;
};

LoggedExperiment LoadLoggedExperiment(const io::FitResultFile& result);

// A sequence's logged controls as logged: at their own times (ctrl_time, else the sample times,
// else x0.time + k * timestep), one column per actuator, named as in the model ("actuator k" when
// unnamed); `held`: the actuator's control is held between its samples (zero-order hold; false:
// linear). Empty (no rows) when the experiment or the sequence is not there or has no controls.
struct LoggedInputs {
  Eigen::VectorXd time;  // Tc (s)
  RowMatrix ctrl;        // Tc x nu
  std::vector<std::string> names;
  std::vector<bool> held;
};
LoggedInputs InputsOf(const LoggedExperiment& logged, const std::string& sequence);

}  // namespace mjsysid::report
