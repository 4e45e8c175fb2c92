// Results of a fit on disk: DIR/result.yaml (human-readable summary) and DIR/result.h5 (arrays).
//
// Contract:
// - Both writers are atomic (write PATH.tmp-<pid>, fsync, rename): a reader never sees a half file,
//   and an interrupted fit leaves the last complete write (the last good iterate) in place.
// - result.yaml keys (schema "mjsysid-result", version 1):
//     format, format_version, name, experiment, status, intervals_valid, termination and
//     termination_kind (TerminationText and the kind's name of FitResult::termination; the kind
//     optional when read: without it kUnknown), created, mjsysid_version, mujoco_version,
//     jacobian_mode, iterations, initial_cost, final_cost, residual_variance, num_residuals,
//     wall_time_s, segment_steps_used and segment_reason (multiple shooting as used and why,
//     SegmentReasonText; optional when read), interval_check and interval_check_kind (only when
//     the interval check ran: IntervalCheckText and the kind's name; the kind optional when read),
//     covariance_jacobian, event_windows (when set), solver (map of setting -> value
//     as text), parameters (list of {name, value, initial, std, ci95: [lo, hi], flags: [...],
//     truth?}), unidentifiable (list of text), warnings (list of text), identified_models (map
//     model -> file), run_id (when the result has one), fit_metrics (list of {sequence, role: fit
//     | validation, channels: [{channel, fit_initial, fit_final, nrmse_initial, nrmse_final,
//     fit_segments?, nrmse_segments?}]}, sysid/assess/metrics.h: fit_final of the estimate in one
//     piece, the segments' beside it for a fit in segments; written for readers of the file,
//     recomputed from result.h5 by ReadResult), starts (multi-start only, sysid/run/multi_start.h:
//     {best, runs: [{start: [...], estimate:
//     [...], initial_cost, final_cost, status, iterations, error?}], spread: [{name, min, max,
//     relative}]}; values in the order of `parameters`; read back), derived (only when the fit
//     derived quantities, sysid/assess/derived_inertials.h: [{name, unit, value, std, ci95: [lo,
//     hi], derived_from, truth?}]; read back), reduced (the reduced model, core/reduced_model.h:
//     {used, collision_pairs, collision_pairs_off, geoms_off, disabled: [island, contact],
//     guard_trips}; optional when read), input_hashes (the files the fit read, by content:
//     [{role: experiment | model | log, path, sha256}], sysid/run/input_hashes.h; absent in
//     results of older versions)
//   std and ci95 bounds that are infinite are written as .inf / -.inf; flags are any of
//   at_lower_bound, at_upper_bound, unidentifiable.
// - result.h5 layout: root attributes format = "mjsysid-result", format_version = 1, status,
//   intervals_valid (int 0/1, as result.yaml's; optional on reading, must agree with result.yaml);
//   /parameters/{value, initial, std, ci95_low, ci95_high} (np) with string attribute `names`;
//   /derived/{value, std, ci95_low, ci95_high} with attribute `names` (only when result.yaml has
//   derived; must name the same quantities); /covariance (np x np); /jacobian (the triangle R,
//   min(nres, np) x np, R^T R = J^T J);
//   /trace/{iteration, cost, step_norm, gradient_norm, seconds, successful} (nit) and
//   /trace/parameters (nit x np);
//   /sequences/<name>/{time (T), measured, simulated_initial, simulated_final (T x ns),
//   simulated_one_piece (T x ns, a fit in segments only: then simulated_final is segment by
//   segment)} with attributes model, sensor_names (strings), sensor_dims (ints); held-out sequences
//   (experiment `validation:`) in the same layout under /validation/<name> (absent when there are
//   none).
// - The run id (FitResultFile::run_id, e.g. "20261122T180501Z-12345-9f3a") names the fit that
//   wrote a file: result.yaml key run_id, result.h5 root attribute run_id, and in each identified
//   model the comment RunIdComment(run_id). ReadResult refuses a folder whose files carry
//   different run ids (files of two runs mixed), or whose listed identified models are missing.
// - Read* throw ResultError naming the file and the key/dataset on missing or malformed content.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/types.h"

namespace mjsysid::io {

class ResultError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A fit's result as stored: the fit itself (sysid/types.h) and what the run adds about it.
// Of FitResult the files keep: parameters (truth included), initial_cost, final_cost,
// iterations, termination, interval_check and segment_reason (as their text and kind: read back,
// a record keeps the text as written, not the numbers), num_residuals, seconds (wall_time_s),
// segment_steps_used, event_windows, derived, of the diagnostics jacobian_mode, reduction and
// the covariance's Jacobian (covariance_jacobian_iteration, last_step_std_errors),
// uncertainty.{residual_variance, unidentifiable, covariance}, jacobian, trace, sequences
// (x0_final excepted; channel_fits recomputed from the signals), validation, starts, best_start,
// start_spread (result.yaml), warnings, intervals_valid (both files); outcome, converged and
// interrupted are read back from status.
// a file a fit read and the SHA-256 of its bytes (sysid/run/input_hashes.h)
struct InputHash {
  std::string role;    // experiment, model (an MJCF file or a file it includes) or log
  std::string path;    // as the experiment resolved it (absolute)
  std::string sha256;  // 64 lowercase hex digits
};

struct FitResultFile : FitResult {
  std::string name, experiment, created;
  std::string status;  // FitStatusName(outcome), or running (a checkpoint)
  std::string run_id;  // the fit that wrote the files; "" in results of older versions
  std::string mjsysid_version, mujoco_version;
  std::map<std::string, std::string> solver;             // setting -> value as text
  std::map<std::string, std::string> identified_models;  // model name -> file name in DIR
  // the experiment, model and log files the fit read, by content; empty in results of older
  // versions
  std::vector<InputHash> input_hashes;
};

void WriteResultYaml(const std::string& path, const FitResultFile& result);
void WriteResultH5(const std::string& path, const FitResultFile& result);

// the XML comment that marks an identified model as written by the run `run_id`
std::string RunIdComment(const std::string& run_id);

// reads DIR/result.yaml and DIR/result.h5 into one FitResultFile; checks that they and the
// identified models they list come from one run
FitResultFile ReadResult(const std::string& dir);

// reads a result.yaml-like file and a result.h5-like file (e.g. a fit's checkpoint.yaml and
// checkpoint.h5) into one FitResultFile; checks that both carry the same run id
FitResultFile ReadResultFiles(const std::string& yaml_path, const std::string& h5_path);

}  // namespace mjsysid::io
