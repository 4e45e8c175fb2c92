// Model parameters that a fit can change: the table of parameter kinds (the only definition of
// what a kind is), and the writers that change a parameter in a compiled mjModel.
//
// Contract:
// - A ParameterSpec names a parameter the way a user writes it in YAML: a kind (a name of
//   ParameterKindTable()), a MuJoCo object name, and a component index. CheckParameterSpec()
//   checks what needs no model, Resolve() checks it against a model; both throw ParameterError
//   naming the kind, object and index, what was expected, and which part of the spec is wrong.
// - Writing a value makes the edited model behave exactly like a model compiled from XML with that
//   value: derived constants are recomputed with mj_setConst (on a scratch mjData: it overwrites
//   qpos) where the parameter feeds them (masses, inertias, armature, gear), and engine shortcuts
//   that would ignore the edit (a body's "same frame" and "simple" flags for centre-of-mass and
//   inertia edits) are turned off when the parameter is resolved. Tested against models compiled
//   from XML.
// - Joint parameters apply to every dof of the joint, as the MJCF attribute does (mjsJoint has one
//   damping, frictionloss, armature and stiffness per joint): a ball joint's damping is one
//   parameter for its three dofs, and joint kinds take index 0 only, for every joint type.
// - stage: the first pipeline stage the parameter enters (mjSTAGE_NONE: positions, mjSTAGE_POS:
//   velocities, mjSTAGE_VEL: actuation). Steps after a parameter change may skip the stages before.
#pragma once

#include <mujoco/mujoco.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace mjsysid {

// The part of a ParameterSpec an error is about (a YAML reader points at that key).
enum class ParameterSpecPart { kNone, kKind, kObject, kField, kIndex };

// A parameter spec that does not fit the kind table or the model. what() is the message followed
// by " (hint: <hint>)" when there is a hint.
class ParameterError : public std::runtime_error {
 public:
  explicit ParameterError(const std::string& message);
  ParameterError(ParameterSpecPart part, const std::string& message, const std::string& hint = {});

  ParameterSpecPart part() const { return part_; }
  const std::string& message() const { return message_; }
  const std::string& hint() const { return hint_; }

 private:
  ParameterSpecPart part_ = ParameterSpecPart::kNone;
  std::string message_;
  std::string hint_;
};

enum class ParameterKind {
  kBodyMass,            // body_mass of a body
  kBodyMassInertia,     // body_mass, with body_inertia scaled along (uniform density change)
  kBodyInertia,         // body_inertia[index], principal inertia in the inertial frame
  kBodyCom,             // body_ipos[index], centre of mass in the body frame
  kJointDamping,        // dof_damping of every dof of a joint
  kJointFrictionLoss,   // dof_frictionloss of every dof of a joint
  kJointArmature,       // dof_armature of every dof of a joint
  kJointStiffness,      // jnt_stiffness of a joint
  kGeomFriction,        // geom_friction[index] of a geom: 0 sliding, 1 torsional, 2 rolling
  kActuatorGain,        // actuator_gainprm[index]
  kActuatorBias,        // actuator_biasprm[index]
  kActuatorGear,        // actuator_gear[index] (first output of the actuator)
  kTendonDamping,       // tendon_damping of a tendon
  kTendonStiffness,     // tendon_stiffness of a tendon
  kTendonFrictionLoss,  // tendon_frictionloss of a tendon
  kTendonLengthSpring,  // tendon_lengthspring: 0 both ends (rest length), 1 lower, 2 upper end
  kGeomSolref,          // geom_solref[index] of a geom
  kGeomSolimp,          // geom_solimp[index] of a geom
  kPairSolref,          // pair_solref[index] of an explicit contact pair
  kPairSolimp,          // pair_solimp[index] of an explicit contact pair
  kPairFriction,        // pair_friction[index] of an explicit contact pair
  kActuatorKp,          // position gain of a position servo (gainprm[0], biasprm[1]) or pid
  kActuatorKv,          // velocity gain of a position/velocity servo or pid (biasprm[2], ...)
  kActuatorKi,          // integral gain of a pid actuator (gainprm[0])
  kBodyInertial,        // log-Cholesky variable [index] of a body's 10 inertial parameters
  kActuatorDelay,       // actuator_delay: the native delay of an actuator's control (history)
  kSensorDelay,         // sensor_delay: the native delay of a sensor's output (history)
  kDcMotorConstant,     // dcmotor: motor constant K (gainprm[1])
  kDcMotorResistance,   // dcmotor: resistance R (gainprm[0]; the inductance L kept)
  kDcMotorInductance,   // dcmotor: inductance L (dynprm[0] = L / R)
  kDcMotorCogging,      // dcmotor: cogging[index] (biasprm[index])
  kDcMotorLugre,        // dcmotor: lugre[index] (dynprm[5..6], biasprm[3..5])
  kField,               // any mjtNum array of mjModel, by field name and flat index
};

// Writes an identified value back into the MJCF element of its object.
//   element:    the object's element in the mjSpec (nullptr for kinds without an object)
//   identified: the compiled model with every identified value written (ParameterSet::Write)
//   id, index:  the object's id in identified, and the component
//   value:      the identified value
// Returns false when the kind has no MJCF attribute (the value is not written).
using MjcfWriter = bool (*)(mjsElement* element, const mjModel& identified, int id, int index,
                            double value);

