#include "sysid/fit/memory_estimate.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

namespace mjsysid {

MemoryEstimate EstimateFitMemory(const MemoryEstimateInput& in) {
  constexpr long long kDouble = 8;
  MemoryEstimate e;
  const int threads = std::max(1, in.threads);
  const int fits = std::max(1, in.concurrent_fits);
  long long per_fit = 0;        // grows with the samples, held by each concurrent fit
  long long shared = 0;         // grows with the samples, held once (the log's copies)
  long long largest_block = 0;  // the largest residual block's rows [J r], bytes
  for (const MemoryEstimateInput::Sequence& s : in.sequences) {
    if (s.model < 0 || s.model >= static_cast<int>(in.models.size())) continue;
    const MemoryEstimateInput::Model& m = in.models[s.model];
    const long long T = std::max(0LL, s.samples);
    e.samples += T;
    const long long nx = 2LL * m.nv + m.na;  // tangent state
    const long long ncol = in.variables + (in.multiple_shooting ? nx : 0);
    // a rollout: states (nq + nv + na), sensors, the step state (1 + nv), an int
    const long long rollout = (m.nq + m.nv + m.na + m.nsensordata + 1 + m.nv) * kDouble + 4;
    // the cache's entry and the one kept aside, the start's trajectories
    per_fit += T * 3 * rollout;
    // DyDp, current and kept aside
    per_fit += T * 2 * m.nsensordata * ncol * kDouble;
    // DxDp (multiple shooting: continuity residuals), current and kept aside
    if (in.multiple_shooting) per_fit += T * 2 * nx * ncol * kDouble;
    // the result's signals: measured, simulated at the start and at the estimate
    per_fit += T * 3 * m.nsensordata * kDouble;
    // Ceres' copies of every row when the blocks are not compressed (its Jacobian, the block
    // scratch, the dense QR's copy and work arrays, the evaluator's and minimizer's vectors)
    if (!in.compress_blocks) per_fit += T * 5 * m.nsensordata * (ncol + 1) * kDouble;
    const long long block_rows =
        in.multiple_shooting && in.segment_samples > 0 ? std::min(T, in.segment_samples) : T;
    largest_block = std::max(largest_block, block_rows * m.nsensordata * (ncol + 1) * kDouble);
    // the log: BuiltProblem's, Problem's copy; the sample grid (times and controls)
    shared += 2 * s.log_doubles * kDouble + T * (1 + m.nu) * kDouble;
  }
  // the compressed blocks' scratch: one per worker folding ahead (at most one per sequence or
  // segment), one for the fit thread
  const long long blocks = static_cast<long long>(in.sequences.size());
  per_fit += (1 + std::min<long long>(threads, std::max(1LL, blocks))) * largest_block;
  // one mjData per worker and model, and three more per model (the checks, the reduced model's
  // probe, the identified model's check)
  long long data = 0;
  for (const MemoryEstimateInput::Model& m : in.models) data += (threads + 3) * m.data_bytes;
  e.fixed_bytes = kProcessBaseBytes + fits * data;
  e.bytes = e.fixed_bytes + fits * per_fit + shared;
  e.per_sample_bytes = e.samples > 0 ? (fits * per_fit + shared) / e.samples : 0;
  return e;
}

namespace {

// the first number in the file (a cgroup's limit or usage); -1: absent or "max"
long long ReadNumber(const std::string& path) {
  std::ifstream f(path);
  std::string text;
  if (!(f >> text) || text == "max") return -1;
  try {
    return std::stoll(text);
  } catch (...) {
    return -1;
  }
}

}  // namespace

long long AvailableMemoryBytes() {
  long long available = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string line;
  while (std::getline(meminfo, line)) {
    if (line.rfind("MemAvailable:", 0) == 0) {
      std::istringstream fields(line.substr(13));
      long long kb = 0;
      if (fields >> kb) available = kb * 1024;
      break;
    }
  }
  if (available <= 0) {
    const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    if (pages > 0 && page > 0) available = static_cast<long long>(pages) * page;
  }
  // the cgroup's limit (v2, then v1) less what the group already uses
  const long long limit_v2 = ReadNumber("/sys/fs/cgroup/memory.max");
  const long long limit_v1 = ReadNumber("/sys/fs/cgroup/memory/memory.limit_in_bytes");
  long long limit = -1, usage = 0;
  if (limit_v2 > 0) {
    limit = limit_v2;
    usage = std::max(0LL, ReadNumber("/sys/fs/cgroup/memory.current"));
  } else if (limit_v1 > 0 && limit_v1 < (1LL << 60)) {  // v1 reads a huge number for no limit
    limit = limit_v1;
    usage = std::max(0LL, ReadNumber("/sys/fs/cgroup/memory/memory.usage_in_bytes"));
  }
  if (limit > 0) {
    const long long room = std::max(0LL, limit - usage);
    available = available > 0 ? std::min(available, room) : room;
  }
  return available;
}

std::string FormatGB(long long bytes) {
  char buf[32];
  const double gb = static_cast<double>(bytes) / 1e9;
  std::snprintf(buf, sizeof(buf), gb < 1000 ? "%.3g GB" : "%.0f GB", gb);
  return buf;
}

}  // namespace mjsysid
