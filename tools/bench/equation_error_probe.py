"""The equation-error start (`initial: auto`) on noisy and encoder-only copies of the shipped logs.

Writes, per case and mode, a copy of experiments/logs/<case>.h5 and an experiment that marks every
parameter `initial: auto`, runs `sysid fit` and prints the start's largest relative error from the
experiment's `simulate.truth` (with FULL=auto or FULL=shipped: the whole fit, its status,
iterations, final error and wall time). docs/numerics.md, "The equation-error start on noisy logs".

Modes: exact (the log as shipped: the integrator's own states), noisy (Gaussian noise of LEVEL,
default 1 %, of each channel's standard deviation on qpos and qvel, numpy seed SEED, default 7),
quant (qpos rounded to 2 pi / 2^14, a 14-bit encoder, and no qvel).

usage: python tools/bench/equation_error_probe.py [cases] [modes] [--out DIR]
  env: SYSID (default build/default/bin/sysid), LEVEL, SEED, FULL
"""
import os
import subprocess
import sys
import time

import h5py
import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def copy_log(src_path, dst_path, mode, level):
    rng = np.random.default_rng(int(os.environ.get("SEED", "7")))
    quantum = 2 * np.pi / 2**14
    with h5py.File(src_path) as src, h5py.File(dst_path, "w") as dst:
        for a in src.attrs:
            dst.attrs[a] = src.attrs[a]
        for s in src:
            g = dst.create_group(s)
            for a in src[s].attrs:
                g.attrs[a] = src[s].attrs[a]
            for k in src[s]:
                x = src[s][k][()]
                if mode == "noisy" and k in ("qpos", "qvel"):
                    x = x + rng.normal(size=x.shape) * level * x.std(axis=0)
                if mode == "quant":
                    if k == "qvel":
                        continue
                    if k == "qpos":
                        x = np.round(x / quantum) * quantum
                g[k] = x
                for a in src[s][k].attrs:
                    g[k].attrs[a] = src[s][k].attrs[a]


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    out = sys.argv[sys.argv.index("--out") + 1] if "--out" in sys.argv else "results/ee_probe"
    if "--out" in sys.argv:
        args.remove(out)
    cases = args[0].split(",") if args else [
        "spring_mass", "pendulum", "double_pendulum", "cartpole", "arm7"]
    modes = args[1].split(",") if len(args) > 1 else ["exact", "noisy", "quant"]
    sysid = os.environ.get("SYSID", os.path.join(ROOT, "build/default/bin/sysid"))
    level = float(os.environ.get("LEVEL", "0.01"))
    full = os.environ.get("FULL")
    for case in cases:
        cfg = yaml.safe_load(open(f"{ROOT}/experiments/{case}.yaml"))
        truth = cfg["simulate"]["truth"]
        for mode in modes:
            d = os.path.abspath(f"{out}/{case}_{mode}")
            os.makedirs(d, exist_ok=True)
            copy_log(f"{ROOT}/experiments/{cfg['data']}", d + "/log.h5", mode, level)
            c = dict(cfg)
            c["model"] = os.path.normpath(f"{ROOT}/experiments/" + cfg["model"])
            c["data"] = d + "/log.h5"
            if full != "shipped":
                for p in c["parameters"]:
                    p["initial"] = "auto"
            c["solver"] = dict(c.get("solver", {}))
            if not full:
                c["solver"]["max_iterations"] = 1
            yaml.safe_dump(c, open(d + "/exp.yaml", "w"))
            t0 = time.time()
            r = subprocess.run([sysid, "fit", d + "/exp.yaml", "--out", d + "/out"],
                               capture_output=True, text=True)
            wall = time.time() - t0
            if not os.path.exists(d + "/out/result.yaml"):
                print(case, mode, "exit", r.returncode, r.stderr[-400:])
                continue
            res = yaml.safe_load(open(d + "/out/result.yaml"))
            ps = res["parameters"]
            start = max(abs(p["initial"] / truth[p["name"]] - 1) for p in ps)
            final = max(abs(p["value"] / truth[p["name"]] - 1) for p in ps)
            line = f"{case:16s} {mode:6s} start max error {100 * start:6.2f} %"
            if full:
                line += (f"  fit from {full}: {res['status']}, {res['iterations']} iterations,"
                         f" final max error {100 * final:.2f} %, {wall:.1f} s")
            print(line)
            for w in res.get("warnings", []):
                if w.startswith("initial: auto"):
                    print("   ", w[:160])


if __name__ == "__main__":
    main()
