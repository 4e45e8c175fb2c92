// HDF5 logs written: WriteLog, one group per sequence.
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
#include "sysid/io/log.h"
#include "sysid/io/log_internal.h"

namespace mjsysid::io {
namespace {

using namespace log_internal;  // NOLINT(build/namespaces): the log format's own internals

// ---------------------------------------------------------------------------------------------
// hdf5 plumbing

// the shared hdf5 helpers (sysid/io/hdf5_util.h); they throw h5::Error, which the API functions
// below turn into LogError
using h5::FailH5;
using h5::Own;
using H5Id = h5::Id;
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

}  // namespace

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

}  // namespace mjsysid::io
