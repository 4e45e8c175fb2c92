#!/usr/bin/env bash
# Runs the libFuzzer harnesses of the YAML and HDF5 loaders (tests/fuzz, docs/bad-input.md) for a
# bounded time each, starting from the seed corpora. Fails on any crash, sanitizer report, leak,
# timeout or out-of-memory; the reproducer is left in build/fuzz/artifacts/.
#
# usage: tools/run_fuzz.sh [SECONDS_PER_TARGET] [TARGET...]   (default: 60, every target)
# needs the fuzz build: cmake --preset fuzz -G Ninja && cmake --build --preset fuzz
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-60}"
shift || true
targets=("$@")
((${#targets[@]})) || targets=(experiment_fuzz log_fuzz)
bin="$root/build/fuzz/bin"
artifacts="$root/build/fuzz/artifacts"
mkdir -p "$artifacts"
# HDF5 1.10's own bugs on corrupt files (an over-read, small leaks): see the files
export ASAN_OPTIONS="detect_leaks=1:suppressions=$root/tests/fuzz/asan.supp:${ASAN_OPTIONS:-}"
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp:print_suppressions=0:${LSAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
for target in "${targets[@]}"; do
  name="${target%_fuzz}"
  # a scratch copy of the seeds: what the run adds stays out of the source tree
  work="$root/build/fuzz/corpus/$name"
  mkdir -p "$work"
  cp -n "$root/tests/fuzz/corpus/$name"/* "$work"/
  args=(-max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1
    -artifact_prefix="$artifacts/$name-")
  [[ -f "$root/tests/fuzz/$name.dict" ]] && args+=(-dict="$root/tests/fuzz/$name.dict")
  printf '[fuzz] %s for %ss (corpus %s)\n' "$target" "$seconds" "$work"
  "$bin/$target" "${args[@]}" "$work" 2>&1 | grep -vE '^#[0-9]+\s+(NEW|REDUCE|pulse)' || {
    printf '[fuzz] %s FAILED: reproducer in %s\n' "$target" "$artifacts" >&2
    exit 1
  }
done
printf '[fuzz] no crash, leak or timeout\n'
