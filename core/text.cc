#include "core/text.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace mjsysid {

std::string FormatDigits(double x, int digits) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.*g", digits, x);
  return buf;
}

std::string FormatG17(double x) { return FormatDigits(x, 17); }

std::string FormatShortest(double x) {
  char buf[40];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof(buf), "%.*g", digits, x);
    if (!std::isfinite(x) || std::strtod(buf, nullptr) == x) break;
  }
  return buf;
}

std::string FormatYamlNumber(double x) {
  if (std::isnan(x)) return ".nan";
  if (std::isinf(x)) return x > 0 ? ".inf" : "-.inf";
  return FormatShortest(x);
}

std::string Quote(const std::string& s) {
  constexpr size_t kShown = 60;
  std::string out = "'";
  for (size_t i = 0; i < s.size() && i < kShown; ++i) {
    const unsigned char ch = static_cast<unsigned char>(s[i]);
    if (ch < 0x20 || ch == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02X", ch);
      out += buf;
    } else {
      out += s[i];
    }
  }
  out += "'";
  if (s.size() > kShown) out += "... (" + std::to_string(s.size()) + " bytes)";
  return out;
}

size_t EditDistance(const std::string& a, const std::string& b) {
  auto lower = [](char c) { return std::tolower(static_cast<unsigned char>(c)); };
  // one row of the dynamic-programming table at a time
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      const size_t change = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + change});
      diagonal = up;
    }
  }
  return row[b.size()];
}

std::string ClosestName(const std::string& word, const std::vector<std::string>& names) {
  const size_t limit = std::max<size_t>(2, word.size() / 3);
  std::string best;
  size_t best_distance = limit + 1;
  for (const std::string& name : names) {
    const size_t d = EditDistance(word, name);
    if (d < best_distance) {
      best = name;
      best_distance = d;
    }
  }
  return best;
}

std::string JoinNames(const std::vector<std::string>& names) {
  if (names.empty()) return "(none)";
  std::string out;
  for (size_t i = 0; i < names.size() && i < kMaxListedNames; ++i) {
    out += (i ? ", " : "") + names[i];
  }
  if (names.size() > kMaxListedNames) {
    out += ", ... (" + std::to_string(names.size() - kMaxListedNames) + " more)";
  }
  return out;
}

std::string NamesHint(const std::string& word, const std::vector<std::string>& names,
                      const std::string& what) {
  const std::string closest = ClosestName(word, names);
  return (closest.empty() ? "" : "did you mean '" + closest + "'? ") + "valid " + what + ": " +
         JoinNames(names);
}

}  // namespace mjsysid
