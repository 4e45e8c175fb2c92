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
//
// Task model (optional, SetMeter): a meter reads a per-worker counter that only that worker's
// tasks advance (the simulator's step calls). Each ParallelFor then records the cost of every task
// (the counter's growth while it ran) and adds to load() the batch's work (the sum) and its
// makespan on 1..kModelWorkers workers under this pool's scheduling (ListScheduleMakespan): a
// measure of the parallel structure in exact counter units, independent of the machine's load.
#pragma once

#include <atomic>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace mjsysid {

// The makespan of one ParallelFor batch on `workers` workers under the pool's scheduling: the tasks
// are claimed in index order by whichever worker is free first (all start at 0), so task i starts
// at the earliest finish of the tasks before it and ends cost[i] later; a task that follows
// another step by step (follows[i] = j < i, -1: none; the directional columns behind their
// rollout) also ends no earlier than task j. cost.size() tasks, follows empty or of that size.
long long ListScheduleMakespan(const std::vector<long long>& cost, const std::vector<int>& follows,
                               int workers);

// what the meter recorded over many batches (ThreadPool::load)
struct PoolLoad {
  static constexpr int kModelWorkers = 4;
  long long batches = 0;
  long long work = 0;                      // sum of all task costs (= span[1])
  long long span[kModelWorkers + 1] = {};  // span[w]: sum of the batches' makespans on w workers
};

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
  // tells the task model that in the next ParallelFor task i follows task follows[i] step by step
  // (-1: none; one entry per task, else ignored; without a meter ignored); the scheduling is the
  // same
  void SetNextFollows(std::vector<int> follows) {
    if (meter_) follows_ = std::move(follows);
  }

  // Sets the meter (see Task model above; nullptr: none, the default). meter(worker) is called on
  // that worker's thread before and after each of its tasks.
  void SetMeter(std::function<long long(int worker)> meter) { meter_ = std::move(meter); }
  // what the meter recorded since construction or ResetLoad (not during a ParallelFor)
  const PoolLoad& load() const { return load_; }
  void ResetLoad() { load_ = PoolLoad(); }

 private:
  // adds the batch just run (cost_, follows_) to load_
  void RecordBatch();
  void WorkerLoop(int worker);
  void RunItems(int worker);
  // fn(worker, i), metered when a meter is set
  void Run(const std::function<void(int, int)>& fn, int worker, int i);

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
  std::function<long long(int)> meter_;
  std::vector<long long> cost_;  // per task of the running batch (each slot written by its task)
  std::vector<int> follows_;     // SetNextFollows
  PoolLoad load_;
};

}  // namespace mjsysid
