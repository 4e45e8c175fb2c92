#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on a shipped example: simulate a
# pendulum log from known truth, fit damping, friction loss and mass to it, and write a report.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
tools/bootstrap.sh
cmake --preset default -G Ninja >/dev/null
cmake --build --preset default -j "$(nproc)"
sysid=build/default/bin/sysid
experiment=experiments/pendulum.yaml
out=results/pendulum

printf '\n== simulate a log from the truth in %s\n' "$experiment"
"$sysid" simulate "$experiment"
printf '\n== check the experiment, its data and the Jacobians\n'
"$sysid" check "$experiment"
printf '\n== fit (estimates against truth below)\n'
"$sysid" fit "$experiment" --out "$out"
printf '\n== report\n'
"$sysid" report "$out"
printf '\nopen %s/report.html; results: %s/result.yaml, %s/result.h5\n' "$out" "$out" "$out"
