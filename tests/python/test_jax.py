"""mjsysid.jax: jax.grad through RolloutModel rollouts under jax.jit, against the numpy vjp and
whole-rollout central differences of mujoco.mj_step alone (rollout_oracle.py)."""

import mujoco
import numpy as np
import pytest

import mjsysid
from rollout_oracle import FREE_BODY, PENDULUM, central_gradient, loss, loss_weights, quaternion

jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)  # mjsysid.jax needs float64 (for this process)

import jax.numpy as jnp  # noqa: E402
import mjsysid.jax as mjj  # noqa: E402

PENDULUM_DAMPING = [{"name": "damping", "target": "joint_damping", "object": "hinge"}]


def pendulum():
    rng = np.random.default_rng(2)
    rm = mjsysid.RolloutModel(PENDULUM, parameters=PENDULUM_DAMPING)
    return rm, np.array([0.4, -0.3]), rng.uniform(-1, 1, (15, 1)), rm.parameter_values()


@pytest.mark.parametrize("name", ["pendulum", "free_body"])
def test_jit_grad_equals_vjp_and_central_differences(name):
    if name == "pendulum":
        rm, x0, ctrl, params = pendulum()
        model, parameters = mujoco.MjModel.from_xml_string(PENDULUM), PENDULUM_DAMPING
    else:
        model, parameters = mujoco.MjModel.from_xml_string(FREE_BODY), []
        rm = mjsysid.RolloutModel(model)
        x0 = np.concatenate([[0.1, -0.2, 1.0], 1.3 * quaternion(2.0, [1, -2, 0.5]),
                             [0.3, 0.1, -0.2], [1.5, -2.0, 3.0]])
        ctrl, params = np.random.default_rng(3).uniform(-1, 1, (20, 1)), np.zeros(0)
    ws, wy = loss_weights(model, len(ctrl))

    @jax.jit
    def f(x0, ctrl, params):
        return loss(*mjj.rollout(rm, x0, ctrl, params), ws, wy)

    got = jax.grad(f, argnums=(0, 1, 2))(x0, ctrl, params)
    # the same Linearization from numpy: the wrapper adds nothing (1e-12: the same arithmetic)
    lin = rm.linearize(x0, ctrl, params)
    vjp = lin.vjp(ws, wy * lin.sensors)
    # the oracle; tolerance of per-step forward differences, as test_torch.py explains
    expected = central_gradient(model, parameters, x0, ctrl, params, ws, wy)
    for what, g, v, e in zip(("x0", "ctrl", "params"), got, vjp, expected):
        assert g.shape == e.shape and g.dtype == jnp.float64, what
        np.testing.assert_allclose(g, v, rtol=1e-12, atol=1e-14, err_msg=what)
        scale = np.abs(e).max() if e.size else 0.0
        np.testing.assert_allclose(g, e, rtol=1e-4, atol=1e-5 * scale, err_msg=what)
    assert f(x0, ctrl, params) == pytest.approx(loss(*rm.rollout(x0, ctrl, params), ws, wy),
                                                rel=1e-14)


def test_batched_shapes_and_vmap():
    rm, x0, ctrl, params = pendulum()
    xs = jnp.stack([x0, x0 + 0.1, x0 - 0.2])
    cs = jnp.stack([ctrl, -ctrl, 0.5 * ctrl])
    steps = len(ctrl)
    for x, c, batch in ((xs, cs, (3,)), (x0, cs, (3,)), (xs, ctrl, (3,)), (x0, ctrl, ())):
        states, sensors = jax.jit(lambda x, c: mjj.rollout(rm, x, c, params))(x, c)
        assert states.shape == batch + (steps + 1, 2) and sensors.shape == batch + (steps, 2)
        np.testing.assert_array_equal(states, rm.rollout(np.asarray(x), np.asarray(c), params)[0])

    def total(x, c, p):
        states, sensors = mjj.rollout(rm, x, c, p)
        return (states**2).sum() + sensors.sum()

    # a batch's gradient: per sequence for x0 and ctrl, summed for params; vmap (one callback per
    # element) gives the same as the batched call (one callback, the model's threads)
    gx, gc, gp = jax.jit(jax.grad(total, argnums=(0, 1, 2)))(xs, cs, params)
    single = [jax.grad(total, argnums=(0, 1, 2))(x, c, params) for x, c in zip(xs, cs)]
    np.testing.assert_allclose(gx, np.stack([s[0] for s in single]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(gc, np.stack([s[1] for s in single]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(gp, sum(s[2] for s in single), rtol=1e-12)
    vx = jax.vmap(jax.grad(total), in_axes=(0, 0, None))(xs, cs, params)
    np.testing.assert_allclose(vx, gx, rtol=1e-12, atol=1e-14)


def test_params_none_is_the_model_values_without_gradient():
    rm, x0, ctrl, params = pendulum()

    def f(x, c, p=None):
        return mjj.rollout(rm, x, c, p)[1].sum()

    np.testing.assert_array_equal(jax.grad(f)(x0, ctrl), jax.grad(f)(x0, ctrl, params))
    assert f(x0, ctrl) == f(x0, ctrl, params)


def test_needs_x64_and_fitting_shapes():
    rm, x0, ctrl, params = pendulum()
    jax.config.update("jax_enable_x64", False)
    try:
        with pytest.raises(RuntimeError, match="jax_enable_x64"):
            mjj.rollout(rm, x0, ctrl, params)
    finally:
        jax.config.update("jax_enable_x64", True)
    with pytest.raises(ValueError, match="ctrl"):
        mjj.rollout(rm, x0, ctrl[:, [0, 0]], params)
    with pytest.raises(ValueError, match="params"):
        mjj.rollout(rm, x0, ctrl, np.zeros(2))
