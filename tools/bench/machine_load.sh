#!/usr/bin/env bash
# Sourced by the benchmark scripts (run_fit_benchmarks.sh, run_design_benchmark.sh); uses the
# caller's $idle_wait (seconds).
#
# machine_load THREADS: the load before a run of THREADS threads, as bench_fit measures it: waits
# up to $idle_wait s for other processes to use <= 0.5 core per thread (busy jiffies of /proc/stat
# over 1 s: user nice system irq softirq steal), then prints "<others' cores> <1-minute load average> <1: idle, 0: not>"
machine_load() {
  local threads="$1" start=$SECONDS s0 s1 line
  while :; do
    s0="$(head -1 /proc/stat)"
    sleep 1
    s1="$(head -1 /proc/stat)"
    line="$(awk -v a="$s0" -v b="$s1" -v n="$(nproc)" -v t="$threads" \
      -v l="$(cut -d' ' -f1 /proc/loadavg)" 'BEGIN {
        split(a, x); split(b, y); busy = 0; total = 0
        for (i = 2; i <= 9; i++) { d = y[i] - x[i]; total += d; if (i != 5 && i != 6) busy += d }
        o = total > 0 ? n * busy / total : 0
        printf "%.3f %s %d", o, l, (o <= 0.5 * t) }')"
    if [[ "${line##* }" == 1 ]] || ((SECONDS - start >= idle_wait)); then break; fi
  done
  echo "$line"
}
