#!/usr/bin/env python3
"""Fit an mjsysid experiment with MuJoCo's own Python toolbox `mujoco.sysid` (benchmark peer).

usage: python tools/peer/mujoco_sysid_fit.py EXP.yaml LOG.h5 --out DIR
         [--optimizer mujoco|scipy] [--residual ours|stock] [--max-iters N] [--threads N]

Reads the subset of our experiment YAML the peer needs (model, parameters, sensors, sensor_time,
sequences, solver.max_iterations, simulate.truth) and our HDF5 log (sysid/io/log.h), builds the
equivalent mujoco.sysid problem, fits it and writes DIR/peer_result.json. See tools/peer/README.md
for the mapping and the time convention.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import io
import json
import math
import os
import pathlib
import platform
import sys
import time

import h5py
import mujoco
from mujoco import sysid
import numpy as np
import yaml

SUPPORTED_KINDS = (
    "body_mass",
    "body_mass_inertia",
    "geom_friction",
    "joint_damping",
    "joint_frictionloss",
    "joint_armature",
    "joint_stiffness",
)


STRICT = False  # --strict: features the peer cannot express fail (exit 3) instead of a warning


def unsupported(msg: str):
  if STRICT:
    fail(f"unsupported: {msg}", 3)
  print(f"warning: {msg}", file=sys.stderr)


def fail(msg: str, code: int = 2):
  print(f"mujoco_sysid_fit: {msg}", file=sys.stderr)
  sys.exit(code)


def num(v, what: str) -> float:
  # PyYAML is YAML 1.1: `1e-4` (no dot) loads as a string; our schema (YAML 1.2) allows it.
  if isinstance(v, bool):
    fail(f"{what}: expected a number, got {v!r}")
  if isinstance(v, (int, float)):
    return float(v)
  if isinstance(v, str):
    t = v.strip().lower()
    if t in (".inf", "+.inf"):
      return math.inf
    if t == "-.inf":
      return -math.inf
    try:
      return float(t)
    except ValueError:
      pass
  fail(f"{what}: expected a number, got {v!r}")


# ------------------------------------------------------------------------------------------------
# experiment


def load_experiment(path: pathlib.Path) -> dict:
  with open(path) as f:
    exp = yaml.safe_load(f)
  if "models" in exp:
    fail(f"{path}: several models (`models:`) are not supported by this driver yet")
  if "model" not in exp:
    fail(f"{path}: no `model`")
  exp["_model_path"] = (path.parent / exp["model"]).resolve()
  for key in ("measurement", "multiple_shooting"):
    if exp.get(key):
      unsupported(f"`{key}` is ignored by the peer driver")
  if ((exp.get("solver") or {}).get("loss") or {}).get("type", "none") != "none":
    unsupported("solver.loss (a robust loss per residual) is ignored by the peer driver")
  if (exp.get("initial_state") or {}).get("estimate"):
    unsupported("initial_state.estimate is ignored (initial states are taken from the log)")
  params = []
  for p in exp.get("parameters") or []:
    kind = p["target"]
    if kind not in SUPPORTED_KINDS:
      fail(f"parameter {p['name']}: target {kind} not supported (supported: "
           f"{', '.join(SUPPORTED_KINDS)})")
    if p.get("prior"):
      unsupported(f"parameter {p['name']}: prior ignored (mujoco.sysid has no priors)")
    lo, hi = p.get("bounds", [-math.inf, math.inf])
    params.append({
        "name": p["name"],
        "target": kind,
        "object": p["object"],
        "index": int(p.get("index", 0)),
        "initial": num(p["initial"], f"{p['name']}.initial"),
        "lower": num(lo, f"{p['name']}.bounds[0]"),
        "upper": num(hi, f"{p['name']}.bounds[1]"),
        "transform": p.get("transform", "none"),
    })
  exp["_params"] = params
  truth = ((exp.get("simulate") or {}).get("truth")) or {}
  exp["_truth"] = {k: num(v, f"simulate.truth.{k}") for k, v in truth.items()}
  return exp


def sensor_weights(exp: dict, model: mujoco.MjModel) -> dict[str, float]:
  """Per-sensor residual weight as in our fit: 1/sigma, or weight, or 1; only listed sensors."""
  entries = exp.get("sensors")
  if not entries:
    return {model.sensor(i).name: 1.0 for i in range(model.nsensor)}
  w = {}
  for e in entries:
    if isinstance(e, str):
      w[e] = 1.0
    elif "sigma" in e:
      w[e["name"]] = 1.0 / num(e["sigma"], f"sensors.{e['name']}.sigma")
    else:
      w[e["name"]] = num(e.get("weight", 1.0), f"sensors.{e['name']}.weight")
  return w


# ------------------------------------------------------------------------------------------------
# model and parameters


def prepare_spec(model_path: pathlib.Path, params: list[dict]) -> mujoco.MjSpec:
  spec = mujoco.MjSpec.from_file(str(model_path))
  # Our simulate and fit run with opt.tolerance = min(model, 1e-10) (docs/cli.md); do the same.
  spec.option.tolerance = min(spec.option.tolerance, 1e-10)
  compiled = spec.compile()
  for p in params:
    if p["target"] in ("body_mass", "body_mass_inertia"):
      # Freeze the compiled inertial (often derived from geoms) as an explicit <inertial>, so
      # writing body.mass changes the mass only, like our body_mass writer (inertia kept).
      # Done once here, not per compile as mujoco.sysid's apply_body_mass_ipos does.
      b = spec.body(p["object"])
      if b is None:
        fail(f"parameter {p['name']}: no body {p['object']}")
      cb = compiled.body(p["object"])
      b.explicitinertial = True
      b.fullinertia = np.full(6, np.nan)
      b.mass = float(cb.mass[0])
      b.inertia = np.array(cb.inertia)
      b.ipos = np.array(cb.ipos)
      b.iquat = np.array(cb.iquat)
      p["_mass0"], p["_inertia0"] = float(cb.mass[0]), np.array(cb.inertia)
    elif p["target"] == "geom_friction":
      if spec.geom(p["object"]) is None:
        fail(f"parameter {p['name']}: no geom {p['object']}")
    else:
      j = spec.joint(p["object"])
      if j is None:
        fail(f"parameter {p['name']}: no joint {p['object']}")
      if p["index"] != 0:
        fail(f"parameter {p['name']}: index {p['index']}: MjSpec joint attributes are per "
             "joint (all dofs share them); only index 0 is supported")
      cj = compiled.joint(p["object"])
      if p["target"] != "joint_stiffness" and cj.type[0] in (mujoco.mjtJoint.mjJNT_BALL,
                                                             mujoco.mjtJoint.mjJNT_FREE):
        print(f"warning: parameter {p['name']}: writes all dofs of joint {p['object']}",
              file=sys.stderr)
  return spec


def make_modifier(p: dict):
  kind, obj = p["target"], p["object"]
  log = p["_log"]

  def value(param) -> float:
    v = float(param.value[0])
    return math.exp(v) if log else v

  if kind == "body_mass":
    def mod(spec, param):
      spec.body(obj).mass = value(param)
  elif kind == "body_mass_inertia":
    # mass and the principal inertia scaled with it (our body_mass_inertia writer)
    def mod(spec, param):
      v = value(param)
      spec.body(obj).mass = v
      spec.body(obj).inertia = p["_inertia0"] * (v / p["_mass0"])
  elif kind == "geom_friction":
    index = p["index"]

    def mod(spec, param):
      spec.geom(obj).friction[index] = value(param)
  elif kind == "joint_damping":
    def mod(spec, param):
      spec.joint(obj).damping[0] = value(param)  # MjSpec: array, [0] = dof_damping
  elif kind == "joint_stiffness":
    def mod(spec, param):
      spec.joint(obj).stiffness[0] = value(param)  # [0] = jnt_stiffness
  elif kind == "joint_frictionloss":
    def mod(spec, param):
      spec.joint(obj).frictionloss = value(param)
  elif kind == "joint_armature":
    def mod(spec, param):
      spec.joint(obj).armature = value(param)
  else:
    raise AssertionError(kind)
  return mod


def check_writer(spec: mujoco.MjSpec, p: dict, param) -> None:
  """Every writer must change the compiled model (docs/numerics.md, "MuJoCo traps"): compare with the model field."""
  field = {"body_mass": ("body", "mass"), "body_mass_inertia": ("body", "mass"),
           "geom_friction": ("geom", "friction"), "joint_damping": ("dof", "damping"),
           "joint_stiffness": ("jnt", "stiffness"), "joint_frictionloss": ("dof", "frictionloss"),
           "joint_armature": ("dof", "armature")}[p["target"]]
  s = spec.copy()
  param.apply_modifier(s)
  m = s.compile()
  if field[0] == "body":
    got = m.body(p["object"]).mass[0]
  elif field[0] == "geom":
    got = m.geom(p["object"]).friction[p["index"]]
  else:
    jid = m.joint(p["object"]).id
    adr = m.jnt_dofadr[jid] if field[0] == "dof" else jid
    got = getattr(m, f"{field[0]}_{field[1]}")[adr]
  want = math.exp(param.value[0]) if p["_log"] else param.value[0]
  if not np.isclose(got, want, rtol=1e-12, atol=0):
    fail(f"parameter {p['name']}: writer check failed ({got} != {want})", 1)


# ------------------------------------------------------------------------------------------------
# log


def load_log(path: pathlib.Path, exp: dict, model: mujoco.MjModel):
  """Returns the sequences as dicts and the log's sensor_time."""
  seqs = []
  with h5py.File(path, "r") as f:
    sensor_time = f.attrs.get("sensor_time", "pre")
    if isinstance(sensor_time, bytes):
      sensor_time = sensor_time.decode()
    want = exp.get("sequences")
    names = [k for k in f.keys() if isinstance(f[k], h5py.Group)]
    if want:
      names = [n for n in want if n in f]
      missing = [n for n in want if n not in f]
      if missing:
        fail(f"{path}: sequences not in the log: {missing}")
    for name in names:
      g = f[name]
      t = np.asarray(g["time"], dtype=float)
      ctrl = np.asarray(g["ctrl"], dtype=float)
      sd = np.asarray(g["sensordata"], dtype=float)
      snames = [s.decode() if isinstance(s, bytes) else str(s)
                for s in g["sensordata"].attrs["names"]]
      sdims = [int(d) for d in g["sensordata"].attrs["dims"]]
      # reorder the columns into the model's sensordata layout; absent sensors stay NaN
      full = np.full((t.size, model.nsensordata), np.nan)
      col = 0
      for sn, dim in zip(snames, sdims):
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, sn)
        if sid < 0 or model.sensor_dim[sid] != dim:
          fail(f"{path}: /{name}/sensordata: sensor {sn} (dim {dim}) not in the model")
        adr = model.sensor_adr[sid]
        full[:, adr:adr + dim] = sd[:, col:col + dim]
        col += dim
      if ctrl.shape[1] != model.nu:
        fail(f"{path}: /{name}/ctrl: {ctrl.shape[1]} columns, model has nu={model.nu}")
      if "qpos" not in g or "qvel" not in g:
        fail(f"{path}: /{name}: no qpos/qvel; the peer needs the initial state from the log")
      qpos0 = np.asarray(g["qpos"][0], dtype=float)
      qvel0 = np.asarray(g["qvel"][0], dtype=float)
      act0 = np.asarray(g["act"][0], dtype=float) if "act" in g else None
      seqs.append({"name": name, "time": t, "ctrl": ctrl, "sensordata": full,
                   "qpos0": qpos0, "qvel0": qvel0, "act0": act0})
  return seqs, sensor_time


