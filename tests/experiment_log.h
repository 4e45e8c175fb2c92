// Helper of tests that fit a shipped experiment on a log of their own size.
#pragma once

#include <string>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"

namespace mjsysid::test {

// experiments/`name` with its data replaced by a log of `sequences` x `steps` samples that
// sim::SimulateExperiment (what `sysid simulate` runs, 1 thread) writes from the experiment's
// `simulate:` section into a fresh folder `tag` under the temporary directory; the returned
// config reads that log
inline io::ExperimentConfig ShippedExperimentWithLog(const std::string& name, int sequences,
                                                     int steps, const std::string& tag) {
  const std::string dir = FreshTempDir(tag);
  io::ExperimentConfig cfg = io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/" + name);
  cfg.simulate.sequences = sequences;
  cfg.simulate.steps = steps;
  const std::string log = dir + "/log.h5";
  cfg.data = {io::DataFile{log, {}}};
  sim::SimulateSettings settings;
  settings.threads = 1;
  io::WriteLog(log, sim::SimulateExperiment(cfg, settings));
  return cfg;
}

}  // namespace mjsysid::test
