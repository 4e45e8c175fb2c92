#include "core/parameters.h"

#include <mujoco/mjxmacro.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>

#include "core/mujoco_env.h"
#include "core/text.h"

namespace mjsysid {
namespace {

// ---------------------------------------------------------------------------------------------
// MJCF writers: an identified value into the mjSpec element of its object

// bodies: an explicit inertial clause with the identified compiled mass, inertial frame and
// principal inertia (a mass, inertia or centre-of-mass edit changes them together)
bool WriteInertial(mjsElement* element, const mjModel& m, int id, int /*index*/, double /*value*/) {
  mjsBody* b = mjs_asBody(element);
  b->explicitinertial = 1;
  b->mass = m.body_mass[id];
  for (int k = 0; k < 3; ++k) b->ipos[k] = m.body_ipos[3 * id + k];
  for (int k = 0; k < 4; ++k) b->iquat[k] = m.body_iquat[4 * id + k];
  for (int k = 0; k < 3; ++k) b->inertia[k] = m.body_inertia[3 * id + k];
  b->fullinertia[0] = std::numeric_limits<double>::quiet_NaN();  // diagonal inertia, not full
  b->ialt.type = mjORIENTATION_QUAT;                             // iquat, not an alternative
  return true;
}

// joints: the joint's one attribute (mjsJoint has no per-dof values; [0] is the linear term)
bool WriteJointDamping(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asJoint(element)->damping[0] = value;
  return true;
}
bool WriteJointFrictionLoss(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asJoint(element)->frictionloss = value;
  return true;
}
bool WriteJointArmature(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asJoint(element)->armature = value;
  return true;
}
bool WriteJointStiffness(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asJoint(element)->stiffness[0] = value;
  return true;
}

// geoms and actuators: one component of an array attribute
bool WriteGeomFriction(mjsElement* element, const mjModel&, int, int index, double value) {
  mjs_asGeom(element)->friction[index] = value;
  return true;
}
bool WriteActuatorGain(mjsElement* element, const mjModel&, int, int index, double value) {
  mjs_asActuator(element)->gainprm[index] = value;
  return true;
}
bool WriteActuatorBias(mjsElement* element, const mjModel&, int, int index, double value) {
  mjs_asActuator(element)->biasprm[index] = value;
  return true;
}
bool WriteActuatorGear(mjsElement* element, const mjModel&, int, int index, double value) {
  mjs_asActuator(element)->gear[index] = value;
  return true;
}

// field: written by its array's row in core/field_mjcf.h (which reuses the writers above); the
// kind alone has no attribute
bool WriteNothing(mjsElement*, const mjModel&, int, int, double) { return false; }

// ---------------------------------------------------------------------------------------------
// the kind table: the only definition of what a parameter kind is

// Stages: a mass, inertia, armature, gear or friction enters the position stage (mj_setConst
// recomputes what depends on it, or the constraint solver reads it); damping and stiffness enter
// the passive forces of the velocity stage; gains and biases the actuation.
// Columns: kind, name, object, num_indices, indices, units, model_fields, stage, set_const, mjcf,
// write_mjcf (see ParameterKindInfo).
const std::vector<ParameterKindInfo> kKinds = {
    {ParameterKind::kBodyMass, "body_mass", mjOBJ_BODY, 1, "one value per body", "kg",
     "`body_mass`", mjSTAGE_NONE, true,
     "explicit `<inertial>`: the identified mass, pos, quat, diaginertia", WriteInertial},
    {ParameterKind::kBodyMassInertia, "body_mass_inertia", mjOBJ_BODY, 1, "one value per body",
     "kg", "`body_mass`, and `body_inertia` scaled by the mass ratio (constant density)",
     mjSTAGE_NONE, true, "as `body_mass`", WriteInertial},
    {ParameterKind::kBodyInertia, "body_inertia", mjOBJ_BODY, 3,
     "principal moments of inertia about the inertial frame's axes", "kg m^2", "`body_inertia`",
     mjSTAGE_NONE, true, "as `body_mass`", WriteInertial},
    {ParameterKind::kBodyCom, "body_com", mjOBJ_BODY, 3,
     "x, y, z of the centre of mass in the body frame", "m", "`body_ipos`", mjSTAGE_NONE, true,
     "as `body_mass`", WriteInertial},
    {ParameterKind::kJointDamping, "joint_damping", mjOBJ_JOINT, 1,
     "one MJCF attribute per joint, applied to every dof", "N s/m (slide), N m s/rad (hinge, ball)",
     "`dof_damping`", mjSTAGE_POS, false, "`damping` of the `<joint>`", WriteJointDamping},
    {ParameterKind::kJointFrictionLoss, "joint_frictionloss", mjOBJ_JOINT, 1,
     "one MJCF attribute per joint, applied to every dof", "N (slide), N m (hinge, ball)",
     "`dof_frictionloss`", mjSTAGE_NONE, false, "`frictionloss` of the `<joint>`",
     WriteJointFrictionLoss},
    {ParameterKind::kJointArmature, "joint_armature", mjOBJ_JOINT, 1,
     "one MJCF attribute per joint, applied to every dof", "kg (slide), kg m^2 (hinge, ball)",
     "`dof_armature`", mjSTAGE_NONE, true, "`armature` of the `<joint>`", WriteJointArmature},
    {ParameterKind::kJointStiffness, "joint_stiffness", mjOBJ_JOINT, 1,
     "one MJCF attribute per joint", "N/m (slide), N m/rad (hinge, ball)", "`jnt_stiffness`",
     mjSTAGE_POS, false, "`stiffness` of the `<joint>`", WriteJointStiffness},
    {ParameterKind::kGeomFriction, "geom_friction", mjOBJ_GEOM, 3, "sliding, torsional, rolling",
     "1 (sliding), m (torsional, rolling)", "`geom_friction`", mjSTAGE_NONE, false,
     "`friction[index]` of the `<geom>`", WriteGeomFriction},
    {ParameterKind::kActuatorGain, "actuator_gain", mjOBJ_ACTUATOR, mjNGAIN,
     "element of the gain parameters", "those of the gain type", "`actuator_gainprm`", mjSTAGE_VEL,
     false, "`gainprm[index]` of the actuator", WriteActuatorGain},
    {ParameterKind::kActuatorBias, "actuator_bias", mjOBJ_ACTUATOR, mjNBIAS,
     "element of the bias parameters", "those of the bias type", "`actuator_biasprm`", mjSTAGE_VEL,
     false, "`biasprm[index]` of the actuator", WriteActuatorBias},
    {ParameterKind::kActuatorGear, "actuator_gear", mjOBJ_ACTUATOR, 6,
     "element of the gear of the actuator's first output", "those of the transmission",
     "`actuator_gear`", mjSTAGE_NONE, true, "`gear[index]` of the actuator", WriteActuatorGear},
    {ParameterKind::kField, "field", mjOBJ_UNKNOWN, 0,
     "flat index into the array, row * columns + column", "those of the array",
     "the array named in `field`", mjSTAGE_NONE, true,
     "the array's attribute where it has one (`core/field_mjcf.h`: e.g. `solref` of a `<pair>`, "
     "`damping` of a dof's `<joint>`); other arrays: not written (a warning)",
     WriteNothing},
};

// ---------------------------------------------------------------------------------------------
// names and hints

// the number of objects of a type in m
int ObjectCount(const mjModel& m, mjtObj type) {
  switch (type) {
    case mjOBJ_BODY:
      return static_cast<int>(m.nbody);
    case mjOBJ_JOINT:
      return static_cast<int>(m.njnt);
    case mjOBJ_GEOM:
      return static_cast<int>(m.ngeom);
    case mjOBJ_ACTUATOR:
      return static_cast<int>(m.nu);
    default:
      return 0;
  }
}

// the names of m's objects of a type, in id order (unnamed ones left out)
std::vector<std::string> ObjectNames(const mjModel& m, mjtObj type) {
  std::vector<std::string> names;
  for (int i = 0; i < ObjectCount(m, type); ++i) {
    const char* name = mj_id2name(&m, type, i);
    if (name && name[0]) names.emplace_back(name);
  }
  return names;
}

// what a message calls the parameter: "body_inertia of body 'tip'", "field 'dof_damping'"
std::string Subject(const ParameterKindInfo& info, const ParameterSpec& spec) {
  if (info.kind == ParameterKind::kField) return "field '" + spec.field + "'";
  return std::string(info.name) + " of " + info.object_name() + " '" + spec.object + "'";
}

// ---------------------------------------------------------------------------------------------
// spec checks shared by CheckParameterSpec, ParameterIndexCount and Parameter::Resolve

// the kind of a spec, or ParameterError
const ParameterKindInfo& KindOf(const ParameterSpec& spec) {
  const ParameterKindInfo* info = FindParameterKind(spec.kind);
  if (!info) {
    throw ParameterError(ParameterSpecPart::kKind, "unknown parameter kind '" + spec.kind + "'",
                         NamesHint(spec.kind, ParameterKindNames(), "kinds"));
  }
  return *info;
}

// the index of a spec against a number of valid indices, or ParameterError
void CheckIndex(const ParameterKindInfo& info, const ParameterSpec& spec, int count) {
  if (spec.index >= 0 && spec.index < count) return;
  const std::string range = count == 1 ? "0 only" : "0.." + std::to_string(count - 1);
  throw ParameterError(ParameterSpecPart::kIndex,
                       "index " + std::to_string(spec.index) + " is out of range for " +
                           Subject(info, spec) + " (" + range + ": " + info.indices + ")");
}

// an array of mjModel: name, byte offset of its pointer, number of elements, element type

// the mjtNum array a field spec names, or ParameterError
ModelArray FieldOf(const mjModel& m, const ParameterSpec& spec) {
  const std::vector<ModelArray> arrays = ModelArrays(m);
  const auto it = std::find_if(arrays.begin(), arrays.end(),
                               [&](const ModelArray& a) { return spec.field == a.name; });
  if (it == arrays.end()) {
    // the floating-point arrays, closest names first (the full list is long)
    std::vector<std::string> names;
    for (const ModelArray& a : arrays) {
      if (a.is_mjtnum) names.emplace_back(a.name);
    }
    std::stable_sort(names.begin(), names.end(), [&](const std::string& a, const std::string& b) {
      return EditDistance(spec.field, a) < EditDistance(spec.field, b);
    });
    throw ParameterError(ParameterSpecPart::kField,
                         "field: mjModel has no array named '" + spec.field + "'",
                         NamesHint(spec.field, names, "arrays (closest first)"));
  }
  if (!it->is_mjtnum) {
    throw ParameterError(ParameterSpecPart::kField, "field: mjModel array '" + spec.field +
                                                        "' holds " + it->type +
                                                        ", not a floating-point (mjtNum) type");
  }
  if (it->size == 0) {
    throw ParameterError(ParameterSpecPart::kField,
                         "field: mjModel array '" + spec.field + "' is empty in this model");
  }
  return *it;
}

// the id of the object a spec names, or ParameterError
int ObjectOf(const mjModel& m, const ParameterKindInfo& info, const ParameterSpec& spec) {
  const int id = mj_name2id(&m, info.object, spec.object.c_str());
  if (id < 0) {
    throw ParameterError(
        ParameterSpecPart::kObject,
        std::string(info.name) + ": no " + info.object_name() + " named '" + spec.object + "'",
        NamesHint(spec.object, ObjectNames(m, info.object),
                  std::string(info.object_name()) + " names"));
  }
  return id;
}

mjtNum* FieldArray(const mjModel* m, int offset) {
  return *reinterpret_cast<mjtNum* const*>(reinterpret_cast<const char*>(m) + offset);
}

}  // namespace

std::vector<ModelArray> ModelArrays(const mjModel& model) {
  const mjModel* m = &model;
  std::vector<ModelArray> out;
  MJMODEL_POINTERS_PREAMBLE(m)
  (void)nuser_body, (void)nuser_jnt, (void)nuser_geom, (void)nuser_site, (void)nuser_cam;
  (void)nuser_tendon, (void)nuser_actuator, (void)nuser_sensor, (void)nq, (void)nv, (void)na;
  (void)nu, (void)nmocap, (void)nplastic;
#define X(type, fname, nr, nc)                                       \
  out.push_back({#fname, static_cast<int>(offsetof(mjModel, fname)), \
                 static_cast<int>(m->nr * (nc)), #type, std::is_same<type, mjtNum>::value});
#define XNV X
  MJMODEL_POINTERS
#undef XNV
#undef X
  return out;
}

// ---------------------------------------------------------------------------------------------
// public look-ups

ParameterError::ParameterError(const std::string& message)
    : ParameterError(ParameterSpecPart::kNone, message) {}

ParameterError::ParameterError(ParameterSpecPart part, const std::string& message,
                               const std::string& hint)
    : std::runtime_error(hint.empty() ? message : message + " (hint: " + hint + ")"),
      part_(part),
      message_(message),
      hint_(hint) {}

const char* ParameterKindInfo::object_name() const {
  return object == mjOBJ_UNKNOWN ? "mjModel array" : mju_type2Str(object);
}

const std::vector<ParameterKindInfo>& ParameterKindTable() { return kKinds; }

const ParameterKindInfo* FindParameterKind(const std::string& name) {
  for (const ParameterKindInfo& k : kKinds) {
    if (name == k.name) return &k;
  }
  return nullptr;
}

const ParameterKindInfo& ParameterKindInfoOf(ParameterKind kind) {
  for (const ParameterKindInfo& k : kKinds) {
    if (k.kind == kind) return k;
  }
  throw std::logic_error("ParameterKind missing from the kind table");
}

const std::string& ParameterKindName(ParameterKind kind) {
  const size_t row = static_cast<size_t>(&ParameterKindInfoOf(kind) - kKinds.data());
  return ParameterKindNames()[row];
}

const std::vector<std::string>& ParameterKindNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const ParameterKindInfo& k : kKinds) out.emplace_back(k.name);
    return out;
  }();
  return names;
}

