"""The installed package: one libmujoco shared with `import mujoco`, the pins, the stubs."""

import os
import pathlib
import re
import subprocess
import sys

import mujoco
import pytest

import mjsysid


def _pins(text):
    return dict(re.findall(r'^\s*"?([A-Za-z0-9_.-]+)==([0-9][^"\s,]*)"?', text, re.M))


def test_one_libmujoco_shared_with_mujoco():
    # both modules report the same library version, and the process maps one libmujoco file
    assert mjsysid.mujoco_version() == mujoco.mj_versionString()
    with open("/proc/self/maps") as maps:
        libs = {line.split()[-1] for line in maps if "libmujoco" in line}
    assert len(libs) == 1, libs
    assert pathlib.Path(next(iter(libs))).parent == pathlib.Path(mujoco.__file__).parent


def test_mujoco_pins_agree(root):
    # pyproject.toml builds and runs against the wheel tools/deps/requirements.txt pins
    req = _pins((root / "tools/deps/requirements.txt").read_text())
    pyproject = (root / "pyproject.toml").read_text()
    for section in ("requires", "dependencies"):
        block = re.search(section + r"\s*=\s*\[(.*?)\]", pyproject, re.S).group(1)
        pins = _pins(block.replace(",", "\n"))
        for name in ("mujoco", "mujoco-core"):
            assert pins[name] == req[name], (section, name)


def test_build_pins_agree(root):
    # tools/run_tests.sh builds without isolation from requirements-dev.txt: the same pins
    dev = _pins((root / "tools/deps/requirements-dev.txt").read_text())
    block = re.search(r"requires\s*=\s*\[(.*?)\]", (root / "pyproject.toml").read_text(),
                      re.S).group(1)
    pins = _pins(block.replace(",", "\n"))
    for name in ("scikit-build-core", "nanobind"):
        assert pins[name] == dev[name], name


def test_stubs_and_py_typed_installed():
    package = pathlib.Path(mjsysid.__file__).parent
    assert (package / "py.typed").is_file()
    stub = (package / "_mjsysid.pyi").read_text()
    for name in ("def fit(", "def fit_experiment(", "def simulate(", "class FitResult"):
        assert name in stub


def test_extras_pin_what_the_requirements_pin(root):
    # mjsysid[bags] installs rosbags and PyYAML at the pins of tools/deps/requirements.txt
    req = _pins((root / "tools/deps/requirements.txt").read_text())
    block = re.search(r"bags\s*=\s*\[(.*?)\]", (root / "pyproject.toml").read_text(), re.S)
    pins = _pins(block.group(1).replace(",", "\n"))
    assert set(pins) == {"rosbags", "PyYAML"}
    for name, version in pins.items():
        assert req[name] == version, name


def test_gradient_extras_pin_what_the_dev_requirements_pin(root):
    # mjsysid[torch] and mjsysid[jax] install what tests/python/test_torch.py and test_jax.py ran
    # with: the pins of tools/deps/requirements-dev.txt
    dev = _pins((root / "tools/deps/requirements-dev.txt").read_text())
    pyproject = (root / "pyproject.toml").read_text()
    for extra, names in (("torch", {"torch"}), ("jax", {"jax", "jaxlib"})):
        block = re.search(r"^" + extra + r"\s*=\s*\[(.*?)\]", pyproject, re.S | re.M)
        assert block, extra
        pins = _pins(block.group(1).replace(",", "\n"))
        assert set(pins) == names, extra
        for name, version in pins.items():
            assert dev[name] == version, name


def test_the_sysid_command_is_installed_with_the_package():
    # the console script next to this Python runs the program inside the package
    script = pathlib.Path(sys.executable).parent / "sysid"
    assert script.is_file(), script
    program = pathlib.Path(mjsysid.__file__).parent / "bin" / "sysid"
    assert os.access(program, os.X_OK), program
    version = subprocess.run([str(script), "--version"], capture_output=True, text=True,
                             timeout=60, env={k: v for k, v in os.environ.items()
                                              if k != "LD_LIBRARY_PATH"})
    assert version.returncode == 0, version.stderr
    assert mjsysid.__version__ in version.stdout
    assert mujoco.mj_versionString() in version.stdout
    usage = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=60)
    assert usage.returncode == 0, usage.stderr
    for command in ("simulate", "check", "fit", "report", "import"):
        assert command in usage.stdout, command
    # bad input: exit 2 and the reason, through the script as from the program itself
    bad = subprocess.run([str(script), "fit", "/nonexistent/experiment.yaml"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2, (bad.returncode, bad.stderr)
    assert "/nonexistent/experiment.yaml" in bad.stderr


def test_the_report_renderer_leaves_pytorch_importable(pendulum, tmp_path):
    # the motion clip loads libOSMesa at run time (tools/report/render.cc); loaded globally, its
    # libLLVM's symbols crashed PyTorch's triton (its own LLVM) on import afterwards. A fresh
    # interpreter: report with a motion clip, then import torch and triton
    pytest.importorskip("torch")
    pytest.importorskip("triton")
    script = f"""
import mjsysid
exp = mjsysid.load_experiment({str(pendulum)!r})
mjsysid.simulate(exp)
mjsysid.fit_experiment(exp, out={str(tmp_path / "out")!r})
summary = mjsysid.report({str(tmp_path / "out")!r})
assert "frames" in summary, summary  # the clip was rendered: libOSMesa was loaded
import torch, triton
print("imported", torch.__version__, triton.__version__)
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])
    assert "imported" in run.stdout
