// Synthetic control signals and sensor noise for `sysid simulate` (docs/experiment-schema.md,
// `simulate` block).
//
// Contract:
// - Signals are sampled at t_k = k * dt, k = 0 .. steps-1 (row k of a log's ctrl is the control
//   applied at sample k, docs/numerics.md "Time convention").
// - Shapes (io::ExcitationType):
//   - sines: sum of sines at the given frequencies, each with a random phase, scaled so that the
//     largest |value| over the horizon equals the amplitude exactly;
//   - chirp: amplitude * sin(phi0 + 2 pi (f0 t + (f1 - f0) t^2 / (2 D))), a linear sweep of the
//     instantaneous frequency from f0 at t = 0 to f1 at t = D = steps * dt; phi0 random;
//   - prbs: +amplitude or -amplitude, drawn at random for each interval
//     [j * switch_period, (j + 1) * switch_period); the value changes only at the first sample of
//     an interval, i.e. at (the first sample at or after) a multiple of switch_period;
//   - zero: all zeros.
// - Randomness: every random draw comes from a std::mt19937_64 whose seed is derived from the
//   caller's seed and a stream index with SeedFor (splitmix64), so that every (seed, stream) pair
//   gives an independent, reproducible stream on every platform. Controls of sequence s of a
//   simulation use the seed `simulate.seed + s`, so different sequences differ.
// - Controls of a model: an excitation list either has one entry for every actuator (actuator
//   "") or one entry per named actuator; actuators without an entry get zero. Each actuator gets
//   its own stream (stream = actuator index), so an actuator's signal does not change when the
//   excitation of another one does. Controls of actuators with ctrllimited are clipped to their
//   ctrlrange (what MuJoCo applies anyway), so the log records the control that acted.
// - Failure: a name that is not an actuator / sensor of the model, or bad sizes, throw
//   std::invalid_argument naming it (ValidateExperimentAgainstModel catches these earlier, with
//   the YAML position).
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"

namespace mjsysid::sim {

// a seed for the independent stream `stream` of `seed` (splitmix64 of both)
std::uint64_t SeedFor(std::uint64_t seed, std::uint64_t stream);

// one control signal of `steps` samples at t_k = k * dt (dt > 0, steps >= 0), drawn from seed
Eigen::VectorXd ExcitationSignal(const io::Excitation& excitation, int steps, double dt,
                                 std::uint64_t seed);

// clips each column i of ctrl (steps x nu) to actuator i's ctrlrange when it is ctrllimited
void ClipToCtrlRange(const mjModel& m, RowMatrix* ctrl);

// the controls of one sequence: steps x nu, row k at t_k = k * m.opt.timestep, clipped to the
// ctrlranges; actuator i's signal is drawn from SeedFor(seed, i)
RowMatrix GenerateControls(const mjModel& m, const std::vector<io::Excitation>& excitation,
                           int steps, std::uint64_t seed);

// adds Gaussian noise N(0, sigma^2) to every column of each named sensor of sensordata
// (steps x nsensordata); sensors not named get none. Sensor j (model order) draws from
// SeedFor(seed, j), row by row.
void AddSensorNoise(const mjModel& m, const std::vector<io::NamedValue>& sigmas, std::uint64_t seed,
                    RowMatrix* sensordata);

// a one-line description of an excitation list, e.g. "all: sines amplitude=1 frequencies=[0.5,
// 1.3]" or "m1: chirp amplitude=2 f0=0.1 f1=4; m2: zero"
std::string DescribeExcitation(const std::vector<io::Excitation>& excitation);

}  // namespace mjsysid::sim
