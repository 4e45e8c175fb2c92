// Fitted sensors that jump at contact events: see sysid/contact_channels.h.
#include "sysid/data/contact_channels.h"

#include <string>
#include <vector>

namespace mjsysid {

const char* JumpingSensorType(const mjModel& m, int sensor_id) {
  switch (m.sensor_type[sensor_id]) {
    case mjSENS_TOUCH:
      return "touch";
    case mjSENS_ACCELEROMETER:
      return "accelerometer";
    case mjSENS_FORCE:
      return "force";
    case mjSENS_TORQUE:
      return "torque";
    default:
      return nullptr;
  }
}

std::vector<std::string> DiscontinuousChannelWarnings(const mjModel& m,
                                                      const std::vector<std::string>& fitted,
                                                      const std::vector<Trajectory>& rollouts) {
  // contact-count changes over the rollouts (none: no contact event moves, nothing jumps)
  long long changes = 0, steps = 0;
  for (const Trajectory& t : rollouts) {
    for (size_t k = 1; k < t.ncon.size(); ++k) changes += t.ncon[k] != t.ncon[k - 1] ? 1 : 0;
    steps += static_cast<long long>(t.ncon.size());
  }
  std::vector<std::string> out;
  if (changes == 0) return out;
  // the sensor types whose reading jumps with a contact (touch) or spikes at an impact
  for (const std::string& name : fitted) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
    if (id < 0) continue;
    const char* type = JumpingSensorType(m, id);
    if (!type) continue;
    out.push_back("sensor '" + name + "' (" + type +
                  ") jumps when a contact switches on or off (the rollouts at the initial values "
                  "change their contact count " +
                  std::to_string(changes) + " times in " + std::to_string(steps) +
                  " steps): a contact one step earlier or later moves its residual by the whole "
                  "contact force, so the cost is rugged in every parameter that moves a contact; "
                  "leave it out of the fit or give it a sigma that covers a contact one step off "
                  "(docs/numerics.md, \"Contact: a rugged cost\")");
  }
  return out;
}

}  // namespace mjsysid
