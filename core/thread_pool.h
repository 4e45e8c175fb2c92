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
//
// Hand-off (more than one worker). A batch is published under the mutex (a generation counter)
// and the sleeping workers are woken through a condition variable; the caller waits for the last
// worker the same way. Both sides first spin for a bounded time (kSpinSeconds, yielding the core
// between polls) on the atomic generation and busy count: batches of a fit follow each other after
// a short serial gap (residuals, Ceres' linear algebra), and a futex wake-up on a loaded virtual
// machine costs tens to hundreds of microseconds per batch. Past the bound they sleep: an idle pool
// (between fits) does not spin. time() measures the wall time inside ParallelFor, the wake-up
// latency of the workers and the caller's wait for them.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace mjsysid {

// The makespan of one ParallelFor batch on `workers` workers under the pool's scheduling: the tasks
// are claimed in index order by whichever worker is free first (all start at 0), so task i starts
// at the earliest finish of the tasks before it and ends cost[i] later; a task that follows
// another step by step (follows[i] = j < i, -1: none; the directional columns behind their
// rollout) also ends no earlier than task j; a task that continues another (after[i] = j < i, -1:
// none; a rollout's later pieces) holds its worker until task j has ended and only then starts.
// cost.size() tasks, follows and after empty or of that size.
long long ListScheduleMakespan(const std::vector<long long>& cost, const std::vector<int>& follows,
                               int workers, const std::vector<int>& after = {});

// what the meter recorded over many batches (ThreadPool::load)
struct PoolLoad {
  static constexpr int kModelWorkers = 4;
  long long batches = 0;
  long long work = 0;                      // sum of all task costs (= span[1])
  long long span[kModelWorkers + 1] = {};  // span[w]: sum of the batches' makespans on w workers
};

// the calling thread's CPU time in seconds (CLOCK_THREAD_CPUTIME_ID)
double ThreadCpuSeconds();

// The bound on threads, one rule everywhere (docs/cli.md "Threads").
//
// A thread count requested anywhere (the experiment's solver.threads, `sysid fit --threads`,
// `sysid simulate --threads`, the Python API, every MPI rank's) must be 0 (all cores) or
// 1..kMaxThreads: anything else is bad input, refused before any thread starts (ThreadRequestError
// says why, in one sentence). The cap is fixed, not the machine's core count, so that an
// experiment file that travels between a laptop and a cluster node means the same on both; 256 is
// above any core count a single process of this program can use (a fit's parallel work is its
// segments and Jacobian columns) and far below what exhausts a shared machine (the unbounded
// request `--threads 1000000` started ~32,000 threads, 2.4 GB of stacks, and every other
// process on the machine then failed to fork). A request above the machine's cores is honoured
// (results do not depend on the thread count, core/thread_pool.h's contract; the extra threads
// share the cores).
//
// Invariant: ThreadCount, and so ThreadPool's constructor, never gives more than kMaxThreads,
// whatever it is asked (a caller that skipped the check still cannot start more).
constexpr int kMaxThreads = 256;

// "" when num_threads is a valid request (0 .. kMaxThreads), else why not: "expected 0 (all
// cores) or a whole number from 1 to 256, got N"
std::string ThreadRequestError(long long num_threads);

// The threads a request of num_threads means: num_threads <= 0 is
// std::thread::hardware_concurrency() (at least 1); never more than kMaxThreads.
int ThreadCount(int num_threads);

// wall time of the pool's batches since construction or ResetLoad (steady_clock seconds)
struct PoolTime {
  long long batches = 0;     // ParallelFor calls with n > 0
  long long handed_off = 0;  // of them, those run by more than one worker (n > 1)
  double seconds = 0;        // inside ParallelFor, every batch
  double wake_seconds = 0;   // handed off: publication to the last worker's start, summed
  double wait_seconds = 0;   // handed off: the caller's wait after its own last task, summed
                             // (each of wake and wait is part of `seconds`, their sum need not
                             // be: a worker that starts late is waited for while it wakes)
  long long sleeps = 0;      // handed off: workers that were asleep when the batch came
  // the calling thread's CPU time inside ParallelFor (CLOCK_THREAD_CPUTIME_ID): at 1 thread the
  // batches' whole work, independent of other processes' load
  double cpu_seconds = 0;
  // the sum of two pools' times (a fit's simulators)
  PoolTime& operator+=(const PoolTime& o) {
    batches += o.batches;
    handed_off += o.handed_off;
    seconds += o.seconds;
    wake_seconds += o.wake_seconds;
    wait_seconds += o.wait_seconds;
    sleeps += o.sleeps;
    cpu_seconds += o.cpu_seconds;
    return *this;
  }
};

class ThreadPool {
 public:
  // how long a worker polls for the next batch, and the caller for the workers' end, before
  // sleeping on the condition variable (see Hand-off above)
  // (the environment variable MJSYSID_POOL_SPIN_US overrides it, in microseconds, 0: no spin; for
  // measuring the hand-off)
  static constexpr double kSpinSeconds = 200e-6;

  // num_threads <= 0 means std::thread::hardware_concurrency(); ThreadCount(num_threads) workers
  // (never more than kMaxThreads).
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
  // the same for tasks that continue another (after[i], see ListScheduleMakespan)
  void SetNextAfter(std::vector<int> after) {
    if (meter_) after_ = std::move(after);
  }

  // Sets the meter (see Task model above; nullptr: none, the default). meter(worker) is called on
  // that worker's thread before and after each of its tasks.
  void SetMeter(std::function<long long(int worker)> meter) { meter_ = std::move(meter); }
  // what the meter recorded since construction or ResetLoad (not during a ParallelFor)
  const PoolLoad& load() const { return load_; }
  // wall time of the batches since construction or ResetLoad (not during a ParallelFor)
  const PoolTime& time() const { return time_; }
  void ResetLoad() {
    load_ = PoolLoad();
    time_ = PoolTime();
  }

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
  std::atomic<int> busy_{0};         // workers still in the running batch
  std::atomic<long> generation_{0};  // batches published (written under mutex_)
  std::atomic<bool> stop_{false};    // written under mutex_
  // per worker (index worker - 1): when it started the running batch, whether it had slept
  std::vector<std::chrono::steady_clock::time_point> started_;
  std::vector<char> slept_;
  PoolTime time_;
  double spin_seconds_ = kSpinSeconds;
  std::exception_ptr error_;
  std::function<long long(int)> meter_;
  std::vector<long long> cost_;  // per task of the running batch (each slot written by its task)
  std::vector<int> follows_;     // SetNextFollows
  std::vector<int> after_;       // SetNextAfter
  PoolLoad load_;
};

}  // namespace mjsysid
