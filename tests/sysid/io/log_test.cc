#include "sysid/io/log.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "core/mujoco_env.h"
#include "tests/temp_dir_test.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;
const std::string kModels = MJSYSID_MODELS_DIR;

// ---------------------------------------------------------------------------------------------
// helpers

// a fresh directory per test, removed afterwards
class LogTest : public test::TempDirTest {};

// deterministic, varied values (no two equal, signs mixed)
double Value(int seed, Eigen::Index r, Eigen::Index c) {
  return std::sin(1.3 * static_cast<double>(seed) + 0.7 * static_cast<double>(r) +
                  2.9 * static_cast<double>(c)) *
         std::pow(10.0, static_cast<double>((r + c) % 7) - 3.0);
}

RowMatrix Matrix(Eigen::Index rows, Eigen::Index cols, int seed) {
  RowMatrix m(rows, cols);
  for (Eigen::Index r = 0; r < rows; ++r) {
    for (Eigen::Index c = 0; c < cols; ++c) m(r, c) = Value(seed, r, c);
  }
  return m;
}

Eigen::VectorXd Time(Eigen::Index samples, double period, double start = 0.0) {
  Eigen::VectorXd t(samples);
  for (Eigen::Index k = 0; k < samples; ++k) t[k] = start + period * static_cast<double>(k);
  return t;
}

// a sequence shaped for models/pendulum.xml: actuator torque, sensors angle and rate
Sequence PendulumSequence(const std::string& name, Eigen::Index samples, double period = 0.002) {
  Sequence s;
  s.name = name;
  s.time = Time(samples, period);
  s.ctrl = Matrix(samples, 1, 1);
  s.sensordata = Matrix(samples, 2, 2);
  s.qpos = Matrix(samples, 1, 3);
  s.qvel = Matrix(samples, 1, 4);
  s.sensor_names = {"angle", "rate"};
  s.sensor_dims = {1, 1};
  s.actuator_names = {"torque"};
  return s;
}

Log PendulumLog(Eigen::Index samples = 20) {
  Log log;
  log.sequences.push_back(PendulumSequence("run1", samples));
  log.attributes["model"] = "pendulum.xml";
  return log;
}

// the exception's message; fails the test when fn does not throw LogError
std::string LogErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const LogError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected LogError, got another exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected LogError, nothing thrown";
  return "";
}

// each piece must appear in the message
void ExpectMentions(const std::string& message, std::initializer_list<std::string> pieces) {
  for (const std::string& piece : pieces) {
    EXPECT_NE(message.find(piece), std::string::npos)
        << "message lacks \"" << piece << "\": " << message;
  }
}

bool BitEqual(const double* a, const double* b, Eigen::Index n) {
  return n == 0 || std::memcmp(a, b, static_cast<size_t>(n) * sizeof(double)) == 0;
}

void ExpectBitEqual(const RowMatrix& a, const RowMatrix& b, const std::string& what) {
  ASSERT_EQ(a.rows(), b.rows()) << what;
  ASSERT_EQ(a.cols(), b.cols()) << what;
  EXPECT_TRUE(BitEqual(a.data(), b.data(), a.size())) << what;
}

void ExpectSameSequence(const Sequence& a, const Sequence& b) {
  EXPECT_EQ(a.name, b.name);
  ASSERT_EQ(a.time.size(), b.time.size()) << a.name;
  EXPECT_TRUE(BitEqual(a.time.data(), b.time.data(), a.time.size())) << a.name;
  ExpectBitEqual(a.ctrl, b.ctrl, a.name + " ctrl");
  ExpectBitEqual(a.sensordata, b.sensordata, a.name + " sensordata");
  ExpectBitEqual(a.qpos, b.qpos, a.name + " qpos");
  ExpectBitEqual(a.qvel, b.qvel, a.name + " qvel");
  ExpectBitEqual(a.act, b.act, a.name + " act");
  EXPECT_EQ(a.sensor_names, b.sensor_names);
  EXPECT_EQ(a.sensor_dims, b.sensor_dims);
  EXPECT_EQ(a.actuator_names, b.actuator_names);
}

// raw hdf5 edits of a written file, to make malformed ones

void SilenceHdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }

void EditFile(const std::string& path, const std::function<void(hid_t)>& edit) {
  SilenceHdf5();
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0) << path;
  edit(f);
  ASSERT_GE(H5Fclose(f), 0);
}

// sets one element of a 1-D or 2-D dataset
void SetElement(const std::string& path, const std::string& dataset, hsize_t row, hsize_t col,
                double value) {
  EditFile(path, [&](hid_t f) {
    const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
    ASSERT_GE(d, 0) << dataset;
    const hid_t space = H5Dget_space(d);
    const hsize_t start[2] = {row, col};
    const hsize_t count[2] = {1, 1};
    ASSERT_GE(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
    const hsize_t one = 1;
    const hid_t mem = H5Screate_simple(1, &one, nullptr);
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, &value), 0);
    H5Sclose(mem);
    H5Sclose(space);
    H5Dclose(d);
  });
}

// replaces a dataset by a float64 one of another shape (values 0..n-1)
void ReplaceDataset(const std::string& path, const std::string& dataset,
                    std::vector<hsize_t> dims) {
  EditFile(path, [&](hid_t f) {
    if (H5Lexists(f, dataset.c_str(), H5P_DEFAULT) > 0) {
      ASSERT_GE(H5Ldelete(f, dataset.c_str(), H5P_DEFAULT), 0);
    }
    hsize_t n = 1;
    for (hsize_t d : dims) n *= d;
    std::vector<double> data(n);
    for (hsize_t i = 0; i < n; ++i) data[i] = static_cast<double>(i);
    const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t d = H5Dcreate2(f, dataset.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT,
                               H5P_DEFAULT);
    ASSERT_GE(d, 0);
    if (n > 0) {
      ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0);
    }
    H5Dclose(d);
    H5Sclose(space);
  });
}

