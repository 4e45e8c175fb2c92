// Fitted sensors that jump when a contact switches on or off (docs/numerics.md, "Contact: a rugged
// cost"; docs/stress.md, robust suite).
//
// A touch sensor reads the normal force of the contacts in its site and zero without them; an
// accelerometer, force or torque sensor reads an impulse spread over one step at an impact. When a
// parameter moves a contact one step earlier or later, the residuals of such a sensor change by
// the whole contact force at that step: the cost jumps, in every parameter that moves the contact,
// at steps far below the standard errors. Measured on the robust suite's finger (10-step segments
// from the logged states, continuity weight 100): 68 % worst error with its fingertip touch sensor
// fitted, 1.0 % without it; at the end of the hopper's fit the weighted residual variance was
// 2.3e3 for its foot touch sensor and 415 for its torso accelerometer against 3-95 for the rest.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "core/simulator.h"

namespace mjsysid {

// "touch", "accelerometer", "force" or "torque" for a sensor of those types (their reading jumps
// with a contact or spikes at an impact), nullptr for any other
const char* JumpingSensorType(const mjModel& m, int sensor_id);

// One warning per fitted sensor (names in `fitted`) of type touch, accelerometer, force or torque
// when the rollouts of this model (at the initial values) change their contact count at least once
// (Trajectory::ncon); none otherwise. Each names the sensor, its type and the contact-count
// changes counted, and what the user can do.
std::vector<std::string> DiscontinuousChannelWarnings(const mjModel& m,
                                                      const std::vector<std::string>& fitted,
                                                      const std::vector<Trajectory>& rollouts);

}  // namespace mjsysid
