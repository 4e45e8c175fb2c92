#include "sysid/run/input_hashes.h"

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <system_error>

#include "sysid/io/file_hash.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;

// the files `xml` includes (<include file="..."/>), relative to the main model's folder `base`,
// then theirs, each once (at most 1000)
void AddIncludes(const std::string& xml, const fs::path& base, std::set<std::string>* seen,
                 std::vector<std::string>* out) {
  std::ifstream in(xml, std::ios::binary);
  if (!in) return;
  std::ostringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  static const std::regex kInclude(R"re(<\s*include\s[^>]*\bfile\s*=\s*(?:"([^"]*)"|'([^']*)'))re");
  for (auto it = std::sregex_iterator(s.begin(), s.end(), kInclude); it != std::sregex_iterator();
       ++it) {
    const std::string name = (*it)[1].matched ? (*it)[1].str() : (*it)[2].str();
    const fs::path p = fs::path(name).is_absolute() ? fs::path(name) : base / name;
    const std::string path = p.lexically_normal().string();
    if (seen->size() >= 1000 || !seen->insert(path).second) continue;
    out->push_back(path);
    AddIncludes(path, base, seen, out);
  }
}

void Add(const std::string& role, const std::string& path, std::vector<io::InputHash>* out) {
  if (const std::optional<std::string> h = io::FileSha256(path)) out->push_back({role, path, *h});
}

}  // namespace

std::vector<io::InputHash> HashInputs(const io::ExperimentConfig& cfg) {
  std::vector<io::InputHash> out;
  Add("experiment", cfg.source_file, &out);
  for (const io::ModelSpec& ms : cfg.models) {
    Add("model", ms.path, &out);
    std::set<std::string> seen = {fs::path(ms.path).lexically_normal().string()};
    std::vector<std::string> includes;
    AddIncludes(ms.path, fs::path(ms.path).parent_path(), &seen, &includes);
    for (const std::string& inc : includes) Add("model", inc, &out);
  }
  for (const io::DataFile& df : cfg.data) Add("log", df.path, &out);
  return out;
}

std::vector<io::InputHash> HashAgain(const std::vector<io::InputHash>& recorded) {
  std::vector<io::InputHash> out;
  for (const io::InputHash& r : recorded) {
    out.push_back({r.role, r.path, io::FileSha256(r.path).value_or("")});
  }
  return out;
}

std::vector<std::string> InputChanges(const std::vector<io::InputHash>& recorded,
                                      const std::vector<io::InputHash>& current) {
  const auto same_file = [](const io::InputHash& a, const io::InputHash& b) {
    return a.role == b.role && (a.role == "experiment" || a.path == b.path);
  };
  const auto name = [](const io::InputHash& h) { return h.path + " (" + h.role + ")"; };
  std::vector<std::string> out;
  for (const io::InputHash& r : recorded) {
    const io::InputHash* now = nullptr;
    for (const io::InputHash& c : current) {
      if (same_file(r, c)) now = &c;
    }
    std::error_code ec;
    if (now == nullptr && !fs::exists(r.path, ec)) {
      out.push_back(name(r) + " is gone");
    } else if (now == nullptr || now->sha256.empty()) {
      out.push_back(name(r) + (now == nullptr ? " is no longer an input" : " is gone"));
    } else if (now->sha256 != r.sha256) {
      out.push_back(name(*now) + " changed");
    }
  }
  for (const io::InputHash& c : current) {
    bool known = false;
    for (const io::InputHash& r : recorded) known = known || same_file(r, c);
    if (!known) out.push_back(name(c) + " is a new input");
  }
  return out;
}

}  // namespace mjsysid::run