// replaces an attribute of an object by a variable-length string array (or scalar)
void ReplaceStringAttr(const std::string& path, const std::string& object, const std::string& name,
                       const std::vector<std::string>& values, bool scalar = false) {
  EditFile(path, [&](hid_t f) {
    const hid_t obj = H5Oopen(f, object.c_str(), H5P_DEFAULT);
    ASSERT_GE(obj, 0) << object;
    if (H5Aexists(obj, name.c_str()) > 0) {
      ASSERT_GE(H5Adelete(obj, name.c_str()), 0);
    }
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, H5T_VARIABLE);
    const hsize_t n = values.size();
    const hid_t space = scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr);
    const hid_t a = H5Acreate2(obj, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    std::vector<const char*> ptrs;
    for (const std::string& v : values) ptrs.push_back(v.c_str());
    if (!ptrs.empty()) {
      ASSERT_GE(H5Awrite(a, type, ptrs.data()), 0);
    }
    H5Aclose(a);
    H5Sclose(space);
    H5Tclose(type);
    H5Oclose(obj);
  });
}

// replaces an integer attribute (1-D, or scalar)
void ReplaceIntAttr(const std::string& path, const std::string& object, const std::string& name,
                    const std::vector<int>& values, bool scalar = false) {
  EditFile(path, [&](hid_t f) {
    const hid_t obj = H5Oopen(f, object.c_str(), H5P_DEFAULT);
    ASSERT_GE(obj, 0) << object;
    if (H5Aexists(obj, name.c_str()) > 0) {
      ASSERT_GE(H5Adelete(obj, name.c_str()), 0);
    }
    const hsize_t n = values.size();
    const hid_t space = scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr);
    const hid_t a = H5Acreate2(obj, name.c_str(), H5T_STD_I32LE, space, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    ASSERT_GE(H5Awrite(a, H5T_NATIVE_INT, values.data()), 0);
    H5Aclose(a);
    H5Sclose(space);
    H5Oclose(obj);
  });
}

// ---------------------------------------------------------------------------------------------
// round trip

TEST_F(LogTest, RoundTripIsBitExact) {
  Log log;
  log.sensor_time = "post";
  log.attributes = {{"model", "pendulum.xml"},
                    {"seed", "42"},
                    {"note",
                     "\xc3\xbcnic\xc3\xb6"
                     "de \xe2\x9c\x93"},
                    {"empty", ""}};

  // full: every optional dataset, multi-dimensional sensors, awkward doubles
  Sequence zeta;
  zeta.name = "zeta";
  zeta.time = Time(50, 0.01, 1e3);
  zeta.ctrl = Matrix(50, 2, 5);
  zeta.sensordata = Matrix(50, 4, 6);
  zeta.qpos = Matrix(50, 3, 7);
  zeta.qvel = Matrix(50, 2, 8);
  zeta.act = Matrix(50, 1, 9);
  zeta.sensordata(0, 0) = -0.0;
  zeta.sensordata(1, 1) = std::numeric_limits<double>::denorm_min();
  zeta.sensordata(2, 2) = -1e150;  // the largest magnitude a log may hold (its square is finite)
  zeta.sensordata(3, 3) = -std::numeric_limits<double>::min();
  zeta.ctrl(4, 1) = 1.0 / 3.0;
  zeta.sensor_names = {"s1", "s3"};
  zeta.sensor_dims = {1, 3};
  zeta.actuator_names = {"a0", "\xce\xb1"};

  // zero-width ctrl and sensordata, a single sample
  Sequence alpha;
  alpha.name = "alpha";
  alpha.time = Time(1, 0.002);
  alpha.ctrl = RowMatrix(1, 0);
  alpha.sensordata = RowMatrix(1, 0);

  // qpos only, and act present but zero-width
  Sequence mid;
  mid.name = "mid sequence";
  mid.time = Time(17, 0.004, -1.0);
  mid.ctrl = Matrix(17, 1, 10);
  mid.sensordata = Matrix(17, 4, 11);
  mid.qpos = Matrix(17, 7, 12);
  mid.act = RowMatrix(17, 0);
  mid.sensor_names = {"quat"};
  mid.sensor_dims = {4};
  mid.actuator_names = {"push"};

  log.sequences = {zeta, alpha, mid};
  const std::string path = Path("log.h5");
  WriteLog(path, log);
  const Log back = ReadLog(path);

  EXPECT_EQ(back.sensor_time, "post");
  EXPECT_EQ(back.attributes, log.attributes);
  ASSERT_EQ(back.sequences.size(), 3u);
  // creation order, not alphabetical
  for (size_t i = 0; i < 3; ++i) ASSERT_EQ(back.sequences[i].name, log.sequences[i].name);
  for (size_t i = 0; i < 3; ++i) ExpectSameSequence(log.sequences[i], back.sequences[i]);
  ASSERT_EQ(back.sequences[0].sensordata.rows(), 50);
  EXPECT_TRUE(std::signbit(back.sequences[0].sensordata(0, 0)));
  EXPECT_EQ(back.sequences[2].act.rows(), 17);
  EXPECT_EQ(back.sequences[1].qpos.rows(), 0);
  // no temporary file left
  EXPECT_TRUE(OtherFiles("log.h5").empty());
}

TEST_F(LogTest, FileFollowsTheDocumentedLayout) {
  const std::string path = Path("log.h5");
  WriteLog(path, PendulumLog(5));
  SilenceHdf5();
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  for (const char* attr : {"format", "format_version", "sensor_time", "model"}) {
    EXPECT_GT(H5Aexists(f, attr), 0) << attr;
  }
  int version = 0;
  const hid_t va = H5Aopen(f, "format_version", H5P_DEFAULT);
  ASSERT_GE(H5Aread(va, H5T_NATIVE_INT, &version), 0);
  H5Aclose(va);
  EXPECT_EQ(version, 1);

  // 2-D row-major (T, columns) datasets
  const hid_t d = H5Dopen2(f, "/run1/sensordata", H5P_DEFAULT);
  ASSERT_GE(d, 0);
  const hid_t space = H5Dget_space(d);
  hsize_t dims[2] = {0, 0};
  EXPECT_EQ(H5Sget_simple_extent_ndims(space), 2);
  H5Sget_simple_extent_dims(space, dims, nullptr);
  EXPECT_EQ(dims[0], 5u);
  EXPECT_EQ(dims[1], 2u);
  EXPECT_GT(H5Aexists(d, "names"), 0);
  EXPECT_GT(H5Aexists(d, "dims"), 0);
  H5Sclose(space);
  H5Dclose(d);
  const hid_t t = H5Dopen2(f, "/run1/time", H5P_DEFAULT);
  EXPECT_GT(H5Aexists(t, "units"), 0);
  H5Dclose(t);
  EXPECT_GT(H5Lexists(f, "/run1/qpos", H5P_DEFAULT), 0);
  EXPECT_EQ(H5Lexists(f, "/run1/act", H5P_DEFAULT), 0);
  H5Fclose(f);
}

