#include "sysid/io/marks.h"

#include <utility>

namespace mjsysid::io {

std::string Mark::ToString() const {
  if (line <= 0) return file;
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

const Mark& Marks::Of(const std::string& key) const {
  const auto it = keys.find(key);
  return it == keys.end() ? self : it->second;
}

ConfigError::ConfigError(Mark mark, std::string message, std::string hint)
    : std::runtime_error(mark.ToString() + ": " + message +
                         (hint.empty() ? "" : " (hint: " + hint + ")")),
      mark_(std::move(mark)),
      message_(std::move(message)),
      hint_(std::move(hint)) {}

}  // namespace mjsysid::io
