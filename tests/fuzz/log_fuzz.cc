// libFuzzer harness: bytes as an HDF5 log file (sysid/io/log.h).
//
// The bytes are written to a per-process temporary .h5 file, read with ReadLog's reader (in this
// process, without ReadLog's child process: HDF5's own crashes show up here) and, when that
// succeeds, checked against models/pendulum.xml with ValidateLogAgainstModel. The only failure
// these functions document is LogError: any other exception escaping, a crash, a sanitizer
// report or a leak is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "core/mujoco_env.h"
#include "sysid/io/log.h"

namespace {

namespace fs = std::filesystem;
namespace io = mjsysid::io;

const std::string& TempPath() {
  static const std::string path =
      (fs::temp_directory_path() / ("mjsysid_log_fuzz_" + std::to_string(getpid()) + ".h5"))
          .string();
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const mjModel* model = [] {
    mjsysid::InstallMujocoHandlers();
    std::atexit([] { std::remove(TempPath().c_str()); });
    // kept for the whole run: a static that libFuzzer's leak check does not count
    return mjsysid::LoadModel(MJSYSID_MODELS_DIR "/pendulum.xml").release();
  }();
  const std::string& path = TempPath();
  {
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    if (size > 0) std::fwrite(data, 1, size, f);
    std::fclose(f);
  }
  try {
    // in process: libFuzzer's coverage feedback needs the parsing here, not in ReadLog's child
    const io::Log log = io::internal::ReadLogInProcess(path);
    io::ValidateLogAgainstModel(log, *model, path);
  } catch (const io::LogError&) {
    // the documented failure
  }
  return 0;
}
