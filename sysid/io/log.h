// Logged rollouts: the in-memory form, the HDF5 file format, and checks against a model.
//
// Contract:
// - A Log holds one or more Sequences. Sample k of a sequence is (time(k), ctrl.row(k),
//   sensordata.row(k)) and, when recorded, (qpos.row(k), qvel.row(k), act.row(k)).
// - Time convention (docs/numerics.md, "Time convention"): with sensor_time == "pre" (what mjsysid
//   writes), sensordata.row(k) = y_k = h(x_k, u_k) is what mj_forward computes at state x_k with
//   control u_k = ctrl.row(k), *before* the step that produces x_{k+1}; qpos/qvel/act row k are
//   x_k. With "post", each row was written after its step and the sensors lag by one row:
//   sensordata.row(k + 1) = y_k, what d->sensordata holds after mj_step (MuJoCo computes the
//   sensors at x_k, before integrating).
// - Units: time in seconds; every other quantity in MuJoCo's units for that quantity (the units
//   of the model: SI unless the model says otherwise).
// - Storage order: all matrices are row-major, one row per sample (T rows). In the HDF5 file the
//   same layout is stored as 2-D datasets of shape (T, columns), C order, float64.
// - Indices in error messages (row, column) are 0-based, except CSV line and column numbers,
//   which are 1-based like an editor's.
// - Failure: every function here throws LogError, whose message names the file, the HDF5 object
//   (/sequence/dataset) and, where it applies, the row and column. Nothing is printed: HDF5's own
//   error printing is switched off and its innermost message is appended to ours.
// - Thread safety: the functions may be called from several threads; the HDF5 calls of this
//   library are serialized by one process-wide mutex (HDF5 is not thread-safe by default).
//
// HDF5 layout (format_version 1):
//   /                      attributes: format = "mjsysid-log" (string), format_version = 1 (int),
//                          sensor_time = "pre" | "post" (string), and one string attribute per
//                          Log::attributes entry
//   /<sequence name>/      one group per sequence, in Log::sequences order (creation order)
//     time                 float64 (T)           attribute units = "s"; any sample times (rate,
//                                                jitter, gaps): each is fitted at its own time
//     ctrl                 float64 (T, nu)       attribute names: string (nu), actuator names;
//                                                NaN: held from the last valid value
//     sensordata           float64 (T, ns)       NaN: not measured (masked out of the fit);
//                                                attribute names: string (nsensor), sensor names;
//                                                attribute dims: int32 (nsensor), columns each
//     qpos, qvel, act      float64 (T, nq|nv|na) optional; NaN: not measured
//     ctrl_time            float64 (Tc)          optional: the controls' own times (their own rate,
//                                                seconds); ctrl is then (Tc, nu). Without it ctrl
//                                                has one row per `time`
//     sensor_time/<sensor> float64 (Ts)          optional group: one dataset per sensor logged at
//                                                its own times, named like the model's sensor
//     sensor_values/<sensor> float64 (Ts, dim)   that sensor's values at those times (dim = its
//                                                columns; no attributes needed); NaN: not measured
//   With sensor_time/ and sensor_values/ (both or neither, the same sensor names), `time` and
//   `sensordata` are optional (both or neither) and `ctrl_time` is required when there is no
//   `time`. Reading merges every sensor onto the sequence's sample times: Sequence::time is the
//   union of `time` and all sensor times (sorted, exact duplicates merged), each sensor is NaN
//   (not measured) at the times it was not sampled, and the per-sensor sensors follow the
//   `sensordata` ones in Sequence::sensor_names (in name order). When that union adds times to
//   `time`, ctrl without ctrl_time keeps its own times (Sequence::ctrl_time = `time`), and
//   qpos/qvel/act are an error (states need a value at every sample time). Every time dataset is
//   checked (finite, strictly increasing; CheckTimeBase against the model).
// Strings are variable-length UTF-8. A zero-width matrix (nu = 0, ns = 0) is stored as a
// dataset with a zero dimension. On reading, fixed-length strings, integer or float32 data and
// scalar numeric attributes (stored in Log::attributes as decimal text) are accepted too.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/state.h"

