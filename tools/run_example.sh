#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on a shipped example.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
tools/bootstrap.sh
cmake --preset default -G Ninja >/dev/null
cmake --build --preset default -j "$(nproc)"
build/default/bin/sysid rollout models/pendulum.xml --steps 2000
