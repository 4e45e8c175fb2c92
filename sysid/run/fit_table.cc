// A fit's events as text: see sysid/run/fit_table.h.
#include "sysid/run/fit_table.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "core/text.h"

namespace mjsysid::run {
namespace {

// "NAME  TEXT  S s": a stage's line, its name in five columns, the time right-aligned
std::string StageLine(const char* name, const std::string& text, double seconds) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "  %7.2f s", seconds);
  std::string line = name;
  line.resize(7, ' ');
  line += text;
  if (line.size() < 75) line.resize(75, ' ');
  return line + buf;
}

const char* StageName(FitStage stage) {
  switch (stage) {
    case FitStage::kStart:
      return "start";
    case FitStage::kRefit:
      return "refit";
    case FitStage::kGlobal:
      return "global";
    case FitStage::kSubset:
      return "subset";
    case FitStage::kUncertainty:
    case FitStage::kIntervalCheck:
      return "unc";
    case FitStage::kCheck:
      return "check";
  }
  return "stage";
}

}  // namespace

void FitTable::OnStage(FitStage stage, const std::string& text, double seconds) {
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
  Write(StageLine(StageName(stage), text, seconds));
  header_ = false;
}

void FitTable::OnIteration(const IterationInfo& info) {
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
  if (!header_) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%4s  %13s  %10s  %10s  %8s  %10s", "iter", "cost", "|step|",
                  "|gradient|", "step/std", "time");
    Write(buf);
    header_ = true;
  }
  row_ = info;
  row_ratio_ = next_ratio_;
  next_ratio_ = std::numeric_limits<double>::quiet_NaN();
}

void FitTable::OnStepTest(double step_std_errors, bool before_jacobian, const std::string& text) {
  const std::lock_guard<std::mutex> lock(mutex_);
  // the test with an iterate's own Jacobian completes its row; one before the next iterate's
  // Jacobian belongs to the next row
  if (before_jacobian) {
    next_ratio_ = step_std_errors;
  } else if (row_ && !std::isnan(step_std_errors)) {
    row_ratio_ = step_std_errors;
  }
  FlushLocked();
  if (verbose_) Write("      " + text);
}

void FitTable::OnProgress(const char* what, int done, int total, double seconds) {
  const long long percent = 100LL * done / total;
  const std::string line = StageLine("sim",
                                     std::string(what) + " " + std::to_string(percent) + " % of " +
                                         std::to_string(total) + " steps",
                                     seconds);
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
  Write(line);
}

void FitTable::OnWarning(const std::string& text) {
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
  Write("sysid fit: warning: " + text);
}

void FitTable::OnStartDone(int k, int done, int total, const StartResult& r) {
  std::string line = "sysid fit: start " + std::to_string(k) + " (" + std::to_string(done) + "/" +
                     std::to_string(total) + " done): ";
  if (r.error.empty()) {
    line += std::string(FitStatusName(r.status)) + ", cost " + FormatDigits(r.initial_cost, 6) +
            " -> " + FormatDigits(r.final_cost, 6) + ", " + std::to_string(r.iterations) +
            " iterations";
  } else {
    line += "failed: " + r.error;
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
  Write(line);
}

void FitTable::Flush() {
  const std::lock_guard<std::mutex> lock(mutex_);
  FlushLocked();
}

void FitTable::FlushLocked() {
  if (!row_) return;
  const IterationInfo& it = *row_;
  char step[16] = "-", ratio[16] = "-", buf[160];
  if (it.iteration > 0) std::snprintf(step, sizeof(step), "%.2e", it.step_norm);
  if (!std::isnan(row_ratio_)) std::snprintf(ratio, sizeof(ratio), "%.2g", row_ratio_);
  std::snprintf(buf, sizeof(buf), "%4d  %13.6e  %10s  %10.2e  %8s  %8.2f s%s", it.iteration,
                it.cost, step, it.gradient_norm, ratio, it.seconds,
                it.successful ? "" : "  rejected");
  row_.reset();
  Write(buf);
}

}  // namespace mjsysid::run
