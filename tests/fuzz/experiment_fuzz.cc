// libFuzzer harness: bytes as an experiment YAML file (sysid/io/experiment.h).
//
// The text is parsed as if it were experiments/fuzz.yaml, so that the shipped experiments' model
// paths (../models/NAME.xml) resolve to the shipped models; when the parse succeeds, the config
// is checked against each of its models that is a shipped one (compiled once, cached). The only
// failure these functions document is ConfigError: any other exception escaping, a crash, a
// sanitizer report or a leak is a finding.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

#include "core/mujoco_env.h"
#include "sysid/io/experiment.h"

namespace {

namespace fs = std::filesystem;
namespace io = mjsysid::io;

// a shipped model, compiled on first use; nullptr for any other path or one that fails
const mjModel* ShippedModel(const std::string& path) {
  static std::map<std::string, mjsysid::ModelPtr>* cache =
      new std::map<std::string, mjsysid::ModelPtr>();
  static const std::string models_dir = fs::canonical(MJSYSID_MODELS_DIR).string() + "/";
  // only files directly in models/: the cache stays as small as that folder
  std::error_code ec;
  if (path.rfind(models_dir, 0) != 0 || path.find('/', models_dir.size()) != std::string::npos ||
      !fs::is_regular_file(path, ec)) {
    return nullptr;
  }
  auto it = cache->find(path);
  if (it != cache->end()) return it->second.get();
  mjsysid::ModelPtr m;
  try {
    m = mjsysid::LoadModel(path);
  } catch (const mjsysid::ModelLoadError&) {
  }
  return cache->emplace(path, std::move(m)).first->second.get();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool initialized = [] {
    mjsysid::InstallMujocoHandlers();
    return true;
  }();
  (void)initialized;
  static const std::string yaml_path =
      (fs::canonical(MJSYSID_EXPERIMENTS_DIR) / "fuzz.yaml").string();
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const io::ExperimentConfig config = io::ParseExperiment(text, yaml_path);
    for (const io::ModelSpec& spec : config.models) {
      if (const mjModel* m = ShippedModel(spec.path)) {
        io::ValidateExperimentAgainstModel(config, *m, spec.name);
      }
    }
  } catch (const io::ConfigError&) {
    // the documented failure
  }
  return 0;
}
