#include "sysid/io/log.h"

#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <new>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace mjsysid::io {
namespace {

constexpr char kFormat[] = "mjsysid-log";
constexpr int kFormatVersion = 1;
constexpr const char* kDatasets[] = {"time", "ctrl", "sensordata", "qpos", "qvel", "act"};

// ---------------------------------------------------------------------------------------------
// messages

// the shortest of %.15g..%.17g that reads back as x: tells two doubles apart, stays readable
std::string Exact(double x) {
  char buf[32];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof(buf), "%.*g", digits, x);
    if (std::strtod(buf, nullptr) == x || !std::isfinite(x)) break;
  }
  return buf;
}

// "%.12g": short, for ratios and periods
std::string Short(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.12g", x);
  return buf;
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

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

// edit distance, for "did you mean"
size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t subst = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, subst});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// ---------------------------------------------------------------------------------------------
// hdf5 plumbing

// hdf5 is not thread-safe in its default build: every call of this file runs under this lock
std::mutex& Hdf5Mutex() {
  static std::mutex mu;
  return mu;
}

// no automatic printing of hdf5's error stack (the setting is per thread in thread-safe builds)
void SilenceHdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

herr_t InnermostError(unsigned n, const H5E_error2_t* err, void* data) {
  // the upward walk starts at the most specific error
  if (n == 0 && err != nullptr && err->desc != nullptr)
    *static_cast<std::string*>(data) = err->desc;
  return 0;
}

// the most specific message on hdf5's error stack: read it right after the failing call, before
// any other hdf5 call clears the stack
std::string Hdf5Detail() {
  std::string detail;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, InnermostError, &detail);
  return detail;
}

// Fail, with hdf5's own message appended
[[noreturn]] void FailH5(const std::string& file, const std::string& object,
                         const std::string& what) {
  const std::string detail = Hdf5Detail();
  Fail(file, object, detail.empty() ? what : what + " (HDF5: " + detail + ")");
}

// an owned hdf5 identifier, closed by its own close function
class H5Id {
 public:
  using Closer = herr_t (*)(hid_t);
  H5Id() = default;
  H5Id(hid_t id, Closer close) : id_(id), close_(close) {}
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  H5Id(H5Id&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), close_(o.close_) {}
  H5Id& operator=(H5Id&& o) noexcept {
    if (this != &o) {
      Reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      close_ = o.close_;
    }
    return *this;
  }
  ~H5Id() { Reset(); }

  hid_t get() const { return id_; }

  // closes now; false when hdf5 reports a failure (for files: the final flush failed)
  bool Close() {
    const herr_t status = id_ >= 0 ? close_(id_) : 0;
    id_ = H5I_INVALID_HID;
    return status >= 0;
  }

 private:
  void Reset() {
    if (id_ >= 0) close_(id_);
    id_ = H5I_INVALID_HID;
  }
  hid_t id_ = H5I_INVALID_HID;
  Closer close_ = nullptr;
};

// wraps a freshly returned identifier; a negative one becomes a LogError
H5Id Own(hid_t id, H5Id::Closer close, const std::string& file, const std::string& object,
         const std::string& what) {
  if (id < 0) FailH5(file, object, what);
  return H5Id(id, close);
}

void Check(herr_t status, const std::string& file, const std::string& object,
           const std::string& what) {
  if (status < 0) FailH5(file, object, what);
}

// variable-length utf-8 string type
H5Id Utf8Type(const std::string& file, const std::string& object) {
  H5Id type = Own(H5Tcopy(H5T_C_S1), H5Tclose, file, object, "cannot create a string type");
  Check(H5Tset_size(type.get(), H5T_VARIABLE), file, object, "cannot create a string type");
  Check(H5Tset_cset(type.get(), H5T_CSET_UTF8), file, object, "cannot create a string type");
  return type;
}

// property list making link and attribute names utf-8
H5Id Utf8Names(hid_t cls, const std::string& file) {
  H5Id plist = Own(H5Pcreate(cls), H5Pclose, file, "", "cannot create a property list");
  Check(H5Pset_char_encoding(plist.get(), H5T_CSET_UTF8), file, "",
        "cannot set utf-8 name encoding");
  return plist;
}

