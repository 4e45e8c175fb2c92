// Warnings that recur once per sequence, grouped: the one place where "the same warning for each
// of 20,000 sequences" becomes one warning with a count (issue 35). Used by every command that
// prints warnings (fit, check, simulate, import) and by result.yaml, which records a group as
// {warning: TEXT-WITH-{sequence}, count: N, sequences: [names]} and reads it back as the N
// warnings it stands for (docs/cli.md, "result.yaml").
//
// Two warnings are one group when they differ only by the sequence they name, and name it the same
// way: `sequence 'NAME'` (the fit's own warnings, `validation sequence 'NAME'`) or `: /NAME` ending
// at `/`, `:` or the end (the data's warnings, `LOG: /NAME: ...`, `LOG: /NAME/time: ...`). Any
// other difference (a count, a row, a file) keeps them apart; a warning naming no sequence is a
// group of its own (identical ones are kept, each once per occurrence).
#pragma once

#include <string>
#include <vector>

namespace mjsysid::io {

// the placeholder of a group's pattern
inline constexpr char kSequencePlaceholder[] = "{sequence}";

struct WarningGroup {
  std::string text;     // the first warning, as it was
  std::string pattern;  // the text with its sequence's name as {sequence}; empty: it names none
  std::vector<std::string> sequences;  // the names, in the order of the warnings (1 when alone)

  int Count() const { return pattern.empty() ? 1 : static_cast<int>(sequences.size()); }
  // the warning of the i-th sequence (the pattern with its name)
  std::string Expand(size_t i) const;
};

// the warnings grouped, each group where its first warning was
std::vector<WarningGroup> GroupWarnings(const std::vector<std::string>& warnings);

// one line for a group: the first warning, then, when there are more, "(and 1,999 more sequences
// like it: s1, s2, s3, ...)" naming at most `names` of them
std::string WarningGroupLine(const WarningGroup& group, int names = 3);

// the lines to print for a list of warnings: GroupWarnings, each as WarningGroupLine
std::vector<std::string> GroupedWarningLines(const std::vector<std::string>& warnings);

}  // namespace mjsysid::io
