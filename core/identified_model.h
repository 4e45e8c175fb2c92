// The identified model as MJCF: a model file with identified parameter values written in.
//
// Contract:
// - Each value is written through its kind's MJCF writer (ParameterKindInfo::write_mjcf, the kind
//   table of core/parameters.h), a `field` value through its array's row of the field table
//   (core/field_mjcf.h), into the mjSpec parsed from the model file: joints, geoms, pairs, tendons
//   and actuators get the value in their attribute; bodies get an explicit inertial clause with
//   the identified compiled mass, inertial frame and inertia. Objects are found by compiled id, so
//   unnamed ones (an explicit contact pair) are written too.
// - Compiler options that would rescale or replace written inertials (settotalmass,
//   inertiafromgeom="true", boundmass, boundinertia, balanceinertia) are turned off in the text,
//   and every body's compiled inertial is written explicitly, so the text compiles to the fitted
//   model: the written values and every other body as compiled before. With alignfree (a free
//   body's frame moved to its inertial frame) inertial frames are written in the body frames as
//   written; an identified centre of mass of such a body moves its frame, which the text cannot
//   hold: the checks below warn.
// - Asset paths: when the model has meshes, height fields, skins or textures, meshdir and
//   texturedir are made absolute (the model file's folder joined with them), so the text can be
//   saved in any folder. Included files are inlined by the parser.
// - The spec is compiled to check it, and saved as text at 17 significant digits (when the MuJoCo
//   library exports its XML precision setter; otherwise at MuJoCo's default precision, and the
//   read-back check below reports the rounding). Nothing is written to disk: the caller saves it.
// - warnings (appended to; may be nullptr) names every value that is not in the text: a `field`
//   array without MJCF home (or one dof of a joint whose other dofs differ), a value that does not
//   read back within 1e-9 (relative to max(1, |value|)) from the model compiled from the text,
//   and, when every value was written, every mjtNum array of that model that differs from the
//   fitted model (the file, with the core's writers applied) by more than 1e-9 relative. Each
//   warning contains "identified model".
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

// The mjtNum arrays of two models of the same sizes (nq, nbody, ... equal) where an entry differs
// by more than tolerance * max(1, |value in a|), as "name (worst difference), ..."; "" when
// none. NaN equals NaN.
std::string DifferingArrays(const mjModel& a, const mjModel& b, double tolerance);

}  // namespace mjsysid
