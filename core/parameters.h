// Model parameters that a fit can change, and the writers that change them in a compiled mjModel.
//
// Contract:
// - A ParameterSpec names a parameter the way a user writes it in YAML: a kind (the strings of
//   ParameterKindName), a MuJoCo object name, and a component index. Resolve() checks it against a
//   model and throws ParameterError naming the kind, object and what was expected.
// - Writing a value makes the edited model behave exactly like a model compiled from XML with that
//   value: derived constants are recomputed with mj_setConst (on a scratch mjData: it overwrites
//   qpos) where the parameter feeds them (masses, inertias, armature, gear), and engine shortcuts
//   that would ignore the edit (a body's "same frame" and "simple" flags for centre-of-mass and
//   inertia edits) are turned off when the parameter is resolved. Tested against models compiled
//   from XML.
// - Joint parameters apply to every dof of the joint (as the XML attribute does): a ball joint's
//   damping is one parameter for its three dofs.
// - stage(): the first pipeline stage the parameter enters (mjSTAGE_NONE: positions, mjSTAGE_POS:
//   velocities, mjSTAGE_VEL: actuation). Steps after a parameter change may skip the stages before.
#pragma once

#include <mujoco/mujoco.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace mjsysid {

class ParameterError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class ParameterKind {
  kBodyMass,           // body_mass of a body
  kBodyMassInertia,    // body_mass, with body_inertia scaled along (uniform density change)
  kBodyInertia,        // body_inertia[index], principal inertia in the inertial frame
  kBodyCom,            // body_ipos[index], centre of mass in the body frame
  kJointDamping,       // dof_damping of every dof of a joint
  kJointFrictionLoss,  // dof_frictionloss of every dof of a joint
  kJointArmature,      // dof_armature of every dof of a joint
  kJointStiffness,     // jnt_stiffness of a joint
  kGeomFriction,       // geom_friction[index] of a geom: 0 sliding, 1 torsional, 2 rolling
  kActuatorGain,       // actuator_gainprm[index]
  kActuatorBias,       // actuator_biasprm[index]
  kActuatorGear,       // actuator_gear[index] (first output of the actuator)
  kField,              // any mjtNum array of mjModel, by field name and flat index
};

// the YAML spelling of each kind: "body_mass", "body_mass_inertia", ..., "field"
const char* ParameterKindName(ParameterKind kind);
const std::vector<std::string>& ParameterKindNames();

struct ParameterSpec {
  std::string kind;    // one of ParameterKindNames()
  std::string object;  // body, joint, geom or actuator name (unused for "field")
  std::string field;   // mjModel field name for "field", e.g. "dof_damping"
  int index = 0;       // component: inertia/com axis, friction slot, gain/bias/gear entry,
                       // or the flat index into the field array
  std::string label;   // display name; defaults to "kind:object[index]"
};

// A parameter resolved against one model: where it lives and how to write it.
class Parameter {
 public:
  static Parameter Resolve(const mjModel& m, const ParameterSpec& spec);

  const std::string& label() const { return label_; }
  ParameterKind kind() const { return kind_; }
  int stage() const { return stage_; }
  bool needs_set_const() const { return needs_set_const_; }

  // the value currently in m
  double Read(const mjModel& m) const;

  // writes value into m without recomputing derived constants (see ParameterSet::Write)
  void WriteRaw(mjModel* m, double value) const;

  // turns off the engine shortcuts that would ignore this parameter's edits (call once per model)
  void Prepare(mjModel* m) const;

 private:
  ParameterKind kind_ = ParameterKind::kField;
  std::string label_;
  int id_ = -1;            // object id
  int index_ = 0;          // component index
  int field_offset_ = -1;  // byte offset of the mjtNum array in mjModel (kField)
  int field_size_ = 0;     // number of entries of the array (kField)
  int stage_ = mjSTAGE_NONE;
  bool needs_set_const_ = false;
  double ref_mass_ = 0;  // kBodyMassInertia: mass and inertia at resolution
  double ref_inertia_[3] = {0, 0, 0};
};

// An ordered set of parameters of one model.
class ParameterSet {
 public:
  ParameterSet() = default;
  ParameterSet(const mjModel& m, const std::vector<ParameterSpec>& specs);

  int size() const { return static_cast<int>(params_.size()); }
  const Parameter& operator[](int i) const { return params_[i]; }
  std::vector<std::string> labels() const;

  // prepares m for edits of these parameters (engine shortcuts off); idempotent
  void Prepare(mjModel* m) const;

  // current values in m, length size()
  void Read(const mjModel& m, double* values) const;

  // writes all values (length size()) into m, then mj_setConst once if any parameter needs it.
  // scratch: an mjData of m used by mj_setConst (its state is clobbered).
  void Write(mjModel* m, mjData* scratch, const double* values) const;

  // writes parameter i alone, with mj_setConst if it needs it
  void WriteOne(mjModel* m, mjData* scratch, int i, double value) const;

 private:
  std::vector<Parameter> params_;
};

}  // namespace mjsysid
