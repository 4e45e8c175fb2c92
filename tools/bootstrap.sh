#!/usr/bin/env bash
# Installs what mjsysid needs and is missing: pinned Debian packages and a project-local Python
# virtual environment (.venv) holding MuJoCo's official wheel (libmujoco.so + C headers), the
# Python packages of bag import (requirements.txt) and of the Python tests (requirements-dev.txt).
# Idempotent: when everything is present at the pinned versions it only checks and returns.
#
# usage: tools/bootstrap.sh [--bench]     (--bench also installs mujoco[sysid] for peer benchmarks)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
deps="$root/tools/deps"
venv="${MJSYSID_VENV:-$root/.venv}"
bench=0
[[ "${1:-}" == "--bench" ]] && bench=1

log() { printf '[bootstrap] %s\n' "$*"; }
sudo_cmd=()
if [[ $(id -u) -ne 0 ]]; then sudo_cmd=(sudo); fi

# debian packages: install only those missing or at another version than pinned
mapfile -t pins < <(grep -vE '^\s*(#|$)' "$deps/apt-packages.txt")
missing=()
for pin in "${pins[@]}"; do
  pkg="${pin%%=*}"
  want="${pin#*=}"
  have="$(dpkg-query -W -f='${Version}' "$pkg" 2>/dev/null || true)"
  [[ "$have" == "$want" ]] || missing+=("$pin")
done
if ((${#missing[@]})); then
  log "installing ${#missing[@]} Debian package(s): ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -qq
  if ! "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"; then
    # a Debian point release can retire a pinned version; take bookworm's current one, say so
    log "WARNING: a pinned version is no longer offered; installing the current bookworm versions"
    "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]%%=*}"
  fi
else
  log "Debian packages: all ${#pins[@]} present at pinned versions"
fi

# python virtual environment with the pinned MuJoCo wheel
py=/usr/bin/python3
[[ -x "$py" ]] || py="$(command -v python3)"
if [[ ! -x "$venv/bin/python" ]]; then
  log "creating virtual environment $venv"
  "$py" -m venv "$venv"
fi
req="$deps/requirements.txt"
req_dev="$deps/requirements-dev.txt"
stamp="$venv/.mjsysid-requirements"
want_stamp="$(cat "$req" "$req_dev")"
if ((bench)); then want_stamp+="$(cat "$deps/requirements-bench.txt")"; fi
if [[ ! -f "$stamp" ]] || [[ "$(cat "$stamp")" != "$want_stamp" ]]; then
  log "installing Python requirements into $venv"
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$req" -r "$req_dev"
  if ((bench)); then
    "$venv/bin/pip" install -q --disable-pip-version-check -r "$deps/requirements-bench.txt"
  fi
  printf '%s' "$want_stamp" >"$stamp"
else
  log "Python requirements: present in $venv"
fi
log "MuJoCo $("$venv/bin/python" -c 'import mujoco; print(mujoco.__version__)')"
