// Fitting model parameters to recorded sensor trajectories with Ceres.
//
// Ten lines for a C++ user:
//
//   mjsysid::Problem problem;
//   mjsysid::ModelPtr model = mjsysid::LoadModel("models/arm5.xml");
//   problem.AddModel("arm", *model);
//   problem.AddParameter(mjsysid::FitParameter("a1", {"joint_armature", "j1"}, 0.01)
//                            .Bounds(1e-4, 10).Log());
//   problem.AddSequence(mjsysid::FitSequence("run1", "arm", x0, ctrl, measured));
//   mjsysid::FitResult result = problem.Fit(mjsysid::FitOptions());
//   for (const auto& p : result.parameters)
//     std::printf("%s = %g +- %g\n", p.name.c_str(), p.value, p.std_error);
//
// Model. Residuals r_k = w * rho_hat(gain * y_sim(t_k - delay) + bias - y_meas_k) for every
// sample k and used sensor column (see FitSequence), with y_sim from the core's rollout under the
// time convention of core/simulator.h, w = 1/sigma (or a weight) per sensor, rho_hat the square
// root of a robust loss applied per scalar residual, plus Gaussian prior residuals
// (p - mean)/sigma, plus, in multiple shooting, continuity residuals
// continuity_weight * (x_end(segment i) (-) x_0(segment i+1)) in tangent space.
//
// Variables. Physical parameters are optimised as z = p, log p or p / scale, with bounds mapped
// accordingly; measurement terms (delay in seconds, gain, bias) as themselves; initial states of
// sequences or segments as full physics vectors on a StateManifold (quaternion-correct).
//
// Jacobians come from the core (analytic to Ceres, no Ceres numeric differentiation):
// residual-only evaluations run only the nominal rollout. An evaluation whose simulation warns or
// is not finite returns false, so the trust region shrinks instead of the fit failing.
//
// Errors: bad input (unknown names, shapes, NaN in data, a parameter that has no effect on the
// data, infeasible bounds) throws std::invalid_argument or ParameterError before Ceres starts.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <atomic>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "sysid/uncertainty.h"

namespace mjsysid {

enum class Transform { kNone, kLog, kScale };

// one physical parameter to identify
struct FitParameter {
  FitParameter() = default;
  FitParameter(std::string name_, ParameterSpec target_, double initial_)
      : name(std::move(name_)), target(std::move(target_)), initial(initial_) {}
  FitParameter& Bounds(double lo, double hi) {
    lower = lo;
    upper = hi;
    return *this;
  }
  FitParameter& Log() {
    transform = Transform::kLog;
    return *this;
  }
  FitParameter& Prior(double mean, double sigma) {
    has_prior = true;
    prior_mean = mean;
    prior_sigma = sigma;
    return *this;
  }

  // the optimisation variable of a physical value: z = p, log p (-inf for p <= 0) or p / scale
  double ToVariable(double p) const;
  // the physical value of an optimisation variable (the inverse of ToVariable)
  double FromVariable(double z) const;

  std::string name;      // unique label (results use it)
  ParameterSpec target;  // what it writes: kind, object, field, index (core/parameters.h)
  double initial = 0;
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  Transform transform = Transform::kNone;
  double scale = 1.0;  // Transform::kScale: z = p / scale
  bool has_prior = false;
  double prior_mean = 0, prior_sigma = 1;
  std::vector<std::string> models;  // models it applies to; empty = all
};

// measurement terms of one sensor: measured = gain * simulated(t - delay) + bias
struct FitMeasurement {
  struct Term {
    double initial = 0;
    bool fit = false;
    double lower = -std::numeric_limits<double>::infinity();
    double upper = std::numeric_limits<double>::infinity();
  };
  std::string sensor;
  Term delay{0.0, false, 0.0, std::numeric_limits<double>::infinity()};  // seconds, >= 0
  Term gain{1.0, false};
  Term bias{0.0, false};
};

// one recorded sequence of one model
struct FitSequence {
  FitSequence() = default;
  FitSequence(std::string name_, std::string model_, InitialState x0_, RowMatrix ctrl_,
              RowMatrix measured_)
      : name(std::move(name_)),
        model(std::move(model_)),
        x0(std::move(x0_)),
        ctrl(std::move(ctrl_)),
        measured(std::move(measured_)) {}

