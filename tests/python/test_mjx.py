"""RolloutModel's gradients against MJX automatic differentiation on the CPU, for the smooth models
of rollout_oracle.py (no constraints: the pendulum; no contacts: the free body).

An oracle independent of mjsysid and of finite differences: jax.grad of the same scalar loss
through mujoco.mjx.step in a jax.lax.scan (float64), against `lin.vjp` of a RolloutModel with
central differences. MJX's rollout is first checked to be MuJoCo's (states and sensors equal to
mj_step's, the loss to 1e-12 relative), so that the gradients compared are of the same physics.
mjx.step, as mj_step, leaves in sensordata the sensors of the state before the step: sensors
row k at state k with ctrl k, the convention of rollout_oracle.mj_rollout.

Tolerance: mjsysid's gradient chains central differences of single steps (step 1e-6): truncation
~h^2 (1e-12), rounding ~eps/h (1e-10) per entry, measured <= 4e-9 of the largest entry here;
1e-7 of the largest entry leaves 25x for other CPUs and is ~1e7 below what a sign flip (2) or a
gradient shifted by one step (0.8 to 1.1, asserted below) gives. MJX's XLA compilation of the
gradient takes 20 to 40 s per model on this machine (2 cores), the run a few ms.
"""

import mujoco
import numpy as np
import pytest

import mjsysid
from rollout_oracle import (FREE_BODY, PENDULUM, loss, loss_weights, mj_rollout, quaternion,
                            with_parameters)

jax = pytest.importorskip("jax")
mjx = pytest.importorskip("mujoco.mjx")
jax.config.update("jax_enable_x64", True)  # float64 (for this process), as test_jax.py

import jax.numpy as jnp  # noqa: E402

PENDULUM_DAMPING = [{"name": "damping", "target": "joint_damping", "object": "hinge"}]
RTOL = 1e-7  # of the largest entry of each gradient; see the module docstring


def mjx_loss(model, ws, wy, damping_dof=None):
    """loss(states, sensors) of the rollout by mjx.step, as a function of (x0, ctrl, params):
    params[0] written into dof_damping[damping_dof] (if given); the free joint's quaternion of x0
    normalised inside (the rollout is defined on q/|q|, so the gradient has no radial part)."""
    mx = mjx.put_model(model)
    nq, nv = model.nq, model.nv
    free = model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE

    def f(x0, ctrl, params):
        m = mx
        if damping_dof is not None:
            m = mx.replace(dof_damping=mx.dof_damping.at[damping_dof].set(params[0]))
        qpos = x0[:nq]
        if free:
            qpos = qpos.at[3:7].set(qpos[3:7] / jnp.linalg.norm(qpos[3:7]))
        dx = mjx.make_data(m).replace(qpos=qpos, qvel=x0[nq:nq + nv], act=x0[nq + nv:])

        def body(dx, u):
            dx = mjx.step(m, dx.replace(ctrl=u))  # its sensordata: at the state before the step
            return dx, (jnp.concatenate([dx.qpos, dx.qvel, dx.act]), dx.sensordata)

        _, (states, sensors) = jax.lax.scan(body, dx, ctrl)
        first = jnp.concatenate([qpos, x0[nq:]])[None]
        states = jnp.concatenate([first, states])
        return loss(states, sensors, ws, wy), (states, sensors)

    return f


def case(name):
    if name == "pendulum":
        model = mujoco.MjModel.from_xml_string(PENDULUM)
        x0 = np.array([0.4, -0.3])
        ctrl = np.random.default_rng(2).uniform(-1, 1, (15, 1))
        # damping 0.13, not the model's 0.1: the parameter is written, not read from the model
        return model, PENDULUM_DAMPING, x0, ctrl, np.array([0.13]), 0
    model = mujoco.MjModel.from_xml_string(FREE_BODY)
    # |q| = 1.3: the x0 gradient of both is that of the rollout from q/|q|
    x0 = np.concatenate([[0.1, -0.2, 1.0], 1.3 * quaternion(2.0, [1, -2, 0.5]),
                         [0.3, 0.1, -0.2], [1.5, -2.0, 3.0]])
    ctrl = np.random.default_rng(3).uniform(-1, 1, (15, 1))
    return model, [], x0, ctrl, np.zeros(0), None


@pytest.mark.parametrize("name", ["pendulum", "free_body"])
def test_vjp_equals_mjx_autodiff(name):
    model, parameters, x0, ctrl, params, damping_dof = case(name)
    ws, wy = loss_weights(model, len(ctrl))
    f = jax.jit(jax.value_and_grad(mjx_loss(model, ws, wy, damping_dof), argnums=(0, 1, 2),
                                   has_aux=True))
    (value, (states, sensors)), grads = f(x0, ctrl, params)

    # the same physics: MJX's rollout is mj_step's (rollout_oracle.mj_rollout, parameters written)
    m = with_parameters(model, parameters, params) if parameters else model
    mj_states, mj_sensors = mj_rollout(m, x0, ctrl)
    np.testing.assert_allclose(states, mj_states, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sensors, mj_sensors, rtol=0, atol=1e-12)
    assert float(value) == pytest.approx(loss(mj_states, mj_sensors, ws, wy), rel=1e-12)

    rm = mjsysid.RolloutModel(model, parameters=parameters, central=True)
    lin = rm.linearize(x0, ctrl, params)
    assert float(value) == pytest.approx(loss(lin.states, lin.sensors, ws, wy), rel=1e-12)
    got = lin.vjp(ws, wy * lin.sensors)
    for what, g, e in zip(("x0", "ctrl", "params"), got, grads):
        e = np.asarray(e)
        assert g.shape == e.shape, what
        if not e.size:
            continue
        scale = np.abs(e).max()
        assert scale > 0, what
        err = np.abs(g - e).max() / scale
        assert err < RTOL, (what, err)
        if what == "ctrl":
            # the comparison would see a wrong gradient: a sign flip or a one-step shift
            for wrong in (-g, np.roll(g, 1, axis=0)):
                assert np.abs(wrong - e).max() / scale > 100 * RTOL, what
