// Text in user-facing messages and files, written once for every layer: numbers at full
// precision, quoted names, the closest valid name to a typo ("did you mean") and lists of valid
// names (core's parameter errors, io's YAML, log and CSV errors, log attributes).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace mjsysid {

// "%.<digits>g": x with `digits` significant digits, for messages (e.g. 3 for a ratio, 6 for a
// time)
std::string FormatDigits(double x, int digits);

// "%.17g": every double printed with 17 significant digits (reads back exactly)
std::string FormatG17(double x);

// the shortest of "%.15g", "%.16g", "%.17g" that reads back as x (17 digits for non-finite x)
std::string FormatShortest(double x);

// x as a YAML 1.2 scalar: FormatShortest, or .nan, .inf, -.inf (result files, design files)
std::string FormatYamlNumber(double x);

// 'text' for a message: control bytes as \xNN, cut after 60 bytes with the length said
// ('abc...' (10485760 bytes)), so a huge or binary value is never echoed whole
std::string Quote(const std::string& s);

// at most this many names are listed by JoinNames and NamesHint
inline constexpr size_t kMaxListedNames = 20;

// Levenshtein distance between a and b, ignoring ASCII case
size_t EditDistance(const std::string& a, const std::string& b);

// the name of `names` closest to `word`, or "" when none is within max(2, |word| / 3) edits
// (close enough to be a likely typo); the first of equally close names
std::string ClosestName(const std::string& word, const std::vector<std::string>& names);

// "a, b, c": the first kMaxListedNames names, then ", ... (N more)"; "(none)" when empty
std::string JoinNames(const std::vector<std::string>& names);

// "did you mean 'x'? valid <what>: a, b, c" (without the first part when no name is close)
std::string NamesHint(const std::string& word, const std::vector<std::string>& names,
                      const std::string& what);

}  // namespace mjsysid
