#!/usr/bin/env bash
# The fit benchmark end to end (BENCHMARKS.md): installs what is missing (incl. the pinned peer,
# mujoco[sysid]), builds the release preset, simulates the logs that are missing, fits every case
# with the peer mujoco.sysid (1 and 2 threads, log parameters as ours; and 2 threads in physical
# units, its own parametrization), then runs bench_fit, which fits the same data with
# every one of our methods and the Ceres numeric-diff baseline and merges the peer's rows into
# one table (stdout, OUT/fit_bench.csv, OUT/fit_bench.json, OUT/error_vs_time.svg).
#
# usage: tools/bench/run_fit_benchmarks.sh [--out DIR] [--cases a,b,...] [--columns]
#   --columns  also run bench_jacobian_cost (cost of one Jacobian column per parameter kind, with
#              and without stage skipping; ~3 min) into OUT/jacobian_cost.csv
# Defaults: OUT=results/bench, every shipped experiment; the humanoid is capped at 5 iterations.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
out=results/bench
cases=spring_mass,pendulum,double_pendulum,cartpole,arm5,box_floor,humanoid,arm7
columns=0
while (($#)); do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --cases) cases="$2"; shift 2 ;;
    --columns) columns=1; shift ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "run_fit_benchmarks.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
caps=(humanoid=5)
cap_of() {
  for c in "${caps[@]}"; do [[ "${c%%=*}" == "$1" ]] && echo "${c#*=}"; done
  return 0
}

step() { printf '\n== %s\n' "$*"; }
step "dependencies (with the benchmark peer)"
tools/bootstrap.sh --bench
step "build (release preset)"
cmake --preset release -G Ninja >/dev/null
cmake --build --preset release -j "$(nproc)" --target sysid bench_fit bench_jacobian_cost
bin=build/release/bin
mkdir -p "$out/peer"

step "logs"
for c in ${cases//,/ }; do
  log="experiments/logs/$c.h5"
  if [[ ! -f "$log" ]]; then "$bin/sysid" simulate "experiments/$c.yaml" >/dev/null; fi
  echo "$c: $log"
done

step "peer: mujoco.sysid (tools/peer/mujoco_sysid_fit.py --strict)"
# the same problem as ours: parameters with `transform: log` optimised as log p (--log-transform),
# 1 and 2 threads; and once (2 threads) in physical units, mujoco.sysid's own parametrization
for c in ${cases//,/ }; do
  cap="$(cap_of "$c")"
  for run in 1t 2t phys-2t; do
    t="${run%t}"
    t="${t#phys-}"
    transform=--log-transform
    [[ "$run" == phys-* ]] && transform=
    dir="$out/peer/$c-$run"
    rm -rf "$dir"
    mkdir -p "$dir"
    set +e
    .venv/bin/python tools/peer/mujoco_sysid_fit.py "experiments/$c.yaml" \
      "experiments/logs/$c.h5" --out "$dir" --threads "$t" --strict $transform \
      ${cap:+--max-iters "$cap"} >"$dir/driver.log" 2>&1
    rc=$?
    set -e
    if ((rc == 3)); then
      grep -m1 'unsupported' "$dir/driver.log" | sed 's/^mujoco_sysid_fit: unsupported: //' \
        >"$dir/unsupported.txt"
      echo "$c $run: n/a ($(cat "$dir/unsupported.txt"))"
    elif ((rc != 0)); then
      echo "$c $run: the peer driver failed (exit $rc), see $dir/driver.log" | tee \
        "$dir/unsupported.txt"
    else
      echo "$c $run: $(grep -m1 '^mujoco.sysid' "$dir/driver.log")"
    fi
  done
done

step "bench_fit (ours, oracle, Ceres numeric diff; peer rows merged)"
cap_args=()
for c in "${caps[@]}"; do cap_args+=(--max-iterations "$c"); done
"$bin/bench_fit" --cases "$cases" --out "$out" --peer-dir "$out/peer" "${cap_args[@]}"

if ((columns)); then
  step "bench_jacobian_cost (one Jacobian column per parameter kind and mode)"
  "$bin/bench_jacobian_cost" --csv "$out/jacobian_cost.csv"
fi
step "done: $out"
