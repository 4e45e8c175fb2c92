// The one check of a logged sequence's time base, applied alike by `sysid import`, `sysid check`
// and `sysid fit` (through ValidateLogAgainstModel, sysid/io/log.h). A log's samples may come at
// any times (their own rate, jitter, gaps): the fit simulates on the model's timestep and reads
// each sample at its own time (sysid/data/sample_grid.h), so the time base is not required to match
// the model's grid. What is checked:
//
// Errors (LogError, naming file, dataset and row): fewer than 2 samples; a time that is not finite
// or not greater than the one before; a median sample period below 1/100 of the model timestep
// (times in the wrong unit, e.g. milliseconds read as seconds against a model in microseconds, or
// a clock in ticks); a median sample period above 100 x the model timestep (times in a smaller
// unit read as seconds: milliseconds, microseconds or nanoseconds; the fit would simulate 1000 x
// or more the steps), for the sequence's sample times only (a sensor or the controls at their own
// times may be slow); a time dataset spanning more than one day (86400 s); control samples (when
// they have their own times) that do not overlap the sensor samples. The unit errors name the
// likely unit ("time looks like milliseconds: periods of 2 'seconds' on a 0.002 s model") and the
// fix: time in seconds, or `sysid import --time-scale FACTOR` (ScaleTime).
// Warnings (returned, one line each, naming where): a sample period that varies by more than 50 %
// of the median period (the first such row and how many); a gap longer than 10 median periods
// (the first such gap, its length in periods and how many).
//
// Units: seconds. Float32 time (stored by some loggers) is accepted: it is read as float64.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sysid/io/log.h"

namespace mjsysid::io {

// what a time dataset is to the check: the sequence's sample times (`time`, or the union of its
// time datasets; every check), or a dataset at its own times (a sensor's `sensor_time/<sensor>`,
// `ctrl_time`; any slow rate)
enum class TimeDataset { kSamples, kOwnTimes };

// Checks sample times `time` (T) for a model with timestep `timestep` (s, > 0); `ctrl_time`: the
// controls' own times, or nullptr when the controls share `time`. `file` and `object` name the
// dataset in messages ("<file>: <object>: ..."). Returns the warnings; throws LogError.
std::vector<std::string> CheckTimeBase(const Eigen::VectorXd& time, double timestep,
                                       const std::string& file, const std::string& object,
                                       const Eigen::VectorXd* ctrl_time = nullptr,
                                       TimeDataset kind = TimeDataset::kSamples);

// Multiplies every time of `seq` (time, ctrl_time, own_times) by `factor` (`sysid import
// --time-scale`: 0.001 for milliseconds, 1e-9 for nanoseconds). Throws LogError naming `source`
// unless factor is finite and > 0.
void ScaleTime(double factor, const std::string& source, Sequence* seq);

// the median of the differences of `time` (T >= 2), seconds
double MedianPeriod(const Eigen::VectorXd& time);

}  // namespace mjsysid::io
