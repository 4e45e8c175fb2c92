#include "sysid/io/sequence_models.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <sstream>

#include "core/text.h"

namespace mjsysid::io {
namespace {

constexpr char kRecordPrefix[] = "sequences.";

// group name -> model name, from the log's "sequences.<model>" attributes
std::map<std::string, std::string> RecordedModels(const Log& log, const std::string& path) {
  std::map<std::string, std::string> owner;
  for (const auto& [key, value] : log.attributes) {
    if (key.rfind(kRecordPrefix, 0) != 0) continue;
    const std::string model = key.substr(sizeof(kRecordPrefix) - 1);
    std::stringstream list(value);
    std::string group;
    while (std::getline(list, group, ',')) {
      if (group.empty()) continue;
      const auto [it, added] = owner.emplace(group, model);
      if (!added && it->second != model) {
        throw LogError(path + ": sequence '" + group + "' is recorded for two models ('" +
                       it->second + "' and '" + model + "', attributes " + kRecordPrefix +
                       it->second + " and " + key + ")");
      }
    }
  }
  return owner;
}

int ModelIndex(const ExperimentConfig& config, const std::string& name) {
  for (size_t i = 0; i < config.models.size(); ++i) {
    if (config.models[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

std::vector<SequenceOwner> AssignSequences(const ExperimentConfig& config, const Log& log,
                                           const std::string& path, std::vector<bool>* entry_used) {
  const std::map<std::string, std::string> recorded = RecordedModels(log, path);
  std::vector<SequenceOwner> out;
  for (size_t q = 0; q < log.sequences.size(); ++q) {
    const std::string& group = log.sequences[q].name;
    const auto rec = recorded.find(group);
    const int rec_model = rec == recorded.end() ? -1 : ModelIndex(config, rec->second);

    // 1. the experiment's entries for this group (only these groups when there are entries)
    int model = -1;
    bool selected = config.sequences.empty();
    for (size_t e = 0; e < config.sequences.size(); ++e) {
      const SequenceRef& ref = config.sequences[e];
      if (!EntryNamesGroup(ref, path, group)) continue;
      selected = true;
      if (entry_used) (*entry_used)[e] = true;
      if (ref.model.empty()) continue;
      const int named = ModelIndex(config, ref.model);
      if (rec != recorded.end() && rec->second != ref.model) {
        throw LogError(path + ": sequence '" + group + "' is recorded for model '" + rec->second +
                       "' (attribute " + kRecordPrefix + rec->second + "), but " +
                       ref.mark.ToString() + " fits it with model '" + ref.model + "'");
      }
      model = named;
    }
    if (!selected) continue;

    // 2. the log's record; 3. the only model
    if (model < 0 && rec != recorded.end()) {
      if (rec_model < 0) {
        if (!config.sequences.empty()) {
          throw LogError(path + ": sequence '" + group + "' is recorded for model '" + rec->second +
                         "', which the experiment does not have");
        }
        continue;  // another experiment's data
      }
      model = rec_model;
    }
    if (model < 0 && config.models.size() == 1) model = 0;
    if (model < 0) {
      std::vector<std::string> names;
      for (const ModelSpec& m : config.models) names.push_back(m.name);
      throw LogError(path + ": sequence '" + group +
                     "' belongs to none of the experiment's models (" + JoinNames(names) +
                     "): the log records no model for it (attribute " + kRecordPrefix +
                     "<model>) and the experiment's `sequences:` does not name one; list it as " +
                     "`<model>/" + group + "`");
    }
    out.push_back({static_cast<int>(q), model});
  }
  return out;
}

void CheckSequenceEntriesUsed(const ExperimentConfig& config, const std::vector<bool>& entry_used,
                              const std::vector<std::string>& all_groups) {
  for (size_t e = 0; e < config.sequences.size(); ++e) {
    if (entry_used[e]) continue;
    const SequenceRef& ref = config.sequences[e];
    throw ConfigError(ref.mark,
                      "sequence '" + (ref.model.empty() ? "" : ref.model + "/") + ref.name +
                          "' is in none of the data files",
                      "sequences in the data: " + JoinNames(all_groups));
  }
}

std::string QualifiedSequenceName(const std::string& log_path, const std::string& group) {
  return std::filesystem::path(log_path).stem().string() + ":" + group;
}

bool EntryNamesGroup(const SequenceRef& ref, const std::string& log_path,
                     const std::string& group) {
  return ref.name == group || ref.name == QualifiedSequenceName(log_path, group);
}

std::vector<std::string> SequenceNamesInFit(const std::vector<LoggedSequence>& selected,
                                            const std::vector<LoggedSequence>& in_logs,
                                            std::vector<std::string>* renamed) {
  // group name -> the logs that have it, in order
  std::map<std::string, std::vector<std::string>> logs_of;
  for (const LoggedSequence& q : in_logs.empty() ? selected : in_logs) {
    std::vector<std::string>& paths = logs_of[q.group];
    if (std::find(paths.begin(), paths.end(), q.path) == paths.end()) paths.push_back(q.path);
  }
  std::vector<std::string> names;
  std::map<std::string, size_t> first_of;                      // name -> index into selected
  std::map<std::string, std::vector<std::string>> renamed_as;  // group -> its selected names
  for (size_t i = 0; i < selected.size(); ++i) {
    const LoggedSequence& q = selected[i];
    const bool shared = logs_of[q.group].size() > 1;
    names.push_back(shared ? QualifiedSequenceName(q.path, q.group) : q.group);
    if (shared) renamed_as[q.group].push_back(names.back());
    const auto [it, added] = first_of.emplace(names.back(), i);
    if (!added) {
      const LoggedSequence& p = selected[it->second];
      throw LogError(p.path + ": /" + p.group + " and " + q.path + ": /" + q.group +
                     " would both be named " + Quote(names.back()) +
                     " in the fit (a group name in several logs is named "
                     "'<log file stem>:<group>'): rename one of the log files or groups");
    }
  }
  if (renamed) {
    for (const auto& [group, as] : renamed_as) {
      const std::vector<std::string>& paths = logs_of[group];
      renamed->push_back("sequence " + Quote(group) + " is in " + std::to_string(paths.size()) +
                         " logs (" + JoinNames(paths) + "): named " + JoinNames(as) +
                         " in the fit, its results and report");
    }
  }
  return names;
}

}  // namespace mjsysid::io
