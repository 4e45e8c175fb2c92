// Positions in YAML files and the error that points at one: what every experiment element keeps
// so that a check made later (against a model, against the logs) reports the YAML position.
#pragma once

#include <map>
#include <stdexcept>
#include <string>

namespace mjsysid::io {

// a position in a YAML file: 1-based line and column; 0 when unknown (e.g. a key left out)
struct Mark {
  std::string file;
  int line = 0;
  int column = 0;

  // "file:line:column", or "file" when the line is unknown
  std::string ToString() const;
};

// the mark of an element (self) and of each of its keys' values (keys), as given in the file
struct Marks {
  Mark self;
  std::map<std::string, Mark> keys;

  // the mark of key's value, or self when the key was not given
  const Mark& Of(const std::string& key) const;
};

// a bad experiment file; what() is "FILE:LINE:COLUMN: message (hint: ...)"
// (without ":LINE:COLUMN" when the position is unknown, without the hint when there is none)
class ConfigError : public std::runtime_error {
 public:
  ConfigError(Mark mark, std::string message, std::string hint = {});

  const std::string& file() const { return mark_.file; }
  int line() const { return mark_.line; }
  int column() const { return mark_.column; }
  const Mark& mark() const { return mark_; }
  const std::string& message() const { return message_; }
  const std::string& hint() const { return hint_; }

 private:
  Mark mark_;
  std::string message_;
  std::string hint_;
};

}  // namespace mjsysid::io
