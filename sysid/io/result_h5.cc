#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/assess/metrics.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/hdf5_util.h"
#include "sysid/io/result_fields.h"
#include "sysid/io/result_internal.h"

namespace mjsysid::io::result_internal {
namespace {

// ---------------------------------------------------------------------------------------------
// result.h5

// the fields of result_fields.h that result.h5 does not keep as root attributes
struct SkipFields {
  template <class... A>
  void Int(const FieldKey&, A&&...) {}
  template <class... A>
  void Number(const FieldKey&, A&&...) {}
  template <class... A>
  void Pair(const FieldKey&, A&&...) {}
  template <class... A>
  void Numbers(const FieldKey&, A&&...) {}
  template <class... A>
  void Status(const FieldKey&, A&&...) {}
  template <class... A>
  void Flags(const FieldKey&, A&&...) {}
  template <class... A>
  void Texts(const FieldKey&, A&&...) {}
  template <class... A>
  void Warnings(const FieldKey&, A&&...) {}
  template <class... A>
  void TextMap(const FieldKey&, A&&...) {}
  template <class... A>
  void Map(const FieldKey&, A&&...) {}
  template <class... A>
  void List(const FieldKey&, A&&...) {}
  template <class... A>
  void FitMetrics(const FieldKey&, A&&...) {}
  template <class R>
  void Record(const FieldKey&, const FieldKey&, R&&) {}
};

// the fields marked h5 (text and bool) as root attributes: those written only when set after the
// others, so that the always-present attributes keep one order in every file
class RootAttributeWriter : public SkipFields {
 public:
  RootAttributeWriter(hid_t root, const std::string& file) : root_(root), file_(file) {}

  void Text(const FieldKey& k, const std::string& s) {
    if (!k.h5) return;
    if (k.presence != Presence::kWhenSet) {
      h5::WriteStringAttr(root_, k.name, s, file_, "/");
    } else if (!s.empty()) {
      when_set_.emplace_back(k.name, s);
    }
  }
  // 0 or 1
  void Bool(const FieldKey& k, bool b) {
    if (k.h5) h5::WriteIntAttr(root_, k.name, {b ? 1 : 0}, true, file_, "/");
  }
  void Finish() {
    for (const auto& [name, s] : when_set_) h5::WriteStringAttr(root_, name, s, file_, "/");
  }

 private:
  hid_t root_;
  const std::string& file_;
  std::vector<std::pair<const char*, std::string>> when_set_;
};

// the root attributes marked h5 read back (text: required unless written only when set; bool:
// optional, 0 or 1)
class RootAttributeReader : public SkipFields {
 public:
  RootAttributeReader(hid_t root, const std::string& file) : root_(root), file_(file) {}

  void Text(const FieldKey& k, std::string& s) {
    if (!k.h5) return;
    if (k.presence == Presence::kWhenSet &&
        h5::OpenAttrIfAny(root_, k.name, file_, "/").get() < 0) {
      return;
    }
    s = h5::ReadScalarString(root_, k.name, file_, "/", "");
  }
  void Bool(const FieldKey& k, bool& b) {
    if (!k.h5) return;
    h5::Id attr = h5::OpenAttrIfAny(root_, k.name, file_, "/");
    if (attr.get() < 0) return;
    const std::string where = std::string("/ attribute '") + k.name + "'";
    const std::vector<long long> v = h5::ReadInts(attr.get(), file_, where);
    if (v.size() != 1 || (v[0] != 0 && v[0] != 1)) {
      Fail(file_, where, "expected one value, 0 or 1");
    }
    b = v[0] == 1;
  }

