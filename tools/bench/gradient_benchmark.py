#!/usr/bin/env python3
"""gradient_benchmark: the gradient of a scalar loss over a rollout (issue 37, item 4).

Methods, each timed end to end (the nominal rollout, the derivatives and the reverse pass):

  chained  implemented plainly in Python with `mujoco` and numpy, per sequence and time step:
           mjd_transitionFD(eps=1e-6, forward) at the nominal state (A, B, C, D), one mj_step
           per parameter from the same state (mj_getState / mj_setState, mjSTATE_INTEGRATION) on a
           copy of the model with that parameter moved by h_j = 1e-6 max(|p_j|, 1e-3) (copies
           made once per gradient; mj_setConst after the write where the kind needs it, as
           mjsysid does: joint_armature), then the nominal mj_step; then the reverse pass in numpy:
             lambda_T = dL/dx_T, lambda_k = dL/dx_k + A_k' lambda_k+1 + C_k' dL/dy_k,
             dL/du_k = B_k' lambda_k+1 + D_k' dL/dy_k, dL/dp += F_k' lambda_k+1 + G_k' dL/dy_k
           (states in MuJoCo's tangent space). 2 threads: the batch's sequences over a
           ThreadPoolExecutor, one MjData per task (B = 1 has nothing to share out).
  mjsysid  rm = mjsysid.RolloutModel(model, parameters, threads=N) (built before the clock);
           lin = rm.linearize(x0, ctrl, params); lin.vjp(states_grad, sensors_grad).
  mjx      (optional, arm7 only) jax.value_and_grad of the same loss through mujoco.mjx.step in
           a jax.lax.scan, vmapped over the batch, float64, jit-compiled per cell (lower +
           compile timed apart, `compile` in the method column). MJX's
           constraint solver is a while_loop that reverse mode cannot differentiate unless
           opt.iterations = 1, so MJX runs arm7 with one solver iteration (its only constraint is
           j1's friction loss; `loss vs MuJoCo` shows whether the physics is still MuJoCo's). The
           humanoid (contacts, limits) is not run: the same one-iteration solver would be another
           model. `threads` = the CPUs the process is pinned to (XLA picks its own threads).

Cases: models/arm7.xml (7 hinges, position servos; parameters: joint_damping and joint_armature
of its 7 joints, 14) and models/outside/humanoid27.xml (27 dof, free base, contacts; parameters:
joint_damping of 6 hinges). x0 = the model's qpos0 at rest (the humanoid's feet start 1.5 cm
above the floor and touch it at step 11: T = 5 has no contact, T = 200 falls and lies on the
floor); ctrl = smooth random controls (seeded; cosine-interpolated knots every 0.1 s, 60 % of the
half range about the centre of ctrlrange), one sequence per batch member.

Loss: L = sum over the batch of sum_k=0..T ||qvel_k||^2 + sum_k=0..T-1 ||sensors_k||^2 (no qpos,
so no coordinate/tangent map enters dL/dx); gradients w.r.t. ctrl (B x T x nu), the parameters
(summed over the batch) and x0 (shared by the batch; mjsysid's in coordinates, chained's in the
tangent space, compared through directional derivatives).

Errors: against whole-rollout central differences of L (plain mj_step rollouts) along a few
random directions per input: ctrl (N(0, 1) entries), parameters (N(0, p_j^2): relative), x0 in
the tangent space (x0 (+) h v, N(0, 1) entries); the loss is piecewise smooth (friction loss,
contacts and limits switch), so the step is h = 1e-8: relative error = ||(g.v_i - ref_i)_i|| /
||(ref_i)_i||. The second table: the reference's own noise (the same between steps 1e-8 and
1e-7), steps with contacts, changes of the number of active constraints from step to step,
||g_chained - g_mjsysid|| / ||g_mjsysid|| over the whole ctrl and parameter gradients, and the
same between a method's 1- and 2-thread gradients. `time / mjsysid's`: a method's time over
mjsysid's at the same threads (chained's: the speed-up of mjsysid).

Timing: the median of the runs; a first run under 1 s is an untimed warm-up; at least --repeats
runs (3), more (up to 25) while they add up to less than --budget s (1); a run longer than --slow
s (60) ends the repeats. `runs` says how many were timed.

The GIL probe: a worker thread makes one long MuJoCo call (mj_step(nstep), mjd_transitionFD on a
120-link chain); the main thread sleeps 10 ms and notes when it runs again: before the call's end
means the binding released the GIL.

usage: .venv/bin/python tools/bench/gradient_benchmark.py [--quick] [--json PATH]
         [--models arm7,humanoid] [--T 5,200] [--B 1,20] [--threads 1,2] [--repeats 3]
         [--methods chained,mjsysid,mjx] [--slow S] [--budget S] [--directions N]
         [--mjx-site DIR] [--gil]
`--quick`: T 5,20, B 1,2, 1 run, budget 0, 2 directions, no MJX and no GIL probe unless asked
(--methods ..., --gil): a smoke test of < 20 s. mjsysid must be importable (PYTHONPATH); without
it the mjsysid rows are skipped with a note. MJX: `mujoco.mjx` importable, or installed with
`pip install --target DIR --no-deps mujoco-mjx==3.17.0 jax==0.10.2 jaxlib==0.10.2 ml_dtypes
opt_einsum absl-py etils fsspec trimesh zipp` (no mujoco-mjx 4.0.0 exists; 3.17.0 runs on mujoco
4.0.0 here) and given as --mjx-site DIR (or $MJX_SITE).
"""
import argparse
import copy
import json
import os
import platform
import statistics
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

