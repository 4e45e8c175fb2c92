// CSV import of one logged rollout, with columns named after the model.
//
// Contract:
// - The file is comma separated, one header row then one row per sample. Fields may be quoted
//   ("..." with "" for a quote; no line breaks inside quotes) and are trimmed of spaces and tabs.
//   Blank lines are skipped; CRLF line endings and a UTF-8 byte order mark are accepted.
// - Header names, in any order:
//     time                        seconds, strictly increasing (required)
//     <actuator name>             one column per actuator of the model (all required), the
//                                 control applied at that sample
//     <sensor name>               a 1-D sensor
//     <sensor name>[i]            component i (0-based) of a multi-dimensional sensor
//     qpos[i], qvel[i], act[i]    optional states; when one component is given, all are required
//   Sensors may be left out: the Sequence keeps the sensors present, in model order, with
//   sensor_names/sensor_dims describing them (a multi-dimensional sensor needs all components).
//   A sensor or actuator cell that is empty or NaN is a value not measured (NaN in the Sequence:
//   masked out of the fit, or for a control held from the last valid value), so sensors logged
//   at their own times share one file, each row holding the sensors sampled at its time.
// - The result follows log.h's Sequence contract: ctrl is T x nu in model order with the model's
//   actuator names; qpos/qvel/act are 0 x 0 unless given. Row k's sensors are taken as y_k of
//   the convention the caller records in Log::sensor_time.
// - Failure: LogError naming the file and, as they apply, the line (1-based, the header is line
//   1 unless blank lines precede it), the column (1-based) and its header: an unknown column
//   (with the valid names as a hint), a duplicate or ambiguous column, a missing required column
//   or sensor component, a row with a different number of fields than the header, an empty or
//   non-numeric time or state cell, Inf, NaN outside sensor and actuator columns, non-increasing
//   time, no data rows, an invalid sequence name; a file that is not comma-separated UTF-8/ASCII
//   text (UTF-16/32, NUL bytes, CR-only line ends,
//   ';' separators), with a hint. Values in messages are cut after 60 bytes, control bytes shown
//   as \xNN.
#pragma once

#include <mujoco/mujoco.h>

#include <string>

#include "sysid/io/log.h"

namespace mjsysid::io {

// Reads the CSV file at `path` as one sequence named `sequence_name` for model `m`.
Sequence ImportCsv(const std::string& path, const mjModel& m, const std::string& sequence_name);

}  // namespace mjsysid::io