// 1-D dataspace of n elements (n = 0 allowed)
H5Id Space1(hsize_t n, const std::string& file, const std::string& object) {
  return Own(H5Screate_simple(1, &n, nullptr), H5Sclose, file, object, "cannot create a dataspace");
}

// ---------------------------------------------------------------------------------------------
// writing

void WriteStringAttr(hid_t obj, const std::string& name, const std::string& value,
                     const std::string& file, const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  H5Id type = Utf8Type(file, where);
  H5Id space = Own(H5Screate(H5S_SCALAR), H5Sclose, file, where, "cannot create a dataspace");
  H5Id acpl = Utf8Names(H5P_ATTRIBUTE_CREATE, file);
  H5Id attr = Own(H5Acreate2(obj, name.c_str(), type.get(), space.get(), acpl.get(), H5P_DEFAULT),
                  H5Aclose, file, where, "cannot create attribute");
  const char* ptr = value.c_str();
  Check(H5Awrite(attr.get(), type.get(), &ptr), file, where, "cannot write attribute");
}

void WriteStringArrayAttr(hid_t obj, const std::string& name,
                          const std::vector<std::string>& values, const std::string& file,
                          const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  H5Id type = Utf8Type(file, where);
  H5Id space = Space1(values.size(), file, where);
  H5Id attr = Own(H5Acreate2(obj, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                  H5Aclose, file, where, "cannot create attribute");
  if (values.empty()) return;
  std::vector<const char*> ptrs;
  for (const std::string& v : values) ptrs.push_back(v.c_str());
  Check(H5Awrite(attr.get(), type.get(), ptrs.data()), file, where, "cannot write attribute");
}

void WriteIntAttr(hid_t obj, const std::string& name, const std::vector<int>& values, bool scalar,
                  const std::string& file, const std::string& object) {
  const std::string where = object + " attribute " + Quote(name);
  H5Id space = scalar
                   ? Own(H5Screate(H5S_SCALAR), H5Sclose, file, where, "cannot create a dataspace")
                   : Space1(values.size(), file, where);
  H5Id attr =
      Own(H5Acreate2(obj, name.c_str(), H5T_STD_I32LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
          H5Aclose, file, where, "cannot create attribute");
  if (values.empty()) return;
  Check(H5Awrite(attr.get(), H5T_NATIVE_INT, values.data()), file, where, "cannot write attribute");
}

// a float64 dataset of the given shape, row-major; returns it open for attributes
H5Id WriteDataset(hid_t group, const char* name, const double* data, int rank, const hsize_t* dims,
                  const std::string& file, const std::string& object) {
  H5Id space = Own(H5Screate_simple(rank, dims, nullptr), H5Sclose, file, object,
                   "cannot create a dataspace");
  // no modification times: the same log gives the same bytes
  H5Id dcpl = Own(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, object, "cannot create a plist");
  Check(H5Pset_obj_track_times(dcpl.get(), false), file, object, "cannot set dataset properties");
  H5Id dset = Own(
      H5Dcreate2(group, name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      H5Dclose, file, object, "cannot create dataset");
  hsize_t count = 1;
  for (int i = 0; i < rank; ++i) count *= dims[i];
  if (count > 0) {
    Check(H5Dwrite(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), file,
          object, "cannot write dataset");
  }
  return dset;
}

H5Id WriteMatrix(hid_t group, const char* name, const RowMatrix& mat, const std::string& file,
                 const std::string& object) {
  const hsize_t dims[2] = {static_cast<hsize_t>(mat.rows()), static_cast<hsize_t>(mat.cols())};
  return WriteDataset(group, name, mat.data(), 2, dims, file, object);
}

void WriteSequence(hid_t file_id, const Sequence& seq, const std::string& file) {
  const std::string gpath = "/" + seq.name;
  H5Id lcpl = Utf8Names(H5P_LINK_CREATE, file);
  H5Id gcpl = Own(H5Pcreate(H5P_GROUP_CREATE), H5Pclose, file, gpath, "cannot create a plist");
  Check(H5Pset_obj_track_times(gcpl.get(), false), file, gpath, "cannot set group properties");
  H5Id group = Own(H5Gcreate2(file_id, seq.name.c_str(), lcpl.get(), gcpl.get(), H5P_DEFAULT),
                   H5Gclose, file, gpath, "cannot create group");

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
}

// flushes a written file to disk
void SyncFile(const std::string& path, const std::string& file) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) Fail(file, "", "cannot open " + path + " to flush it: " + std::strerror(errno));
  const int status = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (status != 0) Fail(file, "", "cannot flush " + path + ": " + std::strerror(err));
}

// best effort: makes the rename itself durable
void SyncDirectory(const std::string& path) {
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// removes the temporary file unless the write committed
class TempFile {
 public:
  explicit TempFile(std::string path) : path_(std::move(path)) {}
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    if (!committed_) {
      std::error_code ec;
      std::filesystem::remove(path_, ec);
    }
  }
  const std::string& path() const { return path_; }
  void Commit() { committed_ = true; }

 private:
  std::string path_;
  bool committed_ = false;
};

// ---------------------------------------------------------------------------------------------
// checks shared by reading and writing

void CheckName(const std::string& name, const std::string& file, const std::string& object,
               const std::string& what) {
  if (name.find('\0') != std::string::npos) {
    Fail(file, object, what + " " + Quote(name) + " contains a NUL character");
  }
}

void CheckFinite(const double* data, Eigen::Index rows, Eigen::Index cols, const std::string& file,
                 const std::string& object) {
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < cols; ++c) {
      const double v = data[r * cols + c];
      if (!std::isfinite(v)) {
        Fail(file, object,
             "row " + std::to_string(r) + ", column " + std::to_string(c) + ": value " + Exact(v) +
                 " is not finite (NaN/Inf are not allowed)");
      }
    }
  }
}

