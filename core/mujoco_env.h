// MuJoCo process environment: error and warning handlers, owning model/data handles, loading.
//
// Contract:
// - InstallMujocoHandlers() is called once (idempotent, thread-safe). After it, a MuJoCo error
//   (mju_error, e.g. arena overflow or an invalid argument) becomes a MujocoError carrying
//   MuJoCo's message instead of exiting the process (but MuJoCo's "Could not allocate memory",
//   which becomes std::bad_alloc: the machine is out of memory), and MuJoCo's text warnings are
//   kept per thread (TakeWarningText) instead of printed or written to MUJOCO_LOG.TXT. Every entry
//   point of core/ calls it.
// - Errors never unwind through MuJoCo's C frames when the call runs inside CallMujoco (every call
//   of core/ into the engine does): CallMujoco arms a setjmp target on its own C++ frame, the error
//   handler copies MuJoCo's message into a thread-local slot and longjmps back to it, and
//   CallMujoco throws MujocoError from there. Between that frame and MuJoCo there are no objects
//   with destructors, so nothing is skipped (the rule of std::longjmp).
// - Last resort: an error raised on a thread with no CallMujoco armed (MuJoCo called directly by
//   the host, by sysid/ or tools/, or the XML loaders below) is thrown as MujocoError from inside
//   the handler, unwinding MuJoCo's frames. GCC and Clang on Linux do that (libmujoco carries
//   unwind tables; tested), but C++ does not promise it for C frames. The handler never returns:
//   MuJoCo continues after mju_error when a handler returns.
// - The loaders (LoadModel, LoadModelFromString) are deliberately not armed: MuJoCo's XML parser
//   and compiler are C++ with objects that have destructors (a longjmp would skip them, e.g. the
//   parser's locale override), and they catch their own errors (the compiler installs its own
//   thread-local handler), so an error reaching our handler from there is thrown through C++.
// - After a MujocoError from inside mj_step/mj_forward, the mjData involved is in an unknown state
//   (its stack and arena marks are unbalanced): call mj_resetData on it or discard it. Simulator
//   does so for its workers.
// - Per-step simulation warnings (bad qpos/qacc, contact buffer full, ...) are counters in
//   mjData::warning; SimulationWarnings() reads and names them.
//
// Process-wide handlers, and a host program with its own: InstallMujocoHandlers sets MuJoCo's
// global hooks mju_user_error and mju_user_warning, replacing whatever the host set before (they
// are not chained). These are MuJoCo's legacy hooks, called by MuJoCo's default log handler:
// - a host that sets them again after us replaces ours: MuJoCo errors inside core/ then go to the
//   host's handler (exit, or a return, after which MuJoCo continues in an invalid state), and
//   warnings are no longer captured;
// - a host that installs mju_setLogHandler (or a thread-local handler, as MuJoCo's Python
//   bindings do around their calls) takes precedence over both hooks in the same way;
// - while ours are installed, MuJoCo errors the host triggers outside core/ throw MujocoError (see
//   last resort) instead of exiting, and MuJoCo's warnings are not printed to stderr nor written to
//   MUJOCO_LOG.TXT but collected per thread (read them with TakeWarningText).
// docs/numerics.md ("MuJoCo errors") has the reasoning.
#pragma once

#include <mujoco/mujoco.h>

#include <csetjmp>
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

namespace internal {

// A setjmp target armed by CallMujoco on this thread; targets nest as a list through outer.
struct JumpTarget {
  std::jmp_buf env;
  JumpTarget* outer;
};

// The innermost armed target of this thread (nullptr: none); the error handler pops it.
JumpTarget*& ArmedTarget();

// Throws MujocoError with the message the error handler saved on this thread.
[[noreturn]] void ThrowSavedError();

}  // namespace internal

// Runs f(), which must call only MuJoCo's C functions and plain arithmetic: no objects with
// non-trivial destructors, no C++ exceptions. A MuJoCo error inside f() jumps back to this frame
// (without unwinding MuJoCo's) and is thrown from here as MujocoError with MuJoCo's message; the
// objects f() was writing (mjData, mjModel) are then in an unknown state. Nests; per thread.
// Cost: one setjmp (glibc's does not save the signal mask: no system call).
template <class F>
void CallMujoco(F&& f) {
  internal::JumpTarget here;
  here.outer = internal::ArmedTarget();
  if (setjmp(here.env) != 0) internal::ThrowSavedError();  // the handler has popped `here`
  internal::ArmedTarget() = &here;
  try {
    f();
  } catch (...) {
    internal::ArmedTarget() = here.outer;
    throw;
  }
  internal::ArmedTarget() = here.outer;
}

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

// Whether d has raised a simulation warning (a counter > 0). Inline and without a branch per
// counter: every simulated step asks.
inline bool AnySimulationWarning(const mjData& d) {
  int warned = 0;
  for (int i = 0; i < mjNWARNING; ++i) warned |= d.warning[i].number > 0;
  return warned != 0;
}

// Names of the simulation warnings raised in d (counters > 0), comma separated; "" when none.
std::string SimulationWarnings(const mjData& d);

// Resets all warning counters of d.
void ClearSimulationWarnings(mjData* d);

// "X.Y.Z" of the MuJoCo library loaded at run time.
std::string MujocoVersion();

}  // namespace mjsysid