ARM7_JOINTS = [f"j{i}" for i in range(1, 8)]
HUMANOID_JOINTS = ["abdomen_y", "hip_y_right", "knee_right", "hip_y_left", "knee_left",
                   "elbow_right"]
CASES = {
    "arm7": {
        "path": "models/arm7.xml",
        "parameters": [{"target": "joint_damping", "object": j, "name": f"{j}_damping"}
                       for j in ARM7_JOINTS]
        + [{"target": "joint_armature", "object": j, "name": f"{j}_armature"}
           for j in ARM7_JOINTS],
    },
    "humanoid": {
        "path": "models/outside/humanoid27.xml",
        "parameters": [{"target": "joint_damping", "object": j, "name": f"{j}_damping"}
                       for j in HUMANOID_JOINTS],
    },
}
# parameter kind -> (mjModel array indexed by the joint's first dof, mj_setConst after a write);
# docs/experiment-schema.md's kind table
KINDS = {"joint_damping": ("dof_damping", False), "joint_armature": ("dof_armature", True)}

EPS = 1e-6          # state and control step of mjd_transitionFD (mjsysid's state_step)
REL_STEP = 1e-6     # parameter step h_j = REL_STEP * max(|p_j|, STEP_FLOOR) (mjsysid's default)
STEP_FLOOR = 1e-3
SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
# the reference's central-difference steps along a direction (ctrl and x0: absolute, the
# direction ~ N(0, 1) per entry; parameters: relative, the direction ~ N(0, p_j^2)): the loss is
# piecewise smooth (friction loss, contacts, limits switch), so steps past ~1e-6 cross kinks
# (arm7 T=200: the derivative moves by 1e-3 at h = 1e-4; the humanoid's by orders of magnitude,
# and its x0 derivative still by 2e-2 at h = 1e-7, T=200); 1e-8 is the reference, and its
# relative difference to 1e-7 is reported as the reference's noise
REF_STEPS = (1e-8, 1e-7)


def loadavg():
    with open("/proc/loadavg") as f:
        return f.read().split()[0:3]


# ------------------------------------------------------------------------------------------
# the case: model, parameters, inputs

class Case:
    def __init__(self, name, T, B, seed):
        spec = CASES[name]
        self.name, self.T, self.B = name, T, B
        self.path = os.path.join(ROOT, spec["path"])
        self.m = mujoco.MjModel.from_xml_path(self.path)
        m = self.m
        self.parameters = spec["parameters"]
        self.pfield, self.pindex, self.psetconst = [], [], []
        for p in self.parameters:
            field, setconst = KINDS[p["target"]]
            self.pfield.append(field)
            self.pindex.append(int(m.jnt_dofadr[m.joint(p["object"]).id]))
            self.psetconst.append(setconst)
        self.np = len(self.parameters)
        self.p0 = np.array([getattr(m, f)[i] for f, i in zip(self.pfield, self.pindex)])
        self.nq, self.nv, self.na, self.nu = m.nq, m.nv, m.na, m.nu
        self.ns = m.nsensordata
        self.nstate = m.nq + m.nv + m.na
        self.nt = 2 * m.nv + m.na
        self.x0 = np.concatenate([m.qpos0, np.zeros(m.nv), np.zeros(m.na)])
        self.ctrl = smooth_controls(m, T, B, seed)

    def model_at(self, p):
        """a copy of the model with the parameter values p written (mj_setConst where needed)"""
        mc = copy.copy(self.m)
        setconst = False
        for j in range(self.np):
            getattr(mc, self.pfield[j])[self.pindex[j]] = p[j]
            setconst = setconst or self.psetconst[j]
        if setconst:
            mujoco.mj_setConst(mc, mujoco.MjData(mc))
        return mc

    def steps(self, p):
        return REL_STEP * np.maximum(np.abs(p), STEP_FLOOR)

    def perturbed_models(self, p):
        h = self.steps(p)
        out = []
        for j in range(self.np):
            q = p.copy()
            q[j] += h[j]
            out.append((self.model_at(q), h[j]))
        return out

    def rm_parameters(self):
        return [dict(p) for p in self.parameters]


