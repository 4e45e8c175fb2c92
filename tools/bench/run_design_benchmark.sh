#!/usr/bin/env bash
# The excitation design benchmark (BENCHMARKS.md, "Excitation design"): `sysid design` of the
# release build on the shipped pendulum, cart-pole, servo_arm7 and arm7 experiments with the
# default budget (800 candidates, 120 s) and every thread of the machine, for each criterion
# asked; prints one markdown row per run: the worst relative predicted standard error of the
# experiment's current excitation and of the design (equal duration and amplitude limits), their
# ratio, the candidates tried, the design time, and the machine's load before the run (it waits up
# to --idle-wait s for an idle machine; a row that did not get one says so).
#
# usage: tools/bench/run_design_benchmark.sh [--out DIR] [--cases a,b] [--criteria c1,c2]
#                                            [--idle-wait S] [--build DIR]
# Defaults: OUT=results/design_bench, cases pendulum,cartpole,servo_arm7,arm7, criteria
# worst_relative_std,d_optimal, build/release (configured and built when missing).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
out=results/design_bench
cases=pendulum,cartpole,servo_arm7,arm7
criteria=worst_relative_std,d_optimal
idle_wait=30
build=build/release
while (($#)); do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --cases) cases="$2"; shift 2 ;;
    --criteria) criteria="$2"; shift 2 ;;
    --idle-wait) idle_wait="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "run_design_benchmark.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
source "$root/tools/bench/machine_load.sh"
if [[ ! -x "$build/bin/sysid" ]]; then
  cmake --preset release -G Ninja >/dev/null
  cmake --build --preset release -j "$(nproc)" --target sysid
fi
threads="$(nproc)"
mkdir -p "$out"
echo "| case | criterion | parameters | candidates | time (s) | current worst | design worst | ratio | load |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
IFS=, read -ra case_list <<<"$cases"
IFS=, read -ra criterion_list <<<"$criteria"
for c in "${case_list[@]}"; do
  for k in "${criterion_list[@]}"; do
    load="$(machine_load "$threads")"
    dir="$out/$c-$k"
    "$build/bin/sysid" design "experiments/$c.yaml" --out "$dir" --criterion "$k" \
      --threads "$threads" >"$dir.txt" 2>"$dir.err"
    # the summary's lines: "excitation ... N candidates (...) in S s", one per parameter, "worst"
    awk -v c="$c" -v k="$k" -v load="$load" '
      /^  excitation/ { for (i = 1; i <= NF; i++) { if ($i == "candidates") n = $(i - 1);
                                                   if ($i == "in") t = $(i + 1) } }
      /^  relative std/ { table = 1; next }
      table && /^  worst/ { cur = $2; des = $3; table = 0; next }
      table { np++ }
      END {
        split(load, l, " ")
        note = l[3] == 1 ? "idle" : sprintf("not idle: others %.2f cores", l[1])
        r = (substr(cur, 1, length(cur) - 1) + 0) / (substr(des, 1, length(des) - 1) + 0)
        printf "| %s | %s | %d | %s | %s | %s | %s | %.2fx | %s, load average %s |\n",
               c, k, np, n, t, cur, des, r, note, l[2] }' "$dir.txt"
  done
done
