#!/usr/bin/env python3
"""crate_probe: why the robust suite's crate does not recover (docs/stress.md, "The crate").

Uses the `mujoco` wheel (tools/deps/requirements.txt) on models/robust/crate.xml with its own PRBS
draws of the experiment's excitation (2 pushes of +-60 N, a new random sign every 0.3 s, 4 x 500
steps of 2 ms from the model's rest pose); it does not read the experiment's log. Three probes:

  hops            the box's contact events under MuJoCo settings a modeller could choose (cone,
                  impratio, noslip, integrator, timestep, solref, solimp, margin, gap, solver
                  tolerance, dm_control's stacker.xml contact settings, no friction): steps
                  whose contact count changes, steps with no contact, the largest lift, and
                  |pos(m (1 + h)) - pos(m)| / h over the mass steps h (constant over h where the
                  trajectory is smooth in the mass); then the lift of a box that only slides
                  (no push), started at 0.1 .. 3 m/s.
  equation-error  the equation-error start with the contact forces as unknowns: per sample, the
                  generalized force mj_inverse needs beyond the pushes (contact forces disabled)
                  must equal sum_i J_i' N_i (n_i - mu t_i), t_i the slip direction of contact i,
                  N_i >= 0 unknown per sample and contact (projected out), mass and yaw inertia
                  linear, mu scanned; samples with a sticking contact (slip < 5 cm/s) dropped.
                  With the simulation's own accelerations (exact) and with the central difference
                  of the velocities over +-5 samples.
  steps           from the start (every parameter 40 % off), the Gauss-Newton step of Jacobians
                  by central differences of relative step h in log-parameters, and the cost after
                  it, for whole sequences (--segments 0) or rollouts restarted from the true
                  states every N steps; 1 % sensor noise; then the cost on the straight line
                  from the start to the truth (--sensors: a subset of pos,quat,gyro,accel).
  search          the same cost minimized from the start without derivatives (Nelder-Mead in
                  log parameters, first simplex 10 % wide, 150 iterations) and by a plain
                  Levenberg-Marquardt with central differences of relative step 1e-6 and 1e-2.

Run: .venv/bin/python tools/bench/crate_probe.py hops|equation-error|steps|search [--segments N]
     [--sensors pos,quat,gyro,accel]
"""
import argparse
import os

import mujoco
import numpy as np

MODEL = os.path.join(os.path.dirname(__file__), "..", "..", "models", "robust", "crate.xml")
XML = open(MODEL).read()
OPTION = '<option timestep="0.002" integrator="implicitfast"/>'
TRUTH = np.array([8.0, 0.5, 0.27])  # crate mass, crate friction, yaw inertia (the experiment)
START = np.array([4.8, 0.7, 0.378])  # every one 40 % off
SIGMA = np.array([0.007] * 3 + [0.0046] * 4 + [0.0097] * 3 + [0.12] * 3)  # pos, quat, gyro, accel
SEQS, STEPS, DT = 4, 500, 0.002


def variant(option="", geom="", dt=DT, friction=True):
    """the crate model with extra <option> attributes, extra crate-geom attributes, a timestep"""
    x = XML.replace(OPTION, f'<option timestep="{dt}" integrator="implicitfast" {option}/>')
    x = x.replace('friction="0.5 0.005 0.0001"', 'friction="0.5 0.005 0.0001" ' + geom)
    return x if friction else x.replace('condim="3"', 'condim="1"')


def load(xml, p=TRUTH):
    m = mujoco.MjModel.from_xml_string(xml)
    b, g = m.body("crate").id, m.geom("crate").id
    m.body_mass[b], m.geom_friction[g, 0], m.body_inertia[b, 2] = p
    return m


