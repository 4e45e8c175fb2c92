"""Models and the independent oracle of the gradient tests (test_torch.py, test_jax.py).

The oracle rolls out with the `mujoco` package alone (mj_step in a loop, the parameters written
into a copy of the MjModel here) and differentiates a scalar loss of the whole rollout by central
differences: it shares no code with mjsysid's step-by-step linearization.
"""

import copy

import mujoco
import numpy as np

# one hinge with damping (no friction loss: smooth), a motor, joint position and velocity sensors
PENDULUM = """
<mujoco model="pendulum_grad">
  <option timestep="0.01"/>
  <worldbody>
    <body name="pole" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="0.2"/>
      <geom type="sphere" pos="0 0 -0.5" size="0.05" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor name="torque" joint="hinge" gear="2"/></actuator>
  <sensor>
    <jointpos name="angle" joint="hinge"/>
    <jointvel name="rate" joint="hinge"/>
  </sensor>
</mujoco>
"""

# a free-floating box pushed and twisted by a motor (6-vector gear), under gravity, with no
# collision (contype 0): smooth; an asymmetric inertia makes the rotation gyroscopic
FREE_BODY = """
<mujoco model="free_body_grad">
  <option timestep="0.01"/>
  <worldbody>
    <body name="box" pos="0 0 1">
      <freejoint name="free"/>
      <geom type="box" size="0.2 0.1 0.05" mass="2" contype="0" conaffinity="0"/>
      <site name="tip" pos="0.2 0.1 0"/>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="free" gear="1 0.5 2 0.3 -0.2 0.1"/></actuator>
  <sensor>
    <framepos name="tip_pos" objtype="site" objname="tip"/>
    <framequat name="box_quat" objtype="body" objname="box"/>
    <gyro name="box_gyro" site="tip"/>
  </sensor>
</mujoco>
"""

# two hinges driven through activation dynamics (na = 2): a first-order filter (time constant
# 0.05 s) and an integrator; the actuator force depends on the activation state
ACTIVATION = """
<mujoco model="activation_grad">
  <option timestep="0.005"/>
  <worldbody>
    <body name="a" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0" damping="0.2"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5"/>
      <body name="b" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 1 0" damping="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.3"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <general name="filtered" joint="j1" dyntype="filter" dynprm="0.05" gainprm="1"/>
    <general name="integrated" joint="j2" dyntype="integrator" gainprm="0.5"/>
  </actuator>
  <sensor>
    <jointpos joint="j1"/><jointpos joint="j2"/>
    <jointvel joint="j1"/><jointvel joint="j2"/>
    <actuatorfrc actuator="filtered"/><actuatorfrc actuator="integrated"/>
  </sensor>
</mujoco>
"""

# models/arm7.xml's parameters of the tests: armature (mj_setConst after the write) and damping
ARM7_PARAMETERS = [
    {"name": "j2_armature", "target": "joint_armature", "object": "j2"},
    {"name": "j5_armature", "target": "joint_armature", "object": "j5"},
    {"name": "j3_damping", "target": "joint_damping", "object": "j3"},
    {"name": "j6_damping", "target": "field", "field": "dof_damping", "index": 5},
]


def with_parameters(model, parameters, values):
    """A copy of `model` with the parameters (joint_damping, joint_armature, field) written."""
    m = copy.copy(model)
    for p, v in zip(parameters, values):
        if p["target"] == "field":
            getattr(m, p["field"]).reshape(-1)[p.get("index", 0)] = v
            continue
        joint = m.joint(p["object"])
        dofs = slice(joint.dofadr[0], joint.dofadr[0] + {0: 6, 1: 3}.get(joint.type[0], 1))
        field = {"joint_damping": "dof_damping", "joint_armature": "dof_armature"}[p["target"]]
        getattr(m, field)[dofs] = v
    mujoco.mj_setConst(m, mujoco.MjData(m))  # as the kind table says for armature and fields
    return m


def mj_rollout(model, x0, ctrl):
    """(states (T+1, nstate), sensors (T, nsensordata)) by mj_step, the spec's convention:
    row 0 is x0 with its quaternions normalised, sensors k at state k with ctrl k."""
    d = mujoco.MjData(model)
    nq, nv = model.nq, model.nv
    d.qpos, d.qvel, d.act = x0[:nq], x0[nq:nq + nv], x0[nq + nv:]
    mujoco.mj_normalizeQuat(model, d.qpos)
    states, sensors = [np.concatenate([d.qpos, d.qvel, d.act])], []
    for u in ctrl:
        d.ctrl = u
        mujoco.mj_step(model, d)  # its sensordata: evaluated at the state before the step
        sensors.append(d.sensordata.copy())
        states.append(np.concatenate([d.qpos, d.qvel, d.act]))
    return np.array(states), np.array(sensors).reshape(len(ctrl), model.nsensordata)


def loss_weights(model, steps, seed=0):
    """Fixed random weights of the test loss: sum(ws * states) + sum(wy * sensors**2) / 2."""
    rng = np.random.default_rng(seed)
    nstate = model.nq + model.nv + model.na
    return rng.normal(size=(steps + 1, nstate)), rng.normal(size=(steps, model.nsensordata))


def loss(states, sensors, ws, wy):
    return (ws * states).sum() + 0.5 * (wy * sensors**2).sum()


def central_gradient(model, parameters, x0, ctrl, params, ws, wy, h=1e-5):
    """d loss / d (x0, ctrl, params) of the whole mj_step rollout by central differences.

    Step h relative to max(1, |value|): the truncation error is h^2 times the loss's third
    derivative (~1e-10 here), the rounding error ~1e-16 |loss| / h (~1e-10): the oracle is good
    to ~1e-9, far below the differences a wrong gradient makes.
    """

    def f(x0, ctrl, params):
        m = with_parameters(model, parameters, params) if parameters else model
        return loss(*mj_rollout(m, x0, ctrl), ws, wy)

    args = [np.array(a, dtype=np.float64) for a in (x0, ctrl, params)]
    grads = []
    for i, a in enumerate(args):
        g = np.zeros_like(a)
        for j in np.ndindex(a.shape):
            step = h * max(1.0, abs(a[j]))
            hi, lo = [b.copy() for b in args], [b.copy() for b in args]
            hi[i][j] += step
            lo[i][j] -= step
            g[j] = (f(*hi) - f(*lo)) / (2 * step)
        grads.append(g)
    return grads


def quaternion(angle, axis):
    """The unit quaternion (w, x, y, z) of a rotation by `angle` (rad) about `axis`."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
