// bench_multiple_shooting: the multiple-shooting benchmark (BENCHMARKS.md, "Multiple shooting").
//
// Two measurements, one run, printed as one Markdown table on stdout:
// - arm5 (experiments/arm5.yaml: 5 armatures, 2 x 2000 steps, 200-step segments with free initial
//   states), 1 and 2 simulator threads: wall time per LM iteration against the multiple-shooting
//   floor (1 + np + nx) * sum(T) * t_step / threads, t_step the nominal 1-thread step time (the
//   best of >= 3 rollouts of every sequence, >= 0.3 s). Its log is simulated when missing.
// - chaotic double pendulum (models/double_pendulum.xml released at (2.0, -1.0) rad, a 0.5 Nm
//   multi-sine torque, 5000 steps, truth link masses 1.0, 0.8, start 1.4, 0.5, noise 1e-3 on
//   every sensor channel, seed 3): a single-shooting fit (segment_steps 0) and the default fit
//   (auto: multiple shooting where the sensitivity grows), 2 threads; the time ratio auto /
//   single and both parameter errors.
// Timings are wall clock; nothing here is asserted.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/problem.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// nominal 1-thread step time of the sequences: the best of >= 3 rollouts, >= 0.3 s
double StepTime(const mjModel& m, const std::vector<SequenceInput>& ins) {
  SimulatorOptions so;
  so.threads = 1;
  Simulator sim(m, {}, so);
  std::vector<Trajectory> trs;
  sim.Rollout(ins, &trs);  // warm up
  double best = INFINITY;
  const auto t0 = Clock::now();
  for (int reps = 0; reps < 3 || Seconds(t0) < 0.3; ++reps) {
    sim.ResetStepCount();
    const auto t1 = Clock::now();
    sim.Rollout(ins, &trs);
    best = std::min(best, Seconds(t1) / static_cast<double>(sim.StepCount()));
  }
  return best;
}

double WorstError(const FitResult& r, const std::vector<std::pair<std::string, double>>& truth) {
  double worst = 0;
  for (const auto& [name, value] : truth) {
    for (const ParameterEstimate& e : r.parameters) {
      if (e.name == name) worst = std::max(worst, std::abs(e.value / value - 1));
    }
  }
  return worst;
}

void Row(const std::string& name, int threads, const FitResult& r, double floor_s, double err,
         const std::string& note) {
  std::printf(
      "| %s | %d | %s | %.3f | %d | %.4f | %s | %.2e | %s |\n", name.c_str(), threads,
      FitStatusName(r.outcome), r.seconds, r.iterations,
      r.iterations > 0 ? r.seconds / r.iterations : NAN,
      floor_s > 0 ? std::to_string(r.seconds / r.iterations / floor_s).substr(0, 5).c_str() : "",
      err, note.c_str());
}

// arm5: the experiment as shipped, per thread count
void Arm5() {
  io::ExperimentConfig config = io::LoadExperiment(MJSYSID_EXPERIMENTS_DIR "/arm5.yaml");
  for (const io::DataFile& d : config.data) {
    if (!fs::exists(d.path)) {
      std::fprintf(stderr, "bench_multiple_shooting: simulating %s\n", d.path.c_str());
      fs::create_directories(fs::path(d.path).parent_path());
      io::WriteLog(d.path, sim::SimulateExperiment(config));
    }
  }
  std::vector<std::pair<std::string, double>> truth;
  for (const io::NamedValue& t : config.simulate.truth) truth.emplace_back(t.name, t.value);
  double t_step = 0;
  for (int threads : {1, 2}) {
    run::BuiltProblem b = run::BuildProblem(config, threads);
    long long samples = 0;
    std::vector<SequenceInput> ins;
    for (const FitSequence& s : b.sequences) {
      samples += s.ctrl.rows();
      ins.push_back({s.x0, s.ctrl});
    }
    if (t_step == 0) t_step = StepTime(*b.models[0], ins);
    FitOptions o = b.options;
    o.threads = threads;
    o.verbose = false;
    o.on_iteration = nullptr;
    const FitResult r = b.problem->Fit(o);
    const int np = static_cast<int>(b.parameters.size());
    const int nx = 2 * b.models[0]->nv + b.models[0]->na;
    const double floor_s = (1.0 + np + nx) * samples * t_step / threads;
    Row("arm5 (" + std::to_string(r.segment_steps_used) + "-step segments)", threads, r, floor_s,
        WorstError(r, truth),
        "floor " + std::to_string(floor_s).substr(0, 6) + " s/it, t_step " +
            std::to_string(t_step * 1e6).substr(0, 5) + " us");
  }
}