TEST_F(LogTest, SameLogGivesSameBytes) {
  // no timestamps in the file: written a second apart, the bytes are the same
  WriteLog(Path("a.h5"), PendulumLog(8));
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  WriteLog(Path("b.h5"), PendulumLog(8));
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const std::string a = bytes(Path("a.h5"));
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == bytes(Path("b.h5")));
}

TEST_F(LogTest, ReadsFilesFromOtherWriters) {
  // fixed-length strings, float32 data, integer metadata, no creation-order index
  const std::string path = Path("other.h5");
  SilenceHdf5();
  const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  auto fixed_attr = [](hid_t obj, const char* name, const std::vector<std::string>& values,
                       bool scalar) {
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, 16);
    H5Tset_strpad(type, H5T_STR_NULLPAD);
    const hsize_t n = values.size();
    const hid_t space = scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr);
    std::vector<char> buf(16 * n, '\0');
    for (size_t i = 0; i < n; ++i) std::memcpy(&buf[16 * i], values[i].data(), values[i].size());
    const hid_t a = H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, type, buf.data());
    H5Aclose(a);
    H5Sclose(space);
    H5Tclose(type);
  };
  fixed_attr(f, "format", {"mjsysid-log"}, true);
  fixed_attr(f, "sensor_time", {"pre"}, true);
  {
    const long long one = 1, seed = 42;
    const hid_t space = H5Screate(H5S_SCALAR);
    for (const auto& [name, v] : {std::pair<const char*, long long>{"format_version", one},
                                  std::pair<const char*, long long>{"seed", seed}}) {
      const hid_t a = H5Acreate2(f, name, H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
      H5Awrite(a, H5T_NATIVE_LLONG, &v);
      H5Aclose(a);
    }
    H5Sclose(space);
  }
  const hid_t g = H5Gcreate2(f, "g", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  auto dataset = [g](const char* name, std::vector<hsize_t> dims, const std::vector<float>& v) {
    const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t d =
        H5Dcreate2(g, name, H5T_IEEE_F32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Sclose(space);
    return d;
  };
  H5Dclose(dataset("time", {3}, {0.0f, 0.5f, 1.0f}));
  const hid_t c = dataset("ctrl", {3, 1}, {1.5f, 2.5f, 3.5f});
  fixed_attr(c, "names", {"torque"}, false);
  H5Dclose(c);
  const hid_t s = dataset("sensordata", {3, 2}, {1, 2, 3, 4, 5, 6});
  fixed_attr(s, "names", {"angle", "rate"}, false);
  const int dims[2] = {1, 1};
  const hsize_t two = 2;
  const hid_t dspace = H5Screate_simple(1, &two, nullptr);
  const hid_t da = H5Acreate2(s, "dims", H5T_STD_I32LE, dspace, H5P_DEFAULT, H5P_DEFAULT);
  H5Awrite(da, H5T_NATIVE_INT, dims);
  H5Aclose(da);
  H5Sclose(dspace);
  H5Dclose(s);
  H5Gclose(g);
  ASSERT_GE(H5Fclose(f), 0);

  const Log log = ReadLog(path);
  EXPECT_EQ(log.attributes.at("seed"), "42");
  ASSERT_EQ(log.sequences.size(), 1u);
  const Sequence& seq = log.sequences[0];
  EXPECT_EQ(seq.actuator_names, std::vector<std::string>{"torque"});
  EXPECT_EQ(seq.sensor_names, (std::vector<std::string>{"angle", "rate"}));
  EXPECT_EQ(seq.time[2], 1.0);
  EXPECT_EQ(seq.ctrl(1, 0), 2.5);
  EXPECT_EQ(seq.sensordata(2, 1), 6.0);
}

// ---------------------------------------------------------------------------------------------
// atomic writes

TEST_F(LogTest, FailedWriteKeepsTheOldFile) {
  const std::string path = Path("log.h5");
  const Log good = PendulumLog(10);
  WriteLog(path, good);

  // ctrl one row short: rejected before anything is replaced
  Log bad = PendulumLog(10);
  bad.sequences[0].ctrl = Matrix(9, 1, 1);
  const std::string msg = LogErrorOf([&] { WriteLog(path, bad); });
  ExpectMentions(msg, {path, "/run1/ctrl", "9 rows"});

  const Log back = ReadLog(path);
  ASSERT_EQ(back.sequences.size(), 1u);
  ExpectSameSequence(good.sequences[0], back.sequences[0]);
  EXPECT_TRUE(OtherFiles("log.h5").empty());
}

TEST_F(LogTest, FailedRenameLeavesNoTemporaryFile) {
  // the target is a non-empty directory: the temporary file is written, the rename fails
  const std::string path = Path("target");
  fs::create_directories(fs::path(path) / "inside");
  const std::string msg = LogErrorOf([&] { WriteLog(path, PendulumLog(5)); });
  ExpectMentions(msg, {path, "rename"});
  EXPECT_EQ(OtherFiles("target"), std::vector<std::string>{});
  EXPECT_TRUE(fs::is_directory(path));
}

TEST_F(LogTest, UnwritableDirectoryIsALogError) {
  const std::string path = Path("missing_dir/log.h5");
  const std::string msg = LogErrorOf([&] { WriteLog(path, PendulumLog(5)); });
  ExpectMentions(msg, {path});
  EXPECT_FALSE(fs::exists(Path("missing_dir")));
}

TEST_F(LogTest, WriteRejectsInvalidLogs) {
  const std::string path = Path("log.h5");
  {
    Log log = PendulumLog(10);
    // NaN in sensordata is a value not measured (masked out of the fit); Inf is an error
    log.sequences[0].sensordata(6, 1) = std::numeric_limits<double>::infinity();
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }),
                   {path, "/run1/sensordata", "row 6", "column 1"});
  }
  {
    Log log = PendulumLog(10);
    log.sequences[0].sensor_dims = {1, 2};
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "/run1/sensordata", "dims"});
  }
  {
    Log log = PendulumLog(10);
    log.sequences[0].actuator_names = {};
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "/run1/ctrl", "names"});
  }
  {
    Log log = PendulumLog(10);
    log.sequences[0].qvel = RowMatrix(0, 3);
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "/run1/qvel"});
  }
  {
    Log log = PendulumLog(10);
    log.sequences.push_back(log.sequences[0]);
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "run1", "two sequences"});
  }
  {
    Log log = PendulumLog(10);
    log.sequences[0].name = "a/b";
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "a/b"});
  }
  {
    Log log = PendulumLog(10);
    log.attributes["format"] = "mine";
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "format", "reserved"});
  }
  {
    Log log = PendulumLog(10);
    log.sensor_time = "later";
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "sensor_time", "later"});
  }
  {
    Log log;
    ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }), {path, "no sequences"});
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(OtherFiles("").empty());
}

