// Internal to sysid/io/log*.cc: the log format's constants, its messages and the checks shared by
// writing (log_write.cc), reading (log_read.cc) and validation against a model (log.cc). Each
// check throws LogError "<file>: <object>: <what>".
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sysid/io/log.h"

namespace mjsysid::io::log_internal {

inline constexpr char kFormat[] = "mjsysid-log";
inline constexpr int kFormatVersion = 1;
// the optional groups of sensors logged at their own times
inline constexpr char kSensorTime[] = "sensor_time";
inline constexpr char kSensorValues[] = "sensor_values";

// the items joined by ", ", at most max_items of them, then "... (N more)"
std::string Join(const std::vector<std::string>& items, size_t max_items = 20);
// "<file>: <object>: <what>"
[[noreturn]] void Fail(const std::string& file, const std::string& object, const std::string& what);

// a name without NUL characters (`what`: what the name names, for the message)
void CheckName(const std::string& name, const std::string& file, const std::string& object,
               const std::string& what);
// every value finite; with nan_allowed, NaN passes (a value not measured) and only Inf fails
void CheckFinite(const double* data, Eigen::Index rows, Eigen::Index cols, const std::string& file,
                 const std::string& object, bool nan_allowed = false);
// rows of a matrix against the sample count, with a hint for transposed storage
void CheckRows(const RowMatrix& mat, Eigen::Index samples, bool optional, const std::string& file,
               const std::string& object, const std::string& times = "time");
// a time dataset: at least one sample, finite, strictly increasing
void CheckTimeDataset(const Eigen::VectorXd& time, const std::string& file,
                      const std::string& object);
// the root attributes mjsysid sets itself (format, format_version, sensor_time)
bool IsReservedAttribute(const std::string& key);
// "pre" or "post"
void CheckSensorTime(const std::string& sensor_time, const std::string& file);
// the whole log: sequences, their names, shapes and values, the root attributes
void CheckLog(const Log& log, const std::string& file);

}  // namespace mjsysid::io::log_internal
