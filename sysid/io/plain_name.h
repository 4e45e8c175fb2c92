// Names that become file or folder names (issue 35): one rule, checked here for every such name.
//
// - an experiment's `name:` (or, without one, its file name's stem): its default output folder
//   is results/NAME beside the experiment;
// - a model's name (`models: [{name: ...}]`, or the stem of `model:`): the fit writes
//   NAME_identified.xml into the result folder;
// - a sequence name given to `sysid import` (NAME=A.csv, or a CSV file's stem): a group of the
//   HDF5 log.
//
// A plain name is not empty, has no '/' (nor a NUL character), and is not "." or "..": it names
// one entry of one folder, never the folder itself, its parent or a path elsewhere. Sequence
// names in plot file names are made safe differently (tools/report: SequenceFileName keeps
// letters, digits and "._-" behind a prefix), so they need no rule.
#pragma once

#include <string>

namespace mjsysid::io {

// what a plain name is, for messages
inline constexpr const char kPlainNameRule[] = "a plain name: not empty, no '/', not '.' or '..'";

// "" when `name` is a plain name, else why not, e.g. "it contains '/'"
std::string PlainNameProblem(const std::string& name);

}  // namespace mjsysid::io
