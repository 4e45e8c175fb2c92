#!/usr/bin/env bash
# The fit benchmark end to end (BENCHMARKS.md): installs what is missing (incl. the pinned peer,
# mujoco[sysid]), builds the release preset, simulates the logs that are missing, fits every case
# with the peer mujoco.sysid (1 and 2 threads, log parameters as ours; and 2 threads in physical
# units, its own parametrization), then runs bench_fit, which fits the same data with
# every one of our methods and the Ceres numeric-diff baseline and merges the peer's rows into
# one table (stdout, OUT/fit_bench.csv, OUT/fit_bench.json, OUT/error_vs_time.svg).
#
# Every row runs on an idle machine where it can: before each row (peer runs here, ours in
# bench_fit) it waits up to --idle-wait seconds (default 30) until other processes use at most
# 0.5 core per thread of the row (busy time of /proc/stat over one second; the 1-minute load
# average is recorded too but counts the previous row for a minute), and a row that still is not
# idle says so in its note ("not idle: others used 1.20 cores, load average 2.31"). bench_fit
# also probes the host's speed before and after each of its rows (the case's nominal step time
# against the fastest measured for the case: this virtual machine's speed changes from outside,
# which the load cannot show) and measures a row again, up to 3 times, when the probe was more than
# 8 % slow; a row that never had a steady host says "host slow: probe 1.62x the case's fastest".
# Every row's wall time is the fastest of up to 5 runs of its fit, repeated while the runs add up
# to less than --repeat-budget seconds (default 7.5; bench_fit --repeats/--repeat-budget, the peer
# driver's the same rule): on this noisy virtual machine fits up to ~2.5 s get at least 3 runs,
# the longer ones 1-2.
#
# usage: tools/bench/run_fit_benchmarks.sh [--out DIR] [--cases a,b,...] [--columns]
#                                          [--idle-wait S] [--repeat-budget S]
#   --columns  also run bench_jacobian_cost (cost of one Jacobian column per parameter kind, with
#              and without stage skipping; ~3 min) into OUT/jacobian_cost.csv
# Defaults: OUT=results/bench, every shipped experiment; the humanoid is capped at 5 iterations.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
out=results/bench
cases=spring_mass,pendulum,double_pendulum,cartpole,arm5,box_floor,humanoid,arm7
columns=0
idle_wait=30
repeat_budget=7.5
while (($#)); do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --cases) cases="$2"; shift 2 ;;
    --columns) columns=1; shift ;;
    --idle-wait) idle_wait="$2"; shift 2 ;;
    --repeat-budget) repeat_budget="$2"; shift 2 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "run_fit_benchmarks.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
caps=(humanoid=5)
cap_of() {
  for c in "${caps[@]}"; do [[ "${c%%=*}" == "$1" ]] && echo "${c#*=}"; done
  return 0
}

step() { printf '\n== %s\n' "$*"; }

# machine_load THREADS: the load before a row (tools/bench/machine_load.sh)
source "$root/tools/bench/machine_load.sh"
step "dependencies (with the benchmark peer)"
tools/bootstrap.sh --bench
step "build (release preset)"
# bench_threads too: BENCHMARKS.md runs it from the same build after this script (a stale binary
# once gave another commit's 2-thread figures)
cmake --preset release -G Ninja >/dev/null
cmake --build --preset release -j "$(nproc)" --target sysid bench_fit bench_jacobian_cost bench_threads
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
    machine_load "$t" >"$dir/load.txt"
    set +e
    .venv/bin/python tools/peer/mujoco_sysid_fit.py "experiments/$c.yaml" \
      "experiments/logs/$c.h5" --out "$dir" --threads "$t" --strict $transform \
      --repeats 5 --repeat-budget "$repeat_budget" ${cap:+--max-iters "$cap"} >"$dir/driver.log" 2>&1
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

step "bench_fit (ours, ours without the reduced model, oracle, Ceres numeric diff; peer rows merged)"
cap_args=()
for c in "${caps[@]}"; do cap_args+=(--max-iterations "$c"); done
"$bin/bench_fit" --cases "$cases" --out "$out" --peer-dir "$out/peer" --idle-wait "$idle_wait" \
  --repeats 5 --repeat-budget "$repeat_budget" "${cap_args[@]}"

if ((columns)); then
  step "bench_jacobian_cost (one Jacobian column per parameter kind and mode)"
  "$bin/bench_jacobian_cost" --csv "$out/jacobian_cost.csv"
fi
step "done: $out"
