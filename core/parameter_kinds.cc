// The parameter kinds (core/parameters.h): the kind table, the only definition of what a kind is,
// with each kind's MJCF writer, and the look-ups into the table.
#include <mujoco/mujoco.h>

#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/inertia_cholesky.h"
#include "core/parameters.h"

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

}  // namespace

// ---------------------------------------------------------------------------------------------
// look-ups into the kind table

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

}  // namespace mjsysid
