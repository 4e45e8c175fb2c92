// The files a fit read, by content (SHA-256, sysid/io/file_hash.h), recorded in its checkpoints and
// results (io::FitResultFile::input_hashes, result.yaml key input_hashes) so that `sysid fit
// --resume` and `sysid report` can refuse inputs changed since the fit.
//
// Hashed: the experiment file, each model's MJCF file and the files it includes (<include
// file="..."/>, relative to the main file's folder as MuJoCo resolves them, recursively), and each
// `data:` log. Meshes, textures and other assets the model loads are not hashed.
#pragma once

#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/result.h"

namespace mjsysid::run {

// the experiment's input files and their hashes, in the order: experiment, models (each followed
// by its includes), logs; a file that cannot be read is left out (reading it fails later)
std::vector<io::InputHash> HashInputs(const io::ExperimentConfig& config);

// each recorded input hashed again at its path (sha256 "" when it cannot be read)
std::vector<io::InputHash> HashAgain(const std::vector<io::InputHash>& recorded);

// the differences between the inputs a fit recorded and the current ones, one text each, e.g.
// "/abs/log.h5 (log) changed", "/abs/m.xml (model) is gone", "/abs/b.h5 (log) is a new input";
// files are matched by role and path, the experiment by role alone; a current sha256 "" or a
// recorded file missing from `current` and from the disk is a file that is gone; empty when
// nothing changed
std::vector<std::string> InputChanges(const std::vector<io::InputHash>& recorded,
                                      const std::vector<io::InputHash>& current);

}  // namespace mjsysid::run
