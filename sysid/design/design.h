// `sysid design`: an excitation that tells the experiment's parameters apart, found by searching
// the Fourier family (sysid/design/fourier.h) for the best information criterion
// (sysid/design/information.h) under the constraints a real robot needs.
//
// Contract:
// - The experiment has one model; the design is for its parameters (ParametersOf) and its fitted
//   sensors (`sensors:`, every sensor when empty), each with a noise sigma: sensors[].sigma, else
//   simulate.noise.<sensor>; a sensor with neither throws io::ConfigError (the information needs
//   the noise). Measurement terms (sensor delay, gain, bias), fitted control delays and initial
//   states are not part of the information: the predicted standard errors are those of a fit
//   that knows the initial state and the sensors' calibration.
// - Parameter values: each parameter's `initial` (the model's value for `initial: auto`), or
//   with at_truth the experiment's simulate.truth where it gives one.
// - One sequence of steps = round(duration / timestep) samples from simulate.initial_state (else
//   qpos0 at rest); the controls are applied at the steps as they are (no hold rule or delay).
//   The current excitation is the experiment's `simulate.excitation` (its first sequence, seed
//   simulate.seed) over the same duration.
// - Amplitude limits (the same for the current excitation and the design): actuator i's control
//   stays within centre_i +- amplitude_i, centre_i = 0 (the midpoint of its ctrlrange when 0 lies
//   outside it), amplitude_i = the experiment's excitation amplitude for the actuator (0 for an
//   actuator with none or a `zero` excitation), cut to the ctrlrange where ctrllimited.
// - Constraints checked on the simulated motion of every candidate, and again on the design
//   before it is returned: limited hinge and slide joints stay inside their range shrunk by
//   range_margin of its width at both ends; |qvel| of hinge and slide joints <= max_joint_speed
//   (when > 0); no contact at any step unless contacts are allowed. A candidate that breaks one
//   is simulated again at 0.7 times its amplitude (the same shape), up to 6 times; after that it
//   is rejected.
// - Search: evaluations / 8 random shapes (coefficients N(0, 1) / h for harmonic h), then
//   CMA-ES (sysid/design/cma_es.h) from the best (random shapes go on while none met the
//   constraints), until `evaluations` candidates or time_limit
//   seconds. Reproducible from seed, the same result for any thread count, when the evaluation
//   budget ends the search (time_limited false); the time limit is a bound on a slow machine.
//   Every candidate costs one rollout per amplitude tried and one Jacobian (core/simulator.h).
// - Failure: a bad config or option throws io::ConfigError / std::invalid_argument (the
//   message names the key or option); no candidate meets the constraints: DesignError;
//   simulation failures as core's Simulator.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "sysid/design/fourier.h"
#include "sysid/design/information.h"
#include "sysid/io/experiment.h"

namespace mjsysid::design {

// no excitation met the constraints (or the options cannot be met)
class DesignError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct DesignOptions {
  double duration = 0;  // s; <= 0: simulate.steps * timestep
  DesignCriterion criterion = DesignCriterion::kDOptimal;
  FourierBasis basis;
  double range_margin = 0.05;  // share of a limited joint's range kept free at each end, [0, 0.5)
  double max_joint_speed = 0;  // rad/s (hinge) and m/s (slide); <= 0: no limit
  bool contacts = true;        // false: any contact makes a candidate infeasible
  int evaluations = 1200;      // candidates, >= 1
  double time_limit = 120;     // s of search (the last candidate finishes)
  std::uint64_t seed = 1;
  bool at_truth = false;  // information at simulate.truth instead of the initial values
  int threads = 0;        // simulator workers; <= 0: all cores
};

// the constraint margins of one simulated excitation (>= 0 where met)
struct Margins {
  struct Joint {
    std::string name;
    double lower = 0, upper = 0;  // the allowed band (range shrunk by the margin)
    double min = 0, max = 0;      // of qpos over the motion
    double margin = 0;            // min(min - lower, upper - max)
  };
  std::vector<Joint> joints;   // limited hinge and slide joints
  double max_joint_speed = 0;  // largest |qvel| of hinge and slide joints
  std::string fastest_joint;
  int steps_with_contact = 0;
  std::vector<double> peak;  // max |u - centre| per actuator
};

// one excitation and what it tells
struct Evaluated {
  RowMatrix ctrl;  // steps x nu
  Trajectory motion;
  Information info;
  Margins margins;
  double scale = 1;  // amplitude used, as a share of the limits
  double criterion = 0;
  double score = 0;  // what the search minimises (SearchScore)
  bool feasible = false;
  std::string violation;  // the first constraint broken (when not feasible)
};

struct DesignProgress {
  int evaluation = 0;   // candidates done
  int evaluations = 0;  // budget
  double seconds = 0;
  double best = 0;  // the best criterion value so far (+inf before a feasible one)
  double best_worst_relative_std = 0;
};

struct DesignResult {
  // a hinge or slide joint's position in the motion's states, and its allowed band when limited
  struct JointColumn {
    std::string name;
    int qpos = 0;
    bool limited = false;
    double lower = 0, upper = 0;  // range shrunk by the margin (limited only)
  };
  std::string model_name, model_path;
  std::vector<JointColumn> joints;      // every hinge and slide joint, model order
  std::vector<std::string> parameters;  // names, in the information's order
  std::vector<std::string> actuators;
  std::vector<std::string> joints_checked;
  Eigen::VectorXd values;             // the parameter values the information is computed at
  Eigen::VectorXd centre, amplitude;  // per actuator
  double timestep = 0;
  int steps = 0;
  DesignOptions options;
  Evaluated current, design;
  Eigen::VectorXd coefficients;  // the design's Fourier coefficients (nu * (2 H + 1))
  int evaluations = 0, feasible = 0;
  bool time_limited = false;  // the time limit, not the evaluation budget, ended the search
  double seconds = 0;
};

// the design (see the contract); progress (optional) after every candidate
DesignResult DesignExcitation(const io::ExperimentConfig& config, const DesignOptions& options,
                              const std::function<void(const DesignProgress&)>& progress = {});

}  // namespace mjsysid::design