// ---------------------------------------------------------------------------------------------
// malformed files

class LogReadErrorTest : public LogTest {
 protected:
  void SetUp() override {
    LogTest::SetUp();
    path_ = Path("bad.h5");
    WriteLog(path_, PendulumLog(10));
  }
  std::string ReadError() const {
    return LogErrorOf([&] { ReadLog(path_); });
  }
  std::string path_;
};

TEST_F(LogReadErrorTest, NanStateIsNotMeasuredInfNamesDatasetRowAndColumn) {
  // NaN is allowed in ctrl, sensordata and the states (not measured: docs/real-logs.md); Inf not
  SetElement(path_, "/run1/qpos", 3, 0, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(std::isnan(ReadLog(path_).sequences[0].qpos(3, 0)));
  SetElement(path_, "/run1/qpos", 3, 0, std::numeric_limits<double>::infinity());
  ExpectMentions(ReadError(), {path_, "/run1/qpos", "row 3", "column 0", "inf"});
}

TEST_F(LogReadErrorTest, InfControlIsAnError) {
  SetElement(path_, "/run1/ctrl", 3, 0, std::numeric_limits<double>::infinity());
  ExpectMentions(ReadError(), {path_, "/run1/ctrl", "row 3", "column 0", "inf"});
}

// NaN in ctrl and sensordata reads back as NaN: values not measured
TEST_F(LogReadErrorTest, NanSensorAndControlCellsReadBack) {
  SetElement(path_, "/run1/ctrl", 3, 0, std::numeric_limits<double>::quiet_NaN());
  SetElement(path_, "/run1/sensordata", 7, 1, std::numeric_limits<double>::quiet_NaN());
  const Log log = ReadLog(path_);
  EXPECT_TRUE(std::isnan(log.sequences[0].ctrl(3, 0)));
  EXPECT_TRUE(std::isnan(log.sequences[0].sensordata(7, 1)));
  EXPECT_FALSE(std::isnan(log.sequences[0].sensordata(7, 0)));
}

TEST_F(LogReadErrorTest, InfNamesDatasetRowAndColumn) {
  SetElement(path_, "/run1/sensordata", 7, 1, -std::numeric_limits<double>::infinity());
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "row 7", "column 1", "inf"});
}

TEST_F(LogReadErrorTest, NanInOptionalState) {
  SetElement(path_, "/run1/qvel", 9, 0, std::numeric_limits<double>::infinity());
  ExpectMentions(ReadError(), {path_, "/run1/qvel", "row 9", "column 0"});
}

TEST_F(LogReadErrorTest, NonIncreasingTimeNamesTheRow) {
  SetElement(path_, "/run1/time", 5, 0, 0.008);  // = time[4]
  ExpectMentions(ReadError(), {path_, "/run1/time", "row 5", "strictly increasing"});
}

TEST_F(LogReadErrorTest, NanTime) {
  SetElement(path_, "/run1/time", 2, 0, std::numeric_limits<double>::quiet_NaN());
  ExpectMentions(ReadError(), {path_, "/run1/time", "row 2", "not finite"});
}

TEST_F(LogReadErrorTest, MissingRequiredDataset) {
  EditFile(path_, [](hid_t f) { ASSERT_GE(H5Ldelete(f, "/run1/sensordata", H5P_DEFAULT), 0); });
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "missing"});
}

TEST_F(LogReadErrorTest, WrongRank) {
  ReplaceDataset(path_, "/run1/time", {10, 1});
  ExpectMentions(ReadError(), {path_, "/run1/time", "rank 2", "(10, 1)"});
}

TEST_F(LogReadErrorTest, RowsDifferingFromTime) {
  ReplaceDataset(path_, "/run1/qpos", {9, 1});
  ExpectMentions(ReadError(), {path_, "/run1/qpos", "9 rows", "expected 10"});
}

TEST_F(LogReadErrorTest, TransposedDatasetGetsAHint) {
  ReplaceDataset(path_, "/run1/sensordata", {2, 10});
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "transposed"});
}

TEST_F(LogReadErrorTest, ActuatorNamesNotMatchingColumns) {
  ReplaceStringAttr(path_, "/run1/ctrl", "names", {"torque", "extra"});
  ExpectMentions(ReadError(), {path_, "/run1/ctrl", "2 actuator names", "1 columns"});
}

TEST_F(LogReadErrorTest, SensorNamesNotMatchingDims) {
  ReplaceStringAttr(path_, "/run1/sensordata", "names", {"angle"});
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "1 sensor names", "2 dims"});
}

TEST_F(LogReadErrorTest, SensorDimsNotSummingToColumns) {
  ReplaceIntAttr(path_, "/run1/sensordata", "dims", {1, 2});
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "sum to 3", "2 columns"});
}

TEST_F(LogReadErrorTest, MissingNamesAttribute) {
  EditFile(path_, [](hid_t f) {
    const hid_t d = H5Dopen2(f, "/run1/ctrl", H5P_DEFAULT);
    ASSERT_GE(H5Adelete(d, "names"), 0);
    H5Dclose(d);
  });
  ExpectMentions(ReadError(), {path_, "/run1/ctrl", "names", "missing"});
}

TEST_F(LogReadErrorTest, UnknownDatasetInSequence) {
  ReplaceDataset(path_, "/run1/qpso", {10, 1});
  ExpectMentions(ReadError(), {path_, "/run1/qpso", "unknown"});
}

TEST_F(LogReadErrorTest, DatasetAtTheRoot) {
  ReplaceDataset(path_, "/time", {10});
  ExpectMentions(ReadError(), {path_, "/time", "not a group"});
}

