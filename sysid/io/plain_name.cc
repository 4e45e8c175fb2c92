#include "sysid/io/plain_name.h"

#include <string>

namespace mjsysid::io {

std::string PlainNameProblem(const std::string& name) {
  if (name.empty()) return "it is empty";
  if (name == ".") return "'.' is the folder itself";
  if (name == "..") return "'..' is the parent folder";
  if (name.find('/') != std::string::npos) return "it contains '/'";
  if (name.find('\0') != std::string::npos) return "it contains a NUL character";
  return "";
}

}  // namespace mjsysid::io
