// Parameter values read from and written into a compiled mjModel (core/parameters.h): Parameter's
// Read, WriteRaw and Prepare, and ParameterSet. The kind table is in core/parameter_kinds.cc, the
// resolution of a spec against a model in core/parameter_resolve.cc.
#include "core/parameters.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/inertia_cholesky.h"
#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

mjtNum* FieldArray(const mjModel* m, int offset) {
  return *reinterpret_cast<mjtNum* const*>(reinterpret_cast<const char*>(m) + offset);
}

}  // namespace

double Parameter::Read(const mjModel& m) const {
  const int b = id_;
  switch (kind()) {
    case ParameterKind::kBodyMass:
    case ParameterKind::kBodyMassInertia:
      return m.body_mass[b];
    case ParameterKind::kBodyInertia:
      return m.body_inertia[3 * b + index_];
    case ParameterKind::kBodyCom:
      return m.body_ipos[3 * b + index_];
    case ParameterKind::kJointDamping:
      return m.dof_damping[m.jnt_dofadr[b]];
    case ParameterKind::kJointFrictionLoss:
      return m.dof_frictionloss[m.jnt_dofadr[b]];
    case ParameterKind::kJointArmature:
      return m.dof_armature[m.jnt_dofadr[b]];
    case ParameterKind::kJointStiffness:
      return m.jnt_stiffness[b];
    case ParameterKind::kGeomFriction:
      return m.geom_friction[3 * b + index_];
    case ParameterKind::kActuatorGain:
      return m.actuator_gainprm[mjNGAIN * b + index_];
    case ParameterKind::kActuatorBias:
      return m.actuator_biasprm[mjNBIAS * b + index_];
    case ParameterKind::kActuatorGear:
      return m.actuator_gear[6 * m.actuator_outadr[b] + index_];
    case ParameterKind::kTendonDamping:
      return m.tendon_damping[b];
    case ParameterKind::kTendonStiffness:
      return m.tendon_stiffness[b];
    case ParameterKind::kTendonFrictionLoss:
      return m.tendon_frictionloss[b];
    case ParameterKind::kTendonLengthSpring:
      return m.tendon_lengthspring[2 * b + std::max(index_ - 1, 0)];
    case ParameterKind::kGeomSolref:
      return m.geom_solref[mjNREF * b + index_];
    case ParameterKind::kGeomSolimp:
      return m.geom_solimp[mjNIMP * b + index_];
    case ParameterKind::kPairSolref:
      return m.pair_solref[mjNREF * b + index_];
    case ParameterKind::kPairSolimp:
      return m.pair_solimp[mjNIMP * b + index_];
    case ParameterKind::kPairFriction:
      return m.pair_friction[5 * b + index_];
    case ParameterKind::kActuatorKp:
      return -m.actuator_biasprm[mjNBIAS * b + 1];
    case ParameterKind::kActuatorKv:
      return -m.actuator_biasprm[mjNBIAS * b + 2];
    case ParameterKind::kActuatorKi:
      return m.actuator_gainprm[mjNGAIN * b];
    case ParameterKind::kBodyInertial: {
      double theta[kInertialVariables];
      if (!ToLogCholesky(BodyInertialOf(m, b), theta)) {
        return std::numeric_limits<double>::quiet_NaN();
      }
      return theta[index_];
    }
    case ParameterKind::kActuatorDelay:
      return m.actuator_delay[b];
    case ParameterKind::kSensorDelay:
      return m.sensor_delay[b];
    case ParameterKind::kDcMotorConstant:
      return m.actuator_gainprm[mjNGAIN * b + 1];
    case ParameterKind::kDcMotorResistance:
      return m.actuator_gainprm[mjNGAIN * b];
    case ParameterKind::kDcMotorInductance:
      return m.actuator_dynprm[mjNDYN * b] * m.actuator_gainprm[mjNGAIN * b];
    case ParameterKind::kDcMotorCogging:
      return m.actuator_biasprm[mjNBIAS * b + index_];
    case ParameterKind::kDcMotorLugre:
      return index_ < 2 ? m.actuator_dynprm[mjNDYN * b + 5 + index_]
                        : m.actuator_biasprm[mjNBIAS * b + 1 + index_];
    case ParameterKind::kField:
      return FieldArray(&m, field_offset_)[index_];
  }
  return 0;
}