void CheckParameterSpec(const ParameterSpec& spec) {
  const ParameterKindInfo& info = KindOf(spec);
  if (info.num_indices > 0) CheckIndex(info, spec, info.num_indices);
}

int ParameterIndexCount(const mjModel& m, const ParameterSpec& spec) {
  const ParameterKindInfo& info = KindOf(spec);
  return info.kind == ParameterKind::kField ? FieldOf(m, spec).size : info.num_indices;
}

// ---------------------------------------------------------------------------------------------
// Parameter

Parameter Parameter::Resolve(const mjModel& m, const ParameterSpec& spec) {
  const ParameterKindInfo& info = KindOf(spec);
  Parameter p;
  p.info_ = &info;
  p.index_ = spec.index;

  // the object or the array, then the index
  if (info.kind == ParameterKind::kField) {
    const ModelArray array = FieldOf(m, spec);
    p.field_offset_ = array.offset;
    p.field_size_ = array.size;
    CheckIndex(info, spec, array.size);
  } else {
    p.id_ = ObjectOf(m, info, spec);
    CheckIndex(info, spec, info.num_indices);
  }

  // kind-specific checks
  switch (info.kind) {
    case ParameterKind::kBodyMass:
    case ParameterKind::kBodyMassInertia:
    case ParameterKind::kBodyInertia:
    case ParameterKind::kBodyCom:
      if (p.id_ == 0) {
        throw ParameterError(ParameterSpecPart::kObject,
                             std::string(info.name) +
                                 ": the world body has no mass, inertia or centre of mass to "
                                 "identify",
                             "name a moving body");
      }
      p.ref_mass_ = m.body_mass[p.id_];
      for (int i = 0; i < 3; ++i) p.ref_inertia_[i] = m.body_inertia[3 * p.id_ + i];
      if (info.kind == ParameterKind::kBodyMassInertia && !(p.ref_mass_ > 0)) {
        throw ParameterError(
            ParameterSpecPart::kObject,
            Subject(info, spec) + ": the body has zero mass, so its inertia cannot be scaled along",
            "use body_mass and body_inertia");
      }
      break;
    case ParameterKind::kActuatorGear:
      if (m.actuator_outnum[p.id_] < 1) {
        throw ParameterError(ParameterSpecPart::kObject,
                             Subject(info, spec) + ": the actuator has no output");
      }
      break;
    default:
      break;
  }

  // label: "kind:object", with "[index]" when the kind has several components
  p.label_ = spec.label;
  if (p.label_.empty()) {
    p.label_ = std::string(info.name) + ":" +
               (info.kind == ParameterKind::kField ? spec.field : spec.object);
    if (info.num_indices != 1) p.label_ += "[" + std::to_string(spec.index) + "]";
  }
  return p;
}

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
    case ParameterKind::kField:
      FieldArray(m, field_offset_)[index_] = value;
      break;
  }
}

void Parameter::Prepare(mjModel* m) const {
  if (kind() != ParameterKind::kBodyCom && kind() != ParameterKind::kBodyInertia &&
      kind() != ParameterKind::kBodyMassInertia) {
    return;
  }
  // a body whose inertial frame coincides with its frame skips body_ipos/iquat, and a "simple"
  // body takes its mass-matrix diagonal from dof_M0: both would ignore com/inertia edits
  const int b = id_;
  m->body_sameframe[b] = mjSAMEFRAME_NONE;
  if (kind() == ParameterKind::kBodyCom && m->body_simple[b]) {
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
