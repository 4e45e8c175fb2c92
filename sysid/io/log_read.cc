// HDF5 logs read: ReadLog (in a child process) and ReadLogInProcess, every dataset checked as it
// is read.
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
#include "sysid/io/hdf5_util.h"
#include "sysid/io/log.h"
#include "sysid/io/log_child_process.h"
#include "sysid/io/log_internal.h"

namespace mjsysid::io {
namespace {

using namespace log_internal;  // NOLINT(build/namespaces): the log format's own internals

// every dataset a sequence group may hold (besides the groups of sensors at their own times)
constexpr const char* kDatasets[] = {"time", "ctrl", "sensordata", "qpos",
                                     "qvel", "act",  "ctrl_time"};

// ---------------------------------------------------------------------------------------------
// hdf5 plumbing

// the shared hdf5 helpers (sysid/io/hdf5_util.h); they throw h5::Error, which the API functions
// below turn into LogError
using h5::Check;
using h5::Own;
using H5Id = h5::Id;
using h5::Array;
using h5::AttributeNames;
using h5::Elements;
using h5::LinkNames;
using h5::OpenAttrIfAny;
using h5::ReadInts;
using h5::ReadScalarString;
using h5::ReadStrings;
using h5::ToMatrix;

// ---------------------------------------------------------------------------------------------
// reading

// a free-form root attribute: strings as they are, numeric scalars as decimal text
std::string ReadAttributeAsText(hid_t obj, const std::string& name, const std::string& file) {
  const std::string where = "/ attribute " + Quote(name);
  H5Id attr =
      Own(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose, file, where, "cannot open attribute");
  H5Id ftype = Own(H5Aget_type(attr.get()), H5Tclose, file, where, "cannot read attribute type");
  const H5T_class_t cls = H5Tget_class(ftype.get());
  if (cls == H5T_STRING) {
    std::vector<std::string> v = ReadStrings(attr.get(), file, where);
    if (v.size() != 1) Fail(file, where, "must be a single string");
    return v[0];
  }
  H5Id space = Own(H5Aget_space(attr.get()), H5Sclose, file, where, "cannot read attribute space");
  if (cls != H5T_INTEGER && cls != H5T_FLOAT) {
    Fail(file, where, "must be a string or a number (metadata attributes are text)");
  }
  if (Elements(space.get(), file, where) != 1) Fail(file, where, "must be a single value");
  if (cls == H5T_INTEGER) return std::to_string(ReadInts(attr.get(), file, where)[0]);
  double value = 0;
  Check(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value), file, where, "cannot read attribute");
  return FormatShortest(value);
}

// a numeric dataset of the expected rank, as doubles in row-major order
Array ReadArray(hid_t group, const char* name, int rank, const std::string& file,
                const std::string& object) {
  return h5::ReadArray(group, name, rank, file, object,
                       rank == 1 ? " (T samples)" : " (T samples x columns)");
}

// dataset `dataset` (rows x columns) of a sequence group and its `names` attribute, required
// when there are columns (`meaning` says what the names are); returns the open dataset for its
// other attributes
H5Id ReadNamedColumns(hid_t group, const char* dataset, Eigen::Index rows, const std::string& file,
                      const std::string& gpath, const std::string& meaning, RowMatrix* values,
                      std::vector<std::string>* names, const std::string& times = "time") {
  const std::string where = gpath + "/" + dataset;
  *values = ToMatrix(ReadArray(group, dataset, 2, file, where));
  CheckRows(*values, rows, false, file, where, times);
  H5Id dset =
      Own(H5Dopen2(group, dataset, H5P_DEFAULT), H5Dclose, file, where, "cannot open dataset");
  H5Id attr = OpenAttrIfAny(dset.get(), "names", file, where);
  if (attr.get() >= 0) {
    *names = ReadStrings(attr.get(), file, where + " attribute 'names'");
  } else if (values->cols() > 0) {
    Fail(file, where + " attribute 'names'", "is missing (" + meaning + ")");
  }
  return dset;
}

// a time dataset of a group (rank 1, seconds), checked finite and strictly increasing
Eigen::VectorXd ReadTimes(hid_t group, const char* name, const std::string& file,
                          const std::string& where) {
  Array t = ReadArray(group, name, 1, file, where);
  Eigen::VectorXd time =
      Eigen::Map<Eigen::VectorXd>(t.data.data(), static_cast<Eigen::Index>(t.dims[0]));
  H5Id dset = Own(H5Dopen2(group, name, H5P_DEFAULT), H5Dclose, file, where, "cannot open dataset");
  H5Id units = OpenAttrIfAny(dset.get(), "units", file, where);
  if (units.get() >= 0) {
    std::vector<std::string> u = ReadStrings(units.get(), file, where + " attribute 'units'");
    if (u.size() != 1 || u[0] != "s") {
      Fail(file, where + " attribute 'units'",
           "must be \"s\" (time is stored in seconds), found \"" + Join(u) + "\"");
    }
  }
  CheckTimeDataset(time, file, where);
  return time;
}

// a sensor logged at its own times (sensor_time/<name>, sensor_values/<name>)
struct OwnTimeSensor {
  std::string name;
  Eigen::VectorXd time;  // Ts
  RowMatrix values;      // Ts x dim
};

// the sensors of groups sensor_time/ and sensor_values/ of sequence group `gpath`
std::vector<OwnTimeSensor> ReadOwnTimeSensors(hid_t group, const std::string& file,
                                              const std::string& gpath) {
  const std::string tpath = gpath + "/" + kSensorTime, vpath = gpath + "/" + kSensorValues;
  H5Id tgroup = Own(H5Gopen2(group, kSensorTime, H5P_DEFAULT), H5Gclose, file, tpath,
                    "cannot open group (sensor_time must be a group of one time dataset per "
                    "sensor)");
  H5Id vgroup = Own(H5Gopen2(group, kSensorValues, H5P_DEFAULT), H5Gclose, file, vpath,
                    "cannot open group (sensor_values must be a group of one dataset per sensor)");
  const std::vector<std::string> names = LinkNames(tgroup.get(), file, tpath);
  const std::vector<std::string> value_names = LinkNames(vgroup.get(), file, vpath);
  for (const std::string& v : value_names) {
    if (std::find(names.begin(), names.end(), v) == names.end()) {
      Fail(file, vpath + "/" + v,
           "has no times: expected dataset " + tpath + "/" + v + " (Ts) with the sample times");
    }
  }
  if (names.empty()) Fail(file, tpath, "is empty (expected one time dataset per sensor)");
  std::vector<OwnTimeSensor> out;
  for (const std::string& n : names) {
    if (std::find(value_names.begin(), value_names.end(), n) == value_names.end()) {
      Fail(file, vpath + "/" + n,
           "is missing: expected the values of sensor " + Quote(n) + " at " + tpath + "/" + n +
               " (Ts x dim)");
    }
    OwnTimeSensor s;
    s.name = n;
    s.time = ReadTimes(tgroup.get(), n.c_str(), file, tpath + "/" + n);
    const std::string where = vpath + "/" + n;
    s.values = ToMatrix(h5::ReadArray(vgroup.get(), n.c_str(), 2, file, where,
                                      " (Ts samples x the sensor's columns)"));
    CheckRows(s.values, s.time.size(), false, file, where, tpath + "/" + n);
    if (s.values.cols() < 1) Fail(file, where, "has 0 columns (a sensor has at least 1)");
    CheckFinite(s.values.data(), s.values.rows(), s.values.cols(), file, where, true);
    out.push_back(std::move(s));
  }
  return out;
}

// the rows of `times` in `all` (every time of `times` is in `all`, exactly)
std::vector<Eigen::Index> RowsIn(const std::vector<double>& all, const Eigen::VectorXd& times) {
  std::vector<Eigen::Index> rows(static_cast<size_t>(times.size()));
  for (Eigen::Index k = 0; k < times.size(); ++k) {
    rows[k] = std::lower_bound(all.begin(), all.end(), times[k]) - all.begin();
  }
  return rows;
}

Sequence ReadSequence(hid_t file_id, const std::string& name, const std::string& file) {
  const std::string gpath = "/" + name;
  H5Id group =
      Own(H5Gopen2(file_id, name.c_str(), H5P_DEFAULT), H5Gclose, file, gpath, "cannot open group");
  Sequence seq;
  seq.name = name;

  // members: only the known datasets and groups
  std::set<std::string> present;
  for (const std::string& member : LinkNames(group.get(), file, gpath)) {
    if (std::find(std::begin(kDatasets), std::end(kDatasets), member) == std::end(kDatasets) &&
        member != kSensorTime && member != kSensorValues) {
      Fail(file, gpath + "/" + member,
           "unknown member of a sequence group (expected time, ctrl, sensordata and optionally "
           "qpos, qvel, act, ctrl_time, sensor_time/, sensor_values/)");
    }
    present.insert(member);
  }
  // which datasets are required: sensors at their own times make time and sensordata optional
  const bool own_sensors = present.count(kSensorTime) || present.count(kSensorValues);
  if (own_sensors) {
    for (const char* pair : {kSensorTime, kSensorValues}) {
      if (!present.count(pair)) {
        Fail(file, gpath + "/" + pair,
             "is missing: sensor_time/ (times) and sensor_values/ (values) come together");
      }
    }
    if (present.count("time") != present.count("sensordata")) {
      Fail(file, gpath + "/" + (present.count("time") ? "sensordata" : "time"),
           "is missing: time and sensordata come together (both may be left out when every "
           "sensor is in sensor_time/ and sensor_values/)");
    }
    if (!present.count("time") && !present.count("ctrl_time")) {
      Fail(file, gpath + "/ctrl_time",
           "is missing: without a time dataset the controls need their own times (Tc)");
    }
    for (const char* state : {"qpos", "qvel", "act"}) {
      if (present.count(state) && !present.count("time")) {
        Fail(file, gpath + "/time", std::string("is missing: ") + state + " needs its times");
      }
    }
  }
  const bool has_time = present.count("time") > 0;
  for (const char* required : {"time", "ctrl", "sensordata"}) {
    if (!present.count(required) && !(own_sensors && std::string(required) != "ctrl")) {
      Fail(file, gpath + "/" + required, "required dataset is missing");
    }
  }

  // time and the controls' own times, in seconds
  Eigen::VectorXd time;
  if (has_time) time = ReadTimes(group.get(), "time", file, gpath + "/time");
  if (present.count("ctrl_time")) {
    seq.ctrl_time = ReadTimes(group.get(), "ctrl_time", file, gpath + "/ctrl_time");
  }
  seq.time = time;

  // ctrl and actuator names
  ReadNamedColumns(group.get(), "ctrl", seq.ctrl_time.size() ? seq.ctrl_time.size() : time.size(),
                   file, gpath, "one actuator name per column", &seq.ctrl, &seq.actuator_names,
                   seq.ctrl_time.size() ? "ctrl_time" : "time");

  // sensordata, sensor names and dimensions
  if (present.count("sensordata")) {
    const std::string where = gpath + "/sensordata";
    H5Id dset = ReadNamedColumns(group.get(), "sensordata", time.size(), file, gpath,
                                 "one name per sensor", &seq.sensordata, &seq.sensor_names);
    H5Id dims = OpenAttrIfAny(dset.get(), "dims", file, where);
    if (dims.get() >= 0) {
      const std::string dwhere = where + " attribute 'dims'";
      for (long long d : ReadInts(dims.get(), file, dwhere)) {
        if (d < 1 || d > 1000000000) {
          Fail(file, dwhere, "dimension " + std::to_string(d) + " is out of range (must be >= 1)");
        }
        seq.sensor_dims.push_back(static_cast<int>(d));
      }
    } else if (seq.sensordata.cols() > 0) {
      Fail(file, where + " attribute 'dims'", "is missing (columns of each sensor)");
    }
  }

  // optional states
  const std::pair<const char*, RowMatrix*> optional[] = {
      {"qpos", &seq.qpos}, {"qvel", &seq.qvel}, {"act", &seq.act}};
  for (const auto& [dname, mat] : optional) {
    if (!present.count(dname)) continue;
    *mat = ToMatrix(ReadArray(group.get(), dname, 2, file, gpath + "/" + dname));
    CheckRows(*mat, time.size(), false, file, gpath + "/" + dname);
  }
  if (!own_sensors) return seq;

  // sensors at their own times: merged onto the union of all sample times, NaN where a sensor
  // was not sampled
  const std::vector<OwnTimeSensor> own = ReadOwnTimeSensors(group.get(), file, gpath);
  std::vector<double> all(time.data(), time.data() + time.size());
  if (has_time) seq.own_times.emplace_back(gpath + "/time", time);
  for (const OwnTimeSensor& s : own) {
    all.insert(all.end(), s.time.data(), s.time.data() + s.time.size());
    seq.own_times.emplace_back(gpath + "/" + kSensorTime + "/" + s.name, s.time);
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  const auto T = static_cast<Eigen::Index>(all.size());
  Eigen::Index cols = seq.sensordata.cols();
  for (const OwnTimeSensor& s : own) cols += s.values.cols();
  RowMatrix merged = RowMatrix::Constant(T, cols, std::numeric_limits<double>::quiet_NaN());
  const std::vector<Eigen::Index> base_rows = RowsIn(all, time);
  for (Eigen::Index k = 0; k < time.size(); ++k) {
    merged.row(base_rows[k]).head(seq.sensordata.cols()) = seq.sensordata.row(k);
  }
  Eigen::Index col = seq.sensordata.cols();
  for (const OwnTimeSensor& s : own) {
    const std::vector<Eigen::Index> rows = RowsIn(all, s.time);
    for (Eigen::Index k = 0; k < s.time.size(); ++k) {
      merged.row(rows[k]).segment(col, s.values.cols()) = s.values.row(k);
    }
    col += s.values.cols();
    seq.sensor_names.push_back(s.name);
    seq.sensor_dims.push_back(static_cast<int>(s.values.cols()));
  }
  seq.sensordata = std::move(merged);
  seq.time = Eigen::Map<const Eigen::VectorXd>(all.data(), T);

  // the controls and states of `time`, when the sensor times add samples to it
  if (has_time && T != time.size()) {
    for (const auto& [dname, mat] : optional) {
      if (mat->rows() == 0) continue;
      Fail(file, gpath + "/" + dname,
           "the sensors in sensor_time/ add " + std::to_string(T - time.size()) +
               " sample time(s) not in " + gpath +
               "/time, where this state has no value (logged states need a value at every sample "
               "time: log them at times that include every sensor time, or leave them out)");
    }
    if (seq.ctrl_time.size() == 0) seq.ctrl_time = time;
  }
  return seq;
}

// the caller holds h5::Mutex()
Log ReadLogFileLocked(const std::string& path) {
  const std::string& file = path;
  h5::Silence();
  H5Id f = h5::OpenFile(path, file);
  H5Id root = Own(H5Gopen2(f.get(), "/", H5P_DEFAULT), H5Gclose, file, "/",
                  "cannot open the root group (corrupt file?)");

  // format attributes
  Log log;
  const std::string format = ReadScalarString(root.get(), "format", file, "/",
                                              " (not an mjsysid log: expected \"mjsysid-log\")");
  if (format != kFormat) {
    Fail(file, "/ attribute 'format'",
         "is \"" + format + "\", expected \"" + kFormat + "\" (not an mjsysid log)");
  }
  {
    H5Id version = OpenAttrIfAny(root.get(), "format_version", file, "/");
    if (version.get() < 0) Fail(file, "/ attribute 'format_version'", "is missing");
    std::vector<long long> v = ReadInts(version.get(), file, "/ attribute 'format_version'");
    if (v.size() != 1 || v[0] != kFormatVersion) {
      Fail(file, "/ attribute 'format_version'",
           "version " + (v.empty() ? std::string("?") : std::to_string(v[0])) +
               " is not supported (this build reads version " + std::to_string(kFormatVersion) +
               ")");
    }
  }
  log.sensor_time =
      ReadScalarString(root.get(), "sensor_time", file, "/", " (\"pre\" or \"post\")");
  CheckSensorTime(log.sensor_time, file);
  for (const std::string& key : AttributeNames(root.get(), file, "/")) {
    if (IsReservedAttribute(key)) continue;
    log.attributes[key] = ReadAttributeAsText(root.get(), key, file);
  }

  // one group per sequence; nothing else at the root
  for (const std::string& name : LinkNames(root.get(), file, "/")) {
    H5Id obj = Own(H5Oopen(root.get(), name.c_str(), H5P_DEFAULT), H5Oclose, file, "/" + name,
                   "cannot open (dangling link or corrupt file?)");
    if (H5Iget_type(obj.get()) != H5I_GROUP) {
      const bool flat = name == "time" || name == "ctrl" || name == "sensordata";
      Fail(file, "/" + name,
           std::string("is not a group: each sequence is a group holding its datasets") +
               (flat ? " (move root-level time/ctrl/sensordata into a group)" : ""));
    }
    log.sequences.push_back(ReadSequence(f.get(), name, file));
  }
  if (log.sequences.empty()) Fail(file, "/", "the log has no sequences (no groups at the root)");

  // the same checks as on writing
  CheckLog(log, file);
  return log;
}

}  // namespace

Log ReadLog(const std::string& path) {
  try {
    return internal::ReadInChildProcess(path, ReadLogFileLocked);
  } catch (const h5::Error& e) {
    throw LogError(e.what());
  }
}

namespace internal {

Log ReadLogInProcess(const std::string& path) {
  try {
    std::lock_guard<std::mutex> lock(h5::Mutex());
    return ReadLogFileLocked(path);
  } catch (const h5::Error& e) {
    throw LogError(e.what());
  }
}

}  // namespace internal

}  // namespace mjsysid::io
