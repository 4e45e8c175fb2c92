#!/usr/bin/env bash
# The multiple-shooting benchmark (BENCHMARKS.md, "Multiple shooting"), one command: builds the
# release preset's bench_multiple_shooting and prints its table (arm5 time per iteration against
# the multiple-shooting floor at 1 and 2 threads; a chaotic 5000-step double pendulum fit in
# single shooting and auto). The load average is printed first: time on an idle machine.
# usage: tools/bench/run_ms_benchmark.sh
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
cmake --preset release -G Ninja >/dev/null
cmake --build --preset release -j "$(nproc)" --target bench_multiple_shooting >/dev/null
echo "load: $(uptime)"
build/release/bin/bench_multiple_shooting