TEST_F(LogReadErrorTest, NoSequences) {
  EditFile(path_, [](hid_t f) { ASSERT_GE(H5Ldelete(f, "/run1", H5P_DEFAULT), 0); });
  ExpectMentions(ReadError(), {path_, "no sequences"});
}

TEST_F(LogReadErrorTest, NotAnMjsysidLog) {
  ReplaceStringAttr(path_, "/", "format", {"something-else"}, true);
  ExpectMentions(ReadError(), {path_, "format", "something-else"});
}

TEST_F(LogReadErrorTest, NewerFormatVersion) {
  ReplaceIntAttr(path_, "/", "format_version", {2}, true);
  ExpectMentions(ReadError(), {path_, "format_version", "version 2"});
}

TEST_F(LogReadErrorTest, BadSensorTime) {
  ReplaceStringAttr(path_, "/", "sensor_time", {"later"}, true);
  ExpectMentions(ReadError(), {path_, "sensor_time", "later"});
}

TEST_F(LogReadErrorTest, TimeUnitsOtherThanSeconds) {
  ReplaceStringAttr(path_, "/run1/time", "units", {"ms"}, true);
  ExpectMentions(ReadError(), {path_, "/run1/time", "units", "ms"});
}

TEST_F(LogReadErrorTest, TruncatedFile) {
  const auto size = fs::file_size(path_);
  fs::resize_file(path_, size / 2);
  ExpectMentions(ReadError(), {path_});
}

// HDF5 1.10 itself loops forever on a global heap object of size 0 (found by tests/fuzz/log_fuzz,
// reproducer tests/fuzz/corpus/log/regression-global-heap-loop.h5): ReadLog refuses such a file
// before HDF5 parses it
TEST_F(LogReadErrorTest, GlobalHeapObjectOfSizeZero) {
  std::string bytes;
  {
    std::ifstream in(path_, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const size_t gcol = bytes.find("GCOL");
  ASSERT_NE(gcol, std::string::npos) << "no global heap: the names are not variable-length?";
  // the first object (header at byte 16 of the collection): index 0, size 0
  const size_t object = gcol + 16;
  for (size_t i = 0; i < 16; ++i) bytes[object + i] = '\0';
  std::ofstream(path_, std::ios::binary | std::ios::trunc) << bytes;
  ExpectMentions(ReadError(), {path_, "corrupt global heap collection", "byte"});
}

// a dataspace claiming far more data than the file holds is refused before anything is allocated
// (found by tests/fuzz/log_fuzz: a corrupt shape made ReadLog allocate and zero 8 GB)
TEST_F(LogReadErrorTest, ShapeLargerThanTheFile) {
  EditFile(path_, [](hid_t f) {
    ASSERT_GE(H5Ldelete(f, "/run1/sensordata", H5P_DEFAULT), 0);
    const hsize_t dims[2] = {10, hsize_t{1} << 30};  // 80 GB, never written
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t d = H5Dcreate2(f, "/run1/sensordata", H5T_IEEE_F64LE, space, H5P_DEFAULT,
                               H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    H5Dclose(d);
    H5Sclose(space);
  });
  ExpectMentions(ReadError(), {path_, "/run1/sensordata", "(10, 1073741824)", "can hold"});
}

TEST_F(LogTest, NonHdf5File) {
  const std::string path = Path("notes.h5");
  std::ofstream(path) << "time,ctrl\n0,1\n";
  ExpectMentions(LogErrorOf([&] { ReadLog(path); }), {path, "not an HDF5 file"});
}

TEST_F(LogTest, MissingFile) {
  const std::string path = Path("nope.h5");
  ExpectMentions(LogErrorOf([&] { ReadLog(path); }), {path, "no such file"});
}

// ---------------------------------------------------------------------------------------------
// against a model

class ValidateTest : public ::testing::Test {
 protected:
  void SetUp() override { model_ = LoadModel(kModels + "/pendulum.xml"); }
  std::string ValidateError(const Log& log) const {
    return LogErrorOf([&] { ValidateLogAgainstModel(log, *model_, "data.h5"); });
  }
  ModelPtr model_;
};

TEST_F(ValidateTest, MatchingLogPasses) {
  EXPECT_NO_THROW(ValidateLogAgainstModel(PendulumLog(), *model_, "data.h5"));
  Log log = PendulumLog();
  log.sequences[0].time = Time(20, 0.01);             // 5 steps per sample
  log.sequences[0].sensor_names = {"rate", "angle"};  // any sensor order, any subset
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *model_, "data.h5"));
  log.sequences[0].sensor_names = {"rate"};
  log.sequences[0].sensor_dims = {1};
  log.sequences[0].sensordata = Matrix(20, 1, 3);
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *model_, "data.h5"));
}

TEST_F(ValidateTest, UnknownSensorWithHint) {
  Log log = PendulumLog();
  log.sequences[0].sensor_names = {"angel", "rate"};
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/sensordata", "unknown sensor 'angel'",
                                      "did you mean 'angle'", "angle, rate"});
}

TEST_F(ValidateTest, WrongSensorDimension) {
  Log log = PendulumLog();
  log.sequences[0].sensor_dims = {1, 2};
  log.sequences[0].sensordata = Matrix(20, 3, 2);
  ExpectMentions(ValidateError(log), {"data.h5", "'rate'", "2 columns", "dimension 1"});
}

TEST_F(ValidateTest, RepeatedSensor) {
  Log log = PendulumLog();
  log.sequences[0].sensor_names = {"rate", "rate"};
  ExpectMentions(ValidateError(log), {"data.h5", "'rate'", "twice"});
}

TEST_F(ValidateTest, ExtraActuatorColumn) {
  Log log = PendulumLog();
  log.sequences[0].ctrl = Matrix(20, 2, 1);
  log.sequences[0].actuator_names = {"torque", "torq"};
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/ctrl", "2 columns", "nu = 1",
                                      "unknown actuator 'torq'", "torque"});
}

TEST_F(ValidateTest, MissingActuatorColumn) {
  Log log = PendulumLog();
  log.sequences[0].ctrl = RowMatrix(20, 0);
  log.sequences[0].actuator_names = {};
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/ctrl", "nu = 1", "missing", "'torque'"});
}

