"""Python and the command line do the same thing: simulate, fit, check, report, bad input.

Truth, start, noise: those of experiments/pendulum.yaml (truth damping 0.08, frictionloss 0.03,
bob_mass 1.2; start 0.2, 0.01, 0.8; noise sigma 0.001 rad and 0.01 rad/s; 3 x 2000 steps).
"""

import subprocess

import numpy as np
import pytest

import mjsysid


def run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600)


def test_simulate_equals_cli(pendulum, tmp_path, sysid):
    log = mjsysid.simulate(str(pendulum))  # written to the experiment's data: path
    cli_log = tmp_path / "cli.h5"
    assert run([sysid, "simulate", str(pendulum), "--out", str(cli_log)]).returncode == 0
    for a, b, c in zip(log.sequences, mjsysid.read_log(str(cli_log)).sequences,
                       mjsysid.read_log(str(tmp_path / "pendulum.h5")).sequences):
        assert a.name == b.name == c.name
        for field in ("time", "ctrl", "sensordata", "qpos", "qvel"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
            np.testing.assert_array_equal(getattr(a, field), getattr(c, field))
        assert a.sensor_names == ["angle", "rate"] and a.actuator_names == ["torque"]


def test_fit_equals_cli_fit(pendulum, tmp_path, sysid):
    # one log, fitted by the CLI and by Python: the same estimates to 1e-12 relative
    mjsysid.simulate(str(pendulum))
    cli_out = tmp_path / "cli_fit"
    proc = run([sysid, "fit", str(pendulum), "--out", str(cli_out), "--quiet"])
    assert proc.returncode == 0, proc.stderr
    fit = mjsysid.fit_experiment(str(pendulum), out=str(tmp_path / "py_fit"))
    assert fit.status == "converged" and fit.exit_code == 0
    cli = mjsysid.read_result(str(cli_out))
    assert [p.name for p in fit.parameters] == [p.name for p in cli.parameters]
    for p, q in zip(fit.parameters, cli.parameters):
        assert p.value == pytest.approx(q.value, rel=1e-12, abs=0), p.name
        assert p.std_error == pytest.approx(q.std_error, rel=1e-9), p.name
    assert fit.iterations == cli.iterations
    # what Python got is what it wrote
    written = mjsysid.read_result(fit.out_dir)
    assert [p.value for p in written.parameters] == [p.value for p in fit.parameters]
    assert written.run_id == fit.run_id


def test_check_and_report(pendulum, tmp_path, sysid):
    mjsysid.simulate(str(pendulum))
    check = mjsysid.check(str(pendulum))
    assert set(check["per_variable"]) == {"damping", "frictionloss", "bob_mass"}
    # the same Jacobian check as `sysid check` prints (its worst error and per-variable lines)
    proc = run([sysid, "check", str(pendulum)])
    assert proc.returncode == 0, proc.stderr
    lines = {line.split()[0]: line.split()[1] for line in proc.stdout.splitlines()
             if len(line.split()) >= 2}
    assert lines["worst"] == f"{check['worst_relative_error']:.2e}"
    for name, err in check["per_variable"].items():
        assert lines[name] == f"{err:.2e}", name
    out = tmp_path / "fit"
    mjsysid.fit_experiment(mjsysid.load_experiment(str(pendulum)), out=str(out))
    summary = mjsysid.report(str(out))
    assert (out / "report.html").stat().st_size > 10000
    assert (out / "cost.png").is_file() and "report.html" in summary


def test_bad_input_raises_value_error_with_the_cli_message(pendulum, tmp_path, sysid):
    bad = tmp_path / "bad.yaml"
    bad.write_text(pendulum.read_text().replace("object: hinge", "object: hnige", 1))
    proc = run([sysid, "check", str(bad)])
    assert proc.returncode == 2
    with pytest.raises(ValueError) as err:
        mjsysid.check(str(bad))
    assert proc.stderr.strip() == "sysid check: " + str(err.value)
    assert "hnige" in str(err.value)
    # a missing experiment file, and a model that does not load, through the fit
    proc = run([sysid, "fit", str(tmp_path / "missing.yaml")])
    with pytest.raises(ValueError) as err:
        mjsysid.fit_experiment(str(tmp_path / "missing.yaml"))
    assert proc.returncode == 2 and proc.stderr.strip() == "sysid fit: " + str(err.value)


def test_simulate_replaces_only_its_own_log(pendulum, tmp_path, sysid):
    # the CLI's rule (sysid/run/log_output.h): a file simulate did not write for this experiment
    # is kept (ValueError) unless force=True; its own log is replaced
    data = tmp_path / "pendulum.h5"
    data.write_text("robot data, not a log")
    with pytest.raises(ValueError, match="exists and is not an mjsysid log; not replaced"):
        mjsysid.simulate(str(pendulum))
    assert data.read_text() == "robot data, not a log"
    mjsysid.simulate(str(pendulum), force=True)
    assert mjsysid.read_log(str(data)).sequences
    mjsysid.simulate(str(pendulum))  # its own log: replaced without force
    # a log of another experiment (the CLI simulating a copy) at the same path: kept
    other = tmp_path / "other.yaml"
    other.write_text(pendulum.read_text())
    assert run([sysid, "simulate", str(other), "--out", str(data), "--force"]).returncode == 0
    before = data.read_bytes()
    with pytest.raises(ValueError, match=r"holds a log written by sysid simulate \(mjsysid .*\) of "):
        mjsysid.simulate(str(pendulum))
    assert data.read_bytes() == before
