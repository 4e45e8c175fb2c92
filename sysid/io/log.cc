#include "sysid/io/log.h"

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
#include "sysid/io/atomic_file.h"
#include "sysid/io/hdf5_util.h"
#include "sysid/io/log_child_process.h"
#include "sysid/io/time_base.h"

namespace mjsysid::io {
namespace {

constexpr char kFormat[] = "mjsysid-log";
constexpr int kFormatVersion = 1;
constexpr const char* kDatasets[] = {"time", "ctrl", "sensordata", "qpos",
                                     "qvel", "act",  "ctrl_time"};
// the optional groups of sensors logged at their own times
constexpr char kSensorTime[] = "sensor_time";
constexpr char kSensorValues[] = "sensor_values";

// ---------------------------------------------------------------------------------------------
// messages

std::string Join(const std::vector<std::string>& items, size_t max_items = 20) {
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
// hdf5 plumbing

// the shared hdf5 helpers (sysid/io/hdf5_util.h); they throw h5::Error, which the API functions
// below turn into LogError
using h5::Check;
using h5::FailH5;
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
using h5::WriteDataset;
using h5::WriteIntAttr;
using h5::WriteStringArrayAttr;
using h5::WriteStringAttr;

// ---------------------------------------------------------------------------------------------
// writing

H5Id WriteMatrix(hid_t group, const char* name, const RowMatrix& mat, const std::string& file,
                 const std::string& object) {
  const hsize_t dims[2] = {static_cast<hsize_t>(mat.rows()), static_cast<hsize_t>(mat.cols())};
  return WriteDataset(group, name, mat.data(), 2, dims, file, object);
}

void WriteSequence(hid_t file_id, const Sequence& seq, const std::string& file) {
  const std::string gpath = "/" + seq.name;
  H5Id group = h5::CreateGroup(file_id, seq.name, false, file, gpath);

  // time, with its unit
  const hsize_t t_dims[1] = {static_cast<hsize_t>(seq.time.size())};
  H5Id time = WriteDataset(group.get(), "time", seq.time.data(), 1, t_dims, file, gpath + "/time");
  WriteStringAttr(time.get(), "units", "s", file, gpath + "/time");

  // ctrl, with actuator names
  H5Id ctrl = WriteMatrix(group.get(), "ctrl", seq.ctrl, file, gpath + "/ctrl");
  WriteStringArrayAttr(ctrl.get(), "names", seq.actuator_names, file, gpath + "/ctrl");

  // sensordata, with sensor names and dimensions
  H5Id sens = WriteMatrix(group.get(), "sensordata", seq.sensordata, file, gpath + "/sensordata");
  WriteStringArrayAttr(sens.get(), "names", seq.sensor_names, file, gpath + "/sensordata");
  WriteIntAttr(sens.get(), "dims", seq.sensor_dims, false, file, gpath + "/sensordata");

  // optional states: absent when 0 rows
  const std::pair<const char*, const RowMatrix*> optional[] = {
      {"qpos", &seq.qpos}, {"qvel", &seq.qvel}, {"act", &seq.act}};
  for (const auto& [name, mat] : optional) {
    if (mat->rows() == 0) continue;
    WriteMatrix(group.get(), name, *mat, file, gpath + "/" + name);
  }

  // optional: the controls' own times
  if (seq.ctrl_time.size() > 0) {
    const hsize_t c_dims[1] = {static_cast<hsize_t>(seq.ctrl_time.size())};
    H5Id ct = WriteDataset(group.get(), "ctrl_time", seq.ctrl_time.data(), 1, c_dims, file,
                           gpath + "/ctrl_time");
    WriteStringAttr(ct.get(), "units", "s", file, gpath + "/ctrl_time");
  }
}

// ---------------------------------------------------------------------------------------------
// checks shared by reading and writing

void CheckName(const std::string& name, const std::string& file, const std::string& object,
               const std::string& what) {
  if (name.find('\0') != std::string::npos) {
    Fail(file, object, what + " " + Quote(name) + " contains a NUL character");
  }
}

// every value finite; with nan_allowed, NaN passes (a value not measured) and only Inf fails
void CheckFinite(const double* data, Eigen::Index rows, Eigen::Index cols, const std::string& file,
                 const std::string& object, bool nan_allowed = false) {
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < cols; ++c) {
      const double v = data[r * cols + c];
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
               const std::string& object, const std::string& times = "time") {
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

}  // namespace

// -----------------------------------------------------------------------------------------------

namespace internal {

std::string NameHint(const std::string& wrong, const std::vector<std::string>& valid,
                     const std::string& what) {
  std::string out = Quote(wrong);
  // closest valid name, when close enough to be a typo
  const std::string best = ClosestName(wrong, valid);
  if (!best.empty()) out += " (did you mean " + Quote(best) + "?)";
  out += "; " + what + ": " + (valid.empty() ? std::string("none") : Join(valid));
  return out;
}

}  // namespace internal

void WriteLog(const std::string& path, const Log& log) {
  CheckLog(log, path);
  std::lock_guard<std::mutex> lock(h5::Mutex());
  h5::Silence();
  const std::string& file = path;
  try {
    // everything into the temporary file; all handles closed before the rename
    ReplaceAtomically(path, [&](const std::string& tmp) {
      H5Id f = h5::CreateFile(tmp, file);
      H5Id root = Own(H5Gopen2(f.get(), "/", H5P_DEFAULT), H5Gclose, file, "/", "cannot open root");
      WriteStringAttr(root.get(), "format", kFormat, file, "/");
      WriteIntAttr(root.get(), "format_version", {kFormatVersion}, true, file, "/");
      WriteStringAttr(root.get(), "sensor_time", log.sensor_time, file, "/");
      for (const auto& [key, value] : log.attributes) {
        WriteStringAttr(root.get(), key, value, file, "/");
      }
      for (const Sequence& seq : log.sequences) WriteSequence(f.get(), seq, file);
      root.Close();
      if (!f.Close()) FailH5(file, "", "cannot finish writing temporary file " + tmp);
    });
  } catch (const h5::Error& e) {
    throw LogError(e.what());
  } catch (const FileError& e) {
    throw LogError(e.what());
  }
}

namespace {

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

Sequence WindowOf(const Sequence& seq, double start, double end, const std::string& file) {
  Eigen::Index first = 0, last = seq.time.size();  // rows [first, last)
  while (first < last && seq.time[first] < start) ++first;
  while (last > first && seq.time[last - 1] > end) --last;
  const Eigen::Index n = last - first;
  if (n < 2) {
    Fail(file, "/" + seq.name + "/time",
         "the window [" + FormatDigits(start, 9) + ", " + FormatDigits(end, 9) + "] s holds " +
             std::to_string(n) + " sample(s) of " + FormatDigits(seq.time[0], 9) + " .. " +
             FormatDigits(seq.time[seq.time.size() - 1], 9) + " s: at least 2 are needed");
  }
  Sequence w = seq;
  w.time = seq.time.segment(first, n);
  // controls at their own times stay whole: the hold and a delay reach back before the window
  if (seq.ctrl_time.size() == 0) w.ctrl = seq.ctrl.middleRows(first, n);
  w.sensordata = seq.sensordata.middleRows(first, n);
  for (auto [from, to] :
       {std::pair{&seq.qpos, &w.qpos}, {&seq.qvel, &w.qvel}, {&seq.act, &w.act}}) {
    if (from->rows() > 0) *to = from->middleRows(first, n);
  }
  return w;
}

void ValidateLogAgainstModel(const Log& log, const mjModel& m, const std::string& path_for_messages,
                             std::vector<std::string>* warnings) {
  const std::string& file = path_for_messages;
  CheckLog(log, file);
  const auto nu = static_cast<Eigen::Index>(m.nu);
  const auto nsensor = static_cast<int>(m.nsensor);

  // the model's names, for matching and hints
  std::vector<std::string> model_sensors;
  for (int i = 0; i < nsensor; ++i) {
    const char* n = mj_id2name(&m, mjOBJ_SENSOR, i);
    if (n) model_sensors.push_back(n);
  }
  std::vector<std::string> model_actuators;
  for (Eigen::Index i = 0; i < nu; ++i) {
    const char* n = mj_id2name(&m, mjOBJ_ACTUATOR, static_cast<int>(i));
    model_actuators.push_back(n ? n : "");
  }
  auto display = [](const std::string& n) { return n.empty() ? std::string("<unnamed>") : n; };

  for (const Sequence& seq : log.sequences) {
    const std::string gpath = "/" + seq.name;

    // sensors: known names, matching dimensions, no repeats
    std::set<std::string> seen;
    for (size_t i = 0; i < seq.sensor_names.size(); ++i) {
      const std::string& name = seq.sensor_names[i];
      const int id = name.empty() ? -1 : mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
      if (id < 0) {
        Fail(file, gpath + "/sensordata",
             "unknown sensor " + internal::NameHint(name, model_sensors, "the model's sensors"));
      }
      if (m.sensor_dim[id] != seq.sensor_dims[i]) {
        Fail(file, gpath + "/sensordata",
             "sensor " + Quote(name) + " has " + std::to_string(seq.sensor_dims[i]) +
                 " columns in the log but dimension " + std::to_string(m.sensor_dim[id]) +
                 " in the model");
      }
      if (!seen.insert(name).second) {
        Fail(file, gpath + "/sensordata", "sensor " + Quote(name) + " appears twice");
      }
    }

    // actuators: exactly the model's, in model order
    if (seq.actuator_names != model_actuators) {
      const std::string where = gpath + "/ctrl";
      const std::string counts = seq.ctrl.cols() == nu
                                     ? std::string()
                                     : "ctrl has " + std::to_string(seq.ctrl.cols()) +
                                           " columns, the model has nu = " + std::to_string(nu) +
                                           " actuators; ";
      for (const std::string& name : seq.actuator_names) {
        if (std::find(model_actuators.begin(), model_actuators.end(), name) ==
            model_actuators.end()) {
          Fail(file, where,
               counts + "unknown actuator " +
                   internal::NameHint(name, model_actuators, "the model's actuators"));
        }
      }
      std::vector<std::string> missing;
      for (const std::string& name : model_actuators) {
        if (std::find(seq.actuator_names.begin(), seq.actuator_names.end(), name) ==
            seq.actuator_names.end()) {
          missing.push_back(Quote(display(name)));
        }
      }
      if (!missing.empty()) {
        Fail(file, where,
             counts + "missing actuator(s) " + Join(missing) +
                 " (ctrl needs one column per actuator of the model, in model order)");
      }
      std::vector<std::string> got, want;
      for (const std::string& n : seq.actuator_names) got.push_back(display(n));
      for (const std::string& n : model_actuators) want.push_back(display(n));
      Fail(file, where,
           "actuator columns [" + Join(got) + "] must be the model's actuators in model order [" +
               Join(want) + "]");
    }

    // states: model widths
    const std::tuple<const char*, const RowMatrix*, const char*, Eigen::Index> states[] = {
        {"qpos", &seq.qpos, "nq", static_cast<Eigen::Index>(m.nq)},
        {"qvel", &seq.qvel, "nv", static_cast<Eigen::Index>(m.nv)},
        {"act", &seq.act, "na", static_cast<Eigen::Index>(m.na)}};
    for (const auto& [name, mat, size_name, width] : states) {
      if (mat->rows() == 0 || mat->cols() == width) continue;
      Fail(file, gpath + "/" + name,
           "has " + std::to_string(mat->cols()) + " columns, the model has " + size_name + " = " +
               std::to_string(width));
    }

    // values not measured (NaN): a control needs a valid first value to hold, a sensor column at
    // least one measured sample
    for (Eigen::Index i = 0; i < seq.ctrl.cols(); ++i) {
      if (std::isnan(seq.ctrl(0, i))) {
        Fail(file, gpath + "/ctrl",
             "row 0, column " + std::to_string(i) + " (actuator " +
                 Quote(display(seq.actuator_names[i])) +
                 "): NaN in the first row: a NaN control is held from the last valid value, and "
                 "there is none before it (start the log at the first command)");
      }
    }
    for (Eigen::Index c = 0, i = 0, first = 0; c < seq.sensordata.cols(); ++c) {
      if (c == first + seq.sensor_dims[i]) first += seq.sensor_dims[i++];
      if (seq.sensordata.col(c).array().isNaN().all()) {
        Fail(file, gpath + "/sensordata",
             "column " + std::to_string(c) + " (sensor " + Quote(seq.sensor_names[i]) +
                 "): every value is NaN (not measured): nothing to fit; leave the sensor out");
      }
    }

    // the time base (sysid/io/time_base.h) of every time dataset: increasing, in seconds; its
    // warnings. The sample times and the controls' own times must overlap. With sensors at their
    // own times the union is checked for errors only (its period varies by construction) and
    // each time dataset as read gives the warnings.
    const double dt = m.opt.timestep;
    const Eigen::VectorXd* ctrl_time = seq.ctrl_time.size() ? &seq.ctrl_time : nullptr;
    const bool merged = !seq.own_times.empty();
    std::vector<std::string> found = CheckTimeBase(
        seq.time, dt, file,
        gpath + (merged ? " (sample times: the union of its time datasets)" : "/time"), ctrl_time);
    if (merged) {
      found.clear();
      for (const auto& [object, times] : seq.own_times) {
        for (std::string& w : CheckTimeBase(times, dt, file, object)) found.push_back(std::move(w));
      }
    }
    if (ctrl_time && ctrl_time->size() >= 2) {
      for (std::string& w : CheckTimeBase(*ctrl_time, dt, file, gpath + "/ctrl_time")) {
        found.push_back(std::move(w));
      }
    }
    for (std::string& w : found) {
      if (warnings) warnings->push_back(std::move(w));
    }
  }
}

}  // namespace mjsysid::io
