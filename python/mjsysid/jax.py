"""JAX gradients through MuJoCo rollouts (`import mjsysid.jax`; needs `pip install
"mjsysid[jax]"` and float64: `jax.config.update("jax_enable_x64", True)`).

`rollout` is a `jax.custom_vjp` function: its forward pass runs `RolloutModel.rollout` on the host
through `jax.pure_callback` (so it works under `jax.jit`), its backward pass recomputes the
nominal rollout with `RolloutModel.linearize` and applies that `Linearization`'s `vjp`, in a
second callback (docs/python.md, "Gradients through physics"). Under `jax.vmap` the callbacks
run once per element, one after the other; pass batched arrays instead to use the model's
threads.
"""

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["rollout"]


def _check_x64():
    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            "mjsysid.jax.rollout needs float64 arrays, which JAX disables by default: call "
            "jax.config.update('jax_enable_x64', True) at startup (or set JAX_ENABLE_X64=1)")


def _host(a):
    """A callback argument (a JAX array on the CPU) as the contiguous float64 array C++ takes."""
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64))


def _out_shapes(rm, x0, ctrl):
    """(states, sensors) shapes of RolloutModel.rollout, checked here at trace time: an exception
    inside a pure_callback is undefined behaviour for JAX."""
    if x0.ndim not in (1, 2) or x0.shape[-1] != rm.nstate:
        raise ValueError(f"x0 has shape {x0.shape}, expected ({rm.nstate},) or (B, {rm.nstate})")
    if ctrl.ndim not in (2, 3) or ctrl.shape[-1] != rm.nu:
        raise ValueError(f"ctrl has shape {ctrl.shape}, expected (T, {rm.nu}) or (B, T, {rm.nu})")
    if x0.ndim == 2 and ctrl.ndim == 3 and x0.shape[0] != ctrl.shape[0]:
        raise ValueError(f"x0 has {x0.shape[0]} rows but ctrl {ctrl.shape[0]} sequences")
    batch = x0.shape[:1] if x0.ndim == 2 else ctrl.shape[:-2]
    steps = ctrl.shape[-2]
    return (jax.ShapeDtypeStruct(batch + (steps + 1, rm.nstate), jnp.float64),
            jax.ShapeDtypeStruct(batch + (steps, rm.nsensordata), jnp.float64))


def _differentiable_rollout(rm, wrt):
    """A custom_vjp function (x0, ctrl, params) -> (states, sensors) of `rm`, whose backward
    pass computes the derivative blocks of `wrt` only (a params not in wrt gets zeros)."""

    def forward_host(x0, ctrl, params):
        return tuple(np.asarray(a) for a in rm.rollout(_host(x0), _host(ctrl), _host(params)))

    def vjp_host(x0, ctrl, params, states_grad, sensors_grad):
        lin = rm.linearize(_host(x0), _host(ctrl), _host(params), wrt=wrt)
        x0_grad, ctrl_grad, params_grad = lin.vjp(_host(states_grad), _host(sensors_grad))
        if params_grad is None:  # not in wrt: params were the model's own values (a constant)
            params_grad = np.zeros(np.shape(params))
        return np.asarray(x0_grad), np.asarray(ctrl_grad), np.asarray(params_grad)

    @jax.custom_vjp
    def f(x0, ctrl, params):
        return jax.pure_callback(forward_host, _out_shapes(rm, x0, ctrl), x0, ctrl, params,
                                 vmap_method="sequential")

    def fwd(x0, ctrl, params):
        # residuals: the inputs; the backward pass recomputes the rollout it linearizes
        return f(x0, ctrl, params), (x0, ctrl, params)

    def bwd(inputs, cotangents):
        shapes = tuple(jax.ShapeDtypeStruct(a.shape, jnp.float64) for a in inputs)
        return jax.pure_callback(vjp_host, shapes, *inputs, *cotangents,
                                 vmap_method="sequential")

    f.defvjp(fwd, bwd)
    return f


def rollout(rm, x0, ctrl, params=None):
    """Differentiable `rm.rollout(x0, ctrl, params)` for JAX (jit, grad, vjp, vmap).

    Args:
        rm: a `mjsysid.RolloutModel`.
        x0: initial state (nstate,) or (B, nstate): qpos, qvel, act (quaternions are normalised;
            their gradient is that of the normalised rollout).
        ctrl: controls (T, nu) or (B, T, nu), one row per time step of the model.
        params: (np,) parameter values in the units of their kinds (shared by the batch), or None
            for `rm.parameter_values()`, a constant without a gradient.

    Returns:
        (states, sensors): float64 arrays (B?, T+1, nstate) and (B?, T, nsensordata), batched
        iff x0 or ctrl is. Inputs are converted to float64 (a float32 input gets a float32
        gradient back).

    Raises:
        RuntimeError: float64 is not enabled in JAX.
        ValueError: shapes that do not fit the model.
    """
    _check_x64()
    x0 = jnp.asarray(x0, dtype=jnp.float64)
    ctrl = jnp.asarray(ctrl, dtype=jnp.float64)
    if params is None:
        params, wrt = jnp.asarray(rm.parameter_values(), dtype=jnp.float64), ("x0", "ctrl")
    else:
        params, wrt = jnp.asarray(params, dtype=jnp.float64), ("x0", "ctrl", "params")
    if params.shape != (rm.np,):
        raise ValueError(f"params has shape {params.shape}, expected ({rm.np},)")
    return _differentiable_rollout(rm, wrt)(x0, ctrl, params)