 private:
  hid_t root_;
  const std::string& file_;
};

// a 1-D int32 dataset
void WriteInts(hid_t group, const char* name, const std::vector<int>& values,
               const std::string& file, const std::string& object) {
  h5::Id space = h5::Space1(values.size(), file, object);
  h5::Id dcpl =
      h5::Own(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, object, "cannot create a plist");
  h5::Check(H5Pset_obj_track_times(dcpl.get(), false), file, object,
            "cannot set dataset properties");
  h5::Id dset = h5::Own(
      H5Dcreate2(group, name, H5T_STD_I32LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      H5Dclose, file, object, "cannot create dataset");
  if (values.empty()) return;
  h5::Check(H5Dwrite(dset.get(), H5T_NATIVE_INT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
            file, object, "cannot write dataset");
}

void WriteVector(hid_t group, const char* name, const std::vector<double>& values,
                 const std::string& file, const std::string& object) {
  const hsize_t dims[1] = {values.size()};
  h5::WriteDataset(group, name, values.data(), 1, dims, file, object);
}

void WriteMatrix(hid_t group, const char* name, const double* data, Eigen::Index rows,
                 Eigen::Index cols, const std::string& file, const std::string& object) {
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  h5::WriteDataset(group, name, data, 2, dims, file, object);
}

void WriteH5Parameters(hid_t root, const FitResultFile& r, const std::string& file) {
  h5::Id group = h5::CreateGroup(root, "parameters", true, file, "/parameters");
  std::vector<std::string> names;
  std::vector<double> columns[5];
  for (const ParameterEstimate& p : r.parameters) {
    names.push_back(p.name);
    const double values[5] = {p.value, p.initial, p.std_error, p.ci95_low, p.ci95_high};
    for (int i = 0; i < 5; ++i) columns[i].push_back(values[i]);
  }
  h5::WriteStringArrayAttr(group.get(), "names", names, file, "/parameters");
  const char* datasets[5] = {"value", "initial", "std", "ci95_low", "ci95_high"};
  for (int i = 0; i < 5; ++i) {
    WriteVector(group.get(), datasets[i], columns[i], file,
                std::string("/parameters/") + datasets[i]);
  }
}

// /derived (only when the fit derived quantities, e.g. body_inertial's mass): attribute names,
// datasets value, std, ci95_low, ci95_high (units and provenance: result.yaml's derived)
void WriteH5Derived(hid_t root, const FitResultFile& r, const std::string& file) {
  if (r.derived.empty()) return;
  h5::Id group = h5::CreateGroup(root, "derived", true, file, "/derived");
  std::vector<std::string> names;
  std::vector<double> columns[4];
  for (const DerivedQuantity& d : r.derived) {
    names.push_back(d.name);
    const double values[4] = {d.value, d.std_error, d.ci95_low, d.ci95_high};
    for (int i = 0; i < 4; ++i) columns[i].push_back(values[i]);
  }
  h5::WriteStringArrayAttr(group.get(), "names", names, file, "/derived");
  const char* datasets[4] = {"value", "std", "ci95_low", "ci95_high"};
  for (int i = 0; i < 4; ++i) {
    WriteVector(group.get(), datasets[i], columns[i], file, std::string("/derived/") + datasets[i]);
  }
}

void WriteH5Trace(hid_t root, const FitResultFile& r, const std::string& file) {
  h5::Id group = h5::CreateGroup(root, "trace", true, file, "/trace");
  std::vector<int> iteration, successful;
  std::vector<double> cost, step_norm, gradient_norm, seconds;
  const size_t width = r.trace.empty() ? r.parameters.size() : r.trace[0].parameters.size();
  RowMatrix params(static_cast<Eigen::Index>(r.trace.size()), static_cast<Eigen::Index>(width));
  for (size_t i = 0; i < r.trace.size(); ++i) {
    const IterationInfo& e = r.trace[i];
    iteration.push_back(e.iteration);
    successful.push_back(e.successful ? 1 : 0);
    cost.push_back(e.cost);
    step_norm.push_back(e.step_norm);
    gradient_norm.push_back(e.gradient_norm);
    seconds.push_back(e.seconds);
    for (size_t j = 0; j < width; ++j) {
      params(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = e.parameters[j];
    }
  }
  WriteInts(group.get(), "iteration", iteration, file, "/trace/iteration");
  WriteVector(group.get(), "cost", cost, file, "/trace/cost");
  WriteVector(group.get(), "step_norm", step_norm, file, "/trace/step_norm");
  WriteVector(group.get(), "gradient_norm", gradient_norm, file, "/trace/gradient_norm");
  WriteVector(group.get(), "seconds", seconds, file, "/trace/seconds");
  WriteInts(group.get(), "successful", successful, file, "/trace/successful");
  WriteMatrix(group.get(), "parameters", params.data(), params.rows(), params.cols(), file,
              "/trace/parameters");
}

// one sequence under /sequences (fitted) or /validation (held out): `where` is that group's path
void WriteH5Sequence(hid_t sequences, const SequenceResult& s, const std::string& file,
                     const std::string& where) {
  const std::string g = where + "/" + s.name;
  h5::Id group = h5::CreateGroup(sequences, s.name, true, file, g);
  h5::WriteStringAttr(group.get(), "model", s.model, file, g);
  h5::WriteStringArrayAttr(group.get(), "sensor_names", s.sensor_names, file, g);
  h5::WriteIntAttr(group.get(), "sensor_dims", s.sensor_dims, false, file, g);
  const hsize_t t_dims[1] = {static_cast<hsize_t>(s.time.size())};
  h5::Id time = h5::WriteDataset(group.get(), "time", s.time.data(), 1, t_dims, file, g + "/time");
  h5::WriteStringAttr(time.get(), "units", "s", file, g + "/time");
  const std::pair<const char*, const RowMatrix*> mats[] = {
      {"measured", &s.measured},
      {"simulated_initial", &s.simulated_initial},
      {"simulated_final", &s.simulated_final},
      {"simulated_one_piece", &s.simulated_one_piece}};  // (multiple shooting only)
  for (const auto& [name, m] : mats) {
    if (m->rows() == 0 && m == &s.simulated_one_piece) continue;
    WriteMatrix(group.get(), name, m->data(), m->rows(), m->cols(), file, g + "/" + name);
  }
  // fitted states (optional: only when the fit had `states`), laid out like the sensors
  if (s.state_names.empty()) return;
  h5::WriteStringArrayAttr(group.get(), "state_names", s.state_names, file, g);
  h5::WriteIntAttr(group.get(), "state_dims", s.state_dims, false, file, g);
  h5::WriteIntAttr(group.get(), "state_residual_dims", s.state_residual_dims, false, file, g);
  const std::pair<const char*, const RowMatrix*> states[] = {
      {"state_measured", &s.state_measured},
      {"state_simulated_initial", &s.state_simulated_initial},
      {"state_simulated_final", &s.state_simulated_final},
      {"state_residual_final", &s.state_residual_final},
      {"state_simulated_one_piece", &s.state_simulated_one_piece}};
  for (const auto& [name, m] : states) {
    if (m->rows() == 0 && m == &s.state_simulated_one_piece) continue;
    WriteMatrix(group.get(), name, m->data(), m->rows(), m->cols(), file, g + "/" + name);
  }
}

}  // namespace

void WriteH5(const std::string& tmp, const FitResultFile& r, const std::string& file) {
  h5::Id f = h5::CreateFile(tmp, file);
  {
    h5::Id root =
        h5::Own(H5Gopen2(f.get(), "/", H5P_DEFAULT), H5Gclose, file, "/", "cannot open root");
    h5::WriteStringAttr(root.get(), "format", kFormat, file, "/");
    h5::WriteIntAttr(root.get(), "format_version", {kFormatVersion}, true, file, "/");
    // status, intervals_valid (as result.yaml's), run_id (when the result has one)
    RootAttributeWriter attributes(root.get(), file);
    VisitResultFields(attributes, r);
    attributes.Finish();
    WriteH5Parameters(root.get(), r, file);
    WriteH5Derived(root.get(), r, file);

    // covariance (np x np) and jacobian (nres x np); ColMajor covariance stored row-major
    const RowMatrix cov = r.uncertainty.covariance;
    WriteMatrix(root.get(), "covariance", cov.data(), cov.rows(), cov.cols(), file, "/covariance");
    WriteMatrix(root.get(), "jacobian", r.jacobian.data(), r.jacobian.rows(), r.jacobian.cols(),
                file, "/jacobian");
    WriteH5Trace(root.get(), r, file);

    // sequences, in order; each checked as it is written; the held-out ones (if any) under
    // /validation in the same layout
    std::set<std::string> seen;
    const std::pair<const char*, const std::vector<SequenceResult>*> groups[] = {
        {"sequences", &r.sequences}, {"validation", &r.validation}};
    for (const auto& [gname, list] : groups) {
      if (list == &r.validation && list->empty()) continue;
      const std::string where = std::string("/") + gname;
      h5::Id seqs = h5::CreateGroup(root.get(), gname, true, file, where);
      for (const SequenceResult& s : *list) {
        if (!seen.insert(s.name).second) {
          Fail(file, where + "/" + s.name, "two sequences are named " + Quote(s.name));
        }
        CheckSequence(s, file, where);
        WriteH5Sequence(seqs.get(), s, file, where);
      }
    }
  }
  if (!f.Close()) h5::FailH5(file, "", "cannot finish writing temporary file " + tmp);
}

namespace {

// a required dataset of `group`, as doubles
h5::Array ReadRequired(hid_t group, const char* name, int rank, const std::string& file,
                       const std::string& object) {
  if (!h5::HasLink(group, name, file, object)) Fail(file, object, "required dataset is missing");
  return h5::ReadArray(group, name, rank, file, object);
}

h5::Id OpenGroup(hid_t parent, const char* name, const std::string& file,
                 const std::string& object) {
  if (!h5::HasLink(parent, name, file, object)) Fail(file, object, "required group is missing");
  return h5::Own(H5Gopen2(parent, name, H5P_DEFAULT), H5Gclose, file, object,
                 "cannot open group (not a group, or corrupt file?)");
}

// a 1-D dataset of n values
std::vector<double> ReadColumn(hid_t group, const char* name, size_t n, const std::string& file,
                               const std::string& object) {
  h5::Array a = ReadRequired(group, name, 1, file, object);
  if (a.dims[0] != n) {
    Fail(file, object,
         "has " + std::to_string(a.dims[0]) + " values, expected " + std::to_string(n));
  }
  return a.data;
}

// a required attribute
h5::Id RequiredAttr(hid_t obj, const char* name, const std::string& file,
                    const std::string& object) {
  h5::Id attr = h5::OpenAttrIfAny(obj, name, file, object);
  if (attr.get() < 0) Fail(file, object + " attribute " + Quote(name), "is missing");
  return attr;
}

void ReadH5Parameters(hid_t root, const std::string& file, const FitResultFile& r) {
  h5::Id group = OpenGroup(root, "parameters", file, "/parameters");
  h5::Id names_attr = RequiredAttr(group.get(), "names", file, "/parameters");
  const std::vector<std::string> names =
      h5::ReadStrings(names_attr.get(), file, "/parameters attribute 'names'");
  std::vector<std::string> expected;
  for (const ParameterEstimate& p : r.parameters) expected.push_back(p.name);
  if (names != expected) {
    Fail(file, "/parameters attribute 'names'",
         "the parameters differ from result.yaml's (" + std::to_string(names.size()) + " vs " +
             std::to_string(expected.size()) + "; written by different fits?)");
  }
  for (const char* name : {"value", "initial", "std", "ci95_low", "ci95_high"}) {
    ReadColumn(group.get(), name, names.size(), file, std::string("/parameters/") + name);
  }
}

// /derived, when present: the names of result.yaml's derived quantities, and every column
void ReadH5Derived(hid_t root, const std::string& file, const FitResultFile& r) {
  std::vector<std::string> expected;
  for (const DerivedQuantity& d : r.derived) expected.push_back(d.name);
  if (!h5::HasLink(root, "derived", file, "/")) {
    if (!expected.empty()) Fail(file, "/derived", "is missing (result.yaml has derived:)");
    return;
  }
  h5::Id group = OpenGroup(root, "derived", file, "/derived");
  h5::Id names_attr = RequiredAttr(group.get(), "names", file, "/derived");
  const std::vector<std::string> names =
      h5::ReadStrings(names_attr.get(), file, "/derived attribute 'names'");
  if (names != expected) {
    Fail(file, "/derived attribute 'names'",
         "the derived quantities differ from result.yaml's (" + std::to_string(names.size()) +
             " vs " + std::to_string(expected.size()) + "; written by different fits?)");
  }
  for (const char* name : {"value", "std", "ci95_low", "ci95_high"}) {
    ReadColumn(group.get(), name, names.size(), file, std::string("/derived/") + name);
  }
}

void ReadH5Trace(hid_t root, const std::string& file, FitResultFile* r) {
  h5::Id group = OpenGroup(root, "trace", file, "/trace");
  const h5::Array it = ReadRequired(group.get(), "iteration", 1, file, "/trace/iteration");
  const size_t n = it.dims[0];
  std::vector<double> cols[6];
  cols[0] = it.data;
  for (int c = 1; c < 6; ++c) {
    cols[c] = ReadColumn(group.get(), kTraceColumns[c], n, file,
                         std::string("/trace/") + kTraceColumns[c]);
  }
  const RowMatrix params =
      h5::ToMatrix(ReadRequired(group.get(), "parameters", 2, file, "/trace/parameters"));
  if (static_cast<size_t>(params.rows()) != n) {
    Fail(file, "/trace/parameters",
         "has " + std::to_string(params.rows()) + " rows, expected " + std::to_string(n) +
             " (one per trace entry)");
  }
  for (size_t i = 0; i < n; ++i) {
    if (!(std::abs(cols[0][i]) < 1e9)) {
      Fail(file, "/trace/iteration",
           "row " + std::to_string(i) + ": " + Number(cols[0][i]) + " is not an iteration number");
    }
    IterationInfo e;
    e.iteration = static_cast<int>(cols[0][i]);
    e.cost = cols[1][i];
    e.step_norm = cols[2][i];
    e.gradient_norm = cols[3][i];
    e.seconds = cols[4][i];
    e.successful = cols[5][i] != 0;
    const auto row = params.row(static_cast<Eigen::Index>(i));
    e.parameters = row.transpose();
    r->trace.push_back(std::move(e));
  }
}

// one sequence of /sequences or /validation (`where`); its channel fits computed from its signals
SequenceResult ReadH5Sequence(hid_t sequences, const std::string& name, const std::string& file,
                              const std::string& where) {
  const std::string g = where + "/" + name;
  h5::Id group = h5::Own(H5Gopen2(sequences, name.c_str(), H5P_DEFAULT), H5Gclose, file, g,
                         "cannot open group (not a group, or corrupt file?)");
  SequenceResult s;
  s.name = name;
  s.model = h5::ReadScalarString(group.get(), "model", file, g, "");
  {
    h5::Id attr = RequiredAttr(group.get(), "sensor_names", file, g);
    s.sensor_names = h5::ReadStrings(attr.get(), file, g + " attribute 'sensor_names'");
  }
  {
    h5::Id attr = RequiredAttr(group.get(), "sensor_dims", file, g);
    for (long long d : h5::ReadInts(attr.get(), file, g + " attribute 'sensor_dims'")) {
      if (d < 1 || d > 1000000000) {
        Fail(file, g + " attribute 'sensor_dims'",
             "dimension " + std::to_string(d) + " is out of range (must be >= 1)");
      }
      s.sensor_dims.push_back(static_cast<int>(d));
    }
  }
  const h5::Array t = ReadRequired(group.get(), "time", 1, file, g + "/time");
  s.time = Eigen::Map<const Eigen::VectorXd>(t.data.data(), static_cast<Eigen::Index>(t.dims[0]));
  const std::pair<const char*, RowMatrix*> mats[] = {{"measured", &s.measured},
                                                     {"simulated_initial", &s.simulated_initial},
                                                     {"simulated_final", &s.simulated_final}};
  for (const auto& [dname, m] : mats) {
    *m = h5::ToMatrix(ReadRequired(group.get(), dname, 2, file, g + "/" + dname));
  }
  // a fit in segments: the estimate in one piece too (checked with the others by CheckSequence)
  if (h5::HasLink(group.get(), "simulated_one_piece", file, g)) {
    s.simulated_one_piece = h5::ToMatrix(
        ReadRequired(group.get(), "simulated_one_piece", 2, file, g + "/simulated_one_piece"));
  }
  s.channel_fits = ChannelFits(s);
  // fitted states, when the fit had them
  h5::Id names = h5::OpenAttrIfAny(group.get(), "state_names", file, g);
  if (names.get() < 0) return s;
  s.state_names = h5::ReadStrings(names.get(), file, g + " attribute 'state_names'");
  const std::pair<const char*, std::vector<int>*> dims[] = {
      {"state_dims", &s.state_dims}, {"state_residual_dims", &s.state_residual_dims}};
  for (const auto& [aname, out] : dims) {
    h5::Id attr = RequiredAttr(group.get(), aname, file, g);
    for (long long d : h5::ReadInts(attr.get(), file, g + " attribute '" + aname + "'")) {
      if (d < 1 || d > 1000000000) {
        Fail(file, g + " attribute '" + aname + "'",
             "dimension " + std::to_string(d) + " is out of range (must be >= 1)");
      }
      out->push_back(static_cast<int>(d));
    }
    if (out->size() != s.state_names.size()) {
      Fail(file, g + " attribute '" + aname + "'", "needs one entry per state name");
    }
  }
  const std::pair<const char*, RowMatrix*> states[] = {
      {"state_measured", &s.state_measured},
      {"state_simulated_initial", &s.state_simulated_initial},
      {"state_simulated_final", &s.state_simulated_final},
      {"state_residual_final", &s.state_residual_final},
      {"state_simulated_one_piece", &s.state_simulated_one_piece}};
  for (const auto& [dname, m] : states) {
    if (m == &s.state_simulated_one_piece && !h5::HasLink(group.get(), dname, file, g)) continue;
    *m = h5::ToMatrix(ReadRequired(group.get(), dname, 2, file, g + "/" + dname));
    const bool residual = m == &s.state_residual_final;
    long long cols = 0;
    for (int d : residual ? s.state_residual_dims : s.state_dims) cols += d;
    if (m->rows() != s.time.size() || m->cols() != cols) {
      Fail(file, g + "/" + dname,
           "must be " + std::to_string(s.time.size()) + " x " + std::to_string(cols) +
               " (samples x the columns of the " +
               (residual ? "state_residual_dims" : "state_dims") + ")");
    }
  }
  return s;
}

}  // namespace

// `run_id` is the run id of result.h5 ("" when it has none)

void ReadH5(const std::string& path, FitResultFile* r, std::string* run_id) {
  const std::string& file = path;
  std::lock_guard<std::mutex> lock(h5::Mutex());
  h5::Silence();
  h5::Id f = h5::OpenFile(path, file);
  h5::Id root = h5::Own(H5Gopen2(f.get(), "/", H5P_DEFAULT), H5Gclose, file, "/",
                        "cannot open the root group (corrupt file?)");

  // format attributes
  const std::string format = h5::ReadScalarString(
      root.get(), "format", file, "/", " (not an mjsysid result: expected \"mjsysid-result\")");
  if (format != kFormat) {
    Fail(file, "/ attribute 'format'",
         "is \"" + format + "\", expected \"" + kFormat + "\" (not an mjsysid result)");
  }
  {
    h5::Id version = RequiredAttr(root.get(), "format_version", file, "/");
    const std::vector<long long> v =
        h5::ReadInts(version.get(), file, "/ attribute 'format_version'");
    if (v.size() != 1 || v[0] != kFormatVersion) {
      Fail(file, "/ attribute 'format_version'",
           "version " + (v.empty() ? std::string("?") : std::to_string(v[0])) +
               " is not supported (this build reads version " + std::to_string(kFormatVersion) +
               ")");
    }
  }
  // status (required, not compared), run_id (for the caller), intervals_valid (optional: files
  // before it have none; the same as result.yaml's)
  FitResultFile stored;
  stored.intervals_valid = r->intervals_valid;
  RootAttributeReader attributes(root.get(), file);
  VisitResultFields(attributes, stored);
  *run_id = stored.run_id;
  if (stored.intervals_valid != r->intervals_valid) {
    Fail(file, "/ attribute 'intervals_valid'",
         std::string("is ") + (stored.intervals_valid ? "1" : "0") +
             " but result.yaml's intervals_valid is " + (r->intervals_valid ? "true" : "false") +
             " (written by different fits?)");
  }

  // arrays
  ReadH5Parameters(root.get(), file, *r);
  ReadH5Derived(root.get(), file, *r);
  r->uncertainty.covariance =
      h5::ToMatrix(ReadRequired(root.get(), "covariance", 2, file, "/covariance"));
  r->jacobian = h5::ToMatrix(ReadRequired(root.get(), "jacobian", 2, file, "/jacobian"));
  ReadH5Trace(root.get(), file, r);
  h5::Id seqs = OpenGroup(root.get(), "sequences", file, "/sequences");
  for (const std::string& name : h5::LinkNames(seqs.get(), file, "/sequences")) {
    r->sequences.push_back(ReadH5Sequence(seqs.get(), name, file, "/sequences"));
  }
  if (h5::HasLink(root.get(), "validation", file, "/")) {
    h5::Id held_out = OpenGroup(root.get(), "validation", file, "/validation");
    for (const std::string& name : h5::LinkNames(held_out.get(), file, "/validation")) {
      r->validation.push_back(ReadH5Sequence(held_out.get(), name, file, "/validation"));
    }
  }
  CheckArrays(*r, file);
}

}  // namespace mjsysid::io::result_internal
