#include "core/state_sensors.h"

namespace mjsysid {

StateSensorPlan PlanStateSensors(const mjModel& m) {
  StateSensorPlan plan;
  // sleeping sensors keep old values; a model without sensors has nothing to copy
  if (m.nsensor == 0 || (m.opt.enableflags & mjENBL_SLEEP)) return plan;
  for (int i = 0; i < m.nsensor; ++i) {
    const int type = m.sensor_type[i], j = m.sensor_objid[i];
    const bool encoder = type == mjSENS_JOINTPOS || type == mjSENS_JOINTVEL;
    // hinge and slide joints only: one qpos and one dof
    const bool one_dof = m.sensor_objtype[i] == mjOBJ_JOINT &&
                         (m.jnt_type[j] == mjJNT_HINGE || m.jnt_type[j] == mjJNT_SLIDE);
    // a history buffer (delay, interval) may supply the value instead of the state
    const bool history = m.sensor_history && m.sensor_history[2 * i] > 0;
    if (!encoder || !one_dof || history || m.sensor_dim[i] != 1 ||
        m.sensor_datatype[i] != mjDATATYPE_REAL) {
      return StateSensorPlan();
    }
    StateSensorPlan::Copy c;
    c.adr = m.sensor_adr[i];
    c.qpos = type == mjSENS_JOINTPOS ? m.jnt_qposadr[j] : -1;
    c.qvel = type == mjSENS_JOINTVEL ? m.jnt_dofadr[j] : -1;
    c.cutoff = m.sensor_cutoff[i] > 0 ? m.sensor_cutoff[i] : 0;
    plan.copies.push_back(c);
  }
  plan.complete = true;
  return plan;
}

}  // namespace mjsysid