  std::string name;
  std::string model;   // a name given to AddModel
  InitialState x0;     // initial state (the estimate's start when initial states are fitted)
  RowMatrix ctrl;      // T x nu
  RowMatrix measured;  // T x nsensordata of the model: y_k in the model's sensordata layout
  std::vector<std::string> sensors;  // sensors whose columns are fitted; empty = all sensors
};

// one Gauss-Newton/LM iteration, as reported to callbacks and kept in FitResult::trace
struct IterationInfo {
  int iteration = 0;
  double cost = 0;
  double step_norm = 0;
  double gradient_norm = 0;
  double seconds = 0;  // since the fit started
  bool successful = false;
  Eigen::VectorXd parameters;  // physical values after the iteration (FitResult order)
};

struct FitOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-10;
  JacobianOptions jacobian;  // mode, differences, steps (core/simulator.h)
  int threads = 0;           // simulator threads; <= 0: all cores
  enum class Loss { kNone, kHuber, kCauchy } loss = Loss::kNone;
  double loss_scale = 1.0;  // in weighted residual units
  bool estimate_initial_state = false;
  int segment_steps = 0;  // multiple shooting: samples per segment; 0 = single
  double continuity_weight = 1.0;
  std::map<std::string, double> sensor_weights;  // sensor name -> weight (1/sigma); default 1
  UncertaintyOptions uncertainty;
  bool verbose = false;  // one progress line per iteration on stderr
  std::function<void(const IterationInfo&)> on_iteration;  // e.g. checkpoint the iterate
  const std::atomic<bool>* interrupt = nullptr;  // set to stop after the current iteration
};

struct ParameterEstimate {
  std::string name;
  double value = 0, initial = 0;
  double std_error = 0;  // +inf when unidentifiable
  double ci95_low = 0, ci95_high = 0;
  bool at_lower = false, at_upper = false;  // stopped on a bound (then not estimated: fixed)
  bool identifiable = true;
};

struct SequenceResult {
  std::string name, model;
  std::vector<std::string> sensors;  // fitted sensors
  RowMatrix measured;                // T x nsensordata
  RowMatrix simulated_initial;       // T x nsensordata, at the initial parameters
  RowMatrix simulated_final;         // T x nsensordata, at the estimate (measurement terms on)
  Eigen::VectorXd x0_final;          // estimated initial physics vector (or the given one)
};

struct FitResult {
  std::vector<ParameterEstimate> parameters;  // physical parameters, then measurement terms
  double initial_cost = 0, final_cost = 0;    // 0.5 |r|^2
  int iterations = 0;
  bool converged = false;
  bool interrupted = false;
  std::string termination;  // Ceres' message
  int num_residuals = 0;
  Uncertainty uncertainty;  // over FitResult::parameters (order as there)
  RowMatrix jacobian;       // dr/dp at the estimate (physical units)
  std::vector<IterationInfo> trace;
  std::vector<SequenceResult> sequences;
  std::vector<std::string> warnings;
  double seconds = 0;
  long long simulation_steps = 0;  // step calls of all simulators (Simulator::StepCount)
  std::string jacobian_mode;       // the core mode used
};

// result of Problem::CheckJacobians
struct JacobianCheck {
  double worst_relative_error = 0;  // over every residual block and variable
  std::vector<std::pair<std::string, double>> per_variable;  // parameters, measurement terms,
                                                             // then "x0 of <sequence>"
  std::string worst_where;  // the variable and block of the worst error
};

class Problem {
 public:
  Problem();
  ~Problem();
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;

  // copies m; name is what FitParameter::models and FitSequence::model refer to
  void AddModel(const std::string& name, const mjModel& m);
  void AddParameter(const FitParameter& parameter);
  void AddMeasurement(const FitMeasurement& measurement);
  void AddSequence(const FitSequence& sequence);

  // runs the fit; throws std::invalid_argument / ParameterError on bad input
  FitResult Fit(const FitOptions& options);

  // Checks the core's analytic Jacobians of every residual block at the initial point against
  // Ceres' numeric differentiation (ceres::GradientChecker, central differences of whole
  // rollouts). Returns the worst relative error per variable. Throws like Fit on bad input.
  JacobianCheck CheckJacobians(const FitOptions& options);

  struct Impl;  // the state behind the API (named here for the cost functions in problem.cc)

 private:
  struct Prepared {
    std::vector<Trajectory> initial;                 // rollouts at the initial values
    std::vector<std::string> names;                  // parameters, then measurement terms
    std::vector<std::pair<double, double>> mbounds;  // bounds of the measurement terms
    std::vector<double> minitial;                    // their initial values
    std::string jacobian_mode;
  };
  // validates the inputs, builds the simulators, variables and segments
  void Prepare(const FitOptions& options, Prepared* out);

  std::unique_ptr<Impl> impl_;
};

}  // namespace mjsysid