TEST_F(ValidateTest, ActuatorsOutOfModelOrder) {
  const ModelPtr arm = LoadModel(kModels + "/arm5.xml");
  Log log;
  Sequence s = PendulumSequence("run1", 20);
  s.ctrl = Matrix(20, 5, 1);
  s.actuator_names = {"m1", "m3", "m2", "m4", "m5"};
  s.sensordata = RowMatrix(20, 0);
  s.sensor_names = {};
  s.sensor_dims = {};
  s.qpos = RowMatrix();
  s.qvel = RowMatrix();
  log.sequences.push_back(s);
  const std::string msg = LogErrorOf([&] { ValidateLogAgainstModel(log, *arm, "arm.h5"); });
  ExpectMentions(msg, {"arm.h5", "/run1/ctrl", "model order", "m1, m2, m3, m4, m5"});
  log.sequences[0].actuator_names = {"m1", "m2", "m3", "m4", "m5"};
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *arm, "arm.h5"));
}

TEST_F(ValidateTest, StateWidths) {
  Log log = PendulumLog();
  log.sequences[0].qpos = Matrix(20, 2, 3);
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/qpos", "2 columns", "nq = 1"});
  log = PendulumLog();
  log.sequences[0].act = Matrix(20, 1, 3);
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/act", "na = 0"});
}

// Any sample period is accepted (each sample is fitted at its own time, sysid/data/sample_grid.h);
// the time base's warnings name where the period varies or a gap is long; a period below 1/100 of
// the timestep is a unit error (sysid/io/time_base.h)
TEST_F(ValidateTest, AnySamplePeriodWithWarningsAndUnitErrors) {
  Log log = PendulumLog();
  std::vector<std::string> warnings;
  for (double period : {0.003, 0.001, 0.01}) {
    log.sequences[0].time = Time(20, period);
    EXPECT_NO_THROW(ValidateLogAgainstModel(log, *model_, "data.h5", &warnings)) << period;
  }
  EXPECT_TRUE(warnings.empty());
  // every other step 30 % longer: within 50 %, no warning
  for (Eigen::Index k = 1; k < 20; k += 2) log.sequences[0].time.tail(20 - k).array() += 0.003;
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *model_, "data.h5", &warnings));
  EXPECT_TRUE(warnings.empty());
  // one step 1.6 x the median: a varying period, named by its rows
  log.sequences[0].time = Time(20, 0.01);
  log.sequences[0].time.tail(13).array() += 0.006;
  ValidateLogAgainstModel(log, *model_, "data.h5", &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  ExpectMentions(warnings[0],
                 {"data.h5", "/run1/time", "varies by more than 50 %", "rows 6 and 7"});
  // a gap of 12 periods
  warnings.clear();
  log.sequences[0].time = Time(20, 0.01);
  log.sequences[0].time.tail(5).array() += 0.11;
  ValidateLogAgainstModel(log, *model_, "data.h5", &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  ExpectMentions(warnings[0], {"1 gap(s) longer than 10 sample periods", "rows 14 and 15", "12"});
  // microseconds against a 2 ms model, read as seconds
  log.sequences[0].time = Time(20, 0.000002);
  ExpectMentions(ValidateError(log),
                 {"data.h5", "/run1/time", "below 1/100 of the model timestep"});
}

TEST_F(ValidateTest, SingleSampleCannotGiveAPeriod) {
  Log log = PendulumLog(1);
  ExpectMentions(ValidateError(log), {"data.h5", "/run1/time", "at least 2"});
}

TEST_F(ValidateTest, MultiDimensionalSensors) {
  const ModelPtr box = LoadModel(kModels + "/box_floor.xml");
  Log log;
  Sequence s;
  s.name = "push";
  s.time = Time(30, 0.002);
  s.ctrl = Matrix(30, 1, 1);
  s.actuator_names = {"push_x"};
  s.sensordata = Matrix(30, 10, 2);
  s.sensor_names = {"box_pos", "box_quat", "box_vel"};
  s.sensor_dims = {3, 4, 3};
  s.qpos = Matrix(30, 7, 3);
  s.qvel = Matrix(30, 6, 4);
  log.sequences.push_back(s);
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *box, "box.h5"));
  log.sequences[0].sensor_dims = {3, 3, 4};
  ExpectMentions(LogErrorOf([&] { ValidateLogAgainstModel(log, *box, "box.h5"); }),
                 {"box.h5", "'box_quat'", "3 columns", "dimension 4"});
}

TEST_F(ValidateTest, RecordedRolloutRoundTripsAndValidates) {
  // record the pendulum the mjsysid way: y_k from mj_forward at x_k, then step
  const DataPtr d = MakeData(*model_);
  d->qpos[0] = 0.3;
  const Eigen::Index samples = 40;
  Sequence s;
  s.name = "rollout";
  s.time.resize(samples);
  s.ctrl.resize(samples, 1);
  s.sensordata.resize(samples, 2);
  s.qpos.resize(samples, 1);
  s.qvel.resize(samples, 1);
  for (Eigen::Index k = 0; k < samples; ++k) {
    d->ctrl[0] = std::sin(0.1 * static_cast<double>(k));
    mj_forward(model_.get(), d.get());
    s.time[k] = d->time;
    s.ctrl(k, 0) = d->ctrl[0];
    s.sensordata(k, 0) = d->sensordata[0];
    s.sensordata(k, 1) = d->sensordata[1];
    s.qpos(k, 0) = d->qpos[0];
    s.qvel(k, 0) = d->qvel[0];
    mj_step(model_.get(), d.get());
  }
  s.sensor_names = {"angle", "rate"};
  s.sensor_dims = {1, 1};
  s.actuator_names = {"torque"};
  // pre convention: the angle sensor equals qpos of the same row
  EXPECT_EQ(s.sensordata(7, 0), s.qpos(7, 0));

  Log log;
  log.sequences.push_back(s);
  const fs::path path =
      fs::temp_directory_path() / ("mjsysid_rollout_" + std::to_string(::getpid()) + ".h5");
  WriteLog(path.string(), log);
  const Log back = ReadLog(path.string());
  fs::remove(path);
  EXPECT_EQ(back.sensor_time, "pre");
  ExpectSameSequence(s, back.sequences.at(0));
  EXPECT_NO_THROW(ValidateLogAgainstModel(back, *model_, path.string()));
}

