#include "core/thread_pool.h"

#include <algorithm>

namespace mjsysid {

long long ListScheduleMakespan(const std::vector<long long>& cost, const std::vector<int>& follows,
                               int workers) {
  // the free time of each worker; a task goes to the one free first (the pool's atomic counter)
  std::vector<long long> free_at(std::max(workers, 1), 0);
  std::vector<long long> end(cost.size(), 0);
  long long span = 0;
  for (size_t i = 0; i < cost.size(); ++i) {
    auto w = std::min_element(free_at.begin(), free_at.end());
    end[i] = *w + cost[i];
    // a follower waits for the task it trails: it ends after it
    const int j = follows.empty() ? -1 : follows[i];
    if (j >= 0 && j < static_cast<int>(i)) end[i] = std::max(end[i], end[j]);
    *w = end[i];
    span = std::max(span, end[i]);
  }
  return span;
}

ThreadPool::ThreadPool(int num_threads) {
  if (num_threads <= 0) num_threads = static_cast<int>(std::thread::hardware_concurrency());
  if (num_threads <= 0) num_threads = 1;
  for (int w = 1; w < num_threads; ++w) threads_.emplace_back([this, w] { WorkerLoop(w); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
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
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
    }
    RunItems(worker);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--busy_ == 0) done_.notify_one();
    }
  }
}

void ThreadPool::RecordBatch() {
  if (follows_.size() != cost_.size()) follows_.clear();
  ++load_.batches;
  for (long long c : cost_) load_.work += c;
  for (int w = 1; w <= PoolLoad::kModelWorkers; ++w) {
    load_.span[w] += ListScheduleMakespan(cost_, follows_, w);
  }
  follows_.clear();
}

void ThreadPool::ParallelFor(int n, const std::function<void(int, int)>& fn) {
  if (n <= 0) {
    follows_.clear();
    return;
  }
  if (meter_) cost_.assign(n, 0);
  // serial fast path: no synchronisation
  if (threads_.empty() || n == 1) {
    try {
      for (int i = 0; i < n; ++i) Run(fn, 0, i);
    } catch (...) {
      if (meter_) RecordBatch();
      throw;
    }
    if (meter_) RecordBatch();
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = &fn;
    n_ = n;
    next_.store(0);
    error_ = nullptr;
    busy_ = static_cast<int>(threads_.size());
    ++generation_;
  }
  wake_.notify_all();
  RunItems(0);
  std::exception_ptr error;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return busy_ == 0; });
    fn_ = nullptr;
    error = error_;
    error_ = nullptr;
  }
  // a failed batch is recorded too (the tasks that did not run cost 0), so that the work is
  // every counted step
  if (meter_) RecordBatch();
  if (error) std::rethrow_exception(error);
}

}  // namespace mjsysid
