#include "core/parameters.h"

#include <mujoco/mjxmacro.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>

#include "core/inertia_cholesky.h"
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

// tendons: the tendon's attribute ([0] of the polynomial attributes is the linear term); the
// spring's rest length range written whole from the compiled row (a {-1, -1} "from qpos_spring"
// becomes explicit)
bool WriteTendonDamping(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asTendon(element)->damping[0] = value;
  return true;
}
bool WriteTendonStiffness(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asTendon(element)->stiffness[0] = value;
  return true;
}
bool WriteTendonFrictionLoss(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asTendon(element)->frictionloss = value;
  return true;
}
bool WriteTendonLengthSpring(mjsElement* element, const mjModel& m, int id, int, double) {
  for (int k = 0; k < 2; ++k)
    mjs_asTendon(element)->springlength[k] = m.tendon_lengthspring[2 * id + k];
  return true;
}

// contact softness and friction: the attribute written whole from the compiled row (so values
// MuJoCo took from defaults or from the geoms become explicit)
template <int N>
void CopyRow(double* attribute, const mjtNum* array, int id) {
  for (int k = 0; k < N; ++k) attribute[k] = array[N * id + k];
}
bool WriteGeomSolref(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<mjNREF>(mjs_asGeom(element)->solref, m.geom_solref, id);
  return true;
}
bool WriteGeomSolimp(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<mjNIMP>(mjs_asGeom(element)->solimp, m.geom_solimp, id);
  return true;
}
bool WritePairSolref(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<mjNREF>(mjs_asPair(element)->solref, m.pair_solref, id);
  return true;
}
bool WritePairSolimp(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<mjNIMP>(mjs_asPair(element)->solimp, m.pair_solimp, id);
  return true;
}
bool WritePairFriction(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<5>(mjs_asPair(element)->friction, m.pair_friction, id);
  return true;
}

// servo gains: gain and bias rows written whole from the compiled actuator (a gain lives in both)
bool WriteServo(mjsElement* element, const mjModel& m, int id, int, double) {
  CopyRow<mjNGAIN>(mjs_asActuator(element)->gainprm, m.actuator_gainprm, id);
  CopyRow<mjNBIAS>(mjs_asActuator(element)->biasprm, m.actuator_biasprm, id);
  return true;
}

// native delays: the element's delay (its history buffer, nsample and interp, stay as written)
bool WriteActuatorDelay(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asActuator(element)->delay = value;
  return true;
}
bool WriteSensorDelay(mjsElement* element, const mjModel&, int, int, double value) {
  mjs_asSensor(element)->delay = value;
  return true;
}

