// The memory a fit will hold, estimated before it starts (docs/numerics.md "Memory estimate"),
// and the limit it is checked against.
//
// What dominates (docs/numerics.md "Memory", docs/bench/history.md "Memory"): per sample of every
// fitted sequence, the evaluation cache (sysid/solve/evaluation_cache.h) holds a rollout and its
// Jacobian DyDp (nsensordata x ncol doubles, ncol = the fitted variables, + nx for a segment whose
// initial state is a variable) twice (the current entry and the one kept aside until the next
// Jacobians), in multiple shooting also DxDp (nx x ncol, twice); the start's trajectories of the
// input checks are a third rollout; the log is held three times (the built problem, Problem's
// copy, the sample grid); the compressed blocks' scratch holds one block's rows [J r] per worker
// (fold ahead), or, with compression off, Ceres holds about five copies of every row of the
// Jacobian; the result keeps three signal columns per sensor value. Independent of the samples:
// one mjData per simulator worker and model (and a few more: the checks, the identified model's
// check), and the process itself (libraries, Ceres, HDF5). Ceres' own Jacobian is the blocks'
// thin-QR triangles, (n + 1) rows per segment: small next to the above.
//
// Multi-start runs min(starts, threads) fits at a time, each with its own caches.
// segment_steps auto (-1) is estimated as single shooting: the probe that chooses segments runs
// after the check; a fit that auto puts into segments holds DxDp too (measured in
// docs/numerics.md "Memory estimate").
//
// The library never prints: the caller compares with the limit and reports.
#pragma once

#include <string>
#include <vector>

namespace mjsysid {

struct MemoryEstimateInput {
  struct Model {
    int nq = 0, nv = 0, na = 0, nu = 0;
    int nsensordata = 0;
    long long data_bytes = 0;  // one mjData of the model (its buffer and arena)
  };
  struct Sequence {
    int model = 0;              // index into models
    long long samples = 0;      // logged samples fitted (rows of `measured`)
    long long log_doubles = 0;  // doubles of its log (time, controls, measured, logged states)
  };
  std::vector<Model> models;
  std::vector<Sequence> sequences;
  // fitted variables: the parameters, measurement terms and control delays
  int variables = 0;
  // multiple shooting: segment_steps > 0 (each segment's initial state a variable); 0 and auto
  // (-1): single shooting
  bool multiple_shooting = false;
  long long segment_samples = 0;  // multiple shooting: samples per segment (0: unknown)
  int threads = 1;                // simulator workers of one fit (>= 1)
  int concurrent_fits = 1;        // multi-start: fits run at the same time
  bool compress_blocks = true;    // FitOptions::advanced.compress_blocks
};

struct MemoryEstimate {
  long long bytes = 0;             // the estimated peak (resident), bytes
  long long samples = 0;           // over every sequence
  long long per_sample_bytes = 0;  // the part that grows with the samples, per sample (mean)
  long long fixed_bytes = 0;       // the part that does not
};

// the process's own resident memory before a fit holds anything (libraries, Ceres, HDF5,
// MuJoCo), measured (docs/numerics.md "Memory estimate")
constexpr long long kProcessBaseBytes = 48LL << 20;

MemoryEstimate EstimateFitMemory(const MemoryEstimateInput& in);

// the share of the available memory a fit may use by default
constexpr double kDefaultMemoryShare = 0.8;

// The memory available to this process, bytes: /proc/meminfo MemAvailable (else sysconf's
// available pages), and no more than the cgroup's limit minus its usage (cgroup v2 memory.max,
// v1 memory.limit_in_bytes) where one is set; 0 when nothing can be read.
long long AvailableMemoryBytes();

// "3.21 GB", "0.115 GB" (3 significant digits; decimal: 1 GB = 1e9 bytes, as solver.memory_limit_gb
// and --memory-limit)
std::string FormatGB(long long bytes);

}  // namespace mjsysid