TEST(NameHintTest, SuggestsCloseNamesOnly) {
  const std::vector<std::string> valid = {"angle", "rate"};
  EXPECT_NE(internal::NameHint("angel", valid, "sensors").find("did you mean 'angle'"),
            std::string::npos);
  EXPECT_EQ(internal::NameHint("completely_different", valid, "sensors").find("did you mean"),
            std::string::npos);
  std::vector<std::string> many;
  for (int i = 0; i < 25; ++i) many.push_back("s" + std::to_string(i));
  const std::string hint = internal::NameHint("zzzzzzzz", many, "sensors");
  EXPECT_NE(hint.find("s19"), std::string::npos);
  EXPECT_EQ(hint.find("s20"), std::string::npos);
  EXPECT_NE(hint.find("5 more"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// controls and sensors at their own times (ctrl_time, sensor_time/, sensor_values/)

// writes float64 dataset `dataset` (1-D when cols == 0) of `values`, creating missing groups
void AddDataset(const std::string& path, const std::string& dataset, const double* values,
                hsize_t rows, hsize_t cols) {
  EditFile(path, [&](hid_t f) {
    const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl, 1);
    const hsize_t dims[2] = {rows, cols};
    const hid_t space = H5Screate_simple(cols ? 2 : 1, dims, nullptr);
    const hid_t d =
        H5Dcreate2(f, dataset.c_str(), H5T_IEEE_F64LE, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(d, 0) << dataset;
    if (rows > 0) {
      ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
    }
    H5Dclose(d);
    H5Sclose(space);
    H5Pclose(lcpl);
  });
}

void AddTimes(const std::string& path, const std::string& dataset, const Eigen::VectorXd& t) {
  AddDataset(path, dataset, t.data(), static_cast<hsize_t>(t.size()), 0);
}

void AddValues(const std::string& path, const std::string& dataset, const RowMatrix& v) {
  AddDataset(path, dataset, v.data(), static_cast<hsize_t>(v.rows()),
             static_cast<hsize_t>(v.cols()));
}

void DeleteLink(const std::string& path, const std::string& link) {
  EditFile(path, [&](hid_t f) { ASSERT_GE(H5Ldelete(f, link.c_str(), H5P_DEFAULT), 0) << link; });
}

TEST_F(LogTest, ControlsAtTheirOwnTimesRoundTrip) {
  // truth: controls at 50 Hz (6 rows) beside sensors at 100 Hz (11 rows)
  Log log = PendulumLog(11);
  Sequence& s = log.sequences[0];
  s.time = Time(11, 0.01);
  s.ctrl_time = Time(6, 0.02);
  s.ctrl = Matrix(6, 1, 7);
  const std::string path = Path("ctrl_time.h5");
  WriteLog(path, log);
  const Log back = ReadLog(path);
  ExpectSameSequence(back.sequences[0], s);
  ASSERT_EQ(back.sequences[0].ctrl_time.size(), 6);
  EXPECT_TRUE(BitEqual(back.sequences[0].ctrl_time.data(), s.ctrl_time.data(), 6));
  EXPECT_TRUE(back.sequences[0].own_times.empty());
  // ctrl rows must follow ctrl_time, named as such
  s.ctrl = Matrix(11, 1, 7);
  ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }),
                 {"/run1/ctrl", "has 11 rows", "expected 6 = the samples in ctrl_time"});
  s.ctrl = Matrix(6, 1, 7);
  s.ctrl_time[3] = s.ctrl_time[2];
  ExpectMentions(LogErrorOf([&] { WriteLog(path, log); }),
                 {"/run1/ctrl_time", "row 3", "strictly increasing"});
}

// a file whose sequence has `angle` in sensordata at 100 Hz and `rate` at 250 Hz in
// sensor_time/rate, sensor_values/rate; controls at 50 Hz; 0.1 s long
class OwnTimesTest : public LogTest {
 protected:
  void SetUp() override {
    LogTest::SetUp();
    path_ = Path("own_times.h5");
    Log log = PendulumLog(11);
    Sequence& s = log.sequences[0];
    s.time = Time(11, 0.01);
    s.sensordata = Matrix(11, 1, 2);
    s.sensor_names = {"angle"};
    s.sensor_dims = {1};
    s.qpos.resize(0, 0);
    s.qvel.resize(0, 0);
    s.ctrl_time = Time(6, 0.02);
    s.ctrl = Matrix(6, 1, 7);
    WriteLog(path_, log);
    rate_time_ = Time(26, 0.004);
    rate_ = Matrix(26, 1, 5);
    AddTimes(path_, "/run1/sensor_time/rate", rate_time_);
    AddValues(path_, "/run1/sensor_values/rate", rate_);
    angle_ = s.sensordata;
  }
  std::string ReadError() const {
    return LogErrorOf([&] { ReadLog(path_); });
  }
  std::string path_;
  Eigen::VectorXd rate_time_;
  RowMatrix rate_, angle_;
};

TEST_F(OwnTimesTest, SensorsMergeOntoTheUnionOfTheirTimes) {
  const Log log = ReadLog(path_);
  const Sequence& s = log.sequences[0];
  // the union of 0:0.01:0.1 and 0:0.004:0.1, sorted, equal doubles merged
  std::vector<double> all(s.time.data(), s.time.data() + s.time.size());
  std::vector<double> expect;
  for (Eigen::Index k = 0; k < 11; ++k) expect.push_back(Time(11, 0.01)[k]);
  for (Eigen::Index k = 0; k < 26; ++k) expect.push_back(rate_time_[k]);
  std::sort(expect.begin(), expect.end());
  expect.erase(std::unique(expect.begin(), expect.end()), expect.end());
  EXPECT_EQ(all, expect);
  EXPECT_EQ(s.sensor_names, (std::vector<std::string>{"angle", "rate"}));
  EXPECT_EQ(s.sensor_dims, (std::vector<int>{1, 1}));
  ASSERT_EQ(s.sensordata.rows(), s.time.size());
  // each sensor at its own times, NaN (not measured) elsewhere
  int angle_seen = 0, rate_seen = 0;
  for (Eigen::Index k = 0; k < s.time.size(); ++k) {
    const double t = s.time[k];
    const Eigen::VectorXd at = Time(11, 0.01);
    const auto a = std::find(at.data(), at.data() + 11, t) - at.data();
    const auto r = std::find(rate_time_.data(), rate_time_.data() + 26, t) - rate_time_.data();
    if (a < 11) {
      EXPECT_EQ(s.sensordata(k, 0), angle_(a, 0)) << t;
      ++angle_seen;
    } else {
      EXPECT_TRUE(std::isnan(s.sensordata(k, 0))) << t;
    }
    if (r < 26) {
      EXPECT_EQ(s.sensordata(k, 1), rate_(r, 0)) << t;
      ++rate_seen;
    } else {
      EXPECT_TRUE(std::isnan(s.sensordata(k, 1))) << t;
    }
  }
  EXPECT_EQ(angle_seen, 11);
  EXPECT_EQ(rate_seen, 26);
  // the controls keep their own times; the time datasets as read are kept for the checks
  EXPECT_EQ(s.ctrl_time.size(), 6);
  ASSERT_EQ(s.own_times.size(), 2u);
  EXPECT_EQ(s.own_times[0].first, "/run1/time");
  EXPECT_EQ(s.own_times[1].first, "/run1/sensor_time/rate");
}