// DC motors: gain, bias and dynamics rows written whole from the compiled actuator (the
// <dcmotor> attributes are stored in them: K and R in gainprm, L / R and two LuGre entries in
// dynprm, cogging and three LuGre entries in biasprm)
bool WriteDcMotor(mjsElement* element, const mjModel& m, int id, int index, double value) {
  WriteServo(element, m, id, index, value);
  CopyRow<mjNDYN>(mjs_asActuator(element)->dynprm, m.actuator_dynprm, id);
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
    {ParameterKind::kTendonDamping, "tendon_damping", mjOBJ_TENDON, 1, "one value per tendon",
     "force / (tendon velocity): N s/m (spatial), that of the joints' coordinates (fixed)",
     "`tendon_damping`", mjSTAGE_POS, false, "`damping` of the tendon", WriteTendonDamping},
    {ParameterKind::kTendonStiffness, "tendon_stiffness", mjOBJ_TENDON, 1, "one value per tendon",
     "force / (tendon length): N/m (spatial), that of the joints' coordinates (fixed)",
     "`tendon_stiffness`", mjSTAGE_POS, false, "`stiffness` of the tendon", WriteTendonStiffness},
    {ParameterKind::kTendonFrictionLoss, "tendon_frictionloss", mjOBJ_TENDON, 1,
     "one value per tendon", "force: N (spatial), that of the joints' coordinates (fixed)",
     "`tendon_frictionloss`", mjSTAGE_NONE, false, "`frictionloss` of the tendon",
     WriteTendonFrictionLoss},
    {ParameterKind::kTendonLengthSpring, "tendon_lengthspring", mjOBJ_TENDON, 3,
     "0 the rest length (both ends of the range; not for a dead band), 1 lower, 2 upper end of "
     "a dead band",
     "tendon length: m (spatial), that of the joints' coordinates (fixed)", "`tendon_lengthspring`",
     mjSTAGE_POS, false, "`springlength` of the tendon (both ends, from the compiled model)",
     WriteTendonLengthSpring},
    {ParameterKind::kGeomSolref, "geom_solref", mjOBJ_GEOM, mjNREF,
     "time constant, damping ratio (or, both negative: -stiffness, -damping)",
     "s, 1 (positive); N/m, N s/m per unit mass (negative)", "`geom_solref`", mjSTAGE_NONE, false,
     "`solref` of the `<geom>` (the whole compiled row)", WriteGeomSolref},
    {ParameterKind::kGeomSolimp, "geom_solimp", mjOBJ_GEOM, mjNIMP,
     "dmin, dmax, width, midpoint, power of the impedance", "1, 1, m, 1, 1", "`geom_solimp`",
     mjSTAGE_NONE, false, "`solimp` of the `<geom>` (the whole compiled row)", WriteGeomSolimp},
    {ParameterKind::kPairSolref, "pair_solref", mjOBJ_PAIR, mjNREF,
     "time constant, damping ratio (or, both negative: -stiffness, -damping)",
     "s, 1 (positive); N/m, N s/m per unit mass (negative)", "`pair_solref`", mjSTAGE_NONE, false,
     "`solref` of the `<pair>` (the whole compiled row)", WritePairSolref},
    {ParameterKind::kPairSolimp, "pair_solimp", mjOBJ_PAIR, mjNIMP,
     "dmin, dmax, width, midpoint, power of the impedance", "1, 1, m, 1, 1", "`pair_solimp`",
     mjSTAGE_NONE, false, "`solimp` of the `<pair>` (the whole compiled row)", WritePairSolimp},
    {ParameterKind::kPairFriction, "pair_friction", mjOBJ_PAIR, 5,
     "tangent 1, tangent 2, torsional, rolling 1, rolling 2", "1 (tangent), m (torsional, rolling)",
     "`pair_friction`", mjSTAGE_NONE, false, "`friction` of the `<pair>` (the whole compiled row)",
     WritePairFriction},
    {ParameterKind::kActuatorKp, "actuator_kp", mjOBJ_ACTUATOR, 1,
     "position gain of a position servo or pid actuator",
     "force / (transmission length): N m/rad (hinge), N/m (slide)",
     "position servo: `actuator_gainprm[0]` = kp and `actuator_biasprm[1]` = -kp; pid: "
     "`actuator_biasprm[1]` = -kp",
     mjSTAGE_VEL, false, "`gainprm` and `biasprm` of the actuator (the compiled rows)", WriteServo},
    {ParameterKind::kActuatorKv, "actuator_kv", mjOBJ_ACTUATOR, 1,
     "velocity gain of a position servo, velocity servo or pid actuator",
     "force / (transmission velocity): N m s/rad (hinge), N s/m (slide)",
     "`actuator_biasprm[2]` = -kv; a velocity servo's `actuator_gainprm[0]` = kv too", mjSTAGE_VEL,
     false, "`gainprm` and `biasprm` of the actuator (the compiled rows)", WriteServo},
    {ParameterKind::kActuatorKi, "actuator_ki", mjOBJ_ACTUATOR, 1,
     "integral gain of a pid actuator", "force / (transmission length x time): N m/(rad s) (hinge)",
     "`actuator_gainprm[0]`", mjSTAGE_VEL, false,
     "`gainprm` and `biasprm` of the actuator (the compiled rows)", WriteServo},
    {ParameterKind::kBodyInertial, "body_inertial", mjOBJ_BODY, kInertialVariables,
     "log-Cholesky variable: 0 alpha, 1..3 d1..d3, 4 s12, 5 s23, 6 s13, 7..9 t1..t3 "
     "(`docs/numerics.md`)",
     "1 (alpha = ln sqrt(m / kg), d = ln(L / m)), m (s, t)",
     "`body_mass`, `body_ipos`, `body_inertia`, `body_iquat` (the full inertia, eigen-decomposed)",
     mjSTAGE_NONE, true, "as `body_mass` (the full inertia as principal moments and quat)",
     WriteInertial},
    {ParameterKind::kActuatorDelay, "actuator_delay", mjOBJ_ACTUATOR, 1,
     "one value per actuator (needs a history buffer, nsample > 0, and interp=\"linear\")", "s",
     "`actuator_delay`", mjSTAGE_VEL, false, "`delay` of the actuator", WriteActuatorDelay},
    {ParameterKind::kSensorDelay, "sensor_delay", mjOBJ_SENSOR, 1,
     "one value per sensor (needs a history buffer, nsample > 0, and interp=\"linear\")", "s",
     "`sensor_delay`", mjSTAGE_VEL, false, "`delay` of the sensor", WriteSensorDelay},
    {ParameterKind::kDcMotorConstant, "dcmotor_motorconst", mjOBJ_ACTUATOR, 1,
     "motor constant K of a <dcmotor> (torque per current = back-EMF per speed)",
     "N m/A (= V s/rad)", "`actuator_gainprm[1]`", mjSTAGE_VEL, false,
     "`gainprm`, `biasprm`, `dynprm` of the actuator (the compiled rows)", WriteDcMotor},
    {ParameterKind::kDcMotorResistance, "dcmotor_resistance", mjOBJ_ACTUATOR, 1,
     "terminal resistance R of a <dcmotor> (its inductance kept)", "Ohm",
     "`actuator_gainprm[0]`, and `actuator_dynprm[0]` = L / R when the inductance is modelled",
     mjSTAGE_VEL, false, "as `dcmotor_motorconst`", WriteDcMotor},
    {ParameterKind::kDcMotorInductance, "dcmotor_inductance", mjOBJ_ACTUATOR, 1,
     "inductance L of a <dcmotor> that models it (an electrical time constant L / R)", "H",
     "`actuator_dynprm[0]` = L / R", mjSTAGE_VEL, false, "as `dcmotor_motorconst`", WriteDcMotor},
    {ParameterKind::kDcMotorCogging, "dcmotor_cogging", mjOBJ_ACTUATOR, 3,
     "entry of the <dcmotor>'s `cogging`: amplitude, periods per revolution, phase", "N m, 1, rad",
     "`actuator_biasprm[index]`", mjSTAGE_VEL, false, "as `dcmotor_motorconst`", WriteDcMotor},
    {ParameterKind::kDcMotorLugre, "dcmotor_lugre", mjOBJ_ACTUATOR, 5,
     "entry of the <dcmotor>'s `lugre` attribute, in its order", "those of the attribute",
     "`actuator_dynprm[5]`, `[6]` (entries 0, 1), `actuator_biasprm[3..5]` (entries 2..4)",
     mjSTAGE_VEL, false, "as `dcmotor_motorconst`", WriteDcMotor},
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
      return static_cast<int>(m.nactuator);  // nu counts controls (a pid has two)
    case mjOBJ_TENDON:
      return static_cast<int>(m.ntendon);
    case mjOBJ_PAIR:
      return static_cast<int>(m.npair);
    case mjOBJ_SENSOR:
      return static_cast<int>(m.nsensor);
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
    case ParameterKind::kBodyInertial: {
      if (p.id_ == 0) {
        throw ParameterError(
            ParameterSpecPart::kObject,
            std::string(info.name) + ": the world body has no inertial to identify",
            "name a moving body");
      }
      double theta[kInertialVariables];
      if (!ToLogCholesky(BodyInertialOf(m, p.id_), theta)) {
        throw ParameterError(
            ParameterSpecPart::kObject,
            Subject(info, spec) +
                ": the body's inertial is not strictly physically consistent (mass " +
                FormatDigits(m.body_mass[p.id_], 6) + " kg, principal moments " +
                FormatDigits(m.body_inertia[3 * p.id_], 6) + ", " +
                FormatDigits(m.body_inertia[3 * p.id_ + 1], 6) + ", " +
                FormatDigits(m.body_inertia[3 * p.id_ + 2], 6) +
                " kg m^2): it has no log-Cholesky variables",
            "give the body a positive mass and principal moments where each pair sums to more than "
            "the third, or use body_mass, body_com and body_inertia");
      }
      break;
    }
    case ParameterKind::kTendonLengthSpring:
      if (p.index_ == 0 &&
          m.tendon_lengthspring[2 * p.id_] != m.tendon_lengthspring[2 * p.id_ + 1]) {
        throw ParameterError(ParameterSpecPart::kIndex,
                             Subject(info, spec) + ": the tendon's spring has a dead band [" +
                                 FormatDigits(m.tendon_lengthspring[2 * p.id_], 6) + ", " +
                                 FormatDigits(m.tendon_lengthspring[2 * p.id_ + 1], 6) +
                                 "], so index 0 (one rest length) would remove it",
                             "fit index 1 (lower end) and 2 (upper end)");
      }
      break;
    case ParameterKind::kActuatorKp:
    case ParameterKind::kActuatorKv:
    case ParameterKind::kActuatorKi: {
      const int a = p.id_;
      const mjtNum* gain = m.actuator_gainprm + mjNGAIN * a;
      const mjtNum* bias = m.actuator_biasprm + mjNBIAS * a;
      const bool affine =
          m.actuator_gaintype[a] == mjGAIN_FIXED && m.actuator_biastype[a] == mjBIAS_AFFINE;
      if (m.actuator_gaintype[a] == mjGAIN_PID) {
        p.servo_ = Servo::kPid;
      } else if (affine && info.kind == ParameterKind::kActuatorKp && gain[0] == -bias[1]) {
        p.servo_ = Servo::kPosition;
      } else if (affine && info.kind == ParameterKind::kActuatorKv && bias[1] != 0) {
        p.servo_ = Servo::kPosition;
      } else if (affine && info.kind == ParameterKind::kActuatorKv && gain[0] == -bias[2]) {
        p.servo_ = Servo::kVelocity;
      }
      if (p.servo_ == Servo::kNone ||
          (info.kind == ParameterKind::kActuatorKi && p.servo_ != Servo::kPid)) {
        const char* expected =
            info.kind == ParameterKind::kActuatorKp
                ? "a <position> servo (fixed gain kp, affine bias with biasprm[1] = -kp) or a <pid>"
            : info.kind == ParameterKind::kActuatorKv
                ? "a <position> servo (affine bias, biasprm[2] = -kv), a <velocity> servo (fixed "
                  "gain kv, affine bias with biasprm[2] = -kv) or a <pid>"
                : "a <pid> actuator";
        throw ParameterError(ParameterSpecPart::kObject,
                             Subject(info, spec) + ": the actuator is not " + expected,
                             "fit its actuator_gain and actuator_bias entries instead");
      }
      break;
    }
    case ParameterKind::kActuatorDelay:
    case ParameterKind::kSensorDelay: {
      // the delayed value is read from the history buffer, interpolated: linearly, the rollout is
      // continuous in the delay; with zero-order hold it is piecewise constant (no derivative)
      const bool actuator = info.kind == ParameterKind::kActuatorDelay;
      const int* history = (actuator ? m.actuator_history : m.sensor_history) + 2 * p.id_;
      const int adr = (actuator ? m.actuator_historyadr : m.sensor_historyadr)[p.id_];
      if (adr < 0 || history[0] <= 0) {
        throw ParameterError(ParameterSpecPart::kObject,
                             Subject(info, spec) + ": the " + info.object_name() +
                                 " has no history buffer, so its delay cannot change",
                             "give it nsample=\"N\" (N timesteps >= the longest delay to fit) "
                             "and interp=\"linear\" in the model");
      }
      if (history[1] != 1) {
        throw ParameterError(ParameterSpecPart::kObject,
                             Subject(info, spec) + ": the " + info.object_name() +
                                 "'s history is interpolated with zero-order hold, where a "
                                 "delay's effect is a step function without a derivative",
                             "set interp=\"linear\" on it in the model");
      }
      break;
    }
    case ParameterKind::kDcMotorConstant:
    case ParameterKind::kDcMotorResistance:
    case ParameterKind::kDcMotorInductance:
    case ParameterKind::kDcMotorCogging:
    case ParameterKind::kDcMotorLugre:
      if (m.actuator_gaintype[p.id_] != mjGAIN_DCMOTOR) {
        throw ParameterError(ParameterSpecPart::kObject,
                             Subject(info, spec) + ": the actuator is not a <dcmotor>",
                             "fit its actuator_gain and actuator_bias entries instead");
      }
      if (info.kind == ParameterKind::kDcMotorInductance &&
          !(m.actuator_dynprm[mjNDYN * p.id_] > 0)) {
        throw ParameterError(
            ParameterSpecPart::kObject,
            Subject(info, spec) + ": the motor does not model its inductance (no electrical state)",
            "give the <dcmotor> an inductance to fit it");
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
