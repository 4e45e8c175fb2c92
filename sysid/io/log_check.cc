// HDF5 logs: the checks shared by writing, reading and validation (log_internal.h), and the name
// hints of the validation's messages.
#include <hdf5.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/log_internal.h"

namespace mjsysid::io {
namespace log_internal {

std::string Join(const std::vector<std::string>& items, size_t max_items) {
  std::string out;
  for (size_t i = 0; i < items.size() && i < max_items; ++i) {
    if (i) out += ", ";
    out += items[i];
  }
  if (items.size() > max_items) {
    out += ", ... (" + std::to_string(items.size() - max_items) + " more)";
  }
  return out;
}

// "<file>: <object>: <what>"
[[noreturn]] void Fail(const std::string& file, const std::string& object,
                       const std::string& what) {
  std::string msg = file;
  if (!object.empty()) msg += ": " + object;
  msg += ": " + what;
  throw LogError(msg);
}

// ---------------------------------------------------------------------------------------------
// checks shared by reading and writing

void CheckName(const std::string& name, const std::string& file, const std::string& object,
               const std::string& what) {
  if (name.find('\0') != std::string::npos) {
    Fail(file, object, what + " " + Quote(name) + " contains a NUL character");
  }
}

// every value finite and within +-kLargestLoggedMagnitude; with nan_allowed, NaN passes (a value
// not measured) and only Inf fails
void CheckFinite(const double* data, Eigen::Index rows, Eigen::Index cols, const std::string& file,
                 const std::string& object, bool nan_allowed) {
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < cols; ++c) {
      const double v = data[r * cols + c];
      if (std::isfinite(v) && std::abs(v) > kLargestLoggedMagnitude) {
        Fail(file, object,
             "row " + std::to_string(r) + ", column " + std::to_string(c) + ": value " +
                 FormatShortest(v) + " is beyond +-" + FormatShortest(kLargestLoggedMagnitude) +
                 ", where its square overflows the simulation and the cost (a unit or "
                 "conversion error?)");
      }
      if (std::isfinite(v) || (nan_allowed && std::isnan(v))) continue;
      Fail(file, object,
           "row " + std::to_string(r) + ", column " + std::to_string(c) + ": value " +
               FormatShortest(v) + " is not finite" +
               (nan_allowed ? " (NaN marks a value not measured; Inf is not allowed)"
                            : " (NaN/Inf are not allowed)"));
    }
  }
}

// rows of a matrix against the sample count, with a hint for transposed storage
void CheckRows(const RowMatrix& mat, Eigen::Index samples, bool optional, const std::string& file,
               const std::string& object, const std::string& times) {
  if (optional && mat.rows() == 0) {
    if (mat.cols() != 0) {
      Fail(file, object,
           "has 0 rows but " + std::to_string(mat.cols()) +
               " columns (an absent optional matrix is 0 x 0)");
    }
    return;
  }
  if (mat.rows() != samples) {
    const std::string transposed =
        mat.cols() == samples ? " (stored transposed? rows are samples)" : "";
    Fail(file, object,
         "has " + std::to_string(mat.rows()) + " rows (shape " + std::to_string(mat.rows()) +
             " x " + std::to_string(mat.cols()) + "), expected " + std::to_string(samples) +
             " = the samples in " + times + transposed);
  }
}

// a time dataset: at least one sample, finite, strictly increasing
void CheckTimeDataset(const Eigen::VectorXd& time, const std::string& file,
                      const std::string& object) {
  const Eigen::Index samples = time.size();
  if (samples < 1) Fail(file, object, "is empty (a sequence needs at least 1 sample)");
  CheckFinite(time.data(), samples, 1, file, object);
  for (Eigen::Index k = 1; k < samples; ++k) {
    if (!(time[k] > time[k - 1])) {
      Fail(file, object,
           "row " + std::to_string(k) + ": time " + FormatShortest(time[k]) +
               " is not greater than row " + std::to_string(k - 1) + "'s " +
               FormatShortest(time[k - 1]) + " (time must be strictly increasing)");
    }
  }
}

