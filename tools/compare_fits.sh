#!/usr/bin/env bash
# Bit-for-bit comparison of two builds' fits: simulates each experiment's log once (with OLD),
# fits it with OLD and with NEW (1 thread and the experiment's own threads), and compares the two
# result.yaml files with the lines that record time, run ids or versions left out (every number
# in result.yaml is written so that it reads back exactly, sysid/io/result.h). A refactoring that
# must not change any estimate runs this against the binary of the commit before it.
#
# usage: tools/compare_fits.sh OLD_SYSID NEW_SYSID OUT_DIR [EXPERIMENT.yaml ...]
#        (default: every experiments/*.yaml and experiments/robust/*.yaml but humanoid)
# Prints one line per fit ("same" or "DIFFERENT") and exits 1 if any differs.
set -uo pipefail
if (($# < 3)); then
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
old="$1" new="$2" out="$3"
shift 3
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
experiments=("$@")
if ((${#experiments[@]} == 0)); then
  for e in "$root"/experiments/*.yaml "$root"/experiments/robust/*.yaml; do
    [[ "$(basename "$e")" == humanoid.yaml ]] || experiments+=("$e")
  done
fi
mkdir -p "$out"
# what differs between two runs of the same binary: clocks, ids, versions, dates, paths; and the
# kinds' keys (termination_kind, interval_check_kind: a binary before them has none; their text
# keys stay compared) and the input hashes (input_hashes: absent before them, paths differ)
strip() {
  grep -vE '(seconds|wall_time_s|created|run_id|mjsysid_version|experiment|wake|wait|_time|identified|termination_kind|interval_check_kind|input_hashes):' "$1" |
    grep -vE '^ *- \{role: (experiment|model|log), path: '
}
status=0
for e in "${experiments[@]}"; do
  name="$(basename "$e" .yaml)"
  if ! "$old" simulate "$e" >"$out/$name.simulate.log" 2>&1; then
    echo "$name: simulate failed (see $out/$name.simulate.log)"
    status=1
    continue
  fi
  for threads in 1 0; do
    for which in old new; do
      bin="$old"
      [[ "$which" == new ]] && bin="$new"
      dir="$out/$name.t$threads.$which"
      rm -rf "$dir"
      "$bin" fit "$e" --out "$dir" --threads "$threads" >"$dir.log" 2>&1
      echo $? >"$dir.rc"
    done
    a="$out/$name.t$threads.old" b="$out/$name.t$threads.new"
    if [[ ! -f "$a/result.yaml" || ! -f "$b/result.yaml" ]]; then
      if cmp -s "$a.rc" "$b.rc" && [[ ! -f "$a/result.yaml" && ! -f "$b/result.yaml" ]]; then
        echo "$name threads=$threads: same (no result, exit $(cat "$a.rc"))"
      else
        echo "$name threads=$threads: DIFFERENT (a result is missing; see $a.log, $b.log)"
        status=1
      fi
      continue
    fi
    if diff <(strip "$a/result.yaml") <(strip "$b/result.yaml") >"$out/$name.t$threads.diff" &&
      cmp -s "$a.rc" "$b.rc"; then
      echo "$name threads=$threads: same (exit $(cat "$a.rc"))"
    else
      echo "$name threads=$threads: DIFFERENT (exit $(cat "$a.rc") / $(cat "$b.rc"); $out/$name.t$threads.diff)"
      status=1
    fi
  done
done
exit $status