// rows of a matrix against the sample count, with a hint for transposed storage
void CheckRows(const RowMatrix& mat, Eigen::Index samples, bool optional, const std::string& file,
               const std::string& object) {
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
             " = the samples in time" + transposed);
  }
}

void CheckSequence(const Sequence& seq, const std::string& file) {
  const std::string gpath = "/" + seq.name;
  const Eigen::Index samples = seq.time.size();

  // time: at least one sample, finite, strictly increasing
  if (samples < 1) Fail(file, gpath + "/time", "is empty (a sequence needs at least 1 sample)");
  CheckFinite(seq.time.data(), samples, 1, file, gpath + "/time");
  for (Eigen::Index k = 1; k < samples; ++k) {
    if (!(seq.time[k] > seq.time[k - 1])) {
      Fail(file, gpath + "/time",
           "row " + std::to_string(k) + ": time " + Exact(seq.time[k]) +
               " is not greater than row " + std::to_string(k - 1) + "'s " +
               Exact(seq.time[k - 1]) + " (time must be strictly increasing)");
    }
  }

  // shapes
  CheckRows(seq.ctrl, samples, false, file, gpath + "/ctrl");
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

  // values: finite everywhere
  const std::pair<const char*, const RowMatrix*> mats[] = {{"ctrl", &seq.ctrl},
                                                           {"sensordata", &seq.sensordata},
                                                           {"qpos", &seq.qpos},
                                                           {"qvel", &seq.qvel},
                                                           {"act", &seq.act}};
  for (const auto& [name, mat] : mats) {
    CheckFinite(mat->data(), mat->rows(), mat->cols(), file, gpath + "/" + name);
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

// names of the links in a group, in creation order when the file tracks it, else by name
std::vector<std::string> LinkNames(hid_t group, const std::string& file,
                                   const std::string& object) {
  H5G_info_t info;
  Check(H5Gget_info(group, &info), file, object, "cannot read group (corrupt file?)");
  H5Id gcpl = Own(H5Gget_create_plist(group), H5Pclose, file, object, "cannot read group");
  unsigned order_flags = 0;
  Check(H5Pget_link_creation_order(gcpl.get(), &order_flags), file, object, "cannot read group");
  const H5_index_t index =
      (order_flags & H5P_CRT_ORDER_INDEXED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t len =
        H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    if (len < 0) FailH5(file, object, "cannot list group members (corrupt file?)");
    std::string name(static_cast<size_t>(len) + 1, '\0');
    if (H5Lget_name_by_idx(group, ".", index, H5_ITER_INC, i, name.data(), name.size(),
                           H5P_DEFAULT) < 0) {
      FailH5(file, object, "cannot list group members (corrupt file?)");
    }
    name.resize(static_cast<size_t>(len));
    names.push_back(name);
  }
  return names;
}

// number of elements of an attribute or dataset space; scalar counts as 1, null as 0
hsize_t Elements(hid_t space, const std::string& file, const std::string& where) {
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  if (n < 0) FailH5(file, where, "cannot read the dataspace");
  return static_cast<hsize_t>(n);
}

// a string attribute (scalar or 1-D), variable or fixed length
std::vector<std::string> ReadStrings(hid_t attr, const std::string& file,
                                     const std::string& where) {
  H5Id ftype = Own(H5Aget_type(attr), H5Tclose, file, where, "cannot read attribute type");
  if (H5Tget_class(ftype.get()) != H5T_STRING) Fail(file, where, "is not a string attribute");
  H5Id space = Own(H5Aget_space(attr), H5Sclose, file, where, "cannot read attribute space");
  if (H5Sget_simple_extent_ndims(space.get()) > 1) Fail(file, where, "has rank > 1");
  const hsize_t n = Elements(space.get(), file, where);
  std::vector<std::string> out;
  if (n == 0) return out;
  const htri_t variable = H5Tis_variable_str(ftype.get());
  if (variable < 0) FailH5(file, where, "cannot read attribute type");
  if (variable) {
    // variable length: hdf5 allocates each string; reclaim them whatever happens
    H5Id mtype = Own(H5Tcopy(H5T_C_S1), H5Tclose, file, where, "cannot create a string type");
    Check(H5Tset_size(mtype.get(), H5T_VARIABLE), file, where, "cannot create a string type");
    Check(H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())), file, where,
          "cannot create a string type");
    std::vector<char*> ptrs(n, nullptr);
    if (H5Aread(attr, mtype.get(), ptrs.data()) < 0) FailH5(file, where, "cannot read attribute");
    for (char* p : ptrs) out.emplace_back(p ? p : "");
#if H5_VERSION_GE(1, 12, 0)
    H5Treclaim(mtype.get(), space.get(), H5P_DEFAULT, ptrs.data());
#else
    H5Dvlen_reclaim(mtype.get(), space.get(), H5P_DEFAULT, ptrs.data());
#endif
    return out;
  }
  // fixed length: nul-terminated or nul/space padded
  const size_t size = H5Tget_size(ftype.get());
  if (size == 0) FailH5(file, where, "cannot read attribute type");
  const H5T_str_t pad = H5Tget_strpad(ftype.get());
  std::vector<char> buf(n * size);
  if (H5Aread(attr, ftype.get(), buf.data()) < 0) FailH5(file, where, "cannot read attribute");
  for (hsize_t i = 0; i < n; ++i) {
    const char* p = buf.data() + i * size;
    std::string s(p, strnlen(p, size));
    if (pad == H5T_STR_SPACEPAD) s.erase(s.find_last_not_of(' ') + 1);
    out.push_back(s);
  }
  return out;
}

