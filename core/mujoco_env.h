// MuJoCo process environment: error and warning handlers, owning model/data handles, loading.
//
// Contract:
// - InstallMujocoHandlers() is called once (idempotent, thread-safe). After it, a MuJoCo error
//   (mju_error, e.g. arena overflow or an invalid argument) throws MujocoError with MuJoCo's
//   message instead of exiting the process, and MuJoCo's text warnings are kept per thread
//   (TakeWarningText) instead of printed or written to MUJOCO_LOG.TXT. Every entry point of core/
//   calls it.
// - After a MujocoError thrown from inside mj_step/mj_forward, the mjData involved is in an unknown
//   state (its arena marks may be unbalanced): call mj_resetData on it or discard it.
// - Per-step simulation warnings (bad qpos/qacc, contact buffer full, ...) are counters in
//   mjData::warning; SimulationWarnings() reads and names them.
#pragma once

#include <mujoco/mujoco.h>

#include <memory>
#include <stdexcept>
#include <string>

namespace mjsysid {

// A MuJoCo library error (mju_error), as an exception.
class MujocoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A model that failed to load or compile: the message names the file.
class ModelLoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Installs the error and warning handlers; safe to call many times from many threads.
void InstallMujocoHandlers();

// Returns and clears MuJoCo's text warnings raised on this thread since the last call.
std::string TakeWarningText();

struct ModelDeleter {
  void operator()(mjModel* m) const { mj_deleteModel(m); }
};
struct DataDeleter {
  void operator()(mjData* d) const { mj_deleteData(d); }
};
using ModelPtr = std::unique_ptr<mjModel, ModelDeleter>;
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

// Loads and compiles an MJCF (or MJB) file. Throws ModelLoadError naming the file on failure.
ModelPtr LoadModel(const std::string& path);

// Compiles an MJCF document held in memory. Throws ModelLoadError on failure.
ModelPtr LoadModelFromString(const std::string& xml);

// Deep copy of a model (parameters included).
ModelPtr CopyModel(const mjModel& m);

// Fresh data for a model, at the model's reference configuration.
DataPtr MakeData(const mjModel& m);

// Names of the simulation warnings raised in d (counters > 0), comma separated; "" when none.
std::string SimulationWarnings(const mjData& d);

// Resets all warning counters of d.
void ClearSimulationWarnings(mjData* d);

// "X.Y.Z" of the MuJoCo library loaded at run time.
std::string MujocoVersion();

}  // namespace mjsysid
