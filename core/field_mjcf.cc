#include "core/field_mjcf.h"

#include <mujoco/mjxmacro.h>

namespace mjsysid {
namespace {

// ---------------------------------------------------------------------------------------------
// rows to objects

// a dof's joint
int JointOfDof(const mjModel& m, int dof) { return m.dof_jntid[dof]; }

// the actuator whose first output is this row of actuator_gear; -1 for a later output
int ActuatorOfOutput(const mjModel& m, int output) {
  for (int a = 0; a < m.nactuator; ++a) {
    if (m.actuator_outadr[a] == output && m.actuator_outnum[a] > 0) return a;
  }
  return -1;
}

// ---------------------------------------------------------------------------------------------
// writers: the identified compiled value(s) into the element

// the writer of a kind that writes the same attribute
MjcfWriter KindWriter(ParameterKind kind) { return ParameterKindInfoOf(kind).write_mjcf; }

// an attribute array written whole from the compiled row of N values
template <typename Spec, Spec* (*kAs)(mjsElement*), typename Member, Member kAttr,
          mjtNum* mjModel::*kArray, int N>
bool CopyRow(mjsElement* element, const mjModel& m, int id, int /*index*/, double /*value*/) {
  Spec* s = kAs(element);
  for (int k = 0; k < N; ++k) (s->*kAttr)[k] = (m.*kArray)[N * id + k];
  return true;
}

// a scalar attribute from the compiled value
template <typename Spec, Spec* (*kAs)(mjsElement*), double Spec::*kAttr, mjtNum* mjModel::*kArray>
bool CopyScalar(mjsElement* element, const mjModel& m, int id, int /*index*/, double /*value*/) {
  kAs(element)->*kAttr = (m.*kArray)[id];
  return true;
}

// a per-dof array into its joint's one attribute: only when every dof of the joint agrees
template <mjtNum* mjModel::*kArray, ParameterKind kKind>
bool WriteDofArray(mjsElement* element, const mjModel& m, int joint, int /*index*/,
                   double /*value*/) {
  const int first = m.jnt_dofadr[joint];
  for (int d = first; d < m.nv && m.dof_jntid[d] == joint; ++d) {
    if ((m.*kArray)[d] != (m.*kArray)[first]) return false;
  }
  return KindWriter(kKind)(element, m, joint, 0, (m.*kArray)[first]);
}

// a kind's writer, for an array component written as it is
template <ParameterKind kKind>
bool WriteAsKind(mjsElement* e, const mjModel& m, int id, int index, double value) {
  return KindWriter(kKind)(e, m, id, index, value);
}

// shorthands for the template arguments
#define MJS_ROW(S, as, attr, array, n) \
  CopyRow<S, as, decltype(&S::attr), &S::attr, &mjModel::array, n>
#define MJS_SCALAR(S, as, attr, array) CopyScalar<S, as, &S::attr, &mjModel::array>

// the number of columns of an mjModel array, from MuJoCo's own table; 0 when unknown
int Columns(const mjModel* m, const std::string& array) {
  MJMODEL_POINTERS_PREAMBLE(m)
  (void)nuser_body, (void)nuser_jnt, (void)nuser_geom, (void)nuser_site, (void)nuser_cam;
  (void)nuser_tendon, (void)nuser_actuator, (void)nuser_sensor, (void)nq, (void)nv, (void)na;
  (void)nu, (void)nmocap, (void)nplastic;
#define X(type, name, nr, nc) \
  if (array == #name) return static_cast<int>(nc);
#define XNV X
  MJMODEL_POINTERS
#undef XNV
#undef X
  return 0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// the table: every mjModel array with an MJCF home

const std::vector<FieldMjcfInfo>& FieldMjcfTable() {
  static const std::vector<FieldMjcfInfo> table = {
      // bodies: the explicit inertial clause (as the body kinds), gravity compensation
      {"body_ipos", mjOBJ_BODY, "explicit `<inertial>` (as `body_mass`)", nullptr,
       WriteAsKind<ParameterKind::kBodyMass>},
      {"body_mass", mjOBJ_BODY, "explicit `<inertial>` (as `body_mass`)", nullptr,
       WriteAsKind<ParameterKind::kBodyMass>},
      {"body_inertia", mjOBJ_BODY, "explicit `<inertial>` (as `body_mass`)", nullptr,
       WriteAsKind<ParameterKind::kBodyMass>},
      {"body_gravcomp", mjOBJ_BODY, "`gravcomp` of the `<body>`", nullptr,
       MJS_SCALAR(mjsBody, mjs_asBody, gravcomp, body_gravcomp)},
      // joints and their dofs (one attribute per joint: every dof must agree)
      {"jnt_stiffness", mjOBJ_JOINT, "`stiffness` of the `<joint>`", nullptr,
       WriteAsKind<ParameterKind::kJointStiffness>},
      {"dof_frictionloss", mjOBJ_JOINT, "`frictionloss` of the dof's `<joint>`", JointOfDof,
       WriteDofArray<&mjModel::dof_frictionloss, ParameterKind::kJointFrictionLoss>},
      {"dof_armature", mjOBJ_JOINT, "`armature` of the dof's `<joint>`", JointOfDof,
       WriteDofArray<&mjModel::dof_armature, ParameterKind::kJointArmature>},
      {"dof_damping", mjOBJ_JOINT, "`damping` of the dof's `<joint>`", JointOfDof,
       WriteDofArray<&mjModel::dof_damping, ParameterKind::kJointDamping>},
      // geoms
      {"geom_solmix", mjOBJ_GEOM, "`solmix` of the `<geom>`", nullptr,
       MJS_SCALAR(mjsGeom, mjs_asGeom, solmix, geom_solmix)},
      {"geom_solref", mjOBJ_GEOM, "`solref` of the `<geom>`", nullptr,
       WriteAsKind<ParameterKind::kGeomSolref>},
      {"geom_solimp", mjOBJ_GEOM, "`solimp` of the `<geom>`", nullptr,
       WriteAsKind<ParameterKind::kGeomSolimp>},
      {"geom_friction", mjOBJ_GEOM, "`friction` of the `<geom>`", nullptr,
       WriteAsKind<ParameterKind::kGeomFriction>},
      {"geom_margin", mjOBJ_GEOM, "`margin` of the `<geom>`", nullptr,
       MJS_SCALAR(mjsGeom, mjs_asGeom, margin, geom_margin)},
      {"geom_gap", mjOBJ_GEOM, "`gap` of the `<geom>`", nullptr,
       MJS_SCALAR(mjsGeom, mjs_asGeom, gap, geom_gap)},
      // explicit contact pairs (values MuJoCo took from the geoms become explicit)
      {"pair_solref", mjOBJ_PAIR, "`solref` of the `<pair>`", nullptr,
       WriteAsKind<ParameterKind::kPairSolref>},
      {"pair_solreffriction", mjOBJ_PAIR, "`solreffriction` of the `<pair>`", nullptr,
       MJS_ROW(mjsPair, mjs_asPair, solreffriction, pair_solreffriction, mjNREF)},
      {"pair_solimp", mjOBJ_PAIR, "`solimp` of the `<pair>`", nullptr,
       WriteAsKind<ParameterKind::kPairSolimp>},
      {"pair_margin", mjOBJ_PAIR, "`margin` of the `<pair>`", nullptr,
       MJS_SCALAR(mjsPair, mjs_asPair, margin, pair_margin)},
      {"pair_gap", mjOBJ_PAIR, "`gap` of the `<pair>`", nullptr,
       MJS_SCALAR(mjsPair, mjs_asPair, gap, pair_gap)},
      {"pair_friction", mjOBJ_PAIR, "`friction` of the `<pair>`", nullptr,
       WriteAsKind<ParameterKind::kPairFriction>},
      // tendons
      {"tendon_stiffness", mjOBJ_TENDON, "`stiffness` of the tendon", nullptr,
       WriteAsKind<ParameterKind::kTendonStiffness>},
      {"tendon_damping", mjOBJ_TENDON, "`damping` of the tendon", nullptr,
       WriteAsKind<ParameterKind::kTendonDamping>},
      {"tendon_armature", mjOBJ_TENDON, "`armature` of the tendon", nullptr,
       MJS_SCALAR(mjsTendon, mjs_asTendon, armature, tendon_armature)},
      {"tendon_frictionloss", mjOBJ_TENDON, "`frictionloss` of the tendon", nullptr,
       WriteAsKind<ParameterKind::kTendonFrictionLoss>},
      {"tendon_lengthspring", mjOBJ_TENDON, "`springlength` of the tendon", nullptr,
       WriteAsKind<ParameterKind::kTendonLengthSpring>},
      // actuators
      {"actuator_dynprm", mjOBJ_ACTUATOR, "`dynprm` of the actuator", nullptr,
       MJS_ROW(mjsActuator, mjs_asActuator, dynprm, actuator_dynprm, mjNDYN)},
      {"actuator_gainprm", mjOBJ_ACTUATOR, "`gainprm` of the actuator", nullptr,
       WriteAsKind<ParameterKind::kActuatorGain>},
      {"actuator_biasprm", mjOBJ_ACTUATOR, "`biasprm` of the actuator", nullptr,
       WriteAsKind<ParameterKind::kActuatorBias>},
      {"actuator_gear", mjOBJ_ACTUATOR, "`gear` of the actuator (its first output)",
       ActuatorOfOutput, WriteAsKind<ParameterKind::kActuatorGear>},
  };
  return table;
}

#undef MJS_ROW
#undef MJS_SCALAR

const FieldMjcfInfo* FindFieldMjcf(const std::string& array) {
  for (const FieldMjcfInfo& f : FieldMjcfTable()) {
    if (array == f.array) return &f;
  }
  return nullptr;
}

MjcfTarget MjcfTargetOf(const mjModel& m, const Parameter& p, const ParameterSpec& spec) {
  MjcfTarget t;
  if (p.kind() != ParameterKind::kField) {
    t.object = p.info().object;
    t.id = p.id();
    t.index = p.index();
    t.write_mjcf = p.info().write_mjcf;
    return t;
  }
  // field: the flat index as row and column of the array, the row's object
  const FieldMjcfInfo* f = FindFieldMjcf(spec.field);
  const int columns = Columns(&m, spec.field);
  if (!f || columns <= 0) return t;
  const int row = p.index() / columns;
  t.object = f->object;
  t.id = f->object_of_row ? f->object_of_row(m, row) : row;
  t.index = p.index() % columns;
  if (t.id >= 0) t.write_mjcf = f->write_mjcf;
  return t;
}

}  // namespace mjsysid
