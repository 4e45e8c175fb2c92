// Who may replace an existing HDF5 log output (`sysid simulate`, `sysid import`, Python's
// mjsysid.simulate): one rule, so that no path loses a log it did not write (issue 35).
#pragma once

#include <string>
#include <vector>

namespace mjsysid::run {

// who writes a log output, for the rule and its messages
struct LogWriter {
  std::string command;           // "simulate" or "import"
  std::string experiment;        // simulate: the experiment file it simulates
  std::string label;             // the output in messages; "" = "OPTION OUT"
  std::string option = "--out";  // the option that named the output
  // how to replace anyway, in messages
  std::string force_hint = "--force replaces it, or --out LOG.h5 writes elsewhere";
};

// An HDF5 log output `out`: not one of `inputs` and not a folder, whatever `force`. An existing
// file is replaced only with `force`, or when it is an mjsysid log (a file ReadLog accepts) that
// `writer` may replace: for import any mjsysid log (its --out is explicit); for simulate only a
// log that sysid simulate wrote for the same experiment file (its `generator` attribute
// "mjsysid VERSION simulate", any version, and its `experiment` attribute naming the same file).
// Throws OutputError (sysid/run/output_folder.h) naming the file and who wrote it.
void CheckLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force,
                    const LogWriter& writer);

// CheckLogOutput, then the output's folder created (OutputError when it cannot be): called just
// before the log is written
void PrepareLogOutput(const std::string& out, const std::vector<std::string>& inputs, bool force,
                      const LogWriter& writer);

}  // namespace mjsysid::run