def to_model_sequences(name: str, spec, model, seqs, sensor_time: str) -> sysid.ModelSequences:
  """Builds mujoco.sysid's ModelSequences with the sensor times shifted to its convention.

  mujoco.sysid's rollout stamps h(x_k, u_k) with t_{k+1} (tools/peer/README.md). Our `pre` logs
  hold y_k = h(x_k, u_k) in row k at t_k: restamp row k with t_k + dt. `post` logs already hold
  y_k in row k+1 at t_{k+1}: keep the stamps and drop row 0 (measured before any step).
  The control series gets one extra sample (a copy of the last) at t_T, because mujoco.sysid
  drops the last control sample (trajectory.py timeseries2array) and would otherwise simulate
  only T-1 steps; the copy itself is never applied.
  """
  sensor_map = sysid.TimeSeries.compute_all_sensor_mapping(model)
  ctrl_map = sysid.TimeSeries.compute_all_control_mapping(model)
  names, inits, ctrls, sensors = [], [], [], []
  for s in seqs:
    t = s["time"]
    dt = float(model.opt.timestep)
    period = float(np.median(np.diff(t)))
    if abs(period - dt) > 1e-9 * dt:
      fail(f"sequence {s['name']}: sample period {period} != model timestep {dt}")
    tc = np.append(t, t[-1] + dt)
    uc = np.vstack([s["ctrl"], s["ctrl"][-1:]])
    if sensor_time == "pre":
      ts, ys = t + dt, s["sensordata"]
    else:
      ts, ys = t[1:], s["sensordata"][1:]
    names.append(s["name"])
    inits.append(sysid.create_initial_state(model, s["qpos0"], s["qvel0"], s["act0"]))
    ctrls.append(sysid.TimeSeries(tc, uc, ctrl_map))
    sensors.append(sysid.TimeSeries(ts, ys, sensor_map))
  return sysid.ModelSequences(name, spec, names, inits, ctrls,
                              sensors)


