#!/usr/bin/env bash
# The rollout-gradient benchmark (BENCHMARKS.md, issue 37 item 4): tools/bench/gradient_benchmark.py
# on arm7 and the outside suite's humanoid27, T = 5 and 200 steps, batch 1 and 20, 1 and 2
# threads: the gradient of a scalar loss over the rollout by mjsysid's RolloutModel.linearize +
# vjp against the chained per-step finite differences in plain Python (mjd_transitionFD per
# step) and, when MJX is importable, MJX's jax.grad (arm7 only); errors against whole-rollout
# central differences. Waits up to --idle-wait s for an idle machine (machine_load.sh) and prints
# the machine's load before and after, the markdown tables, and writes DIR/gradient.txt,
# DIR/gradient.json and DIR/gradient.err.
#
# usage: tools/bench/run_gradient_benchmark.sh [--out DIR] [--idle-wait S] [--python PY]
#                                              [--mjx-site DIR] [--quick] [-- ARGS...]
# Defaults: OUT=results/gradient_bench, python .venv/bin/python; mjsysid must be importable by it
# (pip install . into the venv, or PYTHONPATH); --mjx-site: a directory holding mujoco-mjx and jax
# (pip install --target DIR --no-deps mujoco-mjx==3.17.0 jax==0.10.2 jaxlib==0.10.2 ml_dtypes
# opt_einsum absl-py etils fsspec trimesh zipp); without it the mjx rows need `mujoco.mjx` in the
# venv, else they are skipped with a note. ARGS go to gradient_benchmark.py (e.g. --models arm7).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
out=results/gradient_bench
idle_wait=30
python=.venv/bin/python
mjx_site=""
extra=()
while (($#)); do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --idle-wait) idle_wait="$2"; shift 2 ;;
    --python) python="$2"; shift 2 ;;
    --mjx-site) mjx_site="$2"; shift 2 ;;
    --quick) extra+=(--quick); shift ;;
    --) shift; extra+=("$@"); break ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "run_gradient_benchmark.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
source "$root/tools/bench/machine_load.sh"
if ! "$python" -c 'import mjsysid; mjsysid.RolloutModel' 2>/dev/null; then
  echo "run_gradient_benchmark.sh: $python cannot import mjsysid.RolloutModel" \
       "(pip install . into the venv, or set PYTHONPATH)" >&2
  exit 1
fi
if [[ -n "$mjx_site" ]]; then extra+=(--mjx-site "$mjx_site"); fi
mkdir -p "$out"
threads="$(nproc)"
load="$(machine_load "$threads")"
read -r others avg idle <<<"$load"
note="$([[ "$idle" == 1 ]] && echo idle || echo "not idle: others $others cores")"
echo "before: $note, load average $avg ($(date -u '+%Y-%m-%d %H:%M UTC'))"
"$python" tools/bench/gradient_benchmark.py --json "$out/gradient.json" "${extra[@]}" \
  >"$out/gradient.txt" 2>"$out/gradient.err"
cat "$out/gradient.txt"
echo "after: load average $(cut -d' ' -f1-3 /proc/loadavg) ($(date -u '+%Y-%m-%d %H:%M UTC'))"