void CheckSequence(const Sequence& seq, const std::string& file) {
  const std::string gpath = "/" + seq.name;
  const Eigen::Index samples = seq.time.size();

  // time (and the controls' own times): at least one sample, finite, strictly increasing
  CheckTimeDataset(seq.time, file, gpath + "/time");
  const bool own_ctrl_time = seq.ctrl_time.size() > 0;
  if (own_ctrl_time) CheckTimeDataset(seq.ctrl_time, file, gpath + "/ctrl_time");

  // shapes
  CheckRows(seq.ctrl, own_ctrl_time ? seq.ctrl_time.size() : samples, false, file, gpath + "/ctrl",
            own_ctrl_time ? "ctrl_time" : "time");
  CheckRows(seq.sensordata, samples, false, file, gpath + "/sensordata");
  CheckRows(seq.qpos, samples, true, file, gpath + "/qpos");
  CheckRows(seq.qvel, samples, true, file, gpath + "/qvel");
  CheckRows(seq.act, samples, true, file, gpath + "/act");

  // actuator names: one per ctrl column
  if (static_cast<Eigen::Index>(seq.actuator_names.size()) != seq.ctrl.cols()) {
    Fail(file, gpath + "/ctrl",
         std::to_string(seq.actuator_names.size()) + " actuator names (attribute 'names') for " +
             std::to_string(seq.ctrl.cols()) + " columns");
  }
  for (const std::string& n : seq.actuator_names) CheckName(n, file, gpath + "/ctrl", "name");

  // sensor names and dims: one per sensor, dims summing to the columns
  if (seq.sensor_names.size() != seq.sensor_dims.size()) {
    Fail(file, gpath + "/sensordata",
         std::to_string(seq.sensor_names.size()) + " sensor names (attribute 'names') but " +
             std::to_string(seq.sensor_dims.size()) + " dims (attribute 'dims')");
  }
  Eigen::Index sum = 0;
  for (size_t i = 0; i < seq.sensor_dims.size(); ++i) {
    CheckName(seq.sensor_names[i], file, gpath + "/sensordata", "name");
    if (seq.sensor_dims[i] < 1) {
      Fail(file, gpath + "/sensordata",
           "sensor " + Quote(seq.sensor_names[i]) + " has dimension " +
               std::to_string(seq.sensor_dims[i]) + " (must be >= 1)");
    }
    sum += seq.sensor_dims[i];
  }
  if (sum != seq.sensordata.cols()) {
    Fail(file, gpath + "/sensordata",
         "sensor dims (attribute 'dims') sum to " + std::to_string(sum) + " but there are " +
             std::to_string(seq.sensordata.cols()) + " columns");
  }

  // values: finite, except NaN in ctrl, sensordata and the states (not measured: a sensor or
  // state value is masked out of the fit, a control held from the last valid one)
  const std::tuple<const char*, const RowMatrix*, bool> mats[] = {
      {"ctrl", &seq.ctrl, true},
      {"sensordata", &seq.sensordata, true},
      {"qpos", &seq.qpos, true},
      {"qvel", &seq.qvel, true},
      {"act", &seq.act, true}};
  for (const auto& [name, mat, nan_allowed] : mats) {
    CheckFinite(mat->data(), mat->rows(), mat->cols(), file, gpath + "/" + name, nan_allowed);
  }
}

bool IsReservedAttribute(const std::string& key) {
  return key == "format" || key == "format_version" || key == "sensor_time";
}

void CheckSensorTime(const std::string& sensor_time, const std::string& file) {
  if (sensor_time != "pre" && sensor_time != "post") {
    Fail(file, "/ attribute 'sensor_time'",
         "must be \"pre\" or \"post\", found \"" + sensor_time + "\"");
  }
}

void CheckLog(const Log& log, const std::string& file) {
  if (log.sequences.empty()) Fail(file, "/", "the log has no sequences");
  CheckSensorTime(log.sensor_time, file);
  for (const auto& [key, value] : log.attributes) {
    const std::string where = "/ attribute " + Quote(key);
    if (key.empty()) Fail(file, "/", "an attribute has an empty name");
    if (IsReservedAttribute(key)) {
      Fail(file, where, "is reserved (format, format_version and sensor_time are set by mjsysid)");
    }
    CheckName(key, file, where, "name");
    CheckName(value, file, where, "value");
  }
  std::set<std::string> seen;
  for (const Sequence& seq : log.sequences) {
    if (seq.name.empty() || seq.name == "." || seq.name.find('/') != std::string::npos) {
      Fail(file, "/" + seq.name,
           "sequence name " + Quote(seq.name) +
               " is not a valid group name (non-empty, no '/', "
               "not '.')");
    }
    CheckName(seq.name, file, "/", "sequence name");
    if (!seen.insert(seq.name).second) {
      Fail(file, "/" + seq.name, "two sequences have the name " + Quote(seq.name));
    }
    CheckSequence(seq, file);
  }
}

}  // namespace log_internal

namespace internal {

std::string NameHint(const std::string& wrong, const std::vector<std::string>& valid,
                     const std::string& what) {
  std::string out = Quote(wrong);
  // closest valid name, when close enough to be a typo
  const std::string best = ClosestName(wrong, valid);
  if (!best.empty()) out += " (did you mean " + Quote(best) + "?)";
  out += "; " + what + ": " + (valid.empty() ? std::string("none") : log_internal::Join(valid));
  return out;
}

}  // namespace internal

}  // namespace mjsysid::io