def smooth_controls(m, T, B, seed):
    """(B, T, nu): cosine-interpolated random knots every 0.1 s, 60 % of the half range"""
    rng = np.random.default_rng(seed)
    lo, hi = m.actuator_ctrlrange[:, 0].copy(), m.actuator_ctrlrange[:, 1].copy()
    unlimited = ~m.actuator_ctrllimited.astype(bool)
    lo[unlimited], hi[unlimited] = -1.0, 1.0
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    every = max(1, int(round(0.1 / m.opt.timestep)))
    nknot = T // every + 2
    knots = centre + 0.6 * half * rng.uniform(-1, 1, size=(B, nknot, m.nu))
    k = np.arange(T)
    i, s = k // every, (k % every) / every
    w = (0.5 - 0.5 * np.cos(np.pi * s))[None, :, None]
    return (1 - w) * knots[:, i, :] + w * knots[:, i + 1, :]


def set_x0(m, d, x0):
    mujoco.mj_resetData(m, d)
    d.qpos[:] = x0[:m.nq]
    d.qvel[:] = x0[m.nq:m.nq + m.nv]
    d.act[:] = x0[m.nq + m.nv:]


# ------------------------------------------------------------------------------------------
# plain rollouts and the loss (the reference)

def rollout_loss(m, x0, U):
    """L of one sequence, its number of steps with contacts and of changes of the number of
    active constraints (contacts, limits, friction loss) from one step to the next"""
    d = mujoco.MjData(m)
    set_x0(m, d, x0)
    loss = float(d.qvel @ d.qvel)
    contact_steps, changes, nefc = 0, 0, None
    for k in range(U.shape[0]):
        d.ctrl[:] = U[k]
        mujoco.mj_step(m, d)
        loss += float(d.sensordata @ d.sensordata) + float(d.qvel @ d.qvel)
        contact_steps += d.ncon > 0
        changes += nefc is not None and d.nefc != nefc
        nefc = d.nefc
    return loss, contact_steps, changes


def batch_loss(case, p, x0, U):
    m = case.model_at(p)
    return sum(rollout_loss(m, x0, U[b])[0] for b in range(U.shape[0]))


def tangent_add(m, x0, v, h):
    """x0 (+) h v (v in the tangent space: dqpos nv, dqvel nv, dact na)"""
    qpos = x0[:m.nq].copy()
    mujoco.mj_integratePos(m, qpos, v[:m.nv], h)
    return np.concatenate([qpos, x0[m.nq:] + h * v[m.nv:]])


def coordinate_direction(m, x0, v):
    """d/dh of the coordinates of x0 (+) h v at h = 0 (central, h = 1e-6: exact to ~1e-12)"""
    h = 1e-6
    return (tangent_add(m, x0, v, h) - tangent_add(m, x0, v, -h)) / (2 * h)


def reference(case, ndir, seed):
    """central differences of L along random directions: per input (ctrl, params, x0) the
    directions and the derivatives with the steps REF_STEPS"""
    rng = np.random.default_rng(seed + 1000)
    p, x0, U = case.p0, case.x0, case.ctrl
    out = {}
    L0 = batch_loss(case, p, x0, U)

    def cd(f):
        return tuple((f(h) - f(-h)) / (2 * h) for h in REF_STEPS)

    dirs = [rng.standard_normal(U.shape) for _ in range(ndir)]
    out["ctrl"] = (dirs, [cd(lambda t: batch_loss(case, p, x0, U + t * v)) for v in dirs])
    dirs = [rng.standard_normal(case.np) * np.abs(p) for _ in range(ndir)]
    out["params"] = (dirs, [cd(lambda t: batch_loss(case, p + t * v, x0, U)) for v in dirs])
    dirs = [rng.standard_normal(case.nt) for _ in range(ndir)]
    out["x0"] = (dirs, [cd(lambda t: batch_loss(case, p, tangent_add(case.m, x0, v, t), U))
                        for v in dirs])
    return L0, out


