// Joining the records of several fit passes into the one result a user sees (the policy's refit,
// sysid/fit/policy.cc; the global stage, sysid/fit/global_stage.cc): time, simulation steps, the
// ledger (which adds up to the steps) and the trace.
#pragma once

#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid {

// Adds pass `other`'s seconds and simulation steps to *into and its ledger rows, each phase
// prefixed "what: " (e.g. "single-shooting fit: solve: Jacobians"): before into's rows when
// `before` (other ran first), else after them. before: other's trace goes first too (into's trace
// continues it); else the trace is into's alone.
void AddRecords(const FitResult& other, const std::string& what, bool before, FitResult* into);

// A pass's name and its records (seconds, simulation steps, ledger, trace), in the order the
// passes ran
struct PassRecord {
  std::string what;
  int iterations = 0;  // the solver's (a pass that stopped before its first: 0)
  double seconds = 0;
  long long simulation_steps = 0;
  std::vector<LedgerRow> ledger;
  std::vector<IterationInfo> trace;
};
PassRecord RecordOf(const std::string& what, const FitResult& r);

// *into's iterations, seconds, steps and ledger (each row prefixed by its pass): those of the
// passes, in order; its trace: that of passes 0..trace_through (the path to the kept point)
void JoinRecords(const std::vector<PassRecord>& passes, size_t trace_through, FitResult* into);

}  // namespace mjsysid
