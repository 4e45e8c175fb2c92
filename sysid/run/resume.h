// `sysid fit --resume DIR`: continue a fit from its checkpoint.
//
// The checkpoint of output folder DIR is, newest first: DIR.partial/checkpoint.{yaml,h5} (a run
// that was killed, or failed to write its result, after at least one iteration), else DIR's
// result when its status is `interrupted` (a run stopped by a signal). It holds the values after
// the last successful iteration, the costs and the trace so far (sysid/io/result.h).
//
// A resumed fit starts Ceres' Levenberg-Marquardt from the checkpoint's values with the
// iterations left (max_iterations minus those done); its result counts every iteration, keeps
// the first run's initial values and initial cost, and appends its trace to the checkpoint's.
// Ceres' trust-region radius and Jacobian column scaling restart, so the path after the
// checkpoint may differ from the uninterrupted one while the estimate agrees to the solver's
// tolerances (tests/tools/sysid_outputs_test.cc measures it).
#pragma once

#include <optional>
#include <string>

#include "sysid/io/experiment.h"
#include "sysid/io/result.h"

namespace mjsysid::run {

// the checkpoint of output folder `dir`, if any (see above); throws io::ResultError when the
// files are there but unreadable
std::optional<io::FitResultFile> FindCheckpoint(const std::string& dir);

// the experiment with the checkpoint's values as initial values and the iterations left; throws
// OutputError when the checkpoint is not of this experiment (name, parameters) or when the fit
// estimates initial states or uses multiple shooting (their values are not checkpointed)
io::ExperimentConfig ResumedConfig(const io::ExperimentConfig& config,
                                   const io::FitResultFile& checkpoint);

// `resumed` (the fit from the checkpoint) as one run with `checkpoint`: iterations, trace,
// initial cost, wall time and the initial values of the first run
void AppendToCheckpoint(const io::FitResultFile& checkpoint, io::FitResultFile* resumed);

}  // namespace mjsysid::run
