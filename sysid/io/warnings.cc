#include "sysid/io/warnings.h"

#include <cstring>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace mjsysid::io {
namespace {

// where the sequence's name is in a warning: [begin, end), or npos when it names none
std::pair<size_t, size_t> NameSpan(const std::string& w) {
  static const std::string kQuoted = "sequence '";
  size_t at = w.find(kQuoted);
  if (at != std::string::npos) {
    const size_t begin = at + kQuoted.size();
    const size_t end = w.find('\'', begin);
    if (end != std::string::npos && end > begin) return {begin, end};
  }
  at = w.find(": /");
  if (at != std::string::npos) {
    const size_t begin = at + 3;
    size_t end = w.find_first_of("/:", begin);
    if (end == std::string::npos) end = w.size();
    if (end > begin) return {begin, end};
  }
  return {std::string::npos, std::string::npos};
}

// 1999 -> "1,999"
std::string Thousands(size_t n) {
  std::string digits = std::to_string(n), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

}  // namespace

std::string WarningGroup::Expand(size_t i) const {
  if (pattern.empty()) return text;
  std::string w = pattern;
  const size_t at = w.find(kSequencePlaceholder);
  if (at != std::string::npos) w.replace(at, std::strlen(kSequencePlaceholder), sequences.at(i));
  return w;
}

std::vector<WarningGroup> GroupWarnings(const std::vector<std::string>& warnings) {
  std::vector<WarningGroup> groups;
  std::map<std::string, size_t> by_pattern;  // pattern -> its group
  for (const std::string& w : warnings) {
    const auto [begin, end] = NameSpan(w);
    // a text that already holds the placeholder is kept as it is (its pattern would be ambiguous)
    if (begin == std::string::npos || w.find(kSequencePlaceholder) != std::string::npos) {
      groups.push_back(WarningGroup{w, "", {}});
      continue;
    }
    const std::string pattern = w.substr(0, begin) + kSequencePlaceholder + w.substr(end);
    const std::string name = w.substr(begin, end - begin);
    const auto it = by_pattern.find(pattern);
    if (it != by_pattern.end()) {
      groups[it->second].sequences.push_back(name);
      continue;
    }
    by_pattern.emplace(pattern, groups.size());
    groups.push_back(WarningGroup{w, pattern, {name}});
  }
  return groups;
}

std::string WarningGroupLine(const WarningGroup& group, int names) {
  if (group.Count() <= 1) return group.text;
  const size_t more = group.sequences.size() - 1;
  std::string line = group.text + " (and " + Thousands(more) + " more sequence" +
                     (more == 1 ? "" : "s") + " like it: ";
  for (size_t i = 1; i < group.sequences.size() && i <= static_cast<size_t>(names); ++i) {
    line += (i > 1 ? ", " : "") + group.sequences[i];
  }
  if (more > static_cast<size_t>(names)) line += ", ...";
  return line + ")";
}

std::vector<std::string> GroupedWarningLines(const std::vector<std::string>& warnings) {
  std::vector<std::string> lines;
  for (const WarningGroup& g : GroupWarnings(warnings)) lines.push_back(WarningGroupLine(g));
  return lines;
}

}  // namespace mjsysid::io