def directional(case, grads, kind, v):
    """g . v for a method's gradients (x0 in tangent space when grads['x0_tangent'])"""
    if kind == "x0":
        if grads.get("x0_tangent", False):
            return float(grads["x0"] @ v)
        return float(grads["x0"] @ coordinate_direction(case.m, case.x0, v))
    return float(np.sum(grads[kind] * v))


def errors(case, grads, ref):
    res = {}
    for kind, (dirs, vals) in ref.items():
        if grads.get(kind) is None:
            res[kind] = None
            continue
        r = np.array([a for a, _ in vals])
        g = np.array([directional(case, grads, kind, v) for v in dirs])
        res[kind] = float(np.linalg.norm(g - r) / max(np.linalg.norm(r), 1e-300))
    return res


def reference_noise(ref):
    res = {}
    for kind, (_, vals) in ref.items():
        a = np.array([x for x, _ in vals])
        b = np.array([y for _, y in vals])
        res[kind] = float(np.linalg.norm(a - b) / max(np.linalg.norm(a), 1e-300))
    return res


# ------------------------------------------------------------------------------------------
# chained per-step finite differences

def chained_sequence(m, perturbed, x0, U):
    """(loss, dL/dx0 in tangent space, dL/dU (T, nu), dL/dp) of one sequence"""
    T, nu = U.shape
    nq, nv, na, ns = m.nq, m.nv, m.na, m.nsensordata
    nt, npar = 2 * nv + na, len(perturbed)
    A = np.zeros((T, nt, nt))
    Bm = np.zeros((T, nt, nu))
    C = np.zeros((T, ns, nt))
    D = np.zeros((T, ns, nu))
    F = np.zeros((T, nt, npar))
    G = np.zeros((T, ns, npar))
    qvel = np.zeros((T + 1, nv))
    Y = np.zeros((T, ns))
    d = mujoco.MjData(m)
    d2 = mujoco.MjData(m)
    set_x0(m, d, x0)
    qvel[0] = d.qvel
    state = np.zeros(mujoco.mj_stateSize(m, SPEC))
    pq = np.zeros((npar, nq))
    pv = np.zeros((npar, nv))
    pa = np.zeros((npar, na))
    py = np.zeros((npar, ns))
    col = np.zeros(nv)
    for k in range(T):
        d.ctrl[:] = U[k]
        mujoco.mjd_transitionFD(m, d, EPS, False, A[k], Bm[k], C[k], D[k])
        mujoco.mj_getState(m, d, state, SPEC)
        for j, (mj, _) in enumerate(perturbed):
            mujoco.mj_setState(mj, d2, state, SPEC)
            mujoco.mj_step(mj, d2)
            pq[j], pv[j], pa[j], py[j] = d2.qpos, d2.qvel, d2.act, d2.sensordata
        mujoco.mj_step(m, d)
        for j, (_, h) in enumerate(perturbed):
            mujoco.mj_differentiatePos(m, col, h, d.qpos, pq[j])
            F[k, :nv, j] = col
            F[k, nv:2 * nv, j] = (pv[j] - d.qvel) / h
            F[k, 2 * nv:, j] = (pa[j] - d.act) / h
            G[k, :, j] = (py[j] - d.sensordata) / h
        Y[k] = d.sensordata
        qvel[k + 1] = d.qvel
    loss = float(np.sum(qvel * qvel) + np.sum(Y * Y))
    # reverse pass
    lam = np.zeros(nt)
    lam[nv:2 * nv] = 2 * qvel[T]
    gU = np.zeros((T, nu))
    gp = np.zeros(npar)
    for k in range(T - 1, -1, -1):
        gy = 2 * Y[k]
        gU[k] = Bm[k].T @ lam + D[k].T @ gy
        gp += F[k].T @ lam + G[k].T @ gy
        lam_k = A[k].T @ lam + C[k].T @ gy
        lam_k[nv:2 * nv] += 2 * qvel[k]
        lam = lam_k
    return loss, lam, gU, gp