TEST_F(OwnTimesTest, EverySensorAtItsOwnTimesWithoutTimeOrSensordata) {
  DeleteLink(path_, "/run1/time");
  ExpectMentions(ReadError(), {path_, "/run1/time", "is missing", "time and sensordata"});
  DeleteLink(path_, "/run1/sensordata");
  AddTimes(path_, "/run1/sensor_time/angle", Time(11, 0.01));
  AddValues(path_, "/run1/sensor_values/angle", angle_);
  const Sequence s = ReadLog(path_).sequences[0];
  EXPECT_EQ(s.sensor_names, (std::vector<std::string>{"angle", "rate"}));  // name order
  EXPECT_EQ(s.own_times.size(), 2u);
  EXPECT_EQ(s.own_times[0].first, "/run1/sensor_time/angle");
  // without time, the controls need their own times
  DeleteLink(path_, "/run1/ctrl_time");
  ExpectMentions(ReadError(), {path_, "/run1/ctrl_time", "is missing", "their own times"});
}

TEST_F(OwnTimesTest, ControlsOfTimeKeepTheirTimesWhenSensorsAddSamples) {
  // ctrl at `time` (11 rows): the union adds times, so ctrl keeps `time` as its own times
  DeleteLink(path_, "/run1/ctrl_time");
  DeleteLink(path_, "/run1/ctrl");
  const RowMatrix ctrl = Matrix(11, 1, 8);
  AddValues(path_, "/run1/ctrl", ctrl);
  ReplaceStringAttr(path_, "/run1/ctrl", "names", {"torque"});
  const Sequence s = ReadLog(path_).sequences[0];
  ASSERT_EQ(s.ctrl_time.size(), 11);
  EXPECT_TRUE(BitEqual(s.ctrl_time.data(), Time(11, 0.01).data(), 11));
  ExpectBitEqual(s.ctrl, ctrl, "ctrl");
  // states at `time` cannot take the added times
  AddValues(path_, "/run1/qpos", Matrix(11, 1, 3));
  ExpectMentions(ReadError(), {path_, "/run1/qpos", "sample time(s) not in /run1/time",
                               "need a value at every sample time"});
}

TEST_F(OwnTimesTest, BadLayoutsNameFileDatasetAndExpectation) {
  // values without times
  AddValues(path_, "/run1/sensor_values/angle2", Matrix(3, 1, 1));
  ExpectMentions(ReadError(),
                 {path_, "/run1/sensor_values/angle2", "has no times", "/run1/sensor_time/angle2"});
  DeleteLink(path_, "/run1/sensor_values/angle2");
  // times without values
  AddTimes(path_, "/run1/sensor_time/angle2", Time(3, 0.01));
  ExpectMentions(ReadError(), {path_, "/run1/sensor_values/angle2", "is missing", "Ts x dim"});
  DeleteLink(path_, "/run1/sensor_time/angle2");
  // rows differing from the sensor's times
  DeleteLink(path_, "/run1/sensor_values/rate");
  AddValues(path_, "/run1/sensor_values/rate", Matrix(25, 1, 5));
  ExpectMentions(ReadError(), {path_, "/run1/sensor_values/rate", "has 25 rows",
                               "expected 26 = the samples in /run1/sensor_time/rate"});
  DeleteLink(path_, "/run1/sensor_values/rate");
  AddValues(path_, "/run1/sensor_values/rate", rate_);
  // a sensor time going back
  Eigen::VectorXd t = rate_time_;
  t[4] = t[2];
  DeleteLink(path_, "/run1/sensor_time/rate");
  AddTimes(path_, "/run1/sensor_time/rate", t);
  ExpectMentions(ReadError(), {path_, "/run1/sensor_time/rate", "row 4", "strictly increasing"});
  // one of the pair missing
  DeleteLink(path_, "/run1/sensor_time");
  ExpectMentions(ReadError(), {path_, "/run1/sensor_time", "is missing", "come together"});
}

TEST_F(OwnTimesTest, EveryTimeDatasetPassesTheTimeBaseCheck) {
  const ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  Log log = ReadLog(path_);
  // 100 Hz and 250 Hz merged: the union's period varies, each dataset's does not: no warning
  std::vector<std::string> warnings;
  ValidateLogAgainstModel(log, *model, "data.h5", &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings[0];
  // a gap in the rate sensor's own times is named by its dataset
  Eigen::VectorXd t = rate_time_;
  t.tail(5).array() += 0.05;
  DeleteLink(path_, "/run1/sensor_time/rate");
  AddTimes(path_, "/run1/sensor_time/rate", t);
  log = ReadLog(path_);
  ValidateLogAgainstModel(log, *model, "data.h5", &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  ExpectMentions(warnings[0], {"data.h5", "/run1/sensor_time/rate", "gap(s)", "rows 20 and 21"});
  // controls on another clock, then in the wrong unit: named by ctrl_time
  log.sequences[0].ctrl_time.array() += 10.0;
  ExpectMentions(LogErrorOf([&] { ValidateLogAgainstModel(log, *model, "data.h5"); }),
                 {"data.h5", "/run1", "do not overlap"});
  log.sequences[0].ctrl_time = Time(6, 0.00001);
  ExpectMentions(LogErrorOf([&] { ValidateLogAgainstModel(log, *model, "data.h5"); }),
                 {"data.h5", "/run1/ctrl_time", "below 1/100 of the model timestep"});
}

}  // namespace
}  // namespace mjsysid::io
