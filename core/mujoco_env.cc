#include "core/mujoco_env.h"

#include <array>
#include <mutex>
#include <string>

namespace mjsysid {
namespace {

thread_local std::string tls_warning_text;

// mju_error lands here: throw so the caller can recover (never exit the process)
void ErrorHandler(const char* msg) { throw MujocoError(std::string("MuJoCo error: ") + msg); }

// mju_warning lands here: keep the text for the caller, do not print
void WarningHandler(const char* msg) {
  if (!tls_warning_text.empty()) tls_warning_text += '\n';
  tls_warning_text += msg;
}

constexpr std::array<const char*, mjNWARNING> kWarningNames = {
    "inertia (near-singular mass matrix)",
    "contact buffer full",
    "constraint buffer full",
    "bad qpos (NaN/Inf or huge)",
    "bad qvel (NaN/Inf or huge)",
    "bad qacc (NaN/Inf or huge: simulation diverged)",
    "bad ctrl (NaN/Inf)",
};

}  // namespace

void InstallMujocoHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    mju_user_error = ErrorHandler;
    mju_user_warning = WarningHandler;
  });
}

std::string TakeWarningText() {
  std::string out;
  out.swap(tls_warning_text);
  return out;
}

ModelPtr LoadModel(const std::string& path) {
  InstallMujocoHandlers();
  char error[1024] = "";
  mjModel* m = nullptr;
  try {
    m = mj_loadXML(path.c_str(), nullptr, error, sizeof(error));
  } catch (const MujocoError& e) {
    throw ModelLoadError(path + ": " + e.what());
  }
  if (!m) {
    throw ModelLoadError(path + ": cannot load model: " +
                         (error[0] ? std::string(error) : std::string("unknown error")));
  }
  return ModelPtr(m);
}

ModelPtr LoadModelFromString(const std::string& xml) {
  InstallMujocoHandlers();
  char error[1024] = "";
  mjSpec* spec = nullptr;
  mjModel* m = nullptr;
  try {
    spec = mj_parseXMLString(xml.c_str(), nullptr, error, sizeof(error));
    if (spec) {
      m = mj_compile(spec, nullptr);
      if (!m) snprintf(error, sizeof(error), "%s", mjs_getError(spec));
    }
  } catch (const MujocoError& e) {
    if (spec) mj_deleteSpec(spec);
    throw ModelLoadError(std::string("<xml string>: ") + e.what());
  }
  if (spec) mj_deleteSpec(spec);
  if (!m) {
    throw ModelLoadError(std::string("<xml string>: cannot compile model: ") +
                         (error[0] ? std::string(error) : std::string("unknown error")));
  }
  return ModelPtr(m);
}

ModelPtr CopyModel(const mjModel& m) {
  InstallMujocoHandlers();
  mjModel* copy = mj_copyModel(nullptr, &m);
  if (!copy) throw MujocoError("mj_copyModel failed (out of memory?)");
  return ModelPtr(copy);
}

DataPtr MakeData(const mjModel& m) {
  InstallMujocoHandlers();
  mjData* d = mj_makeData(&m);
  if (!d) throw MujocoError("mj_makeData failed (out of memory?)");
  return DataPtr(d);
}

std::string SimulationWarnings(const mjData& d) {
  std::string out;
  for (int i = 0; i < mjNWARNING; ++i) {
    if (d.warning[i].number > 0) {
      if (!out.empty()) out += ", ";
      out += kWarningNames[i];
    }
  }
  return out;
}

void ClearSimulationWarnings(mjData* d) {
  for (int i = 0; i < mjNWARNING; ++i) {
    d->warning[i].number = 0;
    d->warning[i].lastinfo = 0;
  }
}

std::string MujocoVersion() {
  const int v = mj_version();
  // mj_version() is X*1000000 + Y*1000 + Z in 4.x (and XYZ in old 3.x releases)
  if (v >= 1000000) {
    return std::to_string(v / 1000000) + "." + std::to_string((v / 1000) % 1000) + "." +
           std::to_string(v % 1000);
  }
  return std::string(mj_versionString());
}

}  // namespace mjsysid
