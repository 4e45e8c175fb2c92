// The identified model as MJCF: a model file with identified parameter values written in.
//
// Contract:
// - Each value is written through its kind's MJCF writer (ParameterKindInfo::write_mjcf, the kind
//   table of core/parameters.h) into the mjSpec parsed from the model file: joints, geoms and
//   actuators get the value in their attribute; bodies get an explicit inertial clause with the
//   identified compiled mass, inertial frame and inertia. The spec is compiled to check it, and
//   saved as text at 17 significant digits (when the MuJoCo library exports its XML precision
//   setter; otherwise at MuJoCo's default precision, and the read-back check below reports the
//   rounding).
// - Nothing is written to disk: the caller saves the text (asset paths in it are as in the model
//   file, relative to that file's folder).
// - warnings (appended to; may be nullptr) names every value that is not in the text: a kind
//   without MJCF attribute (field), or a value that does not read back within 1e-9 (relative to
//   max(1, |value|)) from the model compiled from the text. Each warning contains
//   "identified model".
// - Not thread-safe: MuJoCo's XML precision is process-wide state, set and restored around the
//   save.
#pragma once

#include <string>
#include <vector>

#include "core/parameters.h"

namespace mjsysid {

// Returns the MJCF text of model_path with values[i] written for specs[i] (same lengths).
// Throws ModelLoadError when the file cannot be parsed or the identified model does not compile,
// ParameterError for a spec that does not resolve in the model, std::invalid_argument for
// lengths that differ.
std::string IdentifiedModelXml(const std::string& model_path,
                               const std::vector<ParameterSpec>& specs,
                               const std::vector<double>& values,
                               std::vector<std::string>* warnings);

}  // namespace mjsysid
