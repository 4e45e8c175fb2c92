// Helper of tests that fit a shipped experiment on a log of their own size.
#pragma once

#include <cmath>
#include <random>
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

// standard normal draws from a seeded generator (one distribution, so that consecutive calls
// continue one sequence of draws)
struct NormalNoise {
  explicit NormalNoise(unsigned seed) : rng(seed) {}
  double operator()() { return normal(rng); }
  std::mt19937 rng;
  std::normal_distribution<double> normal;
};

// Gaussian noise of `level` times each column's standard deviation added to x, column by column,
// row by row (a state log made noisy as a robot's encoders and velocity estimates)
inline void AddRelativeNoise(double level, NormalNoise* noise, RowMatrix* x) {
  for (Eigen::Index j = 0; j < x->cols(); ++j) {
    const Eigen::VectorXd col = x->col(j);
    const double sd = std::sqrt((col.array() - col.mean()).square().mean());
    for (Eigen::Index k = 0; k < x->rows(); ++k) (*x)(k, j) += level * sd * (*noise)();
  }
}

}  // namespace mjsysid::test
