"""docs/your-robot.md runs as it stands: its command blocks, in order, in an empty folder, with
the C++ build's `sysid` and this Python on PATH; the fit it documents must end converged with
each truth the stand-in robot hides inside its 95 % interval."""

import os
import pathlib
import re
import subprocess
import sys

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]
# the stand-in robot's truth (docs/your-robot.md, section 2)
TRUTH = {"shoulder_damping": 0.3, "elbow_damping": 0.15, "shoulder_armature": 0.02,
         "elbow_armature": 0.01, "forearm_mass": 0.8}


def test_the_walkthrough_runs_and_finds_the_truth(sysid, tmp_path):
    doc = (ROOT / "docs/your-robot.md").read_text()
    blocks = re.findall(r"^```sh\n(.*?)^```$", doc, flags=re.S | re.M)
    assert len(blocks) >= 5, "the walk-through's command blocks"
    script = "set -euo pipefail\n" + "\n".join(blocks)
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(pathlib.Path(sysid).parent),
                                   str(pathlib.Path(sys.executable).parent), env["PATH"]])
    run = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    result = yaml.safe_load((tmp_path / "result/result.yaml").read_text())
    assert result["status"] == "converged", result["warnings"]
    for p in result["parameters"]:
        low, high = p["ci95"]
        assert low <= TRUTH[p["name"]] <= high, p
        assert abs(p["value"] / TRUTH[p["name"]] - 1) < 0.02, p
    assert (tmp_path / "result/report.html").is_file()
    assert (tmp_path / "result/arm2_identified.xml").is_file()
    assert "converged {" in run.stdout  # the Python lines' print