// an integer attribute (scalar or 1-D)
std::vector<long long> ReadInts(hid_t attr, const std::string& file, const std::string& where) {
  H5Id ftype = Own(H5Aget_type(attr), H5Tclose, file, where, "cannot read attribute type");
  if (H5Tget_class(ftype.get()) != H5T_INTEGER) Fail(file, where, "is not an integer attribute");
  H5Id space = Own(H5Aget_space(attr), H5Sclose, file, where, "cannot read attribute space");
  if (H5Sget_simple_extent_ndims(space.get()) > 1) Fail(file, where, "has rank > 1");
  std::vector<long long> out(Elements(space.get(), file, where));
  if (!out.empty() && H5Aread(attr, H5T_NATIVE_LLONG, out.data()) < 0) {
    FailH5(file, where, "cannot read attribute");
  }
  return out;
}

// an attribute of obj when it exists; an invalid H5Id otherwise
H5Id OpenAttrIfAny(hid_t obj, const char* name, const std::string& file,
                   const std::string& object) {
  const htri_t exists = H5Aexists(obj, name);
  if (exists < 0) FailH5(file, object, "cannot read attributes (corrupt file?)");
  if (!exists) return H5Id();
  return Own(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose, file, object + " attribute " + Quote(name),
             "cannot open attribute");
}