def make_ours_residual(model: mujoco.MjModel, weights: dict[str, float]):
  """A ModifyResidualFn with our residual: w_s * (measured - simulated), matched by time stamp,
  no per-column normalisation (mujoco.sysid's default divides each column by
  ||measured column|| / sqrt(2), signal_modifier.normalize_residual)."""
  cols, w = [], []
  for name, wt in weights.items():
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name)
    if sid < 0:
      fail(f"sensors: no sensor {name} in the model")
    adr, dim = model.sensor_adr[sid], model.sensor_dim[sid]
    cols.extend(range(adr, adr + dim))
    w.extend([wt] * dim)
  cols = np.array(cols)
  w = np.array(w)

  def modify_residual(params, pred, meas, mdl, return_pred_all, state=None, **_):
    dt = mdl.opt.timestep
    idx = np.rint((meas.times - pred.times[0]) / dt).astype(int)
    ok = (idx >= 0) & (idx < pred.times.size)
    idx_ok = idx[ok]
    if np.max(np.abs(pred.times[idx_ok] - meas.times[ok])) > 1e-6 * dt:
      raise RuntimeError("time stamps of measured and simulated sensors do not match")
    y = meas.data[ok][:, cols]
    yhat = pred.data[idx_ok][:, cols]
    res = (y - yhat) * w
    pred_ts = sysid.TimeSeries(meas.times[ok], pred.data[idx_ok], pred.signal_mapping)
    meas_ts = sysid.TimeSeries(meas.times[ok], meas.data[ok], meas.signal_mapping)
    return res, pred_ts, meas_ts

  return modify_residual


