// The files `sysid design` writes (docs/design.md), each atomically (sysid/io/atomic_file.h):
// - DIR/controls.csv: a header `time,<actuator>,...` (every actuator, model order) and one row per
//   simulation step, t_k = k * timestep, the design's control u_k; numbers read back exactly.
//   It is a log's controls as sysid import reads them (sysid/io/csv.h) and what
//   `simulate.excitation: {type: file, path: ...}` plays (docs/experiment-schema.md).
// - DIR/design.yaml: the design's inputs and what it predicts (layout in docs/design.md):
//   predicted standard errors per parameter for the experiment's current excitation (`current`)
//   and the design (`design`), both absolute and relative, the criteria, the amplitude limits and
//   the constraint margins, the search's counts and time.
// Failure: io::FileError naming the file.
#pragma once

#include <string>

#include "sysid/design/design.h"

namespace mjsysid::design {

// the text of controls.csv and design.yaml (experiment: the YAML file, for the record)
std::string ControlsCsv(const DesignResult& r);
std::string DesignYaml(const DesignResult& r, const std::string& experiment);

// Outputs never overwrite inputs: throws std::invalid_argument when dir/controls.csv or
// dir/design.yaml is a folder, or is (through any path or link) the experiment file, one of its
// models or data files
void CheckDesignOutputs(const std::string& dir, const io::ExperimentConfig& config);

// writes both into dir (CheckDesignOutputs first) (created when missing); returns the two paths
std::pair<std::string, std::string> WriteDesign(const DesignResult& r, const std::string& dir,
                                                const io::ExperimentConfig& config);

}  // namespace mjsysid::design
