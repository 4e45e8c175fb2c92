// Synthetic logs from an experiment file: what `sysid simulate` does.
//
// Contract:
// - For each model of the experiment (in config order): load it, check the config against it
//   (io::ValidateExperimentAgainstModel), build a core Simulator with the parameters that apply
//   to that model (fixed solver iterations, sensors on), set the true values (simulate.truth;
//   parameters without a truth entry keep the model's value), generate simulate.sequences control
//   sequences of simulate.steps samples (sysid/sim/excitation.h), roll them out from
//   simulate.initial_state (default: qpos0, zero velocity, time 0) and add the sensor noise.
// - Controls: the rollout gets the generated commands held and delayed as the experiment's
//   `controls:` state (hold rules, delays, `before`; ExperimentConfig::ActuatorControlsOf and
//   BuildSampleGrid, exactly as the fit holds them): a given delay at its value, a fitted one at
//   its truth (simulate.truth "controls.delay" or "controls.delay.<actuator>"), else at its initial
//   value. The log's ctrl are the commands (undelayed), as a robot logs them.
// - The returned log (sensor_time "pre", docs/numerics.md "Time convention") has one sequence per
//   rollout: "seq0", "seq1", ... with one model; with several models, "MODEL_seq0", ... (a '/' is
//   not allowed in a group name), model by model. Each sequence holds time (k * timestep),
//   ctrl (clipped to the ctrlranges), sensordata (every sensor of the model, model order, with
//   noise), and the true qpos, qvel (and act when na > 0) x_0 .. x_{T-1}, so that a user can
//   check state estimation. Re-simulating ctrl from x_0 with the true parameters through a
//   Simulator with the same options reproduces sensordata bit for bit when the noise is zero (and
//   no delay or hold rule changes the controls; else ctrl held as the fit holds it does).
// - Logged as a robot logs (simulate.sample_rate > 0): the sequence's samples come at t_0 = 0 and
//   k / sample_rate moved by uniform(-jitter, jitter), up to (steps - 1) * timestep, with
//   round(drop * T) rows other than the first and last dropped. ctrl is logged at those instants
//   (the generated control of the step each falls in) and the rollout holds it on the simulation
//   grid as the fit does (BuildSampleGrid with the experiment's hold rules and delays); sensordata,
//   qpos, qvel, act are the rollout interpolated linearly between the two steps around each instant
//   (the fit's DelayedSample; ball and free joints' quaternions normalised again), so re-fitting
//   the noise-free log at the true values gives zero residuals. The instants of sequence s of model
//   i use SeedFor(seed + s, kSampleStream + i). Attributes sample_rate, jitter, drop.
// - Randomness (all reproducible from simulate.seed): the controls of sequence s use seed
//   `seed + s` (the same for every model, so models see the same excitation), the noise of
//   sequence s of model i uses SeedFor(seed + s, kNoiseStream + i).
// - Log attributes (text): generator ("mjsysid <version> simulate"), mujoco_version, experiment
//   (the YAML file), name, model (path; with several models model.NAME per model), timestep (per
//   model with several: timestep.NAME), seed, sequences, steps, excitation (DescribeExcitation),
//   noise.SENSOR (sigma, %.17g), truth.PARAM (the value simulated, %.17g; with several models and
//   a value that differs between them, truth.MODEL.PARAM), truth.controls.delay[.ACTUATOR] (every
//   fitted control delay at the value simulated, %.17g), truth_from_model (comma-separated
//   names of the parameters that kept the model's value, when any), initial_state.qpos and
//   initial_state.qvel (when given; comma-separated %.17g), and with several models
//   sequences.MODEL (that model's sequence names, comma-separated).
// - Failure: a bad config or a name the model lacks throws io::ConfigError (at the YAML position
//   when known), e.g. a truth name that is neither a parameter nor a fitted control delay, or a
//   model with an unnamed sensor;
//   a model that does not load throws ModelLoadError; a parameter that does not resolve throws
//   ParameterError; a rollout that fails (MuJoCo warning, non-finite state) throws
//   SimulationError.
#pragma once

#include <mujoco/mujoco.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"

namespace mjsysid::sim {

// stream index of the sensor noise (see SeedFor); model i uses kNoiseStream + i
inline constexpr std::uint64_t kNoiseStream = 0x6e6f697365;  // "noise"
// stream index of a robot log's sample instants and drops; model i uses kSampleStream + i
inline constexpr std::uint64_t kSampleStream = 0x74696d65;  // "time"

struct SimulateSettings {
  int threads = 0;  // simulator workers; <= 0: all cores
  // the rollouts of one model's sequences (empty: sim.Rollout); `sysid simulate` under mpirun
  // shards them across the ranks (sysid/mpi/sharded_rollout.h)
  std::function<void(Simulator& sim, const std::vector<SequenceInput>& inputs,
                     std::vector<Trajectory>* out)>
      rollout;
  // a progress line before each model's rollouts ("model NAME: N sequences x T steps"), so that a
  // long log is not silent (empty: none)
  std::function<void(const std::string& line)> progress;
};

// simulates the experiment's `simulate` block; see the contract above
io::Log SimulateExperiment(const io::ExperimentConfig& config,
                           const SimulateSettings& settings = SimulateSettings());

// the log's sequence name of sequence s of a model ("seq<s>", or "<model>_seq<s>" when the
// experiment has several models)
std::string SimulatedSequenceName(const io::ExperimentConfig& config, const std::string& model,
                                  int s);

}  // namespace mjsysid::sim