def chained_gradient(case, p, x0, U, pool):
    m = case.model_at(p)
    perturbed = case.perturbed_models(p)
    if pool is None:
        res = [chained_sequence(m, perturbed, x0, U[b]) for b in range(U.shape[0])]
    else:
        res = list(pool.map(lambda b: chained_sequence(m, perturbed, x0, U[b]),
                            range(U.shape[0])))
    return {"loss": sum(r[0] for r in res), "x0": sum(r[1] for r in res), "x0_tangent": True,
            "ctrl": np.stack([r[2] for r in res]), "params": sum(r[3] for r in res)}


# ------------------------------------------------------------------------------------------
# mjsysid

def mjsysid_gradient(case, rm, p, x0, U):
    lin = rm.linearize(x0, U, p)
    S = np.asarray(lin.states)
    Y = np.asarray(lin.sensors)
    nq, nv = case.nq, case.nv
    sg = np.zeros_like(S)
    sg[..., nq:nq + nv] = 2 * S[..., nq:nq + nv]
    gx0, gU, gp = lin.vjp(sg, 2 * Y)
    gx0 = np.asarray(gx0)
    if gx0.ndim == 2:  # per sequence: x0 is shared by the batch
        gx0 = gx0.sum(axis=0)
    loss = float(np.sum(S[..., nq:nq + nv] ** 2) + np.sum(Y ** 2))
    return {"loss": loss, "x0": gx0, "x0_tangent": False, "ctrl": np.asarray(gU),
            "params": np.asarray(gp)}


# ------------------------------------------------------------------------------------------
# MJX (optional)

class Mjx:
    def __init__(self, site):
        if site:
            sys.path.append(site)
            mujoco.__path__.append(os.path.join(site, "mujoco"))
        import contextlib
        import io
        import jax
        jax.config.update("jax_enable_x64", True)
        with contextlib.redirect_stdout(io.StringIO()):  # "Failed to import warp": not used
            from mujoco import mjx
        import jax.numpy as jnp
        self.jax, self.jnp, self.mjx = jax, jnp, mjx
        self.version = getattr(mjx, "__version__", None)
        try:
            from importlib.metadata import version
            self.version = version("mujoco-mjx")
        except Exception:
            pass

    def gradient_fn(self, case):
        jax, jnp, mjx = self.jax, self.jnp, self.mjx
        # MJX's constraint solver is a lax.while_loop, which reverse mode cannot differentiate,
        # except with opt.iterations = 1 (one Newton step, its line search a scan): arm7's only
        # constraint is j1's friction loss; the loss of this model against MuJoCo's is reported
        m = copy.copy(case.m)
        m.opt.iterations = 1
        mx = mjx.put_model(m)
        nq, nv = m.nq, m.nv
        fields = sorted(set(case.pfield))
        sel = {f: [(j, case.pindex[j]) for j in range(case.np) if case.pfield[j] == f]
               for f in fields}

        def loss(p, x0, U):
            repl = {}
            for f in fields:
                arr = getattr(mx, f)
                for j, i in sel[f]:
                    arr = arr.at[i].set(p[j])
                repl[f] = arr
            model = mx.replace(**repl)

            def seq(u_seq):
                dx = mjx.make_data(model).replace(qpos=x0[:nq], qvel=x0[nq:nq + nv])

                def body(carry, u):
                    dx, acc = carry
                    dx = mjx.step(model, dx.replace(ctrl=u))
                    acc = acc + jnp.sum(dx.sensordata ** 2) + jnp.sum(dx.qvel ** 2)
                    return (dx, acc), None

                (dx, acc), _ = jax.lax.scan(body, (dx, jnp.sum(x0[nq:nq + nv] ** 2)), u_seq)
                return acc

            return jnp.sum(jax.vmap(seq)(U))

        return jax.jit(jax.value_and_grad(loss, argnums=(0, 1, 2)))

    def compile(self, case):
        jnp = self.jnp
        f = self.gradient_fn(case)
        args = (jnp.asarray(case.p0), jnp.asarray(case.x0), jnp.asarray(case.ctrl))
        t0 = time.perf_counter()
        compiled = f.lower(*args).compile()
        return compiled, args, time.perf_counter() - t0

    def run(self, compiled, args):
        L, (gp, gx0, gU) = compiled(*args)
        L = self.jax.block_until_ready(L)
        gU = self.jax.block_until_ready(gU)
        return {"loss": float(L), "x0": np.asarray(gx0), "x0_tangent": False,
                "ctrl": np.asarray(gU), "params": np.asarray(gp)}