// a required scalar string attribute
std::string ReadScalarString(hid_t obj, const char* name, const std::string& file,
                             const std::string& object, const std::string& missing_hint) {
  H5Id attr = OpenAttrIfAny(obj, name, file, object);
  const std::string where = object + " attribute " + Quote(name);
  if (attr.get() < 0) Fail(file, where, "is missing" + missing_hint);
  std::vector<std::string> v = ReadStrings(attr.get(), file, where);
  if (v.size() != 1) Fail(file, where, "must hold one string, holds " + std::to_string(v.size()));
  return v[0];
}

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
  return Exact(value);
}

herr_t CollectAttrName(hid_t, const char* name, const H5A_info_t*, void* data) {
  static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}

std::vector<std::string> AttributeNames(hid_t obj, const std::string& file,
                                        const std::string& object) {
  std::vector<std::string> names;
  hsize_t idx = 0;
  Check(H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_INC, &idx, CollectAttrName, &names), file, object,
        "cannot list attributes (corrupt file?)");
  return names;
}

std::string ShapeText(const std::vector<hsize_t>& dims) {
  std::string s = "(";
  for (size_t i = 0; i < dims.size(); ++i) s += (i ? ", " : "") + std::to_string(dims[i]);
  return s + ")";
}

// a numeric dataset of the expected rank, as doubles in row-major order
struct Array {
  std::vector<hsize_t> dims;
  std::vector<double> data;
};

Array ReadArray(hid_t group, const char* name, int rank, const std::string& file,
                const std::string& object) {
  H5Id dset = Own(H5Dopen2(group, name, H5P_DEFAULT), H5Dclose, file, object,
                  "cannot open dataset (not a dataset, or corrupt file?)");
  H5Id type = Own(H5Dget_type(dset.get()), H5Tclose, file, object, "cannot read data type");
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_FLOAT && cls != H5T_INTEGER) Fail(file, object, "must hold numbers (float64)");
  H5Id space = Own(H5Dget_space(dset.get()), H5Sclose, file, object, "cannot read dataspace");
  const int ndims = H5Sget_simple_extent_ndims(space.get());
  if (ndims < 0) FailH5(file, object, "cannot read dataspace");
  Array out;
  out.dims.resize(static_cast<size_t>(ndims));
  if (ndims > 0 && H5Sget_simple_extent_dims(space.get(), out.dims.data(), nullptr) < 0) {
    FailH5(file, object, "cannot read dataspace");
  }
  if (ndims != rank) {
    Fail(file, object,
         "has rank " + std::to_string(ndims) + " (shape " + ShapeText(out.dims) +
             "), expected rank " + std::to_string(rank) +
             (rank == 1 ? " (T samples)" : " (T samples x columns)"));
  }
  const hsize_t n = Elements(space.get(), file, object);
  try {
    out.data.resize(n);
  } catch (const std::bad_alloc&) {
    Fail(file, object, "shape " + ShapeText(out.dims) + " is too large (corrupt file?)");
  } catch (const std::length_error&) {
    Fail(file, object, "shape " + ShapeText(out.dims) + " is too large (corrupt file?)");
  }
  if (n > 0 &&
      H5Dread(dset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data.data()) < 0) {
    FailH5(file, object, "cannot read data (truncated or corrupt file?)");
  }
  return out;
}

RowMatrix ToMatrix(const Array& a) {
  const auto rows = static_cast<Eigen::Index>(a.dims[0]);
  const auto cols = static_cast<Eigen::Index>(a.dims[1]);
  RowMatrix m(rows, cols);
  if (!a.data.empty()) std::copy(a.data.begin(), a.data.end(), m.data());
  return m;
}