# ------------------------------------------------------------------------------------------------


def main() -> int:
  ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
  ap.add_argument("experiment", type=pathlib.Path)
  ap.add_argument("log", type=pathlib.Path)
  ap.add_argument("--out", type=pathlib.Path, required=True)
  ap.add_argument("--optimizer", choices=["mujoco", "scipy", "scipy_parallel_fd"],
                  default="mujoco", help="mujoco.sysid backend (default: mujoco, its default)")
  ap.add_argument("--residual", choices=["ours", "stock"], default="ours",
                  help="ours: w*(y - yhat) like `sysid fit` (default); stock: mujoco.sysid's "
                  "default residual (linear resampling, per-column normalisation)")
  ap.add_argument("--log-transform", action="store_true",
                  help="optimise log(x) for parameters with `transform: log` (like ours); "
                  "default: physical values, mujoco.sysid's usual set-up")
  ap.add_argument("--max-iters", type=int, default=None,
                  help="default: the experiment's solver.max_iterations (100)")
  ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
  ap.add_argument("--repeats", type=int, default=1,
                  help="runs of the fit; wall_time_s is the fastest (repeated while the runs add "
                       "up to less than --repeat-budget seconds)")
  ap.add_argument("--repeat-budget", type=float, default=1.5)
  ap.add_argument("--verbose", action="store_true")
  ap.add_argument("--strict", action="store_true",
                  help="exit 3 on experiment features the peer cannot express (instead of a "
                       "warning and a different problem)")
  args = ap.parse_args()
  global STRICT
  STRICT = args.strict

  t_start = time.perf_counter()
  exp = load_experiment(args.experiment)
  params_cfg = exp["_params"]
  for p in params_cfg:
    p["_log"] = args.log_transform and p["transform"] == "log"
  spec = prepare_spec(exp["_model_path"], params_cfg)
  model = spec.compile()
  seqs, log_sensor_time = load_log(args.log, exp, model)
  sensor_time = exp.get("sensor_time", "pre")
  if log_sensor_time != sensor_time:
    print(f"warning: log sensor_time {log_sensor_time} != experiment {sensor_time}; using the "
          "experiment's", file=sys.stderr)
  weights = sensor_weights(exp, model)
  ms = to_model_sequences(exp.get("name", "model"), spec, model, seqs, sensor_time)

  pdict = sysid.ParameterDict()
  for p in params_cfg:
    if p["_log"]:
      nominal = math.log(p["initial"])
      lo = math.log(p["lower"]) if p["lower"] > 0 else -math.inf
      hi = math.log(p["upper"]) if math.isfinite(p["upper"]) else math.inf
    else:
      nominal, lo, hi = p["initial"], p["lower"], p["upper"]
    par = sysid.Parameter(p["name"], nominal, lo, hi, modifier=make_modifier(p))
    check_writer(spec, p, par)
    pdict.add(par)

  if args.residual == "ours":
    residual_fn = sysid.build_residual_fn(
        models_sequences=[ms], modify_residual=make_ours_residual(model, weights),
        resample_true=False, n_threads=args.threads)
  else:
    residual_fn = sysid.build_residual_fn(
        models_sequences=[ms], sensor_weights=weights, n_threads=args.threads,
        enabled_observations=[(n, sysid.SignalType.MjSensor) for n in weights])
  ours_residual_fn = sysid.build_residual_fn(
      models_sequences=[ms], modify_residual=make_ours_residual(model, weights),
      resample_true=False, n_threads=args.threads)

  # count residual evaluations (columns = rollouts of every sequence)
  counts = {"calls": 0, "columns": 0}

  def counted(x, params, **kw):
    counts["calls"] += 1
    counts["columns"] += 1 if np.ndim(x) == 1 else np.shape(x)[1]
    return residual_fn(x, params, **kw)

  solver = exp.get("solver") or {}
  max_iters = args.max_iters or int(solver.get("max_iterations", 100))
  trace_len = {"n": 0, "objective": None}
  # optimize()'s own `verbose` shadows the backend's, which therefore stays on (FULLITER for
  # mujoco.minimize): send its per-iteration lines to a buffer unless --verbose.
  kwargs = {"max_iters": max_iters}
  if args.optimizer == "mujoco":
    if not args.verbose:
      kwargs["output"] = io.StringIO()
    def cb(trace):
      trace_len["n"] = len(trace)
      trace_len["objective"] = float(trace[-1].objective)
    kwargs["iter_callback"] = cb

  def cost_at(vec) -> float:
    r, _, _ = ours_residual_fn(np.asarray(vec, float), pdict.copy())
    r = np.concatenate(r)
    return 0.5 * float(r @ r)

  initial_cost = cost_at(pdict.as_vector())
  t_setup = time.perf_counter() - t_start
  # the fastest of up to --repeats runs, repeated while their wall time adds up to less than
  # --repeat-budget seconds (bench_fit's rule for ours); every run starts from the same copy
  runs, spent, fit_wall = 0, 0.0, math.inf
  while runs < max(1, args.repeats) and (runs == 0 or spent < args.repeat_budget):
    counts["calls"] = counts["columns"] = 0
    t0 = time.perf_counter()
    opt_params, result = sysid.optimize(pdict.copy(), counted, optimizer=args.optimizer,
                                        verbose=False, **kwargs)
    wall = time.perf_counter() - t0
    runs += 1
    spent += wall
    fit_wall = min(fit_wall, wall)
  final_cost = cost_at(opt_params.as_vector())
  iterations = trace_len["n"] if args.optimizer == "mujoco" else int(getattr(result, "nfev", 0))

  est = {}
  for p in params_cfg:
    v = float(opt_params[p["name"]].value[0])
    v = math.exp(v) if p["_log"] else v
    tr = exp["_truth"].get(p["name"])
    est[p["name"]] = {
        "target": p["target"], "object": p["object"], "index": p["index"],
        "initial": p["initial"], "bounds": [p["lower"], p["upper"]], "estimate": v,
        "truth": tr, "rel_error": None if tr in (None, 0) else (v - tr) / tr,
    }

  versions = {}
  for pkg in ("mujoco", "scipy", "numpy", "h5py"):
    try:
      versions[pkg] = importlib.metadata.version(pkg)
    except importlib.metadata.PackageNotFoundError:
      versions[pkg] = None
  out = {
      "tool": "mujoco.sysid",
      "driver": "tools/peer/mujoco_sysid_fit.py",
      "experiment": str(args.experiment.resolve()),
      "log": str(args.log.resolve()),
      "model": str(exp["_model_path"]),
      "versions": {**versions, "mujoco.__version__": mujoco.__version__,
                   "python": platform.python_version()},
      "settings": {
          "optimizer": args.optimizer, "residual": args.residual,
          "log_transform": args.log_transform, "max_iters": max_iters, "threads": args.threads,
          "sensor_time": sensor_time, "sensor_weights": weights,
          "opt_tolerance": float(model.opt.tolerance),
          "sequences": [s["name"] for s in seqs],
          "steps": [int(s["time"].size) for s in seqs],
      },
      "parameters": est,
      "wall_time_s": fit_wall,
      "runs": runs,
      "setup_time_s": t_setup,
      "iterations": iterations,
      "iterations_meaning": ("mujoco.minimize trace length (iterations incl. rejected steps)"
                             if args.optimizer == "mujoco" else "scipy nfev"),
      "residual_calls": counts["calls"],
      "rollout_columns": counts["columns"],
      "initial_cost": initial_cost,
      "final_cost": final_cost,
      "final_cost_meaning": "0.5*sum((w*(y - yhat))^2), our residual, comparable to result.yaml",
      "optimizer_objective": trace_len["objective"],
  }
  args.out.mkdir(parents=True, exist_ok=True)
  dst = args.out / "peer_result.json"
  tmp = dst.with_suffix(".json.tmp")
  tmp.write_text(json.dumps(out, indent=2) + "\n")
  tmp.replace(dst)

  print(f"mujoco.sysid {mujoco.__version__} ({args.optimizer}, residual {args.residual}): "
        f"{iterations} iterations, {counts['calls']} residual calls / {counts['columns']} "
        f"rollouts, cost {initial_cost:.6g} -> {final_cost:.6g}, {fit_wall:.2f} s")
  print(f"  {'parameter':<20} {'initial':>12} {'estimate':>14} {'truth':>12} {'rel.err':>10}")
  for name, e in est.items():
    tr = "" if e["truth"] is None else f"{e['truth']:.6g}"
    re_ = "" if e["rel_error"] is None else f"{e['rel_error']:+.2e}"
    print(f"  {name:<20} {e['initial']:>12.6g} {e['estimate']:>14.8g} {tr:>12} {re_:>10}")
  print(f"  wrote {dst}")
  return 0


if __name__ == "__main__":
  sys.exit(main())