// the chaotic double pendulum: single shooting against auto on the same 5000-step log
void ChaoticDoublePendulum() {
  ModelPtr m = LoadModel(MJSYSID_MODELS_DIR "/double_pendulum.xml");
  const int T = 5000;
  RowMatrix u(T, m->nu);
  const double freqs[3] = {0.4, 1.1, 2.3}, phase[3] = {0.3, 2.1, 4.4};
  for (int k = 0; k < T; ++k) {
    double v = 0;
    for (int f = 0; f < 3; ++f) v += std::sin(2 * M_PI * freqs[f] * k * m->opt.timestep + phase[f]);
    u(k, 0) = 0.5 * v / 3;
  }
  InitialState x0;
  x0.qpos = Eigen::Vector2d(2.0, -1.0);
  x0.qvel = Eigen::Vector2d(0, 0);
  ParameterSpec m1, m2;
  m1.kind = m2.kind = "body_mass";
  m1.object = "link1";
  m2.object = "link2";
  const std::vector<ParameterSpec> specs = {m1, m2};
  Simulator truth_sim(*m, specs);
  truth_sim.SetParameters(Eigen::Vector2d(1.0, 0.8));
  RowMatrix y = truth_sim.Rollout(SequenceInput{x0, u}).sensors;
  const double sigma = 1e-3;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0, sigma);
  for (Eigen::Index i = 0; i < y.size(); ++i) y.data()[i] += noise(rng);
  auto fit = [&](int segment_steps) {
    Problem problem;
    problem.AddModel("dp", *m);
    problem.AddParameter(FitParameter("m1", specs[0], 1.4).Bounds(0.05, 20).Log());
    problem.AddParameter(FitParameter("m2", specs[1], 0.5).Bounds(0.05, 20).Log());
    problem.AddSequence(FitSequence("seq0", "dp", x0, u, y));
    FitOptions o;
    for (int i = 0; i < m->nsensor; ++i) {
      o.sensor_weights[mj_id2name(m.get(), mjOBJ_SENSOR, i)] = 1.0 / sigma;
    }
    o.segment_steps = segment_steps;
    o.continuity_weight = 10;
    o.threads = 2;
    o.max_iterations = 50;
    return problem.Fit(o);
  };
  const std::vector<std::pair<std::string, double>> truth = {{"m1", 1.0}, {"m2", 0.8}};
  const FitResult single = fit(0);
  Row("double_pendulum chaotic 5000 steps, single shooting", 2, single, 0,
      WorstError(single, truth), SegmentReasonText(single.segment_reason));
  const FitResult automatic = fit(-1);
  Row("double_pendulum chaotic 5000 steps, auto", 2, automatic, 0, WorstError(automatic, truth),
      SegmentReasonText(automatic.segment_reason) + "; time " +
          std::to_string(automatic.seconds / single.seconds).substr(0, 4) + "x single shooting");
}

}  // namespace
}  // namespace mjsysid

int main() {
  mjsysid::InstallMujocoHandlers();
  std::printf(
      "| case | threads | status | wall [s] | iterations | s / iteration | / floor | max rel. "
      "error "
      "| note |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  mjsysid::Arm5();
  mjsysid::ChaoticDoublePendulum();
  return 0;
}
