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
//   non-numeric time or state cell, Inf, a value beyond +-kLargestLoggedMagnitude (1e150, log.h),
//   NaN outside sensor and actuator columns, non-increasing
//   time, no data rows, an invalid sequence name; a file that is not comma-separated UTF-8/ASCII
//   text (UTF-16/32, NUL bytes, CR-only line ends,
//   ';' separators), with a hint. Values in messages are cut after 60 bytes, control bytes shown
//   as \xNN.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "sysid/io/log.h"

namespace mjsysid::io {

// Reads the CSV file at `path` as one sequence named `sequence_name` for model `m`.
Sequence ImportCsv(const std::string& path, const mjModel& m, const std::string& sequence_name);

// Reads several CSV files (each as above, with its own `time` column: its own rate) as one
// sequence: e.g. the controls at 50 Hz in one file and sensors at their own rates in others.
// - Exactly one file holds the actuator columns (all of them; the others none): its times become
//   Sequence::ctrl_time and its controls Sequence::ctrl (Tc x nu). It may hold sensors too.
// - Each sensor comes from one file. The sequence's sample times are the union of the times of
//   the files with sensor columns (sorted, equal times merged); each sensor is NaN (not measured,
//   masked out of the fit) at the times its file has no row, as are its empty cells.
// - State columns (qpos, qvel, act) are an error here (a state needs a value at every sample
//   time). One path: ImportCsv.
// - Failure: LogError naming the file: two files with actuator columns, none with them (nu > 0),
//   a sensor in two files, no sensor at all, states; and every error of ImportCsv.
Sequence ImportCsvFiles(const std::vector<std::string>& paths, const mjModel& m,
                        const std::string& sequence_name);

}  // namespace mjsysid::io