def pin_process(cpus):
    """pins every thread of this process (XLA's pool too) to the CPUs"""
    for tid in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(tid), cpus)
        except OSError:
            pass


# ------------------------------------------------------------------------------------------
# the GIL probe

def gil_probe():
    n = 120
    body = "".join('<body pos="0.05 0 0"><joint name="j%d" type="hinge" axis="0 1 0" '
                   'damping="0.1"/><geom type="capsule" size="0.01" fromto="0 0 0 0.05 0 0"/>'
                   % i for i in range(n)) + "</body>" * n
    xml = (f'<mujoco><worldbody>{body}</worldbody><actuator><motor joint="j0"/></actuator>'
           '<sensor><jointpos joint="j0"/></sensor></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    nt = 2 * m.nv + m.na
    A, B = np.zeros((nt, nt)), np.zeros((nt, m.nu))
    C, D = np.zeros((m.nsensordata, nt)), np.zeros((m.nsensordata, m.nu))
    calls = {"mj_step": lambda: mujoco.mj_step(m, d, 300),
             "mjd_transitionFD": lambda: mujoco.mjd_transitionFD(m, d, EPS, False, A, B, C, D)}
    out = {}
    for name, f in calls.items():
        span = {}

        def worker():
            span["t0"] = time.perf_counter()
            f()
            span["t1"] = time.perf_counter()

        th = threading.Thread(target=worker)
        th.start()
        time.sleep(0.010)
        woke = time.perf_counter()
        th.join()
        call = span["t1"] - span["t0"]
        out[name] = {"call_s": call, "main_woke_after_s": woke - span["t0"],
                     "releases_gil": bool(woke < span["t1"] - 0.5 * (call - 0.010))}
    return out


# ------------------------------------------------------------------------------------------

def timed(fn, repeats, slow, budget=1.0, most=25):
    """median wall time of fn: a first run under 1 s is a warm-up (not counted); then at least
    `repeats` runs, more (up to `most`) while they add up to less than `budget` s; a run longer
    than `slow` s ends the repeats (the number of runs is reported)"""
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    times = [first] if first >= 1.0 else []
    while (len(times) < repeats or (sum(times) < budget and len(times) < most)) and \
            not (times and times[-1] > slow):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), len(times), out


