// The fit's memory estimate (sysid/fit/memory_estimate.h) against the sizes it counts, term by
// term, on a small pendulum-like input; and what moves it (multiple shooting, starts, threads,
// compression off).
#include "sysid/fit/memory_estimate.h"

#include <gtest/gtest.h>

namespace mjsysid {
namespace {

// nq = nv = nu = 1, 2 sensor values, 3 variables, one sequence of 1000 samples with a log of
// time, ctrl and two sensor columns (4 doubles per sample), 1 thread
MemoryEstimateInput Pendulum() {
  MemoryEstimateInput in;
  MemoryEstimateInput::Model m;
  m.nq = 1;
  m.nv = 1;
  m.na = 0;
  m.nu = 1;
  m.nsensordata = 2;
  m.data_bytes = 1000000;
  in.models.push_back(m);
  MemoryEstimateInput::Sequence s;
  s.model = 0;
  s.samples = 1000;
  s.log_doubles = 4 * 1000;
  in.sequences.push_back(s);
  in.variables = 3;
  in.threads = 1;
  return in;
}

// Situation: single shooting, 1 thread. Every term by hand: per sample 3 rollouts of (nq + nv +
// na + nsensordata + 1 + nv) doubles + an int, DyDp twice (2 x 3 doubles), 3 signal columns per
// sensor value, the log twice and the sample grid (1 + nu doubles); two block scratches of
// T x 2 x (3 + 1) doubles (the fit thread and one worker); (1 + 3) mjData and the process base.
TEST(MemoryEstimateTest, SingleShootingCountsEveryTerm) {
  const MemoryEstimate e = EstimateFitMemory(Pendulum());
  const long long T = 1000;
  const long long rollout = (1 + 1 + 0 + 2 + 1 + 1) * 8 + 4;
  const long long per_sample = 3 * rollout + 2 * 2 * 3 * 8 + 3 * 2 * 8;
  const long long scratch = 2 * (T * 2 * 4 * 8);
  const long long log = 2 * 4 * 8 * T + T * 2 * 8;
  EXPECT_EQ(e.samples, T);
  EXPECT_EQ(e.fixed_bytes, kProcessBaseBytes + 4 * 1000000);
  EXPECT_EQ(e.bytes, e.fixed_bytes + T * per_sample + scratch + log);
  EXPECT_EQ(e.per_sample_bytes, (T * per_sample + scratch + log) / T);
}

// Situation: multiple shooting (segment_steps > 0): each segment's state (nx = 2) joins the
// columns (ncol 3 -> 5) of DyDp and DxDp (both held twice), and the block scratch is one
// segment's rows.
TEST(MemoryEstimateTest, MultipleShootingAddsStateColumns) {
  MemoryEstimateInput in = Pendulum();
  in.multiple_shooting = true;
  in.segment_samples = 100;
  const MemoryEstimate e = EstimateFitMemory(in);
  const long long T = 1000;
  const long long rollout = (1 + 1 + 0 + 2 + 1 + 1) * 8 + 4;
  const long long per_sample = 3 * rollout + 2 * 2 * 5 * 8 + 2 * 2 * 5 * 8 + 3 * 2 * 8;
  const long long scratch = 2 * (100 * 2 * 6 * 8);
  const long long log = 2 * 4 * 8 * T + T * 2 * 8;
  EXPECT_EQ(e.bytes, kProcessBaseBytes + 4 * 1000000 + T * per_sample + scratch + log);
}

// Situation: the things a user can turn: more threads add mjData and scratches; two concurrent
// starts hold two fits' caches (not two logs); compression off adds Ceres' row copies.
TEST(MemoryEstimateTest, ThreadsStartsAndCompressionGrowIt) {
  const MemoryEstimate base = EstimateFitMemory(Pendulum());
  MemoryEstimateInput threads = Pendulum();
  threads.threads = 4;
  // 3 more mjData; one sequence: still one worker's scratch
  EXPECT_EQ(EstimateFitMemory(threads).bytes, base.bytes + 3 * 1000000);
  MemoryEstimateInput starts = Pendulum();
  starts.concurrent_fits = 2;
  const long long log = 2 * 4 * 8 * 1000 + 1000 * 2 * 8;
  EXPECT_EQ(EstimateFitMemory(starts).bytes,
            2 * (base.bytes - log - kProcessBaseBytes) + log + kProcessBaseBytes);
  MemoryEstimateInput uncompressed = Pendulum();
  uncompressed.compress_blocks = false;
  EXPECT_EQ(EstimateFitMemory(uncompressed).bytes, base.bytes + 1000LL * 5 * 2 * 4 * 8);
}

// Situation: a sequence naming a model that is not there is not counted: only the fixed part
TEST(MemoryEstimateTest, UnknownModelCountsNothing) {
  MemoryEstimateInput in = Pendulum();
  in.sequences[0].model = 5;
  const MemoryEstimate e = EstimateFitMemory(in);
  EXPECT_EQ(e.samples, 0);
  EXPECT_EQ(e.per_sample_bytes, 0);
  EXPECT_EQ(e.bytes, e.fixed_bytes);
}

TEST(MemoryEstimateTest, FormatsDecimalGigabytes) {
  EXPECT_EQ(FormatGB(115000000), "0.115 GB");
  EXPECT_EQ(FormatGB(3210000000LL), "3.21 GB");
  EXPECT_EQ(FormatGB(2500000000000LL), "2500 GB");
}

// Situation: the machine's available memory is readable here (Linux /proc/meminfo)
TEST(MemoryEstimateTest, AvailableMemoryIsPositive) { EXPECT_GT(AvailableMemoryBytes(), 0); }

}  // namespace
}  // namespace mjsysid
