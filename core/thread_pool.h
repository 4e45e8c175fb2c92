// A persistent pool of worker threads for data-parallel loops.
//
// Contract:
// - ParallelFor(n, fn) calls fn(worker, i) exactly once for every i in [0, n) and returns when all
//   calls have finished. worker is in [0, size()) and identifies the calling thread, so callers can
//   index per-worker scratch (one mjData per worker). The calling thread works too, as worker 0.
// - Work is handed out by an atomic counter: which worker runs which i varies from run to run, so
//   results must not depend on it (each i writes only its own outputs). That is what makes the
//   core's results bit-identical for any thread count.
// - The first exception thrown by fn is rethrown from ParallelFor after all workers stop; the rest
//   of the loop is abandoned.
// - Not reentrant: fn must not call ParallelFor on the same pool.
#pragma once

#include <atomic>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace mjsysid {

class ThreadPool {
 public:
  // num_threads <= 0 means std::thread::hardware_concurrency().
  explicit ThreadPool(int num_threads = 1);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  // number of workers, including the calling thread
  int size() const { return static_cast<int>(threads_.size()) + 1; }

  void ParallelFor(int n, const std::function<void(int worker, int i)>& fn);

 private:
  void WorkerLoop(int worker);
  void RunItems(int worker);

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void(int, int)>* fn_ = nullptr;
  int n_ = 0;
  std::atomic<int> next_{0};
  int busy_ = 0;
  long generation_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
};

}  // namespace mjsysid