def pushes(steps, dt, seed):
    """the PRBS of the experiment: +-60 N per actuator, a new random sign every 0.3 s"""
    rng = np.random.default_rng(seed)
    n = int(round(0.3 / dt))
    u = np.concatenate([np.tile(rng.choice([-60.0, 60.0], size=2), (n, 1))
                        for _ in range(steps // n + 1)])
    return u[:steps]


def rollout(m, u, restart=None, every=0):
    """states (qpos, qvel), qacc, sensors and contact counts of one sequence from rest; restart:
    true states to restart from every `every` steps (multiple shooting on the data)"""
    d = mujoco.MjData(m)
    out = {k: [] for k in ("qpos", "qvel", "qacc", "y", "ncon")}
    for k in range(len(u)):
        if restart is not None and every and k % every == 0:
            d.qpos[:], d.qvel[:] = restart["qpos"][k], restart["qvel"][k]
        out["qpos"].append(d.qpos.copy())
        out["qvel"].append(d.qvel.copy())
        d.ctrl[:] = u[k]
        mujoco.mj_step(m, d)
        out["qacc"].append(d.qacc.copy())
        out["y"].append(d.sensordata.copy())
        out["ncon"].append(d.ncon)
    return {k: np.array(v) for k, v in out.items()}


def hops():
    cases = [
        ("MuJoCo defaults (the model: pyramidal, 2 ms)", {}),
        ("cone elliptic", dict(option='cone="elliptic"')),
        ("cone elliptic, impratio 10", dict(option='cone="elliptic" impratio="10"')),
        ("noslip_iterations 10", dict(option='noslip_iterations="10"')),
        ("integrator Euler", dict(option='integrator="Euler"')),
        ("integrator RK4", dict(option='integrator="RK4"')),
        ("timestep 0.5 ms", dict(dt=0.0005)),
        ("solref 0.004 1 (stiff)", dict(geom='solref="0.004 1"')),
        ("solref 0.02 2 (overdamped)", dict(geom='solref="0.02 2"')),
        ("solimp 0.99 0.99 0.001", dict(geom='solimp="0.99 0.99 0.001"')),
        ("margin 1 mm", dict(geom='margin="0.001"')),
        ("margin 1 mm, gap 1 mm", dict(geom='margin="0.001" gap="0.001"')),
        ("tolerance 1e-10, 100 iterations", dict(option='tolerance="1e-10" iterations="100"')),
        ("dm_control stacker's: 1 ms, elliptic, solref .01 1, solimp .9 .97 .001",
         dict(option='cone="elliptic"', geom='solref="0.01 1" solimp="0.9 0.97 0.001"', dt=0.001)),
        ("no friction (condim 1)", dict(friction=False)),
    ]
    hs = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]
    print("| setting | contact count changes | no contact | largest lift | "
          "norm(d pos) / h at h = " + ", ".join(f"{h:.0e}" for h in hs) + " |")
    print("| --- | --- | --- | --- | --- |")
    for name, kw in cases:
        # the first extra option attribute replaces the model's integrator where it names one
        kw = dict(kw)
        opt = kw.get("option", "")
        xml = variant(**kw)
        if "integrator=" in opt:
            xml = xml.replace('integrator="implicitfast" ', "")
        dt = kw.get("dt", DT)
        steps = int(round(STEPS * DT / dt))
        changes = air = total = 0
        lift = 0.0
        slope = np.zeros(len(hs))
        for s in range(SEQS):
            u = pushes(steps, dt, s)
            r = rollout(load(xml), u)
            nc = r["ncon"]
            changes += np.sum(nc[1:] != nc[:-1])
            air += np.sum(nc == 0)
            total += len(nc)
            lift = max(lift, r["qpos"][:, 2].max() - 0.15)
            for i, h in enumerate(hs):
                r2 = rollout(load(xml, TRUTH * [1 + h, 1, 1]), u)
                slope[i] += np.linalg.norm(r2["qpos"][:, :3] - r["qpos"][:, :3]) / h / SEQS
        print(f"| {name} | {100 * changes / total:.1f} % | {100 * air / total:.1f} % | "
              f"{1e3 * lift:.2f} mm | " + " / ".join(f"{v:.3g}" for v in slope) + " |")
    print("\nfree slide, no push, from speed v0 until v0 / 2 (mass 8 kg, friction 0.5 and 0.2):")
    for mu in (0.5, 0.2):
        m = load(XML, [8.0, mu, 0.27])
        for v0 in (0.1, 0.3, 1.0, 3.0):
            d = mujoco.MjData(m)
            for _ in range(250):
                mujoco.mj_step(m, d)  # settle at rest
            d.qvel[0] = v0
            z, air, n = [], 0, 0
            while d.qvel[0] > 0.5 * v0 and n < 5000:
                mujoco.mj_step(m, d)
                z.append(d.qpos[2])
                air += d.ncon == 0
                n += 1
            print(f"  mu {mu}, v0 {v0} m/s: {n} steps, no contact in {100 * air / n:.0f} %, "
                  f"largest lift {1e3 * (max(z) - 0.15):.3f} mm")


def equation_error():
    us = [pushes(STEPS, DT, 16 + s) for s in range(SEQS)]
    for cone in ("pyramidal", "elliptic"):
        xml = variant(option=f'cone="{cone}"')
        logs = [rollout(load(xml), u) for u in us]
        for window in (0, 5):
            def rows(p, mu):
                # contact forces off for the inverse; contacts found with a 5 mm margin at the
                # logged pose (a box in the air between hops still has its four corners)
                m = load(xml, p)
                m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
                mc = load(xml, p)
                mc.geom_margin[:] = 0.005
                d, dc = mujoco.MjData(m), mujoco.MjData(mc)
                crate_body, crate_geom = m.body("crate").id, m.geom("crate").id
                out = []
                for u, lg in zip(us, logs):
                    for k in range(max(window, 1), STEPS - max(window, 1)):
                        qacc = lg["qacc"][k] if window == 0 else (
                            lg["qvel"][k + window] - lg["qvel"][k - window]) / (2 * window * DT)
                        d.qpos[:], d.qvel[:], d.qacc[:], d.ctrl[:] = (
                            lg["qpos"][k], lg["qvel"][k], qacc, u[k])
                        mujoco.mj_inverse(m, d)
                        mujoco.mj_fwdActuation(m, d)
                        e = d.qfrc_inverse - d.qfrc_actuator
                        dc.qpos[:], dc.qvel[:] = lg["qpos"][k], lg["qvel"][k]
                        mujoco.mj_fwdPosition(mc, dc)
                        cols = []
                        for c in dc.contact[:dc.ncon]:
                            jac = np.zeros((3, m.nv))
                            mujoco.mj_jac(mc, dc, jac, None, c.pos, crate_body)
                            n = c.frame[:3] * (-1 if c.geom[0] == crate_geom else 1)
                            v = jac @ lg["qvel"][k]
                            vt = v - (v @ n) * n
                            if np.linalg.norm(vt) < 0.05:
                                cols = None  # sticking: its force is anywhere in the cone
                                break
                            cols.append(jac.T @ (n - mu * vt / np.linalg.norm(vt)))
                        if cols:
                            q, _ = np.linalg.qr(np.array(cols).T)
                            out.append(e - q @ (q.T @ e))
                return np.concatenate(out)

            best = None
            for mu in np.arange(0.30, 0.725, 0.05):
                p0 = np.array([START[0], mu, START[2]])
                r0 = rows(p0, mu)
                a = np.stack([(rows(p0 + dp, mu) - r0) / 1e-4
                              for dp in (np.array([1e-4, 0, 0]), np.array([0, 0, 1e-4]))], 1)
                x = np.linalg.lstsq(a, -r0, rcond=None)[0]
                p = p0 + [x[0], 0, x[1]]
                r = rows(p, mu)
                if best is None or r @ r < best[1]:
                    best = (p, r @ r, len(r) // 6)
            p, c, n = best
            acc = "exact qacc" if window == 0 else f"qacc over +-{window} samples"
            print(f"{cone}, {acc}: mass {p[0]:.3f} (truth 8), friction {p[1]:.2f} (0.5), yaw "
                  f"inertia {p[2]:.3f} (0.27); {n} sliding samples of {SEQS * STEPS}")


SENSOR_COLUMNS = {"pos": [0, 1, 2], "quat": [3, 4, 5, 6], "gyro": [7, 8, 9], "accel": [10, 11, 12]}


def fit_cost(segments, sensors):
    """the residuals of the fitted sensors as a function of log parameters (noisy data)"""
    rng = np.random.default_rng(16)
    us = [pushes(STEPS, DT, 16 + s) for s in range(SEQS)]
    logs = [rollout(load(XML), u) for u in us]
    ys = [lg["y"] + rng.normal(size=lg["y"].shape) * SIGMA for lg in logs]

    cols = [c for name in sensors.split(",") for c in SENSOR_COLUMNS[name]]

    def res(lp):
        m = load(XML, np.exp(lp))
        return np.concatenate([((rollout(m, u, lg, segments)["y"] - y) / SIGMA)[:, cols].ravel()
                               for u, lg, y in zip(us, logs, ys)])

    return res


def steps(segments, sensors):
    res = fit_cost(segments, sensors)

    def cost(lp):
        r = res(lp)
        return 0.5 * r @ r

    lp0, lpt = np.log(START), np.log(TRUTH)
    print(f"segments {segments}, sensors {sensors}: cost at the start {cost(lp0):.4g}, at the "
          f"truth {cost(lpt):.4g}; the truth is at d log p = {np.round(lpt - lp0, 3)}")
    r0 = res(lp0)
    for h in (1e-6, 1e-4, 1e-2, 1e-1):
        jac = np.stack([(res(lp0 + h * e) - res(lp0 - h * e)) / (2 * h) for e in np.eye(3)], 1)
        step = np.linalg.lstsq(jac, -r0, rcond=None)[0]
        after = ", ".join(f"x{lam}: {cost(lp0 + lam * step):.4g}" for lam in (1.0, 0.25))
        print(f"  h {h:.0e}: Gauss-Newton step d log p = {np.round(step, 3)}, predicted cost "
              f"{0.5 * np.sum((r0 + jac @ step) ** 2):.4g}, cost after the step {after}")
    line = [cost(lp0 + t * (lpt - lp0)) for t in np.linspace(0, 1, 11)]
    print("  cost on the line from the start to the truth: " + " ".join(f"{c:.4g}" for c in line))


def search(segments, sensors):
    res = fit_cost(segments, sensors)

    def cost(lp):
        r = res(lp)
        return 0.5 * r @ r

    x = [np.log(START)] + [np.log(START) + 0.1 * e for e in np.eye(3)]
    f = [cost(v) for v in x]
    for it in range(150):
        order = np.argsort(f)
        x, f = [x[i] for i in order], [f[i] for i in order]
        c = np.mean(x[:-1], 0)
        xr = 2 * c - x[-1]
        fr = cost(xr)
        if fr < f[0]:
            xe = 3 * c - 2 * x[-1]
            fe = cost(xe)
            x[-1], f[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < f[-2]:
            x[-1], f[-1] = xr, fr
        else:
            xc = 0.5 * (c + x[-1])
            fc = cost(xc)
            if fc < f[-1]:
                x[-1], f[-1] = xc, fc
            else:  # shrink towards the best
                x = [x[0]] + [0.5 * (x[0] + v) for v in x[1:]]
                f = [f[0]] + [cost(v) for v in x[1:]]
        if it % 30 == 29 or it == 149:
            b = int(np.argmin(f))
            print(f"  iteration {it + 1}: cost {f[b]:.4g}, error against the truth "
                  f"{np.round(100 * (np.exp(x[b]) / TRUTH - 1), 1)} %")
    print(f"  the truth's cost {cost(np.log(TRUTH)):.4g}")
    # Levenberg-Marquardt on the same residuals (central differences, h 1e-6 and 1e-2)
    for h in (1e-6, 1e-2):
        lp = np.log(START)
        r = res(lp)
        c, lam = 0.5 * r @ r, 1e-3
        for it in range(40):
            jac = np.stack([(res(lp + h * e) - res(lp - h * e)) / (2 * h) for e in np.eye(3)], 1)
            a, g = jac.T @ jac, jac.T @ r
            while lam < 1e8:
                step = np.linalg.solve(a + lam * np.diag(np.diag(a)), -g)
                rn = res(lp + step)
                if 0.5 * rn @ rn < c:
                    lp, r, c, lam = lp + step, rn, 0.5 * rn @ rn, max(lam / 3, 1e-7)
                    break
                lam *= 4
            if lam >= 1e8:
                break
        print(f"  Levenberg-Marquardt, h {h:.0e}: {it + 1} iterations, cost {c:.4g}, error against "
              f"the truth {np.round(100 * (np.exp(lp) / TRUTH - 1), 1)} %")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("probe", choices=["hops", "equation-error", "steps", "search"])
    ap.add_argument("--segments", type=int, default=0)
    ap.add_argument("--sensors", default="pos,quat,gyro,accel", help="steps: the fitted sensors")
    a = ap.parse_args()
    {"hops": hops, "equation-error": equation_error,
     "steps": lambda: steps(a.segments, a.sensors),
     "search": lambda: search(a.segments, a.sensors)}[a.probe]()
