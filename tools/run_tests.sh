#!/usr/bin/env bash
# Installs what is missing, builds with warnings as errors, checks formatting, runs every ctest
# label that fits CI (unit, recovery, stress, browser), installs into a temporary prefix and builds
# and runs tests/consumer against it (find_package(mjsysid)), installs the Python package into the
# venv (pip install .) and runs its tests (pytest tests/python: bindings, bag/MCAP import), builds
# the wheel and checks it in a bare venv (tools/check_wheel.sh), then the
# address+undefined sanitizer build of the unit tests. Idempotent; incremental when the builds
# exist.
#
# Then fuzzes the YAML and HDF5 loaders for a bounded time (libFuzzer, clang-14; docs/bad-input.md).
#
# usage: tools/run_tests.sh [--quick]     (--quick: skip the sanitizer build and the fuzzing)
# MJSYSID_FUZZ_SECONDS: seconds per fuzz target (default 60; 0 skips the fuzzing)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
quick=0
[[ "${1:-}" == "--quick" ]] && quick=1
jobs="$(nproc)"

step() { printf '\n== %s\n' "$*"; }

step "dependencies"
tools/bootstrap.sh

step "clang-format check"
mapfile -t sources < <(git ls-files -co --exclude-standard -- '*.h' '*.cc' | grep -v '^build/')
clang-format-14 --dry-run --Werror "${sources[@]}"
echo "formatted: ${#sources[@]} files"

step "build (RelWithDebInfo, warnings as errors)"
cmake --preset default -G Ninja >/dev/null
cmake --build --preset default -j "$jobs"

step "tests (labels unit, recovery, stress, browser, mpi; 'long' is excluded: see README)"
ctest --preset default -j "$jobs" -LE long

step "install into a temporary prefix; tests/consumer built against it with find_package(mjsysid)"
install_tmp="$(mktemp -d)"
trap 'rm -rf "$install_tmp"' EXIT
cmake --install build/default --prefix "$install_tmp/prefix" >/dev/null
# both programs must run without LD_LIBRARY_PATH (libmujoco through their RPATH)
env -u LD_LIBRARY_PATH "$install_tmp/prefix/bin/sysid" --version
# a C++-only project (project(x CXX): CMake's FindHDF5, which the config runs, needs C) and one
# with C and C++
for languages in "CXX" "C;CXX"; do
  consumer_build="$install_tmp/build-${languages/;/-}"
  cmake -S tests/consumer -B "$consumer_build" -G Ninja \
    -DCMAKE_PREFIX_PATH="$install_tmp/prefix" -DMJSYSID_CONSUMER_LANGUAGES="$languages" >/dev/null
  cmake --build "$consumer_build" -j "$jobs"
  env -u LD_LIBRARY_PATH "$consumer_build/mjsysid_consumer" models/pendulum.xml \
    "$install_tmp/log.h5"
done

step "Python package: pip install . into the venv, then pytest tests/python"
venv="${MJSYSID_VENV:-$root/.venv}"
# build/python/ keeps pip's CMake build; without build isolation (the build requirements are in
# the venv: requirements-dev.txt) a second install rebuilds incrementally
"$venv/bin/pip" install -q --disable-pip-version-check --no-build-isolation "$root"
# the tests compare with this build's sysid, whose bag import runs the same venv's python
MJSYSID_VENV="$venv" MJSYSID_SYSID="$root/build/default/bin/sysid" \
  "$venv/bin/python" -m pytest -q -p no:cacheprovider "$root/tests/python"

step "the built wheel in a bare venv (tools/check_wheel.sh)"
MJSYSID_VENV="$venv" tools/check_wheel.sh

if ((quick == 0)); then
  step "sanitizer build (address, undefined) of the unit tests (target unit_tests)"
  cmake --preset debug -G Ninja >/dev/null
  cmake --build --preset debug -j "$jobs"
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    ctest --preset debug -j "$jobs"

  fuzz_seconds="${MJSYSID_FUZZ_SECONDS:-60}"
  if ((fuzz_seconds > 0)); then
    step "fuzzing the YAML and HDF5 loaders (libFuzzer + ASan/UBSan/LSan, ${fuzz_seconds} s each)"
    cmake --preset fuzz -G Ninja >/dev/null
    cmake --build --preset fuzz -j "$jobs"
    tools/run_fuzz.sh "$fuzz_seconds"
  fi
fi
# the disk the build trees take (CI once ran out of it: CMakeLists.txt, MJSYSID_COMPRESS_DEBUG)
du -sh build/* 2>/dev/null || true
step "all checks passed"