def rel_diff(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


def fmt_err(e):
    return "n/a" if e is None else f"{e:.1e}"


def versions(mjsysid_mod, mjx_obj):
    v = {"python": platform.python_version(), "numpy": np.__version__,
         "mujoco": mujoco.__version__, "nproc": os.cpu_count()}
    if mjsysid_mod is not None:
        v["mjsysid"] = getattr(mjsysid_mod, "__version__", "?")
    if mjx_obj is not None:
        v["jax"] = mjx_obj.jax.__version__
        v["mujoco-mjx"] = mjx_obj.version
    try:
        v["commit"] = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                                     capture_output=True, text=True, timeout=10).stdout.strip()
    except Exception:
        pass
    try:
        with open("/proc/cpuinfo") as f:
            v["cpu"] = next(line.split(":", 1)[1].strip() for line in f
                            if line.startswith("model name"))
    except Exception:
        pass
    return v


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json")
    ap.add_argument("--models")
    ap.add_argument("--T")
    ap.add_argument("--B")
    ap.add_argument("--threads")
    ap.add_argument("--repeats", type=int)
    ap.add_argument("--methods")
    ap.add_argument("--slow", type=float, default=60.0,
                    help="a cell whose run takes longer than this stops repeating (s)")
    ap.add_argument("--budget", type=float,
                    help="short cells repeat (up to 25 runs) while their runs add up to less "
                         "than this (s; default 1, 0 with --quick)")
    ap.add_argument("--directions", type=int)
    ap.add_argument("--seed", type=int, default=37)
    ap.add_argument("--mjx-site", default=os.environ.get("MJX_SITE"))
    ap.add_argument("--gil", action="store_true", help="run the GIL probe (default unless --quick)")
    a = ap.parse_args()
    q = a.quick
    models = (a.models or "arm7,humanoid").split(",")
    Ts = [int(x) for x in (a.T or ("5,20" if q else "5,200")).split(",")]
    Bs = [int(x) for x in (a.B or ("1,2" if q else "1,20")).split(",")]
    threads = [int(x) for x in (a.threads or "1,2").split(",")]
    repeats = a.repeats or (1 if q else 3)
    ndir = a.directions or (2 if q else 3)
    budget = a.budget if a.budget is not None else (0.0 if q else 1.0)
    methods = (a.methods or ("chained,mjsysid" if q else "chained,mjsysid,mjx")).split(",")
    notes = []
    load_before = loadavg()
    t_start = time.time()

    mjsysid_mod = None
    if "mjsysid" in methods:
        try:
            import mjsysid as mjsysid_mod
            if not hasattr(mjsysid_mod, "RolloutModel"):
                raise ImportError("mjsysid has no RolloutModel")
        except ImportError as e:
            notes.append(f"mjsysid rows skipped: {e}")
            mjsysid_mod = None
    mjx_obj = None
    if "mjx" in methods:
        try:
            mjx_obj = Mjx(a.mjx_site)
        except Exception as e:  # noqa: BLE001
            notes.append(f"mjx rows skipped: {type(e).__name__}: {e}")

    gil = gil_probe() if (a.gil or not q) else None

    rows, cells = [], []
    for name in models:
        for T in Ts:
            for B in Bs:
                case = Case(name, T, B, a.seed)
                cell_load = loadavg()
                t0 = time.perf_counter()
                L0, ref = reference(case, ndir, a.seed)
                ref_s = time.perf_counter() - t0
                stats = [rollout_loss(case.m, case.x0, case.ctrl[b])[1:] for b in range(B)]
                cell = {"model": name, "T": T, "B": B, "np": case.np, "loss": L0,
                        "reference_s": ref_s, "reference_noise": reference_noise(ref),
                        "contact_steps": int(sum(c for c, _ in stats)),
                        "constraint_changes": int(sum(c for _, c in stats)), "steps": T * B,
                        "loadavg": cell_load}
                grads = {}
                times = {}
                for th in threads:
                    if "chained" in methods:
                        pool = ThreadPoolExecutor(th) if th > 1 else None
                        sec, n, g = timed(lambda: chained_gradient(case, case.p0, case.x0,
                                                                   case.ctrl, pool),
                                          repeats, a.slow, budget)
                        if pool:
                            pool.shutdown()
                        grads[("chained", th)] = g
                        times[("chained", th)] = (sec, n)
                    if mjsysid_mod is not None:
                        rm = mjsysid_mod.RolloutModel(case.path, parameters=case.rm_parameters(),
                                                      threads=th)
                        sec, n, g = timed(lambda: mjsysid_gradient(case, rm, case.p0, case.x0,
                                                                   case.ctrl),
                                          repeats, a.slow, budget)
                        grads[("mjsysid", th)] = g
                        times[("mjsysid", th)] = (sec, n)
                compile_s = None
                if mjx_obj is not None and name == "arm7":
                    compiled, args, compile_s = mjx_obj.compile(case)
                    allcpus = os.sched_getaffinity(0)
                    for th in threads:
                        pin_process(set(sorted(allcpus)[:th]))
                        try:
                            sec, n, g = timed(lambda: mjx_obj.run(compiled, args), repeats,
                                              a.slow, budget)
                        finally:
                            pin_process(allcpus)
                        grads[("mjx", th)] = g
                        times[("mjx", th)] = (sec, n)
                    cell["mjx_compile_s"] = compile_s
                elif "mjx" in methods and mjx_obj is not None:
                    note = f"mjx: {name} not run (contacts and limits: see the docstring)"
                    if note not in notes:
                        notes.append(note)
                for (meth, th), (sec, n) in times.items():
                    g = grads[(meth, th)]
                    ratio = None
                    if meth == "chained" and ("mjsysid", th) in times:
                        ratio = sec / times[("mjsysid", th)][0]
                    if meth == "mjx" and ("mjsysid", th) in times:
                        ratio = sec / times[("mjsysid", th)][0]
                    row = {"model": name, "T": T, "B": B, "threads": th, "method": meth,
                           "seconds": sec, "runs": n, "ratio_vs_mjsysid": ratio,
                           "loss": g["loss"], "loss_rel_diff": abs(g["loss"] - L0) / abs(L0),
                           "errors": errors(case, g, ref)}
                    if meth == "mjx":
                        row["compile_s"] = compile_s
                    rows.append(row)
                # agreement between methods and between thread counts
                agree = {}
                for th in threads:
                    if ("chained", th) in grads and ("mjsysid", th) in grads:
                        gc, gm = grads[("chained", th)], grads[("mjsysid", th)]
                        agree[f"threads={th}"] = {"ctrl": rel_diff(gc["ctrl"], gm["ctrl"]),
                                                  "params": rel_diff(gc["params"], gm["params"])}
                for meth in ("chained", "mjsysid", "mjx"):
                    ks = [k for k in grads if k[0] == meth]
                    if len(ks) > 1:
                        g1, g2 = grads[ks[0]], grads[ks[-1]]
                        agree[f"{meth} threads {ks[0][1]} vs {ks[-1][1]}"] = {
                            "ctrl": rel_diff(g2["ctrl"], g1["ctrl"]),
                            "params": rel_diff(g2["params"], g1["params"])}
                cell["agreement"] = agree
                cells.append(cell)
                print(f"# done {name} T={T} B={B} (load {' '.join(cell_load)})", file=sys.stderr,
                      flush=True)

    load_after = loadavg()
    ver = versions(mjsysid_mod, mjx_obj)

    print(f"Gradient of a rollout loss (issue 37): {ver}")
    print(f"load average before {' '.join(load_before)}, after {' '.join(load_after)}; "
          f"{time.time() - t_start:.0f} s in all")
    if gil:
        print("GIL probe: " + "; ".join(
            f"{k} {'releases' if v['releases_gil'] else 'HOLDS'} the GIL (call "
            f"{v['call_s'] * 1e3:.0f} ms, main thread ran after "
            f"{v['main_woke_after_s'] * 1e3:.0f} ms)"
            for k, v in gil.items()))
    print()
    print("| model | T | B | threads | method | time [s] | runs | time / mjsysid's | rel. error "
          "ctrl | rel. error params | rel. error x0 | loss vs MuJoCo |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        ratio = ""
        if r["ratio_vs_mjsysid"] is not None:
            ratio = f"{r['ratio_vs_mjsysid']:.2f}x"
        meth = r["method"]
        if meth == "mjx":
            meth = f"mjx (compile {r['compile_s']:.1f} s)"
        e = r["errors"]
        print(f"| {r['model']} | {r['T']} | {r['B']} | {r['threads']} | {meth} | "
              f"{r['seconds']:.4f} | {r['runs']} | {ratio} | {fmt_err(e['ctrl'])} | "
              f"{fmt_err(e['params'])} | {fmt_err(e['x0'])} | {r['loss_rel_diff']:.1e} |")
    print()
    print("| model | T | B | np | steps with contacts | active-set changes | L | reference: noise "
          "ctrl / params / x0 | chained vs mjsysid (ctrl, params) | thread counts agree |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for c in cells:
        n = c["reference_noise"]
        ag = c["agreement"]
        cm = "; ".join(f"{k}: {v['ctrl']:.1e}, {v['params']:.1e}" for k, v in ag.items()
                       if k.startswith("threads="))
        tc = "; ".join(f"{k}: {max(v['ctrl'], v['params']):.1e}" for k, v in ag.items()
                       if not k.startswith("threads="))
        print(f"| {c['model']} | {c['T']} | {c['B']} | {c['np']} | {c['contact_steps']} / "
              f"{c['steps']} | {c['constraint_changes']} | {c['loss']:.6g} | {n['ctrl']:.1e} / "
              f"{n['params']:.1e} / {n['x0']:.1e} | {cm or 'n/a'} | {tc or 'n/a'} |")
    for n in notes:
        print(f"note: {n}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"versions": ver, "loadavg_before": load_before,
                       "loadavg_after": load_after, "gil": gil, "rows": rows, "cells": cells,
                       "notes": notes,
                       "settings": {"models": models, "T": Ts, "B": Bs, "threads": threads,
                                    "repeats": repeats, "directions": ndir, "slow_s": a.slow,
                                    "seed": a.seed, "quick": q, "budget_s": budget, "eps": EPS,
                                    "relative_step": REL_STEP, "step_floor": STEP_FLOOR}},
                      f, indent=1)


if __name__ == "__main__":
    main()
