#include "core/parameters.h"

#include <mujoco/mjxmacro.h>

#include <cmath>
#include <cstddef>
#include <type_traits>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

struct KindInfo {
  ParameterKind kind;
  const char* name;
  mjtObj object;    // object type the name refers to (mjOBJ_UNKNOWN: none)
  int num_indices;  // valid index range [0, num_indices), 0: index must be 0
  int stage;        // first stage the parameter enters
  bool set_const;   // derived constants depend on it
};

// where each parameter enters the pipeline (../shared/DESIGN.md §5)
const KindInfo kKinds[] = {
    {ParameterKind::kBodyMass, "body_mass", mjOBJ_BODY, 0, mjSTAGE_NONE, true},
    {ParameterKind::kBodyMassInertia, "body_mass_inertia", mjOBJ_BODY, 0, mjSTAGE_NONE, true},
    {ParameterKind::kBodyInertia, "body_inertia", mjOBJ_BODY, 3, mjSTAGE_NONE, true},
    {ParameterKind::kBodyCom, "body_com", mjOBJ_BODY, 3, mjSTAGE_NONE, true},
    {ParameterKind::kJointDamping, "joint_damping", mjOBJ_JOINT, 0, mjSTAGE_POS, false},
    {ParameterKind::kJointFrictionLoss, "joint_frictionloss", mjOBJ_JOINT, 0, mjSTAGE_NONE, false},
    {ParameterKind::kJointArmature, "joint_armature", mjOBJ_JOINT, 0, mjSTAGE_NONE, true},
    {ParameterKind::kJointStiffness, "joint_stiffness", mjOBJ_JOINT, 0, mjSTAGE_POS, false},
    {ParameterKind::kGeomFriction, "geom_friction", mjOBJ_GEOM, 3, mjSTAGE_NONE, false},
    {ParameterKind::kActuatorGain, "actuator_gain", mjOBJ_ACTUATOR, mjNGAIN, mjSTAGE_VEL, false},
    {ParameterKind::kActuatorBias, "actuator_bias", mjOBJ_ACTUATOR, mjNBIAS, mjSTAGE_VEL, false},
    {ParameterKind::kActuatorGear, "actuator_gear", mjOBJ_ACTUATOR, 6, mjSTAGE_NONE, true},
    {ParameterKind::kField, "field", mjOBJ_UNKNOWN, 0, mjSTAGE_NONE, true},
};

const KindInfo& Info(ParameterKind kind) {
  for (const KindInfo& k : kKinds) {
    if (k.kind == kind) return k;
  }
  throw std::logic_error("unknown ParameterKind");
}

const char* ObjectTypeName(mjtObj type) {
  switch (type) {
    case mjOBJ_BODY:
      return "body";
    case mjOBJ_JOINT:
      return "joint";
    case mjOBJ_GEOM:
      return "geom";
    case mjOBJ_ACTUATOR:
      return "actuator";
    default:
      return "object";
  }
}

// comma-separated names of all objects of a type (at most 20), for error hints
std::string ObjectNames(const mjModel& m, mjtObj type) {
  int n = 0;
  switch (type) {
    case mjOBJ_BODY:
      n = static_cast<int>(m.nbody);
      break;
    case mjOBJ_JOINT:
      n = static_cast<int>(m.njnt);
      break;
    case mjOBJ_GEOM:
      n = static_cast<int>(m.ngeom);
      break;
    case mjOBJ_ACTUATOR:
      n = static_cast<int>(m.nu);
      break;
    default:
      break;
  }
  std::string out;
  int listed = 0;
  for (int i = 0; i < n && listed < 20; ++i) {
    const char* name = mj_id2name(&m, type, i);
    if (!name || !name[0]) continue;
    out += (listed++ ? ", " : "") + std::string(name);
  }
  return out.empty() ? "(none named)" : out;
}

// a numeric (mjtNum) array of mjModel found by name: byte offset of its pointer, and its length
bool FindModelField(const mjModel* m, const std::string& name, int* offset, int* size,
                    bool* is_mjtnum) {
  MJMODEL_POINTERS_PREAMBLE(m)
  (void)nuser_body, (void)nuser_jnt, (void)nuser_geom, (void)nuser_site, (void)nuser_cam;
  (void)nuser_tendon, (void)nuser_actuator, (void)nuser_sensor, (void)nq, (void)nv, (void)na;
  (void)nu, (void)nmocap, (void)nplastic;
#define X(type, fname, nr, nc)                            \
  if (name == #fname) {                                   \
    *offset = static_cast<int>(offsetof(mjModel, fname)); \
    *size = static_cast<int>(m->nr * (nc));               \
    *is_mjtnum = std::is_same<type, mjtNum>::value;       \
    return true;                                          \
  }
#define XNV X
  MJMODEL_POINTERS
#undef XNV
#undef X
  return false;
}

mjtNum* FieldArray(const mjModel* m, int offset) {
  return *reinterpret_cast<mjtNum* const*>(reinterpret_cast<const char*>(m) + offset);
}

}  // namespace

