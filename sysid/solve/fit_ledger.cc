// The steps and time of a fit by phase: see sysid/fit_ledger.h.
#include "sysid/solve/fit_ledger.h"

#include <cstdio>
#include <utility>

namespace mjsysid {

FitLedger::FitLedger(std::function<long long()> steps) : FitLedger(std::move(steps), nullptr) {}

FitLedger::FitLedger(std::function<long long()> steps, std::function<long long()> critical)
    : steps_(std::move(steps)),
      critical_(std::move(critical)),
      last_time_(std::chrono::steady_clock::now()) {
  last_steps_ = steps_();
  last_critical_ = critical_ ? critical_() : 0;
}

void FitLedger::MeasureBatches(std::function<PoolTime()> time) {
  time_ = std::move(time);
  last_pool_ = time_ ? time_() : PoolTime();
}

// what happened since the last charge goes to the current phase (nothing before the first Enter)
void FitLedger::Charge() {
  const auto now = std::chrono::steady_clock::now();
  const long long steps = steps_();
  const long long critical = critical_ ? critical_() : 0;
  // a counter below its last reading restarted (Prepare built new simulators): counts from 0
  if (steps < last_steps_) last_steps_ = 0;
  if (critical < last_critical_) last_critical_ = 0;
  const PoolTime pool = time_ ? time_() : PoolTime();
  if (pool.batches < last_pool_.batches) last_pool_ = PoolTime();
  if (!current_.empty()) {
    for (LedgerRow& row : rows_) {
      if (row.phase != current_) continue;
      row.steps += steps - last_steps_;
      row.critical_steps += critical - last_critical_;
      row.seconds += std::chrono::duration<double>(now - last_time_).count();
      row.batches += pool.batches - last_pool_.batches;
      row.batch_seconds += pool.seconds - last_pool_.seconds;
      row.wake_seconds += pool.wake_seconds - last_pool_.wake_seconds;
      row.wait_seconds += pool.wait_seconds - last_pool_.wait_seconds;
      row.batch_cpu_seconds += pool.cpu_seconds - last_pool_.cpu_seconds;
      break;
    }
  }
  last_steps_ = steps;
  last_critical_ = critical;
  last_pool_ = pool;
  last_time_ = now;
}

void FitLedger::Enter(const std::string& phase) {
  Charge();
  current_ = phase;
  for (LedgerRow& row : rows_) {
    if (row.phase == phase) {
      ++row.entries;
      return;
    }
  }
  LedgerRow row;
  row.phase = phase;
  row.entries = 1;
  rows_.push_back(row);
}

void FitLedger::Move(FitPhase from, FitPhase to, long long steps) {
  if (steps <= 0) return;
  auto row = [&](FitPhase phase) -> LedgerRow* {
    for (LedgerRow& r : rows_) {
      if (r.phase == FitPhaseName(phase)) return &r;
    }
    return nullptr;
  };
  LedgerRow* source = row(from);
  if (!source) return;
  source->steps -= steps;
  LedgerRow* target = row(to);
  if (!target) {
    LedgerRow added;
    added.phase = FitPhaseName(to);
    added.entries = 1;
    rows_.push_back(added);
    target = &rows_.back();
    source = row(from);  // push_back may have moved it
  }
  target->steps += steps;
}

std::vector<LedgerRow> FitLedger::Finish() {
  Charge();
  return rows_;
}

std::string FormatLedger(const std::vector<LedgerRow>& rows, long long sum_t) {
  long long steps = 0, critical = 0;
  double seconds = 0, batch_seconds = 0;
  for (const LedgerRow& row : rows) {
    steps += row.steps;
    critical += row.critical_steps;
    seconds += row.seconds;
    batch_seconds += row.batch_seconds;
  }
  std::string out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-44s %7s %10s %8s %9s %6s %9s %9s\n", "phase", "entries",
                "steps", "x sum T", "seconds", "time", "2w model", "serial s");
  out += line;
  auto add = [&](const std::string& phase, long long entries, long long st, long long crit,
                 double s, double in_batches) {
    // the modelled 2-thread speed-up: steps over the steps on the critical path at 2 workers
    char model[32] = "-";
    if (crit > 0) std::snprintf(model, sizeof(model), "%.3fx", static_cast<double>(st) / crit);
    std::snprintf(line, sizeof(line), "%-44s %7lld %10lld %8.2f %9.4f %5.1f%% %9s %9.4f\n",
                  phase.c_str(), entries, st, sum_t > 0 ? static_cast<double>(st) / sum_t : 0.0, s,
                  seconds > 0 ? 100.0 * s / seconds : 0.0, model, s - in_batches);
    out += line;
  };
  for (const LedgerRow& row : rows) {
    add(row.phase, row.entries, row.steps, row.critical_steps, row.seconds, row.batch_seconds);
  }
  add("total", 0, steps, critical, seconds, batch_seconds);
  return out;
}

}  // namespace mjsysid
