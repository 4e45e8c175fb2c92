// The one check of a logged sequence's time base, applied alike by `sysid import`, `sysid check`
// and `sysid fit` (through ValidateLogAgainstModel, sysid/io/log.h). A log's samples may come at
// any times (their own rate, jitter, gaps): the fit simulates on the model's timestep and reads
// each sample at its own time (sysid/data/sample_grid.h), so the time base is not required to match
// the model's grid. What is checked:
//
// Errors (LogError, naming file, dataset and row): fewer than 2 samples; a time that is not finite
// or not greater than the one before; a median sample period below 1/100 of the model timestep
// (times in the wrong unit, e.g. milliseconds read as seconds against a model in microseconds, or
// a clock in ticks); control samples (when they have their own times) that do not overlap the
// sensor samples.
// Warnings (returned, one line each, naming where): a sample period that varies by more than 50 %
// of the median period (the first such row and how many); a gap longer than 10 median periods
// (the first such gap, its length in periods and how many).
//
// Units: seconds. Float32 time (stored by some loggers) is accepted: it is read as float64.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace mjsysid::io {

// Checks sample times `time` (T) for a model with timestep `timestep` (s, > 0); `ctrl_time`: the
// controls' own times, or nullptr when the controls share `time`. `file` and `object` name the
// dataset in messages ("<file>: <object>: ..."). Returns the warnings; throws LogError.
std::vector<std::string> CheckTimeBase(const Eigen::VectorXd& time, double timestep,
                                       const std::string& file, const std::string& object,
                                       const Eigen::VectorXd* ctrl_time = nullptr);

// the median of the differences of `time` (T >= 2), seconds
double MedianPeriod(const Eigen::VectorXd& time);

}  // namespace mjsysid::io
