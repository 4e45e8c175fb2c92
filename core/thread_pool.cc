#include "core/thread_pool.h"

#include <algorithm>
#include <cstdlib>
#include <ctime>

namespace mjsysid {

long long ListScheduleMakespan(const std::vector<long long>& cost, const std::vector<int>& follows,
                               int workers, const std::vector<int>& after) {
  // the free time of each worker; a task goes to the one free first (the pool's atomic counter)
  std::vector<long long> free_at(std::max(workers, 1), 0);
  std::vector<long long> end(cost.size(), 0);
  long long span = 0;
  for (size_t i = 0; i < cost.size(); ++i) {
    auto w = std::min_element(free_at.begin(), free_at.end());
    // a continuation holds its worker until the task it continues has ended
    const int a = after.empty() ? -1 : after[i];
    const long long start = a >= 0 && a < static_cast<int>(i) ? std::max(*w, end[a]) : *w;
    end[i] = start + cost[i];
    // a follower waits for the task it trails: it ends after it
    const int j = follows.empty() ? -1 : follows[i];
    if (j >= 0 && j < static_cast<int>(i)) end[i] = std::max(end[i], end[j]);
    *w = end[i];
    span = std::max(span, end[i]);
  }
  return span;
}

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// polls done() for at most `seconds`, yielding the core between polls; true when it became true
template <class Done>
bool SpinUntil(double seconds, Done&& done) {
  if (seconds <= 0) return done();
  const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                   std::chrono::duration<double>(seconds));
  for (;;) {
    for (int k = 0; k < 64; ++k) {
      if (done()) return true;
    }
    if (Clock::now() >= end) return done();
    std::this_thread::yield();
  }
}

}  // namespace

double ThreadCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

std::string ThreadRequestError(long long num_threads) {
  if (num_threads >= 0 && num_threads <= kMaxThreads) return "";
  return "expected 0 (all cores) or a whole number from 1 to " + std::to_string(kMaxThreads) +
         " (the cap on threads, docs/cli.md), got " + std::to_string(num_threads);
}

int ThreadCount(int num_threads) {
  if (num_threads <= 0) num_threads = static_cast<int>(std::thread::hardware_concurrency());
  return std::min(std::max(num_threads, 1), kMaxThreads);
}

ThreadPool::ThreadPool(int num_threads) {
  num_threads = ThreadCount(num_threads);
  if (const char* spin = std::getenv("MJSYSID_POOL_SPIN_US")) {
    spin_seconds_ = std::max(0.0, std::atof(spin) * 1e-6);
  }
  started_.resize(num_threads - 1);
  slept_.assign(num_threads - 1, 0);
  for (int w = 1; w < num_threads; ++w) threads_.emplace_back([this, w] { WorkerLoop(w); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_.store(true, std::memory_order_release);
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void ThreadPool::Run(const std::function<void(int, int)>& fn, int worker, int i) {
  if (!meter_) {
    fn(worker, i);
    return;
  }
  // the task's cost is the meter's growth, also when it throws
  const long long before = meter_(worker);
  try {
    fn(worker, i);
  } catch (...) {
    cost_[i] = meter_(worker) - before;
    throw;
  }
  cost_[i] = meter_(worker) - before;
}

void ThreadPool::RunItems(int worker) {
  // claim items until none are left or one has failed
  for (;;) {
    const int i = next_.fetch_add(1);
    if (i >= n_) return;
    try {
      Run(*fn_, worker, i);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_) error_ = std::current_exception();
      next_.store(n_);
      return;
    }
  }
}

void ThreadPool::WorkerLoop(int worker) {
  long seen = 0;
  for (;;) {
    // the next batch: polled for a bounded time, then waited for asleep
    auto published = [&] {
      return stop_.load(std::memory_order_acquire) ||
             generation_.load(std::memory_order_acquire) != seen;
    };
    bool slept = false;
    if (!SpinUntil(spin_seconds_, published)) {
      std::unique_lock<std::mutex> lock(mutex_);
      slept = !published();
      wake_.wait(lock, published);
    }
    if (stop_.load(std::memory_order_acquire)) return;
    seen = generation_.load(std::memory_order_acquire);
    started_[worker - 1] = Clock::now();
    slept_[worker - 1] = slept;
    RunItems(worker);
    // the last worker out wakes the caller if it sleeps (notified under the mutex, so that a
    // caller between its check and its wait cannot miss it)
    if (busy_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.notify_one();
    }
  }
}

void ThreadPool::RecordBatch() {
  if (follows_.size() != cost_.size()) follows_.clear();
  if (after_.size() != cost_.size()) after_.clear();
  ++load_.batches;
  for (long long c : cost_) load_.work += c;
  for (int w = 1; w <= PoolLoad::kModelWorkers; ++w) {
    load_.span[w] += ListScheduleMakespan(cost_, follows_, w, after_);
  }
  follows_.clear();
  after_.clear();
}

void ThreadPool::ParallelFor(int n, const std::function<void(int, int)>& fn) {
  if (n <= 0) {
    follows_.clear();
    after_.clear();
    return;
  }
  const Clock::time_point start = Clock::now();
  const double cpu_start = ThreadCpuSeconds();
  ++time_.batches;
  if (meter_) cost_.assign(n, 0);
  // serial fast path: no synchronisation
  if (threads_.empty() || n == 1) {
    try {
      for (int i = 0; i < n; ++i) Run(fn, 0, i);
    } catch (...) {
      if (meter_) RecordBatch();
      time_.seconds += Seconds(start, Clock::now());
      time_.cpu_seconds += ThreadCpuSeconds() - cpu_start;
      throw;
    }
    if (meter_) RecordBatch();
    time_.seconds += Seconds(start, Clock::now());
    time_.cpu_seconds += ThreadCpuSeconds() - cpu_start;
    return;
  }
  ++time_.handed_off;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = &fn;
    n_ = n;
    next_.store(0);
    error_ = nullptr;
    busy_.store(static_cast<int>(threads_.size()), std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  RunItems(0);
  // the workers' end: polled for a bounded time, then waited for asleep
  const Clock::time_point own_end = Clock::now();
  auto done = [&] { return busy_.load(std::memory_order_acquire) == 0; };
  if (!SpinUntil(spin_seconds_, done)) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, done);
  }
  const Clock::time_point end = Clock::now();
  std::exception_ptr error;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = nullptr;
    error = error_;
    error_ = nullptr;
  }
  // the hand-off's cost: the last worker's start after publication, the caller's wait
  Clock::time_point last_start = start;
  for (size_t w = 0; w < started_.size(); ++w) {
    last_start = std::max(last_start, started_[w]);
    time_.sleeps += slept_[w];
  }
  time_.wake_seconds += Seconds(start, last_start);
  time_.wait_seconds += Seconds(own_end, end);
  time_.seconds += Seconds(start, end);
  time_.cpu_seconds += ThreadCpuSeconds() - cpu_start;
  // a failed batch is recorded too (the tasks that did not run cost 0), so that the work is
  // every counted step
  if (meter_) RecordBatch();
  if (error) std::rethrow_exception(error);
}

}  // namespace mjsysid
