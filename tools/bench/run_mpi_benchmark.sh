#!/usr/bin/env bash
# The MPI benchmark (BENCHMARKS.md, "Fits sharded across MPI ranks"), one command: a generated arm7
# experiment (21 parameters, 14 sensors) with 32 sequences of 300 steps, simulated once, then
# fitted with 1 rank x 1 thread, 2 ranks x 1 thread (mpirun, TCP over loopback forced) and 1 rank x
# 2 threads. Prints time per iteration (from the progress lines: last iteration's time minus
# iteration 0's, over the iterations), the start (iteration 0's time: Prepare's sharded rollouts
# and Jacobians at the initial values and the first evaluation), speed-up against 1 x 1, rank 0's
# bytes sent and received
# per iteration and its share of time inside MPI calls (MJSYSID_MPI_STATS), then the
# extrapolation to 8, 64 and 512 ranks for 1,000 sequences x 10,000 steps with its assumptions.
# Each configuration runs `repeats` times (default 3), interleaved; the fastest run is shown.
# usage: tools/bench/run_mpi_benchmark.sh [sysid binary [repeats]]  (default: the release preset's
# sysid, built)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
sysid="${1:-}"
repeats="${2:-3}"
if [[ -z "$sysid" ]]; then
  cmake --preset release -G Ninja >/dev/null
  cmake --build --preset release -j 2 --target sysid >/dev/null
  sysid="$root/build/release/bin/sysid"
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# arm7 with 32 sequences of 300 steps, the model by absolute path, progress lines on
sed -e "s#^model: ../models/arm7.xml#model: $root/models/arm7.xml#" \
    -e "s#^data: logs/arm7.h5#data: $work/arm7_32.h5#" \
    -e "s#^  sequences: .*#  sequences: 32#" -e "s#^  steps: .*#  steps: 300#" \
    -e "s#^  jacobian: auto#  jacobian: auto\n  verbose: true#" \
    experiments/arm7.yaml >"$work/arm7_32.yaml"
grep -q "sequences: 32" "$work/arm7_32.yaml" && grep -q "steps: 300" "$work/arm7_32.yaml"
"$sysid" simulate "$work/arm7_32.yaml" >/dev/null
mpi=(mpirun --allow-run-as-root --oversubscribe --mca pml ob1 --mca btl tcp,self
     --mca btl_tcp_if_include lo -x MJSYSID_MPI_STATS=1)
echo "load before: $(uptime)"
# each configuration `repeats` times, interleaved; the table keeps the fastest (least disturbed by
# other load on a shared machine)
for ((i = 0; i < repeats; ++i)); do
  "$sysid" fit "$work/arm7_32.yaml" --out "$work/out" --threads 1 --force >/dev/null \
    2>"$work/r1t1.$i.err"
  "${mpi[@]}" -n 2 "$sysid" fit "$work/arm7_32.yaml" --out "$work/out" --threads 1 --force \
    >/dev/null 2>"$work/r2t1.$i.err"
  "$sysid" fit "$work/arm7_32.yaml" --out "$work/out" --threads 2 --force >/dev/null \
    2>"$work/r1t2.$i.err"
done
echo "load after:  $(uptime)"
python3 - "$work" "$repeats" <<'PY'
import math, re, sys
work, repeats = sys.argv[1], int(sys.argv[2])
def parse(name):
    return min((parse_one(f"{name}.{i}") for i in range(repeats)), key=lambda p: p[1])
def parse_one(name):
    text = open(f"{work}/{name}.err").read()
    iters = [(int(m.group(1)), float(m.group(2)))
             for m in re.finditer(r"^iter\s+(\d+).*?([\d.]+) s$", text, re.M)]
    n = iters[-1][0]
    per_iter = (iters[-1][1] - iters[0][1]) / n
    stats = re.search(r"mpi stats: ranks (\d+) evaluations (\d+) jacobian_evaluations (\d+) "
                      r"bytes (\d+) seconds_mpi ([\d.]+) seconds_own_share ([\d.]+)", text)
    return n, per_iter, stats, iters[-1][1], iters[0][1]
rows = [("1 rank x 1 thread", "r1t1"), ("2 ranks x 1 thread", "r2t1"),
        ("1 rank x 2 threads", "r1t2")]
base = parse("r1t1")
print(f"\n| run | iterations | s / iteration | speed-up | start s | bytes / iteration "
      f"| time in MPI |")
print("| --- | --- | --- | --- | --- | --- | --- |")
for label, name in rows:
    n, t, st, total, start = parse(name)
    if st:
        bytes_it = int(st.group(4)) / n
        mpi_share = float(st.group(5)) / total
        comm = f"{bytes_it:,.0f}", f"{100 * mpi_share:.1f} %"
    else:
        comm = "0", "-"
    print(f"| {label} | {n} | {t:.4f} | {base[1] / t:.2f}x | {start:.2f} | {comm[0]} "
          f"| {comm[1]} |")
# extrapolation (assumptions printed with the table)
n, t1 = base[0], base[1]
n2, st2 = parse("r2t1")[0], parse("r2t1")[2]
evals_per_iter = int(st2.group(2)) / n2
worker_bytes_per_iter = int(st2.group(4)) / n2  # one worker (2 ranks): broadcast + gather
nvar = 21
unit = t1 / (32 * 300)  # seconds per sequence-step of one iteration on one core
alpha, bw = 50e-6, 1.25e9  # latency per message hop (s), bandwidth into rank 0 (B/s, 10 GbE)
print(f"\nextrapolated, 1,000 sequences x 10,000 steps, {nvar} parameters, one core per rank:")
print(f"measured {unit * 1e6:.3f} us per sequence-step per iteration (1 x 1 above), "
      f"{evals_per_iter:.2f} evaluations and {worker_bytes_per_iter:,.0f} bytes per worker per "
      f"iteration (2 ranks above); assumed {alpha * 1e6:.0f} us latency per tree level "
      f"(broadcast and gather each log2(ranks) levels), {bw / 1e9:.2f} GB/s into rank 0, "
      f"compute proportional to sequence-steps, the slowest rank's share ceil(1000 / ranks)")
print("| ranks | sequences / rank (max) | compute s / iteration | communication s / iteration "
      "| s / iteration | rank 0 bytes / iteration |")
print("| --- | --- | --- | --- | --- | --- |")
for ranks in (8, 64, 512):
    per_rank = math.ceil(1000 / ranks)
    compute = unit * per_rank * 10000
    rank0_bytes = (ranks - 1) * worker_bytes_per_iter
    comm = evals_per_iter * 2 * math.ceil(math.log2(ranks)) * alpha + rank0_bytes / bw
    print(f"| {ranks} | {per_rank} | {compute:.1f} | {comm:.4f} | {compute + comm:.1f} | "
          f"{rank0_bytes:,.0f} |")
PY