const char* ParameterKindName(ParameterKind kind) { return Info(kind).name; }

const std::vector<std::string>& ParameterKindNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const KindInfo& k : kKinds) out.emplace_back(k.name);
    return out;
  }();
  return names;
}

Parameter Parameter::Resolve(const mjModel& m, const ParameterSpec& spec) {
  // kind
  const KindInfo* info = nullptr;
  for (const KindInfo& k : kKinds) {
    if (spec.kind == k.name) info = &k;
  }
  if (!info) {
    std::string valid;
    for (const std::string& n : ParameterKindNames()) valid += (valid.empty() ? "" : ", ") + n;
    throw ParameterError("unknown parameter kind '" + spec.kind + "' (expected one of: " + valid +
                         ")");
  }
  Parameter p;
  p.kind_ = info->kind;
  p.stage_ = info->stage;
  p.needs_set_const_ = info->set_const;
  p.index_ = spec.index;

  // object or field
  if (info->kind == ParameterKind::kField) {
    bool is_mjtnum = false;
    if (!FindModelField(&m, spec.field, &p.field_offset_, &p.field_size_, &is_mjtnum)) {
      throw ParameterError("parameter 'field': mjModel has no array named '" + spec.field + "'");
    }
    if (!is_mjtnum) {
      throw ParameterError("parameter 'field': mjModel::" + spec.field +
                           " is not a floating-point (mjtNum) array");
    }
    if (spec.index < 0 || spec.index >= p.field_size_) {
      throw ParameterError("parameter 'field' " + spec.field + ": index " +
                           std::to_string(spec.index) + " out of range [0, " +
                           std::to_string(p.field_size_) + ")");
    }
  } else {
    p.id_ = mj_name2id(&m, info->object, spec.object.c_str());
    if (p.id_ < 0) {
      throw ParameterError(std::string("parameter '") + info->name + "': no " +
                           ObjectTypeName(info->object) + " named '" + spec.object +
                           "' in the model (" + ObjectTypeName(info->object) +
                           "s: " + ObjectNames(m, info->object) + ")");
    }
    const int max_index = info->num_indices > 0 ? info->num_indices : 1;
    if (spec.index < 0 || spec.index >= max_index) {
      throw ParameterError(std::string("parameter '") + info->name + "' of '" + spec.object +
                           "': index " + std::to_string(spec.index) + " out of range [0, " +
                           std::to_string(max_index) + ")");
    }
  }

  // kind-specific checks
  switch (info->kind) {
    case ParameterKind::kBodyMass:
    case ParameterKind::kBodyMassInertia:
    case ParameterKind::kBodyInertia:
    case ParameterKind::kBodyCom:
      if (p.id_ == 0) throw ParameterError("the world body has no mass parameters");
      p.ref_mass_ = m.body_mass[p.id_];
      for (int i = 0; i < 3; ++i) p.ref_inertia_[i] = m.body_inertia[3 * p.id_ + i];
      if (info->kind == ParameterKind::kBodyMassInertia && !(p.ref_mass_ > 0)) {
        throw ParameterError("body_mass_inertia of '" + spec.object +
                             "': the body has zero mass, so its inertia cannot be scaled "
                             "along; use body_mass and body_inertia");
      }
      break;
    case ParameterKind::kJointDamping:
    case ParameterKind::kJointFrictionLoss:
    case ParameterKind::kJointArmature:
      break;
    case ParameterKind::kActuatorGear:
      if (m.actuator_outnum[p.id_] < 1) {
        throw ParameterError("actuator_gear of '" + spec.object + "': actuator has no output");
      }
      break;
    default:
      break;
  }

  p.label_ = spec.label;
  if (p.label_.empty()) {
    p.label_ = std::string(info->name) + ":" +
               (info->kind == ParameterKind::kField ? spec.field : spec.object);
    if (info->num_indices > 0 || info->kind == ParameterKind::kField) {
      p.label_ += "[" + std::to_string(spec.index) + "]";
    }
  }
  return p;
}

double Parameter::Read(const mjModel& m) const {
  const int b = id_;
  switch (kind_) {
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
  switch (kind_) {
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
    case ParameterKind::kField:
      FieldArray(m, field_offset_)[index_] = value;
      break;
  }
}

void Parameter::Prepare(mjModel* m) const {
  if (kind_ != ParameterKind::kBodyCom && kind_ != ParameterKind::kBodyInertia &&
      kind_ != ParameterKind::kBodyMassInertia) {
    return;
  }
  // a body whose inertial frame coincides with its frame skips body_ipos/iquat, and a "simple"
  // body takes its mass-matrix diagonal from dof_M0: both would ignore com/inertia edits
  const int b = id_;
  m->body_sameframe[b] = mjSAMEFRAME_NONE;
  if (kind_ == ParameterKind::kBodyCom && m->body_simple[b]) {
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
