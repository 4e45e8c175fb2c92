#include "core/mujoco_env.h"

#include <array>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <new>
#include <string>

namespace mjsysid {
namespace {

thread_local std::string tls_warning_text;

// this thread's error slot: the innermost CallMujoco target and the last error message (MuJoCo's
// legacy handler text is at most 2048 bytes)
thread_local internal::JumpTarget* tls_armed = nullptr;
thread_local char tls_error_message[2048];

// mju_error lands here. Never returns (MuJoCo would go on after mju_error): save the message, then
// jump back to the innermost CallMujoco of this thread, popping it; with none armed, throw from
// here through MuJoCo's frames (the last resort, see mujoco_env.h)
void ErrorHandler(const char* msg) {
  std::snprintf(tls_error_message, sizeof(tls_error_message), "%s", msg);
  internal::JumpTarget* target = tls_armed;
  if (target) {
    tls_armed = target->outer;
    std::longjmp(target->env, 1);
  }
  internal::ThrowSavedError();
}

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

namespace internal {

JumpTarget*& ArmedTarget() { return tls_armed; }

// MuJoCo's own allocation failure (mj_makeData and its arena: "Could not allocate memory") is
// the machine out of memory, as a failed new: std::bad_alloc, which the runners report as out of
// memory (exit 5), not as a MuJoCo error
void ThrowSavedError() {
  if (std::strstr(tls_error_message, "ould not allocate memory") != nullptr) {
    throw std::bad_alloc();
  }
  throw MujocoError(std::string("MuJoCo error: ") + tls_error_message);
}

}  // namespace internal

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

// The loaders call MuJoCo unarmed on purpose (mujoco_env.h): its parser and compiler are C++ and
// catch their own errors; a MuJoCo error that still reaches our handler is thrown through C++.
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
  mjModel* copy = nullptr;
  CallMujoco([&] { copy = mj_copyModel(nullptr, &m); });
  if (!copy) throw MujocoError("mj_copyModel failed (out of memory?)");
  return ModelPtr(copy);
}

DataPtr MakeData(const mjModel& m) {
  InstallMujocoHandlers();
  mjData* d = nullptr;
  CallMujoco([&] { d = mj_makeData(&m); });
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
