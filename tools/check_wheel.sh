#!/usr/bin/env bash
# The package as a user gets it: builds the wheel (pip wheel, reusing build/python/ of `pip install
# .`), installs it into a bare virtual environment (only the wheel and its declared dependencies,
# at their pins: mujoco, mujoco-core, numpy), and runs there: the import beside `import mujoco`
# (one libmujoco), the `sysid` command's --version, and the shipped pendulum experiment through
# the `sysid` command (simulate, fit: converged) read back with mjsysid.read_result.
#
# The wheel still links Debian's Ceres, HDF5, yaml-cpp and cairo dynamically (docs/python.md):
# this checks the package's own contents and entry points, on a machine that has those libraries.
#
# usage: tools/check_wheel.sh            (tools/run_tests.sh runs it after the Python tests)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${MJSYSID_VENV:-$root/.venv}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$venv/bin/pip" wheel -q --disable-pip-version-check --no-build-isolation --no-deps \
  -w "$work/dist" "$root"
wheel="$(ls "$work"/dist/mjsysid-*.whl)"
echo "wheel: $(basename "$wheel") ($(du -k "$wheel" | cut -f1) KiB)"

# a bare venv: no build tools, no test requirements, nothing from the source tree
"$venv/bin/python" -m venv "$work/bare"
"$work/bare/bin/pip" install -q --disable-pip-version-check "$wheel"
cd "$work"  # away from the source tree: `import mjsysid` must come from the wheel
"$work/bare/bin/python" - <<'PY'
import pathlib, mujoco, mjsysid
assert mjsysid.mujoco_version() == mujoco.mj_versionString()
where = pathlib.Path(mjsysid.__file__).resolve()
assert "bare" in where.parts, where
print("import:", where.parent, "MuJoCo", mujoco.mj_versionString())
PY
env -u LD_LIBRARY_PATH "$work/bare/bin/sysid" --version

# the shipped pendulum experiment, its model found from here
sed "s#model: ../models/pendulum.xml#model: $root/models/pendulum.xml#" \
  "$root/experiments/pendulum.yaml" > "$work/pendulum.yaml"
"$work/bare/bin/sysid" simulate "$work/pendulum.yaml" > "$work/simulate.txt"
"$work/bare/bin/sysid" fit "$work/pendulum.yaml" --out "$work/out" --quiet > "$work/fit.txt"
"$work/bare/bin/python" - "$work/out" <<'PY'
import sys, mjsysid
r = mjsysid.read_result(sys.argv[1])
assert r.status == "converged", r.status
for p in r.parameters:
    assert abs(p.value - p.truth) <= 0.01 * abs(p.truth), (p.name, p.value, p.truth)
print("fit through the wheel's sysid:", r.status,
      ", ".join(f"{p.name} {p.value:.4g} (truth {p.truth:g})" for p in r.parameters))
PY
echo "the wheel works in a bare venv"