Sequence ReadSequence(hid_t file_id, const std::string& name, const std::string& file) {
  const std::string gpath = "/" + name;
  H5Id group =
      Own(H5Gopen2(file_id, name.c_str(), H5P_DEFAULT), H5Gclose, file, gpath, "cannot open group");
  Sequence seq;
  seq.name = name;

  // members: only the known datasets
  std::set<std::string> present;
  for (const std::string& member : LinkNames(group.get(), file, gpath)) {
    if (std::find(std::begin(kDatasets), std::end(kDatasets), member) == std::end(kDatasets)) {
      Fail(file, gpath + "/" + member,
           "unknown member of a sequence group (expected time, ctrl, sensordata and optionally "
           "qpos, qvel, act)");
    }
    present.insert(member);
  }
  for (const char* required : {"time", "ctrl", "sensordata"}) {
    if (!present.count(required)) {
      Fail(file, gpath + "/" + required, "required dataset is missing");
    }
  }

  // time, in seconds
  {
    const std::string where = gpath + "/time";
    Array t = ReadArray(group.get(), "time", 1, file, where);
    seq.time = Eigen::Map<Eigen::VectorXd>(t.data.data(), static_cast<Eigen::Index>(t.dims[0]));
    H5Id dset = Own(H5Dopen2(group.get(), "time", H5P_DEFAULT), H5Dclose, file, where,
                    "cannot open dataset");
    H5Id units = OpenAttrIfAny(dset.get(), "units", file, where);
    if (units.get() >= 0) {
      std::vector<std::string> u = ReadStrings(units.get(), file, where + " attribute 'units'");
      if (u.size() != 1 || u[0] != "s") {
        Fail(file, where + " attribute 'units'",
             "must be \"s\" (time is stored in seconds), found \"" + Join(u) + "\"");
      }
    }
  }

  // ctrl and actuator names
  {
    const std::string where = gpath + "/ctrl";
    seq.ctrl = ToMatrix(ReadArray(group.get(), "ctrl", 2, file, where));
    CheckRows(seq.ctrl, seq.time.size(), false, file, where);
    H5Id dset = Own(H5Dopen2(group.get(), "ctrl", H5P_DEFAULT), H5Dclose, file, where,
                    "cannot open dataset");
    H5Id names = OpenAttrIfAny(dset.get(), "names", file, where);
    if (names.get() >= 0) {
      seq.actuator_names = ReadStrings(names.get(), file, where + " attribute 'names'");
    } else if (seq.ctrl.cols() > 0) {
      Fail(file, where + " attribute 'names'", "is missing (one actuator name per column)");
    }
  }

  // sensordata, sensor names and dimensions
  {
    const std::string where = gpath + "/sensordata";
    seq.sensordata = ToMatrix(ReadArray(group.get(), "sensordata", 2, file, where));
    CheckRows(seq.sensordata, seq.time.size(), false, file, where);
    H5Id dset = Own(H5Dopen2(group.get(), "sensordata", H5P_DEFAULT), H5Dclose, file, where,
                    "cannot open dataset");
    H5Id names = OpenAttrIfAny(dset.get(), "names", file, where);
    H5Id dims = OpenAttrIfAny(dset.get(), "dims", file, where);
    if (names.get() >= 0) {
      seq.sensor_names = ReadStrings(names.get(), file, where + " attribute 'names'");
    } else if (seq.sensordata.cols() > 0) {
      Fail(file, where + " attribute 'names'", "is missing (one name per sensor)");
    }
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
    CheckRows(*mat, seq.time.size(), false, file, gpath + "/" + dname);
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
  const std::string* best = nullptr;
  size_t best_distance = std::max<size_t>(2, wrong.size() / 3) + 1;
  for (const std::string& v : valid) {
    const size_t d = EditDistance(wrong, v);
    if (d < best_distance) {
      best_distance = d;
      best = &v;
    }
  }
  if (best) out += " (did you mean " + Quote(*best) + "?)";
  out += "; " + what + ": " + (valid.empty() ? std::string("none") : Join(valid));
  return out;
}

}  // namespace internal

