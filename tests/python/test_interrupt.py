"""Ctrl-C during a fit: a child Python process fitting the pendulum (the library fit, and the
experiment's fit that writes a result folder) gets SIGINT after its first iteration; it must stop
after the current iteration and return status interrupted (not hang, not die)."""

import os
import signal
import subprocess
import sys
import textwrap

import pytest

CHILD = textwrap.dedent("""
    import sys, time
    import mjsysid
    log = mjsysid.simulate(sys.argv[1], write=False)
    seqs = [{"ctrl": s.ctrl, "measured": s.sensordata, "qpos": s.qpos[0], "qvel": s.qvel[0]}
            for s in log.sequences]
    params = [{"name": "damping", "kind": "joint_damping", "object": "hinge", "initial": 0.2,
               "lower": 1e-4, "upper": 5.0, "log": True}]
    def on_iteration(it):
        print("iteration", it.iteration, flush=True)
        time.sleep(2)  # the signal arrives during the iteration
    if sys.argv[3] == "fit":
        r = mjsysid.fit(sys.argv[2], params, seqs, options={"max_iterations": 100},
                        callback=on_iteration)
    else:  # the experiment's fit, written to a folder as `sysid fit` does
        mjsysid.simulate(sys.argv[1])
        r = mjsysid.fit_experiment(sys.argv[1], out=sys.argv[4], callback=on_iteration)
        assert r.exit_code == 1  # as `sysid fit` exits for an interrupted fit
        assert mjsysid.read_result(sys.argv[4]).status == "interrupted"
    print("status", r.status, r.iterations, flush=True)
""")


@pytest.mark.parametrize("api", ["fit", "fit_experiment"])
def test_sigint_stops_after_the_current_iteration(root, pendulum, tmp_path, api):
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(pendulum), str(root / "models/pendulum.xml"), api,
         str(tmp_path / "out")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = child.stdout.readline()
        assert first.startswith("iteration 0"), (first, child.stderr.read())
        os.kill(child.pid, signal.SIGINT)
        out, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 0, err
    assert "KeyboardInterrupt" not in err
    # stopped after iteration 0, the one the signal arrived in (at most one more step taken)
    word, status, iterations = out.splitlines()[-1].split()
    assert (word, status) == ("status", "interrupted") and int(iterations) <= 1, out
