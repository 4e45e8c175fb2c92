"""Issue 35: no third-party log line from the Python package, and a solver that never started
recorded as such. A fit whose cost Ceres cannot evaluate at the start (23 rate values of 1e150
with sigma 1e-4: each squared residual 1e308, their sum inf) printed Ceres' glog lines
("WARNING: Logging before InitGoogleLogging()", "E... trust_region_minimizer.cc:71] Terminating:
...") through the Python module, and result.yaml said -1 iterations and costs -1."""

import math
import subprocess
import sys

import mjsysid  # noqa: F401  (the installed package; the fit runs in a child Python below)


def test_a_fit_that_cannot_start_prints_no_glog_line_and_records_no_iteration(root, sysid,
                                                                              tmp_path):
    model = root / "models" / "pendulum.xml"
    rows = ["time,torque,angle,rate"]
    for i in range(200):
        rows.append(f"{0.002 * i},0.1,0.3,{'1e150' if 17 <= i < 40 else '0.0'}")
    (tmp_path / "edge.csv").write_text("\n".join(rows) + "\n")
    log = tmp_path / "edge.h5"
    imp = subprocess.run([sysid, "import", str(model), str(tmp_path / "edge.csv"), "--out",
                          str(log)], capture_output=True, text=True)
    assert imp.returncode == 0, imp.stderr
    exp = tmp_path / "edge.yaml"
    exp.write_text(
        f"name: edge\nmodel: {model}\ndata: {log}\nsensors:\n"
        "  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.0001}\n"
        "parameters:\n  - {name: damping, target: joint_damping, object: hinge, initial: 0.1,\n"
        "     bounds: [1.0e-4, 5.0], transform: log}\n"
        "solver: {max_iterations: 20, verbose: false}\n")
    out = tmp_path / "res"
    child = subprocess.run(
        [sys.executable, "-c",
         f"import mjsysid; r = mjsysid.fit_experiment({str(exp)!r}, out={str(out)!r}); "
         "print(r.status)"],
        capture_output=True, text=True)
    # the child's own stderr (fd 2, where glog writes): no glog line
    assert "InitGoogleLogging" not in child.stderr, child.stderr
    assert ".cc:" not in child.stderr, child.stderr  # glog's "file.cc:line]" prefix
    assert "Terminating" not in child.stderr, child.stderr
    # result.yaml: no iteration, no cost; read back the same
    text = (out / "result.yaml").read_text()
    assert "iterations: 0\n" in text and "initial_cost: .nan\n" in text, text[:800]
    assert "iterations: -1" not in text
    result = mjsysid.read_result(str(out))
    assert result.iterations == 0
    assert math.isnan(result.initial_cost) and math.isnan(result.final_cost)
