// Joining fit passes' records (sysid/fit/records.h).
#include "sysid/fit/records.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace mjsysid {

void AddRecords(const FitResult& other, const std::string& what, bool before, FitResult* into) {
  into->seconds += other.seconds;
  into->diagnostics.simulation_steps += other.diagnostics.simulation_steps;
  std::vector<LedgerRow> rows = other.diagnostics.ledger;
  for (LedgerRow& row : rows) row.phase = what + ": " + row.phase;
  std::vector<LedgerRow>& ledger = into->diagnostics.ledger;
  ledger.insert(before ? ledger.begin() : ledger.end(), rows.begin(), rows.end());
  if (before) into->trace.insert(into->trace.begin(), other.trace.begin(), other.trace.end());
}

PassRecord RecordOf(const std::string& what, const FitResult& r) {
  return {what,
          std::max(r.iterations, 0),
          r.seconds,
          r.diagnostics.simulation_steps,
          r.diagnostics.ledger,
          r.trace};
}

void JoinRecords(const std::vector<PassRecord>& passes, size_t trace_through, FitResult* into) {
  into->iterations = 0;
  into->seconds = 0;
  into->diagnostics.simulation_steps = 0;
  into->diagnostics.ledger.clear();
  into->trace.clear();
  for (size_t i = 0; i < passes.size(); ++i) {
    const PassRecord& p = passes[i];
    into->iterations += p.iterations;
    into->seconds += p.seconds;
    into->diagnostics.simulation_steps += p.simulation_steps;
    for (LedgerRow row : p.ledger) {
      row.phase = p.what + ": " + row.phase;
      into->diagnostics.ledger.push_back(std::move(row));
    }
    if (i <= trace_through) into->trace.insert(into->trace.end(), p.trace.begin(), p.trace.end());
  }
}

}  // namespace mjsysid