namespace mjsysid::io {

// One logged rollout. T = time.size() >= 1.
struct Sequence {
  std::string name;                         // HDF5 group name: non-empty, no '/', not "."
  Eigen::VectorXd time;                     // T, seconds, strictly increasing, finite
  RowMatrix ctrl;                           // T x nu (row k = control applied at sample k)
  RowMatrix sensordata;                     // T x nsensordata (row k = y_k, see Log::sensor_time)
  RowMatrix qpos, qvel, act;                // optional: 0 x 0 when absent, else T x nq / nv / na
  std::vector<std::string> sensor_names;    // one per sensor (not per column)
  std::vector<int> sensor_dims;             // columns of each sensor (>= 1); sum = cols
  std::vector<std::string> actuator_names;  // one per ctrl column
  // optional: the controls' own times (Tc, seconds, strictly increasing; dataset ctrl_time); ctrl
  // is then Tc x nu. Empty: ctrl has one row per `time`.
  Eigen::VectorXd ctrl_time;
  // set by ReadLog when sensors come at their own times: the time datasets as read ("/seq/time",
  // "/seq/sensor_time/<sensor>") for the time-base check; empty otherwise. Not written.
  std::vector<std::pair<std::string, Eigen::VectorXd>> own_times;
};

// A set of sequences recorded with one convention, plus free-form metadata.
struct Log {
  std::vector<Sequence> sequences;  // at least one; names unique
  // "pre": y_k computed at x_k before the step (mjsysid's convention); "post": after it
  std::string sensor_time = "pre";
  // free-form metadata (model, seed, versions...); keys non-empty and not one of the reserved
  // root attribute names "format", "format_version", "sensor_time"
  std::map<std::string, std::string> attributes;
};

// Any failure to read, write or check a log. The message names file, object, row and column.
class LogError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes `log` to `path` atomically: the file is written to path + ".tmp-<pid>", flushed to
// disk and renamed over `path`. On any failure (the log fails the checks ReadLog applies, HDF5
// or the file system fails) LogError is thrown, an existing file at `path` is left as it was and
// the temporary file is removed.
void WriteLog(const std::string& path, const Log& log);

// Reads and checks a log written by WriteLog (or by any tool following the layout above).
// HDF5 runs in a forked child process that sends the checked Log back: HDF5 1.10 can crash, hang
// or allocate gigabytes on a corrupt file (docs/bad-input.md), which then becomes a LogError
// ("the HDF5 library crashed reading the file", "did not finish ... in N s", "killed (out of
// memory?)"). The child's address space may grow by max(1 GiB, 64 x the file size).
// Checks: the format attributes; every required dataset present with rank 1 (time) or 2 (others)
// and T rows; names/dims counts matching the columns; no Inf anywhere and no NaN except in ctrl,
// sensordata and qpos/qvel/act, where NaN means "not measured" (a sensor or state cell is masked
// out of the fit and counted, a control is held from the last valid value, a state row with NaN
// does not start a segment or window: docs/real-logs.md); time strictly
// increasing; no unknown datasets in a sequence group and no objects other than groups at the
// root. Sequences come back in the order they were written.
Log ReadLog(const std::string& path);

// the largest magnitude a logged value may have (log checks, CSV import): its square (a
// residual's, a kinetic energy's) must not overflow a double (1e308), so that a simulation or a
// cost with it stays finite
inline constexpr double kLargestLoggedMagnitude = 1e150;

// Checks a log against the model it is meant for (`path_for_messages` names the log in
// messages). Per sequence: every sensor name is a sensor of `m` with the same dimension
// (m.sensor_dim), names unique; ctrl has exactly the model's actuators, in model order (missing,
// extra and misplaced names are named); qpos/qvel/act, when present, are nq/nv/na wide; every time
// dataset (time, ctrl_time, sensor_time/<sensor>) passes CheckTimeBase (sysid/io/time_base.h: at
// least two samples, in seconds; any rate, jitter and gaps are accepted, since each sample is
// fitted at its own time), whose warnings (varying period, long gaps) go to *warnings when given.
// Unknown names come with the model's names (up to 20) as a hint. Throws LogError on the first
// problem found. `sysid import`, `check` and `fit` all check logs through this one function.
void ValidateLogAgainstModel(const Log& log, const mjModel& m, const std::string& path_for_messages,
                             std::vector<std::string>* warnings = nullptr);

// The samples of `seq` with start <= time <= end (seconds, the log's clock): every dataset's rows
// in that range; controls with their own times (ctrl_time) are kept whole (the hold and a delay
// reach back before the window). Throws LogError naming `file`, the sequence and the window when
// fewer than 2 samples fall in it.
Sequence WindowOf(const Sequence& seq, double start, double end, const std::string& file);

namespace internal {

// ReadLog without the child process: HDF5 runs in this process (a corrupt file can crash it).
// For the fuzz harness, whose coverage feedback needs the parsing in its own process.
Log ReadLogInProcess(const std::string& path);

// Shared by log.cc and csv.cc, not part of the API: "'x' (did you mean 'y'?); valid: a, b, ..."
// style hint listing up to 20 of `valid`, with the closest one first when one is close.
std::string NameHint(const std::string& wrong, const std::vector<std::string>& valid,
                     const std::string& what);

}  // namespace internal

}  // namespace mjsysid::io
