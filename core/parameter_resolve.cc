// Parameter specs checked and resolved against a model (core/parameters.h): names and hints for
// the errors, the arrays of mjModel, CheckParameterSpec, ParameterIndexCount and
// Parameter::Resolve.
#include <mujoco/mjxmacro.h>

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "core/inertia_cholesky.h"
#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/text.h"

namespace mjsysid {
namespace {

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

// ParameterError when a body's mass, inertia or centre of mass can move neither a state nor a
// sensor (in exact arithmetic its Jacobian column is zero; computed, it is rounding noise)
void CheckBodyCanAct(const mjModel& m, const ParameterKindInfo& info, const ParameterSpec& spec,
                     int b) {
  if (!BodyWeldedToWorld(m, b) || !SensorsReadingBody(m, b).empty()) return;
  const char* what = info.kind == ParameterKind::kBodyMass      ? "its mass"
                     : info.kind == ParameterKind::kBodyCom     ? "its centre of mass"
                     : info.kind == ParameterKind::kBodyInertia ? "its inertia"
                                                                : "its mass and inertia";
  throw ParameterError(
      ParameterSpecPart::kObject,
      std::string(info.name) + ": body '" + spec.object + "' is welded to the world" +
          (m.body_mocapid[b] >= 0 ? " (a mocap body)" : "") +
          " (no joint between it and the world): " + what +
          " cannot move any state, and no force, torque or subtree sensor reads it",
      "fit a body that moves, or remove the parameter");
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

bool BodyWeldedToWorld(const mjModel& m, int b) {
  for (; b > 0; b = m.body_parentid[b]) {
    if (m.body_dofnum[b] > 0) return false;
  }
  return true;
}

std::vector<int> SensorsReadingBody(const mjModel& m, int b) {
  std::vector<int> out;
  for (int s = 0; s < m.nsensor; ++s) {
    const int type = m.sensor_type[s];
    int body = -1;
    if (type == mjSENS_USER || type == mjSENS_PLUGIN) {
      out.push_back(s);
      continue;
    } else if (type == mjSENS_FORCE || type == mjSENS_TORQUE) {
      body = m.site_bodyid[m.sensor_objid[s]];
    } else if (type == mjSENS_SUBTREECOM || type == mjSENS_SUBTREELINVEL ||
               type == mjSENS_SUBTREEANGMOM) {
      body = m.sensor_objid[s];
    } else {
      continue;
    }
    for (int a = b; a >= 0; a = a > 0 ? m.body_parentid[a] : -1) {
      if (a == body) {
        out.push_back(s);
        break;
      }
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// errors and model-free checks

ParameterError::ParameterError(const std::string& message)
    : ParameterError(ParameterSpecPart::kNone, message) {}

ParameterError::ParameterError(ParameterSpecPart part, const std::string& message,
                               const std::string& hint)
    : std::runtime_error(hint.empty() ? message : message + " (hint: " + hint + ")"),
      part_(part),
      message_(message),
      hint_(hint) {}

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
      CheckBodyCanAct(m, info, spec, p.id_);
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
      CheckBodyCanAct(m, info, spec, p.id_);
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

}  // namespace mjsysid