// number of dofs of a joint
static int JointDofs(const mjModel& m, int j) {
  switch (m.jnt_type[j]) {
    case mjJNT_FREE:
      return 6;
    case mjJNT_BALL:
      return 3;
    default:
      return 1;
  }
}

void Parameter::WriteRaw(mjModel* m, double value) const {
  const int b = id_;
  switch (kind()) {
    case ParameterKind::kBodyMass:
      m->body_mass[b] = value;
      break;
    case ParameterKind::kBodyMassInertia:
      // uniform density change: inertia scales with mass
      m->body_mass[b] = value;
      for (int i = 0; i < 3; ++i)
        m->body_inertia[3 * b + i] = ref_inertia_[i] * (value / ref_mass_);
      break;
    case ParameterKind::kBodyInertia:
      m->body_inertia[3 * b + index_] = value;
      break;
    case ParameterKind::kBodyCom:
      m->body_ipos[3 * b + index_] = value;
      break;
    case ParameterKind::kJointDamping:
      for (int i = 0; i < JointDofs(*m, b); ++i) m->dof_damping[m->jnt_dofadr[b] + i] = value;
      break;
    case ParameterKind::kJointFrictionLoss:
      for (int i = 0; i < JointDofs(*m, b); ++i) m->dof_frictionloss[m->jnt_dofadr[b] + i] = value;
      break;
    case ParameterKind::kJointArmature:
      for (int i = 0; i < JointDofs(*m, b); ++i) m->dof_armature[m->jnt_dofadr[b] + i] = value;
      break;
    case ParameterKind::kJointStiffness:
      m->jnt_stiffness[b] = value;
      break;
    case ParameterKind::kGeomFriction:
      m->geom_friction[3 * b + index_] = value;
      break;
    case ParameterKind::kActuatorGain:
      m->actuator_gainprm[mjNGAIN * b + index_] = value;
      break;
    case ParameterKind::kActuatorBias:
      m->actuator_biasprm[mjNBIAS * b + index_] = value;
      break;
    case ParameterKind::kActuatorGear:
      m->actuator_gear[6 * m->actuator_outadr[b] + index_] = value;
      break;
    case ParameterKind::kTendonDamping:
      m->tendon_damping[b] = value;
      break;
    case ParameterKind::kTendonStiffness:
      m->tendon_stiffness[b] = value;
      break;
    case ParameterKind::kTendonFrictionLoss:
      m->tendon_frictionloss[b] = value;
      break;
    case ParameterKind::kTendonLengthSpring:
      // index 0: one rest length, both ends of the range
      if (index_ != 2) m->tendon_lengthspring[2 * b] = value;
      if (index_ != 1) m->tendon_lengthspring[2 * b + 1] = value;
      break;
    case ParameterKind::kGeomSolref:
      m->geom_solref[mjNREF * b + index_] = value;
      break;
    case ParameterKind::kGeomSolimp:
      m->geom_solimp[mjNIMP * b + index_] = value;
      break;
    case ParameterKind::kPairSolref:
      m->pair_solref[mjNREF * b + index_] = value;
      break;
    case ParameterKind::kPairSolimp:
      m->pair_solimp[mjNIMP * b + index_] = value;
      break;
    case ParameterKind::kPairFriction:
      m->pair_friction[5 * b + index_] = value;
      break;
    case ParameterKind::kActuatorKp:
      // a position servo's force is kp (ctrl - length): the gain and the bias together
      m->actuator_biasprm[mjNBIAS * b + 1] = -value;
      if (servo_ == Servo::kPosition) m->actuator_gainprm[mjNGAIN * b] = value;
      break;
    case ParameterKind::kActuatorKv:
      // a velocity servo's force is kv (ctrl - velocity): the gain and the bias together
      m->actuator_biasprm[mjNBIAS * b + 2] = -value;
      if (servo_ == Servo::kVelocity) m->actuator_gainprm[mjNGAIN * b] = value;
      break;
    case ParameterKind::kActuatorKi:
      m->actuator_gainprm[mjNGAIN * b] = value;
      break;
    case ParameterKind::kBodyInertial: {
      // the body's variables now, this one replaced, mapped back to mass, com and inertia
      double theta[kInertialVariables];
      if (!ToLogCholesky(BodyInertialOf(*m, b), theta)) {
        throw std::logic_error("body_inertial: the body left the physically consistent set");
      }
      theta[index_] = value;
      SetBodyInertial(m, b, FromLogCholesky(theta));
      break;
    }
    case ParameterKind::kActuatorDelay:
      m->actuator_delay[b] = value;
      break;
    case ParameterKind::kSensorDelay:
      m->sensor_delay[b] = value;
      break;
    case ParameterKind::kDcMotorConstant:
      m->actuator_gainprm[mjNGAIN * b + 1] = value;
      break;
    case ParameterKind::kDcMotorResistance: {
      // the electrical time constant L / R follows R, the inductance stays
      const double inductance = m->actuator_dynprm[mjNDYN * b] * m->actuator_gainprm[mjNGAIN * b];
      m->actuator_gainprm[mjNGAIN * b] = value;
      m->actuator_dynprm[mjNDYN * b] = inductance / value;
      break;
    }
    case ParameterKind::kDcMotorInductance:
      m->actuator_dynprm[mjNDYN * b] = value / m->actuator_gainprm[mjNGAIN * b];
      break;
    case ParameterKind::kDcMotorCogging:
      m->actuator_biasprm[mjNBIAS * b + index_] = value;
      break;
    case ParameterKind::kDcMotorLugre:
      if (index_ < 2) {
        m->actuator_dynprm[mjNDYN * b + 5 + index_] = value;
      } else {
        m->actuator_biasprm[mjNBIAS * b + 1 + index_] = value;
      }
      break;
    case ParameterKind::kField:
      FieldArray(m, field_offset_)[index_] = value;
      break;
  }
}

