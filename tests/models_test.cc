// every shipped model compiles and simulates without warnings, so none can rot
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

std::vector<std::string> ShippedModels() {
  std::vector<std::string> paths;
  for (const auto& entry : std::filesystem::directory_iterator(MJSYSID_MODELS_DIR)) {
    if (entry.path().extension() == ".xml") paths.push_back(entry.path().string());
  }
  return paths;
}

TEST(ModelsTest, EveryShippedModelLoadsAndSteps) {
  const std::vector<std::string> paths = ShippedModels();
  ASSERT_GE(paths.size(), 6u);
  for (const std::string& path : paths) {
    SCOPED_TRACE(path);
    ModelPtr m = LoadModel(path);
    DataPtr d = MakeData(*m);
    EXPECT_GT(m->nsensordata, 0) << "a shipped model must have sensors to fit";
    EXPECT_GT(m->nu, 0) << "a shipped model must have actuators to excite it";
    for (int k = 0; k < 500; ++k) {
      for (int i = 0; i < m->nu; ++i) d->ctrl[i] = 0.5 * std::sin(0.01 * k * (i + 1));
      mj_step(m.get(), d.get());
    }
    EXPECT_EQ(SimulationWarnings(*d), "");
  }
}

}  // namespace
}  // namespace mjsysid
