// The Jacobian mode and its inputs: the mode kAuto resolves to from deterministic step counts, the
// modes a model refuses, whether a batch can pipeline its columns behind its rollouts, the
// parameter steps, and the contact share of nominal trajectories.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/simulator.h"

namespace mjsysid {
namespace {

// deterministic cost of a step that skips stages, relative to a full step (used only to choose a
// Jacobian mode; BENCHMARKS.md has the measured values)
constexpr double kCostSkipPos = 0.6;
constexpr double kCostSkipVel = 0.4;

double StageCost(int skipstage) {
  if (skipstage == mjSTAGE_VEL) return kCostSkipVel;
  if (skipstage == mjSTAGE_POS) return kCostSkipPos;
  return 1.0;
}

}  // namespace

double ContactFraction(const std::vector<Trajectory>& trajectories) {
  long near = 0, total = 0;
  for (const Trajectory& tr : trajectories) {
    for (int k = 0; k < tr.T && k < static_cast<int>(tr.ncon.size()); ++k) {
      near += tr.ncon[k] > 0 || (k + 1 < tr.T && tr.ncon[k + 1] != tr.ncon[k]);
      ++total;
    }
  }
  return total ? static_cast<double>(near) / static_cast<double>(total) : 0.0;
}

const char* JacobianModeName(JacobianMode mode) {
  switch (mode) {
    case JacobianMode::kAuto:
      return "auto";
    case JacobianMode::kDirectional:
      return "directional";
    case JacobianMode::kMatrix:
      return "matrix";
    case JacobianMode::kWholeRollout:
      return "whole_rollout";
  }
  return "?";
}

Eigen::VectorXd Simulator::ParameterSteps(const JacobianOptions& opt) const {
  const int np = params_.size();
  if (!opt.parameter_steps.empty() && static_cast<int>(opt.parameter_steps.size()) != np) {
    throw std::invalid_argument("JacobianOptions::parameter_steps has " +
                                std::to_string(opt.parameter_steps.size()) + " entries, expected " +
                                std::to_string(np));
  }
  Eigen::VectorXd p = GetParameters();
  Eigen::VectorXd h(np);
  for (int j = 0; j < np; ++j) {
    h[j] = opt.parameter_steps.empty()
               ? opt.relative_step * std::max(std::abs(p[j]), opt.step_floor)
               : opt.parameter_steps[j];
    if (!(h[j] > 0)) throw std::invalid_argument("parameter step must be positive");
  }
  return h;
}

double Simulator::JacobianCostPerStep(JacobianMode mode, const JacobianOptions& opt,
                                      double contact_fraction) const {
  if (contact_fraction < 0) contact_fraction = ContactsPossible() ? 1.0 : 0.0;
  const int np = params_.size();
  const int ncol = np + (opt.initial_state ? dims_.nx : 0);
  const double sides = opt.central ? 2.0 : 1.0;
  switch (mode) {
    case JacobianMode::kDirectional:
    case JacobianMode::kWholeRollout:
      return sides * ncol;
    case JacobianMode::kMatrix: {
      // transitionFD: nominal step, qpos columns (full), qvel (skip POS), act (skip VEL); run on
      // both sides for central differences, and for forward ones too where contacts may change
      // (the kink check); one base forward; one perturbed step per parameter skipping its stages
      const double fd_sides = opt.central ? 2.0 : 1.0 + contact_fraction;
      double cost = 2.0 + fd_sides * (dims_.nv + kCostSkipPos * dims_.nv + kCostSkipVel * dims_.na);
      for (int j = 0; j < np; ++j) cost += sides * StageCost(params_[j].stage());
      return cost;
    }
    case JacobianMode::kAuto:
      break;
  }
  return JacobianCostPerStep(ChooseJacobianMode(opt, contact_fraction), opt, contact_fraction);
}

bool Simulator::ContactsPossible() const {
  // contacts need collisions enabled and two geoms that may collide (in the full model)
  if (reduced_) return contacts_possible_full_;
  if (model_->opt.disableflags & mjDSBL_CONTACT) return false;
  int colliding = 0;
  for (int g = 0; g < model_->ngeom; ++g) {
    if (model_->geom_contype[g] || model_->geom_conaffinity[g]) ++colliding;
  }
  return colliding >= 2 || model_->npair > 0;
}

JacobianMode Simulator::ChooseJacobianMode(const JacobianOptions& opt,
                                           double contact_fraction) const {
  if (opt.mode != JacobianMode::kAuto) return opt.mode;
  // native delays: the history buffer is state that the one-step modes do not carry
  if (model_->nhistory > 0) return JacobianMode::kWholeRollout;
  // mjd_transitionFD rejects RK4 and history (delays)
  const bool matrix_ok = model_->opt.integrator != mjINT_RK4 && model_->nhistory == 0;
  if (matrix_ok && JacobianCostPerStep(JacobianMode::kMatrix, opt, contact_fraction) <
                       JacobianCostPerStep(JacobianMode::kDirectional, opt, contact_fraction)) {
    return JacobianMode::kMatrix;
  }
  return JacobianMode::kDirectional;
}

JacobianMode Simulator::CheckedJacobianMode(const JacobianOptions& opt,
                                            double contact_fraction) const {
  const JacobianMode mode = ChooseJacobianMode(opt, contact_fraction);
  if (mode == JacobianMode::kMatrix &&
      (model_->opt.integrator == mjINT_RK4 || model_->nhistory > 0)) {
    throw std::invalid_argument(
        "Jacobian mode 'matrix' needs mjd_transitionFD, which supports neither the RK4 "
        "integrator nor delays (history); use 'directional'");
  }
  // Native delays (actuator/sensor history buffers) make the delayed controls and sensor values
  // state that one-step differences over [qpos, qvel, act] leave out (docs/numerics.md, "Native
  // delays"): only whole rollouts differentiate them
  if (mode == JacobianMode::kDirectional && model_->nhistory > 0) {
    throw std::invalid_argument(
        "Jacobian mode 'directional' differentiates one step at a time over qpos, qvel and act, "
        "and this model has native delays (history buffers of " +
        std::to_string(model_->nhistory) +
        " numbers) that it would leave out; use 'whole_rollout' or 'auto'");
  }
  return mode;
}

bool Simulator::CanPipeline(const JacobianOptions& opt, int ncol) const {
  // pipelined only where it can change something and the mode does not depend on the contacts
  // the rollouts will find (ChooseJacobianMode at either end of the contact share)
  const JacobianMode mode = ChooseJacobianMode(opt, 0.0);
  return pool_.size() > 1 && ncol > 0 && mode == JacobianMode::kDirectional &&
         ChooseJacobianMode(opt, 1.0) == mode && model_->nhistory == 0;
}

}  // namespace mjsysid