void Parameter::Prepare(mjModel* m) const {
  if (kind() != ParameterKind::kBodyCom && kind() != ParameterKind::kBodyInertia &&
      kind() != ParameterKind::kBodyMassInertia && kind() != ParameterKind::kBodyInertial) {
    return;
  }
  // a body whose inertial frame coincides with its frame skips body_ipos/iquat, and a "simple"
  // body takes its mass-matrix diagonal from dof_M0: both would ignore com/inertia edits
  const int b = id_;
  m->body_sameframe[b] = mjSAMEFRAME_NONE;
  const bool moves_com =
      kind() == ParameterKind::kBodyCom || kind() == ParameterKind::kBodyInertial;
  if (moves_com && m->body_simple[b]) {
    m->body_simple[b] = 0;
    // recount consecutive simple dofs, as the compiler does
    int count = 0;
    for (int i = static_cast<int>(m->nv) - 1; i >= 0; --i) {
      count = m->body_simple[m->dof_bodyid[i]] ? count + 1 : 0;
      m->dof_simplenum[i] = count;
    }
  }
}

ParameterSet::ParameterSet(const mjModel& m, const std::vector<ParameterSpec>& specs) {
  for (const ParameterSpec& spec : specs) {
    params_.push_back(Parameter::Resolve(m, spec));
    for (size_t i = 0; i + 1 < params_.size(); ++i) {
      if (params_[i].label() == params_.back().label()) {
        throw ParameterError("parameter '" + params_.back().label() + "' is listed twice");
      }
    }
  }
}

std::vector<std::string> ParameterSet::labels() const {
  std::vector<std::string> out;
  for (const Parameter& p : params_) out.push_back(p.label());
  return out;
}

void ParameterSet::Prepare(mjModel* m) const {
  for (const Parameter& p : params_) p.Prepare(m);
}

void ParameterSet::Read(const mjModel& m, double* values) const {
  for (int i = 0; i < size(); ++i) values[i] = params_[i].Read(m);
}

void ParameterSet::Write(mjModel* m, mjData* scratch, const double* values) const {
  bool set_const = false;
  for (int i = 0; i < size(); ++i) {
    params_[i].WriteRaw(m, values[i]);
    set_const = set_const || params_[i].needs_set_const();
  }
  if (set_const) CallMujoco([=] { mj_setConst(m, scratch); });
}

void ParameterSet::WriteOne(mjModel* m, mjData* scratch, int i, double value) const {
  params_[i].WriteRaw(m, value);
  if (params_[i].needs_set_const()) CallMujoco([=] { mj_setConst(m, scratch); });
}

}  // namespace mjsysid