// What a parameter kind is. One row per ParameterKind, in enum order.
struct ParameterKindInfo {
  ParameterKind kind;
  const char* name;          // YAML spelling, e.g. "joint_damping"
  mjtObj object;             // type of the object ParameterSpec::object names;
                             // mjOBJ_UNKNOWN: none (field: an mjModel array named in spec.field)
  int num_indices;           // valid indices [0, num_indices), the same for every object;
                             // 0: the size of the named mjModel array (field)
  const char* indices;       // what the index selects
  const char* units;         // units of the value
  const char* model_fields;  // the mjModel array(s) the value is written to
  int stage;                 // first pipeline stage the value enters
  bool set_const;            // derived constants depend on it: mj_setConst after writing
  const char* mjcf;          // how the value is written back into MJCF (for docs)
  MjcfWriter write_mjcf;     // that writer

  // display name of the object type: "body", "joint", "geom", "actuator"; "mjModel array" for
  // field
  const char* object_name() const;
};

// one array of mjModel (MJMODEL_POINTERS): its name, the byte offset of its pointer in mjModel,
// its number of entries in a model, its element type, and whether that type is mjtNum
struct ModelArray {
  const char* name;
  int offset;
  int size;
  const char* type;
  bool is_mjtnum;
};

// every array of mjModel with its size in m, in mjModel's order
std::vector<ModelArray> ModelArrays(const mjModel& m);

// Whether body b has no degree of freedom between it and the world (it and its ancestors without
// joints: welded to the world, or a mocap body): its mass, inertia and centre of mass move no
// state.
bool BodyWeldedToWorld(const mjModel& m, int b);

// The sensors of m that can read body b's mass, inertia or centre of mass when no state can: force
// and torque sensors at sites of b or of an ancestor (cfrc_int carries the subtree's weight),
// subtree sensors of b or of an ancestor, and user and plugin sensors (which may read anything).
// Parameter::Resolve refuses a body kind on a body welded to the world when this is empty.
std::vector<int> SensorsReadingBody(const mjModel& m, int b);

// every kind, in ParameterKind order
const std::vector<ParameterKindInfo>& ParameterKindTable();

// the row of a kind name; nullptr when unknown
const ParameterKindInfo* FindParameterKind(const std::string& name);

// the row of a kind
const ParameterKindInfo& ParameterKindInfoOf(ParameterKind kind);

// the YAML spelling of each kind: "body_mass", "body_mass_inertia", ..., "field"
const std::string& ParameterKindName(ParameterKind kind);
const std::vector<std::string>& ParameterKindNames();

struct ParameterSpec {
  std::string kind;    // one of ParameterKindNames()
  std::string object;  // body, joint, geom or actuator name (unused for "field")
  std::string field;   // mjModel field name for "field", e.g. "dof_damping"
  int index = 0;       // component: inertia/com axis, friction slot, gain/bias/gear entry,
                       // or the flat index into the field array
  std::string label;   // display name; defaults to "kind:object[index]"
};

// Checks what needs no model: the kind name, and the index against the kind's fixed range (every
// kind but field). Throws ParameterError (the same message Resolve gives).
void CheckParameterSpec(const ParameterSpec& spec);

// The number of valid indices of spec in m: the kind's num_indices, or the number of elements of
// the named mjModel array (field). Throws ParameterError for an unknown kind or array.
int ParameterIndexCount(const mjModel& m, const ParameterSpec& spec);

// A parameter resolved against one model: where it lives and how to write it.
class Parameter {
 public:
  // Throws ParameterError: unknown kind, object or array, index out of range, the world body,
  // a massless body for body_mass_inertia, an actuator without output for actuator_gear, an
  // actuator that is not a servo of the gain's kind (actuator_kp/kv/ki), a body whose inertial
  // is not strictly physically consistent (body_inertial: no log-Cholesky variables), an actuator
  // or sensor without a history buffer or with zero-order-hold interpolation (its delay would have
  // no derivative) for actuator_delay/sensor_delay, an actuator that is not a <dcmotor> (or has no
  // inductance, for dcmotor_inductance) for the dcmotor kinds.
  static Parameter Resolve(const mjModel& m, const ParameterSpec& spec);

  const std::string& label() const { return label_; }
  ParameterKind kind() const { return info_->kind; }
  const ParameterKindInfo& info() const { return *info_; }
  int id() const { return id_; }  // object id; -1 for field
  int index() const { return index_; }
  int stage() const { return info_->stage; }
  bool needs_set_const() const { return info_->set_const; }

  // the value currently in m
  double Read(const mjModel& m) const;

  // writes value into m without recomputing derived constants (see ParameterSet::Write)
  void WriteRaw(mjModel* m, double value) const;

  // turns off the engine shortcuts that would ignore this parameter's edits (call once per model)
  void Prepare(mjModel* m) const;

 private:
  Parameter() = default;

  const ParameterKindInfo* info_ = nullptr;  // a row of ParameterKindTable()
  std::string label_;
  int id_ = -1;            // object id
  int index_ = 0;          // component index
  int field_offset_ = -1;  // byte offset of the mjtNum array in mjModel (kField)
  int field_size_ = 0;     // number of entries of the array (kField)
  double ref_mass_ = 0;    // kBodyMassInertia: mass and inertia at resolution
  double ref_inertia_[3] = {0, 0, 0};
  // servo kinds: the actuator's form, which decides where a gain lives
  enum class Servo { kNone, kPosition, kVelocity, kPid };
  Servo servo_ = Servo::kNone;
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