void WriteLog(const std::string& path, const Log& log) {
  CheckLog(log, path);
  std::lock_guard<std::mutex> lock(Hdf5Mutex());
  SilenceHdf5();
  TempFile tmp(path + ".tmp-" + std::to_string(::getpid()));
  const std::string& file = path;

  // everything into the temporary file; all handles closed before the rename
  {
    H5Id fcpl = Own(H5Pcreate(H5P_FILE_CREATE), H5Pclose, file, "", "cannot create a plist");
    Check(H5Pset_link_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED),
          file, "", "cannot set link creation order");
    H5Id f = Own(H5Fcreate(tmp.path().c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose,
                 file, "", "cannot create temporary file " + tmp.path());
    H5Id root = Own(H5Gopen2(f.get(), "/", H5P_DEFAULT), H5Gclose, file, "/", "cannot open root");
    WriteStringAttr(root.get(), "format", kFormat, file, "/");
    WriteIntAttr(root.get(), "format_version", {kFormatVersion}, true, file, "/");
    WriteStringAttr(root.get(), "sensor_time", log.sensor_time, file, "/");
    for (const auto& [key, value] : log.attributes) {
      WriteStringAttr(root.get(), key, value, file, "/");
    }
    for (const Sequence& seq : log.sequences) WriteSequence(f.get(), seq, file);
    root.Close();
    if (!f.Close()) FailH5(file, "", "cannot finish writing temporary file " + tmp.path());
  }

  // durable, then atomically in place
  SyncFile(tmp.path(), file);
  if (std::rename(tmp.path().c_str(), path.c_str()) != 0) {
    Fail(file, "", "cannot rename " + tmp.path() + " to it: " + std::strerror(errno));
  }
  tmp.Commit();
  SyncDirectory(path);
}

Log ReadLog(const std::string& path) {
  const std::string& file = path;
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) Fail(file, "", "no such file");
  if (!std::filesystem::is_regular_file(status)) Fail(file, "", "is not a regular file");

  std::lock_guard<std::mutex> lock(Hdf5Mutex());
  SilenceHdf5();
  // signature first: a clear message for files that are not hdf5 at all
#if H5_VERSION_GE(1, 12, 0)
  const htri_t is_hdf5 = H5Fis_accessible(path.c_str(), H5P_DEFAULT);
#else
  const htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
#endif
  if (is_hdf5 < 0) FailH5(file, "", "cannot read the file");
  if (is_hdf5 == 0) Fail(file, "", "is not an HDF5 file");
  H5Id f = Own(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, file, "",
               "cannot open HDF5 file (truncated or corrupt?)");
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

void ValidateLogAgainstModel(const Log& log, const mjModel& m,
                             const std::string& path_for_messages) {
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

    // sample period: a whole multiple of the timestep
    const Eigen::Index samples = seq.time.size();
    if (samples < 2) {
      Fail(file, gpath + "/time", "has 1 sample: at least 2 are needed to know the sample period");
    }
    std::vector<double> diffs(static_cast<size_t>(samples - 1));
    for (Eigen::Index k = 1; k < samples; ++k) diffs[k - 1] = seq.time[k] - seq.time[k - 1];
    std::sort(diffs.begin(), diffs.end());
    const size_t mid = diffs.size() / 2;
    const double period = diffs.size() % 2 ? diffs[mid] : 0.5 * (diffs[mid - 1] + diffs[mid]);
    const double timestep = m.opt.timestep;
    const double ratio = period / timestep;
    const double whole = std::round(ratio);
    if (!(timestep > 0) || whole < 1 || std::abs(period - whole * timestep) > 1e-9 * period) {
      Fail(file, gpath + "/time",
           "sample period " + Short(period) + " s (median of diff(time)) is " + Short(ratio) +
               " times the model timestep " + Short(timestep) +
               " s; it must be a whole multiple (1, 2, 3, ...)");
    }
  }
}

}  // namespace mjsysid::io
