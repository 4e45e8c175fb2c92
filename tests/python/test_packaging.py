"""The installed package: one libmujoco shared with `import mujoco`, the pins, the stubs."""

import pathlib
import re

import mujoco

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
