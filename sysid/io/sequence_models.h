// Which model each logged sequence is fitted with: the one rule that `sysid fit`, `sysid check`
// and every other reader of an experiment's data use.
//
// A sequence belongs to exactly one model, by an explicit record and never by its name:
// 1. the experiment's `sequences:` entry "model/seq" names the model of group "seq";
// 2. else the log's record: the attribute "sequences.<model>" (comma-separated group names, written
//    by `sysid simulate` for experiments with several models) that lists the group;
// 3. else, when the experiment has a single model, that model.
// With `sequences:` given, only the groups it names are selected (an entry without a model takes
// the model from 2 or 3). Without it, every group of the log is selected, except groups the log
// records for a model the experiment does not have (they are skipped: another experiment's data).
//
// Failure (bad input, exit 2): a selected group with no model by these rules (several models, no
// record), an entry whose model contradicts the log's record, or a group recorded for two models
// throws LogError naming the file and the group, with the fix.
//
// A sequence is identified by its log file and its group (SequenceNamesInFit): its name in the fit
// (results, report, messages) is its group name, unless a group of that name is in more than one
// of the experiment's logs (every `sysid simulate` log names its groups seq0, seq1, ...): then it
// is named "<log file stem>:<group>" (QualifiedSequenceName, e.g. runA:seq0), a name valid as an
// HDF5 group, as a YAML value and in the report. A `sequences:` or `validation:` entry names a
// group by its group name (in every log that has it) or by that qualified name (in its log only:
// EntryNamesGroup). Which model a sequence belongs to is decided above, on its group in its own
// log, before it is renamed.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"

namespace mjsysid::io {

struct SequenceOwner {
  int sequence = 0;  // index into Log::sequences
  int model = 0;     // index into ExperimentConfig::models
};

// The selected sequences of `log` (read from `path`, for messages) in log order, each with its
// model. entry_used (optional, size config.sequences.size()) is set true for every `sequences:`
// entry that named a group of this log, so that a caller reading several files can report an
// entry that named none (UnusedSequenceEntries).
std::vector<SequenceOwner> AssignSequences(const ExperimentConfig& config, const Log& log,
                                           const std::string& path,
                                           std::vector<bool>* entry_used = nullptr);

// Throws ConfigError at the first `sequences:` entry that no data file had (entry_used false),
// listing the groups that exist (all_groups).
void CheckSequenceEntriesUsed(const ExperimentConfig& config, const std::vector<bool>& entry_used,
                              const std::vector<std::string>& all_groups);

// a logged sequence: the path of its log and its group name there
struct LoggedSequence {
  std::string path;
  std::string group;
};

// "<log file stem>:<group>"
std::string QualifiedSequenceName(const std::string& log_path, const std::string& group);

// true when the `sequences:` / `validation:` entry `ref` names group `group` of the log at
// `log_path`: by the group name, or by its qualified name
bool EntryNamesGroup(const SequenceRef& ref, const std::string& log_path, const std::string& group);

// The names of `selected` (the sequences a fit uses, fitted and held out) in the fit, in the same
// order, by the rule above; `in_logs`: every group of the experiment's logs (empty: `selected`).
// `renamed` (optional) gets one line per group name of a selected sequence that is in several
// logs, saying how the selected ones are named. Throws LogError naming both files when two
// selected names still collide: two logs with the same file stem (in different folders), or a
// group already named like another log's qualified one.
std::vector<std::string> SequenceNamesInFit(const std::vector<LoggedSequence>& selected,
                                            const std::vector<LoggedSequence>& in_logs = {},
                                            std::vector<std::string>* renamed = nullptr);

}  // namespace mjsysid::io
