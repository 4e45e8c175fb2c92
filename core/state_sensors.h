// Sensors that are plain copies of the state (issue 15, item 1: compute only what the fit needs).
//
// A joint encoder in MJCF is a jointpos or jointvel sensor: MuJoCo's sensor stage writes
// qpos[jnt_qposadr] or qvel[jnt_dofadr] into sensordata (then clamps at the cutoff, if any). When
// every sensor of a model is such a copy, a step can skip MuJoCo's sensor stage (its loops over
// all sensors, the per-sensor dispatch) and write the same numbers from the state it starts from:
// y_k is computed at x_k, before the integrator moves qpos and qvel. Bit for bit what MuJoCo
// writes (tested).
//
// Not copies (the plan is then incomplete and the sensor stage runs): any other sensor type, a
// jointpos/jointvel sensor of a ball or free joint, a sensor with a history buffer (delay,
// interval: its value may come from the buffer), user and plugin sensors, and every sensor of a
// model with sleeping enabled (MuJoCo skips sleeping sensors, leaving their old values).
#pragma once

#include <mujoco/mujoco.h>

#include <vector>

namespace mjsysid {

struct StateSensorPlan {
  struct Copy {
    int adr;        // sensordata index
    int qpos;       // qpos index, or -1
    int qvel;       // qvel index, or -1 (exactly one of qpos, qvel is >= 0)
    double cutoff;  // > 0: clamp to [-cutoff, cutoff] as MuJoCo does; 0: none
  };
  std::vector<Copy> copies;
  bool complete = false;  // every sensor of the model is a copy (and the model has sensors)
};

// The plan of m's sensors. Structure only: valid for every parameter value of m's copies.
StateSensorPlan PlanStateSensors(const mjModel& m);

// Writes the sensors of a complete plan into d->sensordata from d's qpos and qvel: call it before
// the step that would compute them (StepSkip with skipsensor = true). No allocation.
inline void CopyStateSensors(const StateSensorPlan& plan, mjData* d) {
  for (const StateSensorPlan::Copy& c : plan.copies) {
    double v = c.qpos >= 0 ? d->qpos[c.qpos] : d->qvel[c.qvel];
    // mju_clip's comparisons, in its order
    if (c.cutoff > 0) v = v < -c.cutoff ? -c.cutoff : (v > c.cutoff ? c.cutoff : v);
    d->sensordata[c.adr] = v;
  }
}

}  // namespace mjsysid
