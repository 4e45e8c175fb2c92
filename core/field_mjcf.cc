#include "core/field_mjcf.h"

#include <mujoco/mjxmacro.h>

#include <type_traits>

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

// shorthands for the template arguments (a row: as many values as the attribute holds)
#define MJS_ROW(S, as, attr, array) \
  CopyRow<S, as, decltype(&S::attr), &S::attr, &mjModel::array, std::extent_v<decltype(S::attr)>>
#define MJS_SCALAR(S, as, attr, array) CopyScalar<S, as, &S::attr, &mjModel::array>

// One-line rows of the table, by writer: `array` the mjModel array (its name is the row's key),
// `object` the mjtObj without mjOBJ_, S the spec type without mjs (Geom: mjsGeom, mjs_asGeom).
// Not formatted: clang-format reads the braces as blocks.
// clang-format off
#define KIND_ROW(array, object, doc, kind) \
  FieldMjcfInfo{#array, mjOBJ_##object, doc, nullptr, WriteAsKind<ParameterKind::kind>}
#define SCALAR_ROW(array, object, doc, S, attr) \
  FieldMjcfInfo{#array, mjOBJ_##object, doc, nullptr, MJS_SCALAR(mjs##S, mjs_as##S, attr, array)}
#define COPY_ROW(array, object, doc, S, attr) \
  FieldMjcfInfo{#array, mjOBJ_##object, doc, nullptr, MJS_ROW(mjs##S, mjs_as##S, attr, array)}
#define DOF_ROW(array, doc, kind)                       \
  FieldMjcfInfo{#array, mjOBJ_JOINT, doc, JointOfDof, \
                WriteDofArray<&mjModel::array, ParameterKind::kind>}
// clang-format on

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
      KIND_ROW(body_ipos, BODY, "explicit `<inertial>` (as `body_mass`)", kBodyMass),
      KIND_ROW(body_mass, BODY, "explicit `<inertial>` (as `body_mass`)", kBodyMass),
      KIND_ROW(body_inertia, BODY, "explicit `<inertial>` (as `body_mass`)", kBodyMass),
      SCALAR_ROW(body_gravcomp, BODY, "`gravcomp` of the `<body>`", Body, gravcomp),
      // joints and their dofs (one attribute per joint: every dof must agree)
      KIND_ROW(jnt_stiffness, JOINT, "`stiffness` of the `<joint>`", kJointStiffness),
      DOF_ROW(dof_frictionloss, "`frictionloss` of the dof's `<joint>`", kJointFrictionLoss),
      DOF_ROW(dof_armature, "`armature` of the dof's `<joint>`", kJointArmature),
      DOF_ROW(dof_damping, "`damping` of the dof's `<joint>`", kJointDamping),
      // geoms
      SCALAR_ROW(geom_solmix, GEOM, "`solmix` of the `<geom>`", Geom, solmix),
      KIND_ROW(geom_solref, GEOM, "`solref` of the `<geom>`", kGeomSolref),
      KIND_ROW(geom_solimp, GEOM, "`solimp` of the `<geom>`", kGeomSolimp),
      KIND_ROW(geom_friction, GEOM, "`friction` of the `<geom>`", kGeomFriction),
      SCALAR_ROW(geom_margin, GEOM, "`margin` of the `<geom>`", Geom, margin),
      SCALAR_ROW(geom_gap, GEOM, "`gap` of the `<geom>`", Geom, gap),
      // explicit contact pairs (values MuJoCo took from the geoms become explicit)
      KIND_ROW(pair_solref, PAIR, "`solref` of the `<pair>`", kPairSolref),
      COPY_ROW(pair_solreffriction, PAIR, "`solreffriction` of the `<pair>`", Pair, solreffriction),
      KIND_ROW(pair_solimp, PAIR, "`solimp` of the `<pair>`", kPairSolimp),
      SCALAR_ROW(pair_margin, PAIR, "`margin` of the `<pair>`", Pair, margin),
      SCALAR_ROW(pair_gap, PAIR, "`gap` of the `<pair>`", Pair, gap),
      KIND_ROW(pair_friction, PAIR, "`friction` of the `<pair>`", kPairFriction),
      // tendons
      KIND_ROW(tendon_stiffness, TENDON, "`stiffness` of the tendon", kTendonStiffness),
      KIND_ROW(tendon_damping, TENDON, "`damping` of the tendon", kTendonDamping),
      SCALAR_ROW(tendon_armature, TENDON, "`armature` of the tendon", Tendon, armature),
      KIND_ROW(tendon_frictionloss, TENDON, "`frictionloss` of the tendon", kTendonFrictionLoss),
      KIND_ROW(tendon_lengthspring, TENDON, "`springlength` of the tendon", kTendonLengthSpring),
      // actuators
      COPY_ROW(actuator_dynprm, ACTUATOR, "`dynprm` of the actuator", Actuator, dynprm),
      KIND_ROW(actuator_gainprm, ACTUATOR, "`gainprm` of the actuator", kActuatorGain),
      KIND_ROW(actuator_biasprm, ACTUATOR, "`biasprm` of the actuator", kActuatorBias),
      {"actuator_gear", mjOBJ_ACTUATOR, "`gear` of the actuator (its first output)",
       ActuatorOfOutput, WriteAsKind<ParameterKind::kActuatorGear>},
  };
  return table;
}

#undef KIND_ROW
#undef SCALAR_ROW
#undef COPY_ROW
#undef DOF_ROW
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
